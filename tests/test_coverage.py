"""Camera-system design: DORI and lens tables, targets, selection, and a room with a pillar whose
plan is rendered with Cycles to check predicted against rendered visibility."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from usdscene.design.candidates import look_rotation
from usdscene.design.lenses import lens_intrinsics, load_lenses
from usdscene.design.occluders import Occluders
from usdscene.design.plan_request import PlanRequest
from usdscene.design.selection import select_cameras
from usdscene.design.targets import SURFACE_LIFT_M, box_points, parse_target_spec, targets_from_places
from usdscene.design.visibility import evaluate_visibility
from usdscene.labels.pixel_density import dori_class, dori_index, load_dori, pixel_density
from usdscene.errors import DocumentError
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

# --------------------------------------------------------------------------------------------
# Pure parts


def test_dori_classes_follow_iec_62676_4_thresholds():
    table = load_dori()
    assert [c.name for c in table] == ["monitor", "detect", "observe", "recognise", "identify", "inspect"]
    assert dori_class(62.5, table) == "observe" and dori_class(62.4, table) == "detect"
    assert dori_class(12.0, table) is None and dori_class(5000, table) == "inspect"
    assert dori_index(np.array([[0.0, 125.0], [np.nan, 250.0]]), table).tolist() == [[-1, 3], [-1, 4]]


def test_a_user_dori_table_replaces_the_shipped_one_and_bad_entries_are_named(tmp_path):
    path = tmp_path / "dori.json"
    path.write_text(json.dumps({"classes": [{"name": "see", "px_per_m": 40}, {"name": "read", "px_per_m": 400}]}))
    assert [c.name for c in load_dori(path)] == ["see", "read"]
    path.write_text(json.dumps({"classes": [{"name": "see", "px_per_m": -1}]}))
    with pytest.raises(DocumentError) as err:
        load_dori(path)
    assert "classes[0].px_per_m" in str(err.value) and "-1" in str(err.value)


def test_shipped_lenses_include_the_papers_fisheye_and_user_lenses_extend_them(tmp_path):
    lenses = load_lenses()
    paper = lenses["fisheye_118_2.13mm"]
    intr = lens_intrinsics(paper)
    assert intr.lens is LensModel.FISHEYE_EQUISOLID and intr.fov_deg == 118.0
    assert intr.fx_px == pytest.approx(2.13 * 640 / 4.0)
    extra = tmp_path / "mine.json"
    extra.write_text(json.dumps({"lenses": {"tele": {"model": "perspective", "focal_length_mm": 12,
                                                     "sensor_width_mm": 6.4, "resolution_px": [1920, 1080]}}}))
    both = load_lenses(extra)
    assert "tele" in both and "cctv_4mm" in both
    extra.write_text(json.dumps({"lenses": {"bad": {"model": "fisheye_equisolid", "focal_length_mm": 2,
                                                    "sensor_width_mm": 4, "resolution_px": [640, 480]}}}))
    with pytest.raises(DocumentError) as err:
        load_lenses(extra)
    assert "lenses.bad.fov_deg" in str(err.value)


@pytest.mark.parametrize("text, message", [
    ("seat_*:on,under", "unknown region 'under'"),
    ("seat_*", "expected PLACE_GLOB:REGION"),
    ("box:b:0,0,0,1,1", "expected box:NAME"),
    ("box:b:0,0,0,1,-1,1", "max corner not above"),
])
def test_bad_target_specs_are_named(text, message):
    with pytest.raises(DocumentError) as err:
        parse_target_spec(text)
    assert message in str(err.value) and err.value.problems[0].where == "--targets"


def test_box_points_stay_inside_the_box_on_two_layers():
    pts = box_points((0.4, 0.6, 0.5), 0.2)
    assert np.all(np.abs(pts[:, 0]) < 0.2) and np.all(np.abs(pts[:, 1]) < 0.3)
    assert sorted(set(np.round(pts[:, 2], 6))) == [SURFACE_LIFT_M, 0.25]


def test_pixel_density_of_a_pinhole_is_focal_over_distance():
    intr = Intrinsics(LensModel.PERSPECTIVE, 640, 480, 500.0, 500.0, 319.5, 239.5)
    cam = Camera("c", intr)  # at the origin looking down +z
    d = pixel_density(cam, np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 5.0]]))
    assert d == pytest.approx([250.0, 100.0], rel=1e-3)


def test_look_rotation_is_a_right_handed_opencv_frame():
    for forward in ([1, 0, 0], [0, 0, -1], [0.3, -0.5, -0.8]):
        r = look_rotation(forward)
        assert np.allclose(r.T @ r, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
        assert np.allclose(r[:, 2], np.asarray(forward) / np.linalg.norm(forward))
        assert r[2, 1] <= 1e-9  # image down never points to the sky


def _brute_force_minimum(cover: np.ndarray, demand: np.ndarray) -> int:
    for n in range(len(cover) + 1):
        for subset in itertools.combinations(range(len(cover)), n):
            if np.all(cover[list(subset)].sum(axis=0) >= demand):
                return n
    raise AssertionError("no cover")


@pytest.mark.parametrize("seed, k", [(0, 1), (1, 1), (2, 2), (3, 2)])
def test_selection_is_the_smallest_cover_and_greedy_is_never_smaller(seed, k):
    rng = np.random.default_rng(seed)
    cover = rng.random((10, 14)) < 0.3
    selection = select_cameras(cover, k, time_limit_s=10)
    demand = np.minimum(cover.sum(axis=0), k)
    assert np.all(cover[list(selection.chosen)].sum(axis=0) >= demand)
    assert len(selection.chosen) == _brute_force_minimum(cover, demand)
    assert selection.method == "milp" and selection.optimal and selection.gap == 0.0
    assert selection.greedy_size >= len(selection.chosen) >= selection.lower_bound
    assert selection.uncoverable == tuple(int(t) for t in np.flatnonzero(cover.sum(axis=0) == 0))


def test_ray_casting_blocks_only_before_the_end_point():
    tri = np.array([[[0.0, -1.0, -1.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]]])
    occ = Occluders(tri)
    blocked = occ.blocked(np.array([-1.0, 0.0, 0.0]), np.array([[1.0, 0.0, 0.0], [-0.1, 0.0, 0.0],
                                                                 [1.0, 0.0, 5.0]]))
    assert blocked.tolist() == [True, False, False]
    hits = occ.first_hit(np.array([[-1.0, 0, 0], [-1.0, 0, 0]]), np.array([[1.0, 0, 0], [-1.0, 0, 0]]))
    assert hits[0] == pytest.approx(1.0, abs=1e-5) and math.isinf(hits[1])


# --------------------------------------------------------------------------------------------
# A room with a pillar, composed from a real catalog and rendered with Cycles

ROOM = (6.0, 4.0, 3.0)     # x, y, z size; floor at z = 0, centred on x = y = 0
PILLAR = (0.6, 0.6, 3.0)   # at the centre, floor to ceiling
# Place regions (is_on): "open" is seen from both walls, "hidden" is behind the pillar for the
# camera on the -X wall.
SPOTS = {"spot_open": (-1.5, 1.2), "spot_hidden": (1.3, 0.0)}


def _box_mesh(stage, path, centre, size, inward):
    from pxr import Gf, UsdGeom

    sx, sy, sz = (s / 2 for s in size)
    pts = [(-sx, -sy, -sz), (sx, -sy, -sz), (sx, sy, -sz), (-sx, sy, -sz),
           (-sx, -sy, sz), (sx, -sy, sz), (sx, sy, sz), (-sx, sy, sz)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    if inward:
        faces = [tuple(reversed(f)) for f in faces]
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr([Gf.Vec3f(x + centre[0], y + centre[1], z + centre[2]) for x, y, z in pts])
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)


def _room_catalog(folder):
    from pxr import Usd, UsdGeom

    folder.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(folder / "room.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Room")
    stage.SetDefaultPrim(root.GetPrim())
    _box_mesh(stage, "/Room/Shell", (0, 0, ROOM[2] / 2), ROOM, inward=True)
    _box_mesh(stage, "/Room/Pillar", (0, 0, PILLAR[2] / 2), PILLAR, inward=False)
    stage.GetRootLayer().Save()
    places = {name: {"kind": "spot", "regions": {"is_on": {
        "matrix": [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, 0, 0, 0, 0, 1], "size_m": [0.4, 0.4, 0.3]}}}
        for name, (x, y) in SPOTS.items()}
    (folder / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1, "classes": {
        "pillar_room": {"kind": "environment", "usd": "room.usda", "extent_m": [[-3, -2, 0], [3, 2, 3]],
                        "relations": [], "places": places}}}))


def _wall_camera(name: str, x: float) -> Camera:
    intr = Intrinsics(LensModel.PERSPECTIVE, 160, 120, 80.0, 80.0, 79.5, 59.5, sensor_width_mm=6.4)
    target = np.array([0.0, 0.0, 0.0])
    position = np.array([x, 0.0, 2.2])
    return Camera(name, intr, pose=Pose.from_rotation_translation(look_rotation(target - position), position))


@pytest.fixture(scope="module")
def room_setup(tmp_path_factory):
    from usdscene.converters.openlabel import write_document, write_openlabel
    from usdscene.document.model import RenderSettings, SceneSpec

    root = tmp_path_factory.mktemp("pillar_room")
    _room_catalog(root / "assets")
    scene = SceneSpec(name="pillar_room", environment="pillar_room", asset_paths=("assets",),
                      cameras=(_wall_camera("west", -2.8), _wall_camera("east", 2.8)),
                      render=RenderSettings(samples=1, denoise=False, resolution_px=(160, 120)))
    document = root / "setup.openlabel.json"
    write_document(document, write_openlabel(scene))
    return root, document



@pytest.fixture(scope="module")
def rescored(room_setup):
    from usdscene.design.camera_design import plan_cameras

    root, document = room_setup
    return plan_cameras(PlanRequest.build(document, targets=["spot_*:on"], mounts="setup", dori="monitor", standard="2015",
                                          occluders="setup", target_spacing_m=0.1), root / "rescored")


@pytest.mark.usd
def test_target_behind_the_pillar_is_occluded_for_the_camera_that_cannot_see_it(rescored):
    report = rescored.coverage
    rows = {t["name"]: t for t in report["targets"]}
    # Only the chosen cameras are listed per target: the east camera sees both spots, so it is
    # the whole plan, and the west camera (blocked by the pillar) is not needed.
    assert [c["name"] for c in report["cameras"]] == ["east"]
    assert report["summary"]["holes"] == [] and report["summary"]["cameras"] == 1
    assert rows["spot_hidden:on"]["covering_cameras"] == 1
    assert rows["spot_open:on"]["cameras"][0]["dori"] in ("monitor", "detect")
    # Re-scoring lists every camera of the setup per target, chosen or not: the west camera
    # sees the open spot and has the hidden one in view with nothing visible.
    scored = {row["camera"]: row for row in rows["spot_open:on"]["scored"]}
    assert set(scored) == {"west", "east"} and scored["east"]["chosen"] and not scored["west"]["chosen"]
    assert scored["west"]["visible_fraction"] == 1.0 and scored["west"]["px_per_m"] > 0
    hidden = {row["camera"]: row for row in rows["spot_hidden:on"]["scored"]}
    assert hidden["west"]["visible_fraction"] == 0.0 and hidden["west"]["in_image_fraction"] == 1.0
    assert [c["name"] for c in report["scored_cameras"]] == ["west", "east"]
    assert report["summary"]["floor_area"]["share"] == 1.0 and report["summary"]["pairs"] >= 3


@pytest.mark.usd
def test_visibility_matrix_of_the_room(room_setup):
    from usdscene.design.camera_design import occluder_scene, read_setup, stage_triangles
    from usdscene.scene.compose import compose_stage

    root, document = room_setup
    setup, catalog = read_setup(document)
    composed = compose_stage(occluder_scene(setup, catalog, "setup"), catalog, root / "stage_vis")
    occ = Occluders(stage_triangles(composed.root_layer, 0))
    targets = targets_from_places(catalog.places("pillar_room"), [parse_target_spec("spot_*:on")],
                                      spacing_m=0.1)
    assert [t.name for t in targets] == ["spot_hidden:on", "spot_open:on"]
    vis = evaluate_visibility(setup.cameras, targets, occ, load_dori())
    west, east = 0, 1
    assert vis.in_image[west, 0] == 1.0 and vis.visible[west, 0] == 0.0  # in view, behind the pillar
    assert vis.visible[west, 1] == 1.0 and vis.visible[east].tolist() == [1.0, 1.0]
    assert 12.5 <= vis.px_per_m[east, 0] < 62.5


@pytest.mark.usd
def test_auto_mounts_cover_both_spots_and_the_plan_is_a_valid_openlabel_setup(room_setup, openlabel_schema_path):
    from usdscene.design.camera_design import plan_cameras
    from usdscene.converters.openlabel import read_openlabel, schema_problems

    root, document = room_setup
    lenses = root / "lenses.json"
    lenses.write_text(json.dumps({"lenses": {"small_wide": {
        "model": "perspective", "focal_length_mm": 2.8, "sensor_width_mm": 4.8, "resolution_px": [160, 120]}}}))
    request = PlanRequest.build(document, targets=["spot_*:on"], lenses_file=lenses, lens_names=["small_wide"],
                                dori="monitor", standard="2015", occluders="setup", spacing_m=1.0)
    plan = plan_cameras(request, root / "auto")
    assert plan.coverage["summary"]["holes"] == [] and 1 <= len(plan.chosen) <= 2
    written = json.loads((root / "auto" / "cameras.openlabel.json").read_text())
    assert schema_problems(written, openlabel_schema_path) == []
    back = read_openlabel(root / "auto" / "cameras.openlabel.json")
    assert [c.name for c in back.cameras] == [c.name for c in plan.chosen]
    assert back.cameras[0].intrinsics.width_px == 160
    image = (root / "auto" / "coverage.png").read_bytes()
    assert image[:8] == b"\x89PNG\r\n\x1a\n"
    # Same inputs, same bytes.
    plan_cameras(request, root / "auto2")
    for name in ("cameras.openlabel.json", "coverage.json", "coverage.png"):
        assert (root / "auto" / name).read_bytes() == (root / "auto2" / name).read_bytes()


@pytest.mark.usd
@pytest.mark.blender
def test_predicted_and_rendered_visibility_agree(room_setup, monkeypatch):
    from usdscene.design.camera_design import plan_cameras
    from usdscene.design.plan_verify import verify_plan

    root, document = room_setup
    # The plan document in root/both names ../assets: outside its folder, so consent to root.
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(root))
    # Re-score both wall cameras at k = 2 so that the blocked west camera is part of the plan.
    plan_cameras(PlanRequest.build(document, targets=["spot_*:on"], mounts="setup", dori="monitor", standard="2015",
                                   occluders="setup", target_spacing_m=0.1, k=2), root / "both")
    result = verify_plan(root / "both", resolution_scale=1.0, samples=1, marker_radius_m=0.06, progress=False)
    pairs = {(p["camera"], p["target"]): p for p in result.report["pairs"]}
    assert set(pairs) == {(c, t) for c in ("west", "east") for t in ("spot_hidden:on", "spot_open:on")}
    assert pairs["west", "spot_hidden:on"]["rendered_visible_fraction"] == 0.0
    assert pairs["east", "spot_hidden:on"]["rendered_visible_fraction"] >= 0.9
    assert result.agreement == 1.0 and result.points_agreeing >= 0.95 * result.points
    assert (root / "both" / "verify" / "sheet.png").stat().st_size > 0


def test_cli_reports_bad_arguments_readably(tmp_path, capsys):
    from usdscene.cli import main

    assert main(["plan-cameras", "-o", str(tmp_path / "p")]) == 2
    assert "needs --setup" in capsys.readouterr().err
    doc = tmp_path / "missing.json"
    assert main(["plan-cameras", "--setup", str(doc), "-o", str(tmp_path / "p"), "--targets", "seat_*:nowhere"]) == 1
    err = capsys.readouterr().err
    assert "usdscene: error: --targets: unknown region 'nowhere'" in err and "Traceback" not in err


@pytest.mark.usd
def test_a_request_over_the_memory_limit_stops_before_any_ray_with_one_line(room_setup, capsys):
    from usdscene.cli import main

    root, document = room_setup
    out = root / "too_big"
    assert main(["plan-cameras", "--setup", str(document), "-o", str(out), "--targets", "spot_*:on",
                 "--occluders", "setup", "--max-memory", "1e-9"]) == 1
    err = capsys.readouterr().err
    line = [row for row in err.splitlines() if "--max-memory" in row]
    assert len(line) == 1 and "2 targets x" in line[0] and "--cell" in line[0] and "Traceback" not in err
    assert not out.exists()  # nothing written
