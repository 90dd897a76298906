"""The camera planner in the open air: a ground, two posts, a kiosk and a tree, composed from a
real catalog; poles, façade mounts, mount nodes and user mounts; the rule that keeps cameras out
of the tree; why a target is uncoverable; the IEC 62676-4:2025 table; and a Cycles render of the
plan checking predicted against rendered visibility."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.design.mount_surfaces import is_mountable
from usdscene.design.plan_request import PlanRequest
from usdscene.document.model import Camera, Intrinsics, LensModel
from usdscene.errors import DocumentError
from usdscene.labels.pixel_density import class_index, dori_class, load_dori, pixel_density, standard_file

# Scene layout, metres, Z up. The tree's crown is where a pole of the 4 m grid would stand and
# right above a spot, so a planner without the mount rule puts cameras in it.
GROUND = (40.0, 30.0)
KIOSK = ((8.0, 4.0), (4.0, 3.0, 3.2))           # centre (x, y), size
POSTS = ((-10.0, -5.0), (10.0, -7.0))           # 0.2 m square, 6 m tall
TREE = (-6.0, 7.0)                              # trunk 0.3 m square to 2.5 m, crown 3 x 3 x 2.5 m above
CROWN_LO = (TREE[0] - 1.5, TREE[1] - 1.5, 2.5)
CROWN_HI = (TREE[0] + 1.5, TREE[1] + 1.5, 5.0)
SPOTS = {"spot_a": (-8.0, 0.0), "spot_b": (0.0, -3.0), "spot_c": (3.0, 7.0), "spot_d": (-5.0, 4.0)}


def _box(stage, path, lo, hi):
    from pxr import Gf, UsdGeom

    (x0, y0, z0), (x1, y1, z1) = lo, hi
    pts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    return mesh


def write_open_air_catalog(folder, *, mount_node: bool = False):
    """A catalog with one environment ``open_lot``: ground, posts, kiosk, tree, spots."""
    from pxr import Gf, Usd, UsdGeom

    folder.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(folder / "open_lot.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Lot")
    stage.SetDefaultPrim(root.GetPrim())
    gx, gy = GROUND[0] / 2, GROUND[1] / 2
    _box(stage, "/Lot/Ground", (-gx, -gy, -0.2), (gx, gy, 0.0))
    (kx, ky), (sx, sy, sz) = KIOSK
    _box(stage, "/Lot/Kiosk", (kx - sx / 2, ky - sy / 2, 0.0), (kx + sx / 2, ky + sy / 2, sz))
    for i, (px, py) in enumerate(POSTS):
        _box(stage, f"/Lot/LampPost_{i}", (px - 0.1, py - 0.1, 0.0), (px + 0.1, py + 0.1, 6.0))
    UsdGeom.Xform.Define(stage, "/Lot/OakTree")
    _box(stage, "/Lot/OakTree/Trunk", (TREE[0] - 0.15, TREE[1] - 0.15, 0.0), (TREE[0] + 0.15, TREE[1] + 0.15, 2.5))
    _box(stage, "/Lot/OakTree/Crown", CROWN_LO, CROWN_HI)
    if mount_node:
        # A bracket on the kiosk's west wall at 3 m, looking west (its -Z axis along world -X).
        node = UsdGeom.Xform.Define(stage, "/Lot/mount_kiosk_west")
        node.AddTranslateOp().Set(Gf.Vec3d(kx - sx / 2 - 0.1, ky, 3.0))
        node.AddRotateYOp().Set(90.0)
    stage.GetRootLayer().Save()
    places = {name: {"kind": "spot", "regions": {"is_on": {
        "matrix": [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, 0, 0, 0, 0, 1], "size_m": [1.2, 1.2, 1.6]}}}
        for name, (x, y) in SPOTS.items()}
    (folder / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1, "classes": {
        "open_lot": {"kind": "environment", "usd": "open_lot.usda",
                     "extent_m": [[-gx, -gy, -0.2], [gx, gy, 6.0]], "relations": [], "places": places}}}))


def write_setup(root, *, mount_node: bool = False):
    from usdscene.converters.openlabel import write_document, write_openlabel
    from usdscene.document.model import RenderSettings, SceneSpec

    write_open_air_catalog(root / "assets", mount_node=mount_node)
    scene = SceneSpec(name="open_lot", environment="open_lot", asset_paths=("assets",),
                      render=RenderSettings(samples=1, denoise=False, resolution_px=(320, 240)))
    document = root / "setup.openlabel.json"
    write_document(document, write_openlabel(scene))
    lenses = root / "lenses.json"
    lenses.write_text(json.dumps({"lenses": {"small_4mm": {
        "model": "perspective", "focal_length_mm": 4.0, "sensor_width_mm": 4.8, "resolution_px": [320, 240]}}}))
    return document, lenses


def _in_crown(points) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return np.all((pts >= np.asarray(CROWN_LO) - 0.1) & (pts <= np.asarray(CROWN_HI) + 0.1), axis=1)


# --------------------------------------------------------------------------------------------
# Pure parts


@pytest.mark.parametrize("path, flag, expected", [
    ("/World/Environment/Lot/OakTree/Crown", None, False),
    ("/World/Environment/Lot/hedge_01", None, False),
    ("/World/Environment/Lot/parked_vehicle_3", None, False),
    ("/World/Environment/Lot/Awning", None, False),
    ("/World/Environment/Lot/StreetLamp", None, True),      # "street" is no tree
    ("/World/Environment/car_park/floor", None, True),      # "car park" is no vehicle
    ("/World/Environment/Lot/Kiosk", None, True),
    ("/World/Environment/Lot/Tree_shelter", True, True),    # the attribute wins
    ("/World/Environment/Lot/GlassWall", False, False),
])
def test_mountable_rule_infers_from_names_and_the_attribute_wins(path, flag, expected):
    assert is_mountable(path, flag) is expected


def test_iec_62676_4_2025_is_the_planners_table_and_400_px_per_m_is_below_validate():
    table = load_dori(standard_file("2025"))
    assert [c.name for c in table] == ["overview", "outline", "discern", "perceive", "characterize", "validate",
                                       "scrutinize"]
    assert [c.group for c in table] == ["LPDO"] * 3 + ["HPDO"] * 4
    assert dori_class(500.0, table) == "validate" and dori_class(1500.0, table) == "scrutinize"
    # A pinhole of 400 px focal length sees a target 1 m away at 400 px/m.
    cam = Camera("c", Intrinsics(LensModel.PERSPECTIVE, 640, 480, 400.0, 400.0, 319.5, 239.5))
    density = float(pixel_density(cam, np.array([[0.0, 0.0, 1.0]]))[0])
    assert density == pytest.approx(400.0, rel=1e-3)
    assert dori_class(density, table) == "characterize"
    assert class_index(dori_class(density, table), table) < class_index("validate", table)
    assert PlanRequest(setup_document="x").standard == "2025" and PlanRequest(setup_document="x").level == "discern"
    assert [c.name for c in load_dori(standard_file("2015"))][-1] == "inspect"


def test_each_reason_for_an_uncoverable_target():
    from usdscene.design.visibility import Visibility, why_uncovered

    # Three candidates, four targets: nobody has t0 in view; t1 is in view but hidden; t2 is
    # seen by half of its points (>= 0.25) at class 0 only; t3 is seen too little and at class 1.
    vis = Visibility.from_dense(in_image=np.array([[0, 1, 1, 1], [0, 1, 0, 1], [0, 0, 0, 1.0]]),
                     visible=np.array([[0, 0, 0.5, 0.1], [0, 0, 0, 0.2], [0, 0, 0, 0.0]]),
                     px_per_m=np.zeros((3, 4)), dori=np.array([[-1, -1, 0, 1], [-1, -1, -1, 1], [-1, -1, -1, -1]]))
    why = why_uncovered(vis, [0, 1, 2, 3], min_visible=0.25, candidates=3)
    assert [(u.reason, u.best_dori) for u in why] == [("out of range", -1), ("occluded", -1),
                                                     ("too few pixels", 0), ("occluded", 1)]
    empty = Visibility.from_dense(np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 1), int))
    assert [(u.reason, u.best_dori) for u in why_uncovered(empty, [0], min_visible=0.25, candidates=0)] == \
        [("no mount", -1)]


def test_a_bad_request_names_every_option_at_once(tmp_path):
    with pytest.raises(DocumentError) as err:
        PlanRequest.build(tmp_path / "setup.json", mounts=str(tmp_path / "nowhere.json"), pole_heights_m=[-1],
                          standard="2019", min_visible=0.0)
    where = [p.where for p in err.value.problems]
    assert set(where) == {"--min-visible", "--pole-heights", "--standard", "--mounts"}
    assert "nowhere.json" in str(err.value) and "-1.0" in str(err.value)


def test_a_bad_mounts_file_names_every_problem(tmp_path):
    from usdscene.design.user_mounts import load_mounts

    path = tmp_path / "mounts.json"
    path.write_text(json.dumps({"mounts": [{"name": "a", "position_m": [0, 0]},
                                           {"name": "b", "position_m": [1, 2, 3], "look_at_m": [[1, 2, 3]]},
                                           {"name": "c", "position_m": [0, 0, 4], "aim": [1, 0, 0]}]}))
    with pytest.raises(DocumentError) as err:
        load_mounts(path)
    text = str(err.value)
    assert "mounts[0].position_m" in text and "mounts[1].look_at_m[0]" in text and "unknown field(s) aim" in text
    path.write_text(json.dumps({"mounts": [{"name": "gate", "position_m": [1, 2, 5], "look_at_m": [[1, 12, 0]]}]}))
    (mount,) = load_mounts(path)
    assert mount.surface == "user" and mount.name == "gate"
    assert np.allclose(mount.aims[0], np.array([0, 10, -5]) / np.linalg.norm([0, 10, -5]))


def test_a_point_beyond_the_image_border_is_not_seen_in_the_render():
    from usdscene.design.plan_verify import _rendered_points

    # Looking down +z from the origin; the first point projects 40 px above the image, the
    # second onto its centre. The mask holds the target's id everywhere but the centre.
    cam = Camera("c", Intrinsics(LensModel.PERSPECTIVE, 64, 48, 40.0, 40.0, 31.5, 23.5))
    mask = np.full((48, 64), 7, np.uint16)
    mask[20:28, 28:36] = 0
    pts = np.array([[0.0, -1.6, 1.0], [0.0, 0.0, 1.0]])
    assert _rendered_points(cam, pts, mask, 7, 0.01).tolist() == [False, False]
    mask[20:28, 28:36] = 7
    assert _rendered_points(cam, pts, mask, 7, 0.01).tolist() == [False, True]


# --------------------------------------------------------------------------------------------
# The open lot, composed and planned


@pytest.fixture(scope="module")
def open_lot(tmp_path_factory):
    root = tmp_path_factory.mktemp("open_lot")
    document, lenses = write_setup(root)
    return root, document, lenses


@pytest.fixture(scope="module")
def lot_plan(open_lot):
    from usdscene.design.camera_design import plan_cameras

    root, document, lenses = open_lot
    request = PlanRequest.build(document, targets=["spot_*:on"], lenses_file=lenses, occluders="setup",
                                dori="overview")
    return plan_cameras(request, root / "plan")


@pytest.mark.usd
def test_open_air_scene_gets_pole_and_facade_mounts_and_none_in_the_tree(open_lot, lot_plan):
    from usdscene.design.camera_design import scene_geometry
    from usdscene.design.candidates import candidate_mounts, open_air_mounts
    from usdscene.design.occluders import Occluders

    root, _, _ = open_lot
    report = lot_plan.coverage
    assert report["request"]["standard"] == "IEC 62676-4:2025" and report["request"]["dori"] == "overview"
    assert report["summary"]["holes"] == [] and len(lot_plan.chosen) >= 1
    assert not _in_crown([c.pose.translation_m for c in lot_plan.chosen]).any()
    # Every candidate mount, not only the chosen ones, stays out of the crown.
    triangles, surfaces, _ = scene_geometry(root / "plan" / "occluders" / "scene.usda", 0)
    assert any("OakTree/Crown" in p for p in surfaces.unmountable_paths)
    occ = Occluders(triangles)
    rooms = candidate_mounts(occ, occ.bounds_m, surfaces=surfaces, structure=Occluders(triangles[surfaces.mountable]))
    outdoor = open_air_mounts(occ, triangles, surfaces, occ.bounds_m)
    kinds = {m.surface for m in outdoor}
    assert kinds == {"pole", "facade"}
    assert not _in_crown([m.position_m for m in rooms + outdoor]).any()
    # Without the rule (everything mountable, nothing to keep clear of) the crown is a ceiling.
    naive = candidate_mounts(occ, occ.bounds_m)
    assert _in_crown([m.position_m for m in naive]).any()
    # Poles stand on the ground at the asked heights.
    heights = sorted({round(m.position_m[2], 3) for m in outdoor if m.surface == "pole"})
    assert heights == [4.0, 6.0]


@pytest.mark.usd
def test_uncoverable_targets_say_why_and_the_best_class_reached(open_lot):
    from usdscene.design.camera_design import plan_cameras

    root, document, lenses = open_lot
    # Inside the ground slab: in many images, seen by none.
    buried = "box:buried:-1,-1,-0.18,1,1,-0.02"
    far = "box:far_away:100,100,0,101,101,1"
    request = PlanRequest.build(document, targets=["spot_a:on", buried, far], lenses_file=lenses,
                                occluders="setup", dori="scrutinize")
    plan = plan_cameras(request, root / "why")
    why = plan.coverage["summary"]["why_uncoverable"]
    assert why["far_away"] == {"reason": "out of range", "best_dori": None}
    assert why["buried"] == {"reason": "occluded", "best_dori": None}
    assert why["spot_a:on"]["reason"] == "too few pixels"
    assert why["spot_a:on"]["best_dori"] in ("outline", "discern", "perceive", "characterize")
    with pytest.raises(DocumentError) as err:
        plan_cameras(PlanRequest.build(document, dori="observe"), root / "bad")
    assert "IEC 62676-4:2015" in str(err.value) and "--standard 2015" in str(err.value)


@pytest.mark.usd
def test_mount_nodes_and_user_mounts_are_candidates(tmp_path):
    from usdscene.design.camera_design import plan_cameras

    document, lenses = write_setup(tmp_path, mount_node=True)
    plan = plan_cameras(PlanRequest.build(document, targets=["spot_*:on"], lenses_file=lenses, occluders="setup",
                                          dori="overview", pole_heights_m=[]), tmp_path / "nodes")
    report = plan.coverage
    assert report["summary"]["mounts"] >= 1
    mounts = tmp_path / "mounts.json"
    mounts.write_text(json.dumps({"mounts": [
        {"name": "north_mast", "position_m": [0.0, 12.0, 6.0], "look_at_m": [[-2.0, 2.0, 0.0]]},
        {"name": "south_mast", "position_m": [0.0, -12.0, 6.0], "look_at_m": [[-2.0, -1.0, 0.0]]}]}))
    user = plan_cameras(PlanRequest.build(document, targets=["spot_*:on"], lenses_file=lenses, occluders="setup",
                                          dori="overview", mounts=str(mounts)), tmp_path / "user")
    positions = {tuple(c.pose.translation_m.round(3)) for c in user.chosen}
    assert positions <= {(0.0, 12.0, 6.0), (0.0, -12.0, 6.0)} and positions
    assert user.coverage["request"]["mounts"] == "mounts.json"


@pytest.mark.usd
def test_mount_node_of_the_environment_is_read(tmp_path):
    from usdscene.design.camera_design import plan_cameras, scene_geometry

    document, lenses = write_setup(tmp_path, mount_node=True)
    plan_cameras(PlanRequest.build(document, targets=["spot_a:on"], lenses_file=lenses, occluders="setup",
                                   dori="overview", pole_heights_m=[]), tmp_path / "p")
    _, _, nodes = scene_geometry(tmp_path / "p" / "occluders" / "scene.usda", 0)
    assert [n[0] for n in nodes] == ["mount_kiosk_west"]
    assert np.allclose(nodes[0][1], [KIOSK[0][0] - KIOSK[1][0] / 2 - 0.1, KIOSK[0][1], 3.0])
    assert np.allclose(nodes[0][2], [-1.0, 0.0, 0.0], atol=1e-6)


@pytest.mark.usd
@pytest.mark.blender
def test_open_air_plan_agrees_with_its_cycles_render(open_lot, lot_plan, monkeypatch):
    from usdscene.design.plan_verify import verify_plan

    root, _, _ = open_lot
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(root))
    result = verify_plan(root / "plan", resolution_scale=1.0, samples=1, marker_radius_m=0.08, progress=False)
    assert result.pairs >= len(lot_plan.chosen)
    assert result.agreement >= 0.95, result.report["pairs"]
    assert result.points_agreeing >= 0.95 * result.points


@pytest.mark.usd
def test_cli_says_why_a_target_is_uncoverable_in_one_line(open_lot, capsys):
    from usdscene.cli import main

    root, document, lenses = open_lot
    assert main(["plan-cameras", "--setup", str(document), "-o", str(root / "cli"), "--lenses", str(lenses),
                 "--occluders", "setup", "--dori", "validate", "--pole-heights", "4",
                 "--targets", "spot_a:on", "box:far_away:100,100,0,101,101,1"]) == 0
    out = capsys.readouterr().out
    assert "at >= validate (IEC 62676-4:2025)" in out
    assert "far_away: out of range; best class any candidate reaches: none" in out
    line = next(l for l in out.splitlines() if l.strip().startswith("spot_a:on:"))
    assert "too few pixels; best class any candidate reaches: " in line and line.split()[-1] != "none"
