"""Scenes from other people's files: every way of writing a Y-up scene, variant sets whose
variants differ in size, orientation rules, colour slots, forward axes, implausible units,
unreachable variants, files outside the working folder, place kinds and the catalog listing.

Every input is built inside the test, the way an exporter or a script writes it: Y-up GLBs
with the Z-up → Y-up turn in the node transforms or baked into the vertices (Blender's
exporter), a USD file with a ``rotateX -90`` root, multi-variant vehicles in centimetres.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.assetgen.asset_import import ImportOptions, import_asset
from usdscene.cli import main
from usdscene.document import model as m
from usdscene.errors import AssetError
from usdscene.scene.catalog import load_catalog

pytestmark = pytest.mark.usd

# Z-up → Y-up: (x, y, z) → (x, z, -y), as glTF exporters turn a Z-up scene.
Z_TO_Y = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
# Bays in Z-up metres: (name, centre x, centre y, yaw deg); 2.4 x 5.0 m, 2.2 m clearance.
BAYS = (("bay_A1", -3.0, 4.0, 0.0), ("bay_A2", 0.0, 4.0, 0.0), ("bay_B1", 3.0, -4.0, 30.0))
BAY_SIZE = (2.4, 5.0, 2.2)


@pytest.fixture()
def workdir(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "assets").mkdir()
    return tmp_path


def _placed(x: float, y: float, z: float, yaw_deg: float = 0.0) -> np.ndarray:
    a = math.radians(yaw_deg)
    out = np.eye(4)
    out[:3, :3] = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]
    out[:3, 3] = (x, y, z)
    return out


def _lot_parts():
    """(floor mesh, [(place node name, box mesh, placement)]) in Z-up metres; each box is
    centred on its node, which stands on the floor."""
    import trimesh

    floor = trimesh.creation.box([14.0, 14.0, 0.2])
    floor.apply_translation([0.0, 0.0, -0.1])
    floor.visual.face_colors = [120, 120, 118, 255]
    boxes = [(f"place.{name}.on", trimesh.creation.box(BAY_SIZE), _placed(x, y, BAY_SIZE[2] / 2, yaw))
             for name, x, y, yaw in BAYS]
    return floor, boxes


def glb_turned_nodes(path: Path) -> Path:
    """Y-up glTF whose nodes carry the turn (Sketchfab, 3ds Max, trimesh scenes): every mesh
    is Z up in its own frame, every node is ``Z_TO_Y @ placement``."""
    import trimesh

    floor, boxes = _lot_parts()
    scene = trimesh.Scene()
    scene.add_geometry(floor, node_name="floor", geom_name="floor", transform=Z_TO_Y)
    for name, box, placed in boxes:
        scene.add_geometry(box, node_name=name, geom_name=name, transform=Z_TO_Y @ placed)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def glb_baked(path: Path) -> Path:
    """Y-up glTF as Blender's exporter writes it: the turn baked into the vertices, node
    transforms expressed in Y-up axes."""
    import trimesh

    floor, boxes = _lot_parts()
    scene = trimesh.Scene()
    scene.add_geometry(floor.copy().apply_transform(Z_TO_Y), node_name="floor", geom_name="floor")
    for name, box, placed in boxes:
        scene.add_geometry(box.copy().apply_transform(Z_TO_Y), node_name=name, geom_name=name,
                           transform=Z_TO_Y @ placed @ Z_TO_Y.T)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def usd_rotated_root(path: Path) -> Path:
    """Y-up USD file whose root prim is ``rotateX -90`` over a Z-up modelled scene."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Lot")
    root.AddRotateXOp().Set(-90.0)
    stage.SetDefaultPrim(root.GetPrim())
    floor, boxes = _lot_parts()
    _usd_mesh(stage, "/Lot/floor", floor)
    for name, box, placed in boxes:
        prim = _usd_mesh(stage, f"/Lot/{name.replace('.', '_')}", box)
        UsdGeom.Xformable(prim).AddTransformOp().Set(Gf.Matrix4d(placed.T.tolist()))
    stage.Save()
    return path


def _usd_mesh(stage, path: str, mesh):
    from pxr import UsdGeom

    usd = UsdGeom.Mesh.Define(stage, path)
    usd.CreatePointsAttr(np.asarray(mesh.vertices, dtype=np.float32).tolist())
    usd.CreateFaceVertexCountsAttr([3] * len(mesh.faces))
    usd.CreateFaceVertexIndicesAttr(np.asarray(mesh.faces).reshape(-1).tolist())
    usd.CreateExtentAttr([mesh.vertices.min(axis=0).tolist(), mesh.vertices.max(axis=0).tolist()])
    return usd


def _crate_obj(path: Path, size=(1.2, 2.0, 1.0)) -> Path:
    """A Z-up box object in metres (a stand-in for a small vehicle)."""
    import trimesh

    box = trimesh.creation.box(size)
    box.apply_translation([0.0, 0.0, size[2] / 2])
    box.export(str(path))
    return path


def _scene_on(places: list[str], environment: str, classes: list[str], seed: int = 4) -> m.SceneSpec:
    objects, refs, relations = [], [], []
    for i, (place, class_name) in enumerate(zip(places, classes)):
        objects.append(m.SceneObject(uid=str(i), name=f"{class_name}_{i}", class_name=class_name,
                                     randomization=m.Randomization(position_noise_m=0.2, rotation_noise_deg=5.0)))
        refs.append(m.PlaceRef(uid=str(100 + i), name=place))
        relations.append(m.Relation(uid=str(i), type="is_on", subject_uid=str(i), object_uid=str(100 + i)))
    return m.SceneSpec(name="lot", environment=environment, objects=tuple(objects), places=tuple(refs),
                       relations=tuple(relations), seed=seed, asset_paths=("assets",))


# --------------------------------------------------------------------------------------------
# 1. Place boxes under rotated nodes


def test_every_way_of_writing_a_y_up_scene_gives_the_same_regions_and_poses(workdir):
    from usdscene.scene.compose import compose_stage

    glb_turned_nodes(workdir / "turned.glb")
    glb_baked(workdir / "baked.glb")
    usd_rotated_root(workdir / "rotated.usda")
    _crate_obj(workdir / "crate.obj")
    import_asset("crate.obj", "crate", "assets", ImportOptions(up_axis="Z"))
    regions, poses = {}, {}
    for source, name in (("turned.glb", "lot_turned"), ("baked.glb", "lot_baked"), ("rotated.usda", "lot_usd")):
        entry = import_asset(source, name, "assets", ImportOptions(kind="environment"))
        regions[name] = {p: (place.regions["is_on"].pose.as_array(), place.regions["is_on"].size_m)
                         for p, place in entry.places.items()}
    catalog = load_catalog(["assets"], base_dir=workdir)
    for name in regions:
        scene = _scene_on(["bay_A1", "bay_B1"], name, ["crate", "crate"])
        result = compose_stage(scene, catalog, workdir / name / "stage")
        poses[name] = {uid: p.spans[0].pose.as_array() for uid, p in result.placements.items()}
    # The modelled truth: each bay's region is the box's bottom face, Z up, its x along the bay.
    for place, x, y, yaw in BAYS:
        expected = _placed(x, y, 0.0, yaw)
        for name in regions:
            pose, size = regions[name][place]
            np.testing.assert_allclose(pose, expected, atol=1e-6, err_msg=f"{name} {place}")
            assert size == BAY_SIZE, (name, place, size)
    for name in ("lot_baked", "lot_usd"):
        for place in regions["lot_turned"]:
            assert np.array_equal(regions[name][place][0], regions["lot_turned"][place][0]), (name, place)
        for uid in poses["lot_turned"]:
            np.testing.assert_allclose(poses[name][uid], poses["lot_turned"][uid], atol=1e-12)
    # The crate stands upright on the asphalt: its up axis is world Z, its base at z = 0.
    for pose in poses["lot_turned"].values():
        assert pose[2, 2] == pytest.approx(1.0) and pose[2, 3] == pytest.approx(0.0, abs=1e-9)


def test_a_place_box_with_no_vertical_axis_is_refused_with_its_node(workdir):
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box([8.0, 0.1, 8.0]), node_name="floor", geom_name="floor")
    tilted = np.eye(4)
    tilted[:3, :3] = trimesh.transformations.rotation_matrix(math.radians(20.0), [1, 0, 0])[:3, :3]
    scene.add_geometry(trimesh.creation.box([2.0, 2.0, 5.0]), node_name="place.ramp_1.on", geom_name="ramp",
                       transform=tilted)
    (workdir / "ramp.glb").write_bytes(scene.export(file_type="glb"))
    with pytest.raises(AssetError) as info:
        import_asset("ramp.glb", "ramp", "assets", ImportOptions(kind="environment"))
    assert "place.ramp_1.on" in str(info.value) and "vertical" in str(info.value)
    assert not (workdir / "assets" / "catalog.json").exists()


# --------------------------------------------------------------------------------------------
# Vehicles as other people model them: Y up, centimetres, variants of different sizes whose
# file origins differ (the rear axle here), a paint material not named Body, facing +Y.

# model: (width, length, height, ground clearance, rear overhang), metres
VEHICLE_MODELS = {"sedan": (1.8, 4.6, 1.45, 0.15, 0.9), "van": (1.95, 4.9, 2.05, 0.2, 0.5),
                  "formula": (1.9, 4.8, 1.0, 0.05, 1.4), "truck": (2.1, 4.9, 2.58, 0.25, 0.6)}
PAINTS = {"red": (0.6, 0.05, 0.04), "green": (0.1, 0.55, 0.08), "blue": (0.05, 0.1, 0.6)}


def vehicle_usd(path: Path, models=VEHICLE_MODELS, paints=PAINTS) -> Path:
    """A Y-up centimetre vehicle facing +Y (once Z up) with variant sets ``model`` and
    ``paint`` on its default prim; the paint is ``Looks/Paint/Surface``; the front bumper is
    the prim ``Nose``. The file's origin is the rear axle, so every model has its own offset."""
    import trimesh
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/Car").GetPrim()
    stage.SetDefaultPrim(root)
    material = UsdShade.Material.Define(stage, "/Car/Looks/Paint")
    shader = UsdShade.Shader.Define(stage, "/Car/Looks/Paint/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    color = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.6)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    to_cm_y_up = Z_TO_Y @ np.diag([100.0, 100.0, 100.0, 1.0])
    models_set = root.GetVariantSets().AddVariantSet("model")
    for name, (width, length, height, clearance, rear) in models.items():
        models_set.AddVariant(name)
        models_set.SetVariantSelection(name)
        with models_set.GetVariantEditContext():
            body = trimesh.creation.box([width, length, height - clearance])
            body.apply_translation([0.0, length / 2 - rear, clearance + (height - clearance) / 2])
            nose = trimesh.creation.box([width * 0.8, 0.1, 0.2])
            nose.apply_translation([0.0, length - rear - 0.05, clearance + 0.3])
            for prim_name, mesh in (("Body", body), ("Nose", nose)):
                usd = _usd_mesh(stage, f"/Car/{prim_name}", mesh.copy().apply_transform(to_cm_y_up))
                UsdShade.MaterialBindingAPI.Apply(usd.GetPrim()).Bind(material)
    models_set.SetVariantSelection(next(iter(models)))
    paints_set = root.GetVariantSets().AddVariantSet("paint")
    for name, rgb in paints.items():
        paints_set.AddVariant(name)
        paints_set.SetVariantSelection(name)
        with paints_set.GetVariantEditContext():
            color.Set(Gf.Vec3f(*rgb))
    paints_set.SetVariantSelection(next(iter(paints)))
    stage.Save()
    return path


def _world_bounds(stage, uid: str, frame: int):
    from pxr import Usd, UsdGeom

    cache = UsdGeom.BBoxCache(Usd.TimeCode(frame), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    prim = next(p for p in stage.Traverse() if p.GetCustomDataByKey("usdscene:uid") == uid)
    return prim, cache.ComputeWorldBound(prim)


def _corners_in_region(bound, region_pose: np.ndarray) -> np.ndarray:
    """(8, 3) corners of an oriented USD bound in a region's frame."""
    box = bound.GetBox()
    lo, hi = np.array(box.GetMin()), np.array(box.GetMax())
    matrix = np.array(bound.GetMatrix()).T
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return (np.linalg.inv(region_pose) @ matrix @ corners.T).T[:, :3]


# 2. Variants other than the default keep their own origin and extent


def test_every_variant_rests_on_its_support_and_centred_in_its_bay(workdir):
    from pxr import Usd

    from usdscene.scene.compose import compose_stage

    models = {k: v for k, v in VEHICLE_MODELS.items() if k != "truck"}
    vehicle_usd(workdir / "car.usda", models=models, paints={"red": PAINTS["red"]})
    glb_turned_nodes(workdir / "lot.glb")
    import_asset("lot.glb", "lot", "assets", ImportOptions(kind="environment"))
    entry = import_asset("car.usda", "car", "assets", ImportOptions(forward_axis="+Y"))
    assert set(entry.variant_extents["appearance"]) == {"sedan-red", "van-red", "formula-red"}
    for name, (lo, hi) in entry.variant_extents["appearance"].items():
        width, length, height, clearance, _ = models[name.split("-")[0]]
        np.testing.assert_allclose(lo, (-width / 2, -length / 2, 0.0), atol=1e-3, err_msg=name)
        np.testing.assert_allclose(hi, (width / 2, length / 2, height - clearance), atol=1e-3, err_msg=name)  # no wheels
    catalog = load_catalog(["assets"], base_dir=workdir)
    scene = _scene_on(["bay_A1", "bay_A2", "bay_B1"], "lot", ["car"] * 3)
    scene = dataclasses.replace(scene, objects=tuple(dataclasses.replace(o, appearance=a) for o, a in
                                           zip(scene.objects, ("sedan-red", "van-red", "formula-red"))))
    result = compose_stage(scene, catalog, workdir / "stage")
    stage = Usd.Stage.Open(str(result.root_layer))
    places = catalog.places("lot")
    for obj, rel in zip(scene.objects, scene.relations):
        region = places[scene.place_by_uid()[rel.object_uid].name].regions["is_on"]
        _, bound = _world_bounds(stage, obj.uid, 0)
        inside = _corners_in_region(bound, region.pose.as_array())
        assert abs(inside[:, 2].min()) < 0.01, (obj.appearance, inside[:, 2].min())  # not floating
        half = np.array(region.size_m[:2]) / 2
        assert np.all(np.abs(inside[:, :2]) <= half + 1e-3), (obj.appearance, inside[:, :2])  # inside the bay


# 3. Orientation rules: vehicles are never laid on a side


def test_a_class_that_only_fits_lying_down_is_not_laid_down_unless_its_rule_allows(workdir, capsys):
    from usdscene.errors import CompositionError
    from usdscene.scene.compose import compose_stage
    from usdscene.scene.placement import fits_region

    glb_turned_nodes(workdir / "lot.glb")
    import_asset("lot.glb", "lot", "assets", ImportOptions(kind="environment"))
    truck = {"truck": VEHICLE_MODELS["truck"]}  # 2.58 m tall, the bays have 2.2 m clearance
    vehicle_usd(workdir / "truck.usda", models=truck, paints={"red": PAINTS["red"]})
    assert main(["assets", "add", "truck.usda", "--class", "truck", "--catalog", "assets"]) == 0
    assert main(["assets", "add", "truck.usda", "--class", "crate_any", "--catalog", "assets",
                 "--orientations", "any"]) == 0
    catalog = load_catalog(["assets"], base_dir=workdir)
    assert catalog["truck"].orientations == "upright_turned"  # the default of assets add
    assert not fits_region(catalog["truck"], BAY_SIZE)
    assert fits_region(catalog["crate_any"], BAY_SIZE)  # lying on a side, as the rule allows
    with pytest.raises(CompositionError) as info:
        compose_stage(_scene_on(["bay_A1"], "lot", ["truck"]), catalog, workdir / "stage")
    assert "upright or turned" in str(info.value) and "lying" not in str(info.value)
    # The generator leaves it out and says so; asked for it alone, it fails.
    _setup_document(workdir / "setup.openlabel.json", "lot")
    capsys.readouterr()
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "doc.openlabel.json",
                 "--frames", "1", "--classes", "truck"]) == 1
    assert "truck" in capsys.readouterr().err
    # The shipped library: passengers and cups stay upright, luggage may lie in a bin.
    shipped = load_catalog()
    assert shipped["passenger"].orientations == "upright_turned"
    assert shipped["coffee_cup"].orientations == "upright_turned"
    assert shipped["trolley_suitcase"].orientations == "any"


def _setup_document(path: Path, environment: str, width: int = 64, height: int = 48) -> Path:
    from test_compose_support import look_at_cv
    from usdscene.converters.openlabel import write_document, write_openlabel

    camera = m.Camera(name="cam", intrinsics=m.Intrinsics(
        lens=m.LensModel.PERSPECTIVE, width_px=width, height_px=height, fx_px=0.5 * width, fy_px=0.5 * width,
        cx_px=(width - 1) / 2, cy_px=(height - 1) / 2, sensor_width_mm=6.4),
        pose=look_at_cv((0.0, -1.0, 16.0), (0.0, 0.0, 0.0)))
    sun = m.Light(uid="0", name="sun", kind=m.LightKind.SUN, power_w=4.0,
                  pose=m.Pose.from_rotation_translation(np.eye(3), (0.0, 0.0, 10.0)))
    setup = m.SceneSpec(name=f"{environment}_setup", cameras=(camera,), lights=(sun,), environment=environment,
                        asset_paths=("assets",), seed=3,
                        render=m.RenderSettings(samples=4, denoise=False, resolution_px=(width, height)))
    write_document(path, write_openlabel(setup))
    return path


# 4. Colours: only a colour the asset really shows is recorded


def test_a_colour_goes_to_the_named_paint_or_is_not_recorded(workdir, caplog):
    from pxr import Usd

    from usdscene.scene.compose import compose_stage

    vehicle_usd(workdir / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]})
    glb_turned_nodes(workdir / "lot.glb")
    import_asset("lot.glb", "lot", "assets", ImportOptions(kind="environment"))
    with caplog.at_level(logging.WARNING):
        plain = import_asset("car.usda", "plain_car", "assets", ImportOptions())
    assert plain.color_shader == "" and "--color-material" in caplog.text
    painted = import_asset("car.usda", "car", "assets", ImportOptions(color_material="Looks/Paint"))
    assert painted.color_shader == "Source/Looks/Paint/Surface"
    with pytest.raises(AssetError) as info:
        import_asset("car.usda", "bad", "assets", ImportOptions(color_material="Looks/Nothing"))
    assert "Looks/Nothing" in str(info.value)

    catalog = load_catalog(["assets"], base_dir=workdir)
    scene = _scene_on(["bay_A1", "bay_A2"], "lot", ["plain_car", "car"])
    scene = dataclasses.replace(scene, objects=tuple(dataclasses.replace(o, color_rgb=(0.54, 0.94, 0.13))
                                                     for o in scene.objects))
    with caplog.at_level(logging.WARNING):
        result = compose_stage(scene, catalog, workdir / "stage")
    assert "plain_car" in caplog.text
    colours = {o.class_name: o.color_rgb for o in result.resolved.objects}
    assert colours == {"plain_car": None, "car": (0.54, 0.94, 0.13)}  # what the labels will record
    stage = Usd.Stage.Open(str(result.root_layer))
    for obj in result.resolved.objects:
        prim, _ = _world_bounds(stage, obj.uid, 0)
        shader = stage.GetPrimAtPath(prim.GetPath().AppendPath("Source/Looks/Paint/Surface"))
        value = tuple(shader.GetAttribute("inputs:diffuseColor").Get())
        if obj.class_name == "car":
            np.testing.assert_allclose(value, (0.54, 0.94, 0.13), atol=1e-6)
        else:
            np.testing.assert_allclose(value, PAINTS["red"], atol=1e-6)  # the asset's own paint, unrecorded
        assert not stage.GetPrimAtPath(prim.GetPath().AppendPath("Looks/Body/Surface"))


# 5. Forward axis


def test_an_asset_facing_plus_y_is_turned_to_face_minus_y(workdir):
    from pxr import Usd, UsdGeom

    vehicle_usd(workdir / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]}, paints={"red": PAINTS["red"]})
    entries = {axis: import_asset("car.usda", f"car_{i}", "assets", ImportOptions(forward_axis=axis))
               for i, axis in enumerate(("-Y", "+Y"))}
    assert load_catalog(["assets"], base_dir=workdir)["car_1"].forward_axis == "+Y"
    noses = {}
    for axis, entry in entries.items():
        stage = Usd.Stage.Open(str(entry.usd_path))
        cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
        nose = stage.GetDefaultPrim().GetPrimAtPath("Source/Nose")
        noses[axis] = np.array(cache.ComputeWorldBound(nose).ComputeAlignedRange().GetMidpoint())
    assert noses["-Y"][1] > 2.0  # as written, the front is at +Y ...
    assert noses["+Y"][1] < -2.0  # ... and turned, at -Y, where a document's "forward" is
    np.testing.assert_allclose(entries["+Y"].extent_min_m, (-0.9, -2.3, 0.0), atol=1e-3)
    with pytest.raises(AssetError):
        import_asset("car.usda", "car_x", "assets", ImportOptions(forward_axis="up"))


# Must show: a generated car park sequence from a multi-variant vehicle class


@pytest.mark.blender
def test_generated_car_park_vehicles_stand_in_their_bays_in_the_colour_recorded(workdir):
    import cv2
    from pxr import Usd

    from usdscene.document.output_layout import image_path, mask_ids, mask_path
    from usdscene.pipeline import run_pipeline

    glb_turned_nodes(workdir / "lot.glb")
    vehicle_usd(workdir / "vehicle.usda")
    assert main(["assets", "add", "lot.glb", "--class", "lot", "--kind", "environment", "--catalog", "assets"]) == 0
    assert main(["assets", "add", "vehicle.usda", "--class", "vehicle", "--catalog", "assets", "--forward-axis", "+Y",
                 "--orientations", "upright", "--color-material", "Looks/Paint"]) == 0
    _setup_document(workdir / "setup.openlabel.json", "lot", 128, 96)
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "doc.openlabel.json",
                 "--frames", "2", "--objects-per-frame", "3", "--classes", "vehicle", "--seed", "2"]) == 0
    summary = run_pipeline(workdir / "doc.openlabel.json", workdir / "out", progress=False)
    assert summary.images_written == 2

    from usdscene.converters.openlabel import read_openlabel

    scene = read_openlabel(workdir / "doc.openlabel.json")
    catalog = load_catalog(["assets"], base_dir=workdir)
    places, place_names = catalog.places("lot"), {p.uid: p.name for p in scene.places}
    ids = mask_ids(scene)
    stage = Usd.Stage.Open(str(workdir / "out" / "stage" / "scene.usda"))
    models = set()
    checked = 0
    for rel in scene.relations:
        frame = rel.frame_intervals[0].frame_start
        obj = scene.object_by_uid()[rel.subject_uid]
        models.add(obj.appearance.split("-")[0])
        region = places[place_names[rel.object_uid]].regions[rel.type]
        prim, bound = _world_bounds(stage, obj.uid, frame)
        inside = _corners_in_region(bound, region.pose.as_array())
        assert abs(inside[:, 2].min()) < 0.01, (obj.appearance, inside[:, 2].min())  # on the asphalt
        assert np.all(np.abs(inside[:, :2]) <= np.array(region.size_m[:2]) / 2 + 1e-3), obj.appearance
        from pxr import UsdGeom

        up = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(frame)))[2, :3]
        np.testing.assert_allclose(up, (0.0, 0.0, 1.0), atol=1e-9)  # upright, never on a side
        # The rendered paint has the hue of the colour the document (and so the labels) records.
        image = cv2.imread(str(image_path(workdir / "out", "cam", frame)))[:, :, ::-1] / 255.0
        mask = cv2.imread(str(mask_path(workdir / "out", "cam", frame)), cv2.IMREAD_UNCHANGED)
        pixels = image[mask == ids[obj.uid]]
        assert len(pixels) >= 20, (obj.uid, len(pixels))
        linear = np.where(pixels <= 0.04045, pixels / 12.92, ((pixels + 0.055) / 1.055) ** 2.4).mean(axis=0)
        recorded = np.array(obj.color_rgb)
        assert np.argmax(linear) == np.argmax(recorded), (obj.appearance, linear, recorded)
        cosine = linear @ recorded / np.linalg.norm(linear) / np.linalg.norm(recorded)
        assert cosine > 0.95, (obj.appearance, linear, recorded)
        checked += 1
    assert checked == 6 and "truck" not in models and len(models) >= 2


# 6. Implausible sizes are named, with the likely unit


def test_a_vehicle_modelled_in_centimetres_but_declared_in_metres_is_warned_about(workdir, caplog):
    from pxr import Usd, UsdGeom

    vehicle_usd(workdir / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]}, paints={"red": PAINTS["red"]})
    stage = Usd.Stage.Open(str(workdir / "car.usda"))  # the kit: centimetres, declared as metres
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.Save()
    with caplog.at_level(logging.WARNING):
        entry = import_asset("car.usda", "car", "assets", ImportOptions())
    assert max(entry.size_m) > 400  # registered as asked ...
    assert "implausible" in caplog.text and "--unit-scale 0.01" in caplog.text  # ... but not silently
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        import_asset("car.usda", "car_m", "assets", ImportOptions(unit_scale_m=0.01))
    assert "implausible" not in caplog.text
    glb_turned_nodes(workdir / "lot.glb")
    with caplog.at_level(logging.WARNING):
        import_asset("lot.glb", "tiny_lot", "assets", ImportOptions(kind="environment", unit_scale_m=0.001))
    assert "an environment" in caplog.text and "--unit-scale 1" in caplog.text


# 7. Requested classes that fit nowhere are named on the terminal


def test_generate_names_the_classes_it_leaves_out(workdir, capsys):
    glb_turned_nodes(workdir / "lot.glb")
    import_asset("lot.glb", "lot", "assets", ImportOptions(kind="environment"))
    vehicle_usd(workdir / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]}, paints={"red": PAINTS["red"]})
    import_asset("car.usda", "sedan", "assets", ImportOptions())
    vehicle_usd(workdir / "truck.usda", models={"truck": VEHICLE_MODELS["truck"]}, paints={"red": PAINTS["red"]})
    import_asset("truck.usda", "truck", "assets", ImportOptions())
    import_asset("truck.usda", "lorry", "assets", ImportOptions())
    _setup_document(workdir / "setup.openlabel.json", "lot")
    capsys.readouterr()
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "doc.openlabel.json",
                 "--frames", "1", "--classes", "sedan", "truck", "lorry", "backpack"]) == 0
    out = capsys.readouterr().out
    assert "left out" in out and "lorry, truck" in out
    assert "over 2 classes" in out
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "none.openlabel.json",
                 "--frames", "1", "--classes", "truck", "lorry"]) == 1
    err = capsys.readouterr().err
    assert "none of the classes lorry, truck fits" in err


# 8. Variants nobody can reach are warned about


def test_variant_sets_below_the_default_prim_and_classes_without_variants_are_warned_about(workdir, caplog,
                                                                                           capsys):
    from pxr import Usd, UsdGeom

    vehicle_usd(workdir / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]}, paints={"red": PAINTS["red"]})
    stage = Usd.Stage.Open(str(workdir / "car.usda"))
    for i in range(1, 3):  # the kit's wheels: a variant set on every wheel prim
        wheel = UsdGeom.Xform.Define(stage, f"/Car/wheel{i}").GetPrim()
        wheels = wheel.GetVariantSets().AddVariantSet("wheels")
        for name in ("wheelRed", "wheelBlack"):
            wheels.AddVariant(name)
        wheels.SetVariantSelection("wheelBlack")
    stage.Save()
    with caplog.at_level(logging.WARNING):
        entry = import_asset("car.usda", "car", "assets", ImportOptions())
    assert "wheel1:wheels" in caplog.text and "wheel2:wheels" in caplog.text
    assert entry.appearances == ("sedan-red",)
    glb_turned_nodes(workdir / "lot.glb")
    import_asset("lot.glb", "lot", "assets", ImportOptions(kind="environment"))
    _setup_document(workdir / "setup.openlabel.json", "lot")
    capsys.readouterr()
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "doc.openlabel.json",
                 "--frames", "1", "--classes", "car"]) == 0
    out = capsys.readouterr().out
    assert "one appearance only, so not varied: car" in out
    report = json.loads((workdir / "doc.openlabel.json.report.json").read_text())
    assert report["coverage"]["classes_without_variants"] == ["car"]
    # The car names no colour material (4.): the generated document records no colour for it.
    doc = json.loads((workdir / "doc.openlabel.json").read_text())["openlabel"]
    cars = [o for o in doc["objects"].values() if o["type"] == "car"]
    assert cars and all("color_rgb" not in json.dumps(o) for o in cars)
    from usdscene.scene.compose import draw_looks

    scene = _scene_on(["bay_A1"], "lot", ["car"])
    scene = dataclasses.replace(scene, objects=tuple(dataclasses.replace(
        o, randomization=m.Randomization(random_appearance=True)) for o in scene.objects))
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        draw_looks(scene, load_catalog(["assets"], base_dir=workdir), np.random.default_rng(0))
    assert "random appearance" in caplog.text and "'car'" in caplog.text


# 9. A file named on the command line may lie outside the working folder


def test_assets_add_reads_a_file_outside_the_working_folder(tmp_path, monkeypatch, caplog):
    project = tmp_path / "project"
    project.mkdir()
    monkeypatch.chdir(project)
    glb_turned_nodes(tmp_path / "lot.glb")
    assert main(["assets", "add", "../lot.glb", "--class", "lot", "--kind", "environment",
                 "--catalog", "assets"]) == 0
    assert len(load_catalog(["assets"], include_default=False)["lot"].places) == len(BAYS)
    vehicle_usd(tmp_path / "car.usda", models={"sedan": VEHICLE_MODELS["sedan"]}, paints={"red": PAINTS["red"]})
    with caplog.at_level(logging.WARNING):
        assert main(["assets", "add", "../car.usda", "--class", "car", "--catalog", "assets"]) == 0
    assert "--asset-path" in caplog.text  # scenes reading it there need the folder allowed
    # Paths found inside documents and catalogs stay contained.
    (project / "assets" / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1, "classes": {
        "car": {"kind": "object", "usd": "../../car.usda"}}}))
    with pytest.raises(AssetError) as info:
        load_catalog(["assets"], base_dir=project, include_default=False)
    assert "outside" in str(info.value)


# 10. Place kinds: the name without its number, row letters included


def test_place_kinds_drop_row_letters_with_the_number(workdir):
    from usdscene.scene.catalog import place_kind

    entry = import_asset(glb_turned_nodes(workdir / "lot.glb"), "lot", "assets", ImportOptions(kind="environment"))
    assert {place.kind for place in entry.places.values()} == {"bay"}
    assert [place_kind(n) for n in ("bay_A3", "bay_B12", "seat_03A", "bin_02L", "aisle_04", "gate_12_bench_3",
                                    "row12")] == ["bay", "bay", "seat", "bin", "aisle", "gate_12_bench", "row"]


# 11. The catalog listing: plain off a terminal, per region, and removing a class


def test_assets_list_off_a_terminal_per_region_and_remove(workdir, capsys):
    glb_turned_nodes(workdir / "lot.glb")
    _crate_obj(workdir / "crate.obj")
    assert main(["assets", "add", "lot.glb", "--class", "lot", "--kind", "environment", "--catalog", "assets"]) == 0
    assert main(["assets", "add", "crate.obj", "--class", "crate", "--catalog", "assets", "--up-axis", "Z"]) == 0
    capsys.readouterr()
    assert main(["assets", "list", "--catalog", "assets", "--no-default"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split("\t")[:3] == ["class", "kind", "size x*y*z (m)"]
    rows = {line.split("\t")[0]: line.split("\t") for line in lines[1:]}
    assert set(rows) == {"crate", "lot"} and rows["lot"][5] == "3" and rows["crate"][6] == "upright_turned"
    assert all("\t" in line and len(line.split("\t")) == 8 for line in lines)  # never wrapped
    assert main(["assets", "list", "--catalog", "assets", "--no-default", "--regions"]) == 0
    lines = capsys.readouterr().out.splitlines()
    regions = {line.split("\t")[1]: line.split("\t") for line in lines[1:]}
    assert set(regions) == {name for name, *_ in BAYS}
    assert regions["bay_B1"][4] == "2.40 x 5.00 x 2.20" and regions["bay_B1"][5] == "+0.00 +0.00 +1.00"
    assert regions["bay_B1"][7] == "30.0"
    assert main(["assets", "remove", "crate", "--catalog", "assets"]) == 0
    assert not (workdir / "assets" / "imported" / "crate.usda").exists()
    assert "crate" not in load_catalog(["assets"], include_default=False)
    assert main(["assets", "remove", "crate", "--catalog", "assets"]) == 1
    assert "not in this catalog" in capsys.readouterr().err
    assert main(["assets", "remove", "backpack"]) == 1  # the generated library is rebuilt, not edited
    assert "generated library" in capsys.readouterr().err
