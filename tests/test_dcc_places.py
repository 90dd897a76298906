"""Places authored in DCC files (``assets add --kind environment``), variant sets of added USD
assets, and the whole path: DCC environment → generated document → tiny render → labels of
objects resting on their places.

Every file is built inside the test: a Y-up GLB in metres, a Y-up USD file in centimetres, an
OBJ, and a Y-up centimetre vehicle USD with two variant sets.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from test_compose_support import look_at_cv
from usdscene.document import model as m
from usdscene.assetgen.asset_import import ImportOptions, import_asset
from usdscene.scene.catalog import load_catalog
from usdscene.cli import main
from usdscene.errors import AssetError

pytestmark = pytest.mark.usd

BENCH_TOP_M = 0.45


def _glb_environment(path: Path) -> Path:
    """A Y-up glTF car-park corner in metres: a floor (top at 0), a bench (top at 0.45) and
    three places: a box on the floor, a box on the bench, an empty scaled to a kerb."""
    import trimesh

    scene = trimesh.Scene()
    floor = trimesh.creation.box([10.0, 0.1, 8.0])
    floor.apply_translation([0.0, -0.05, 0.0])
    floor.visual.face_colors = [110, 110, 115, 255]
    scene.add_geometry(floor, node_name="floor", geom_name="floor")
    bench = trimesh.creation.box([2.0, BENCH_TOP_M, 0.5])
    bench.apply_translation([3.0, BENCH_TOP_M / 2, 3.0])
    bench.visual.face_colors = [150, 90, 40, 255]
    scene.add_geometry(bench, node_name="bench", geom_name="bench")
    bay = np.eye(4)
    bay[:3, 3] = [-2.0, 1.0, 0.0]  # a 2.5 x 2 (up) x 5 m box standing on the floor
    scene.add_geometry(trimesh.creation.box([2.5, 2.0, 5.0]), node_name="place.bay_01.on", geom_name="bay",
                       transform=bay)
    seat = np.eye(4)
    seat[:3, 3] = [3.0, BENCH_TOP_M + 0.3, 3.0]
    scene.add_geometry(trimesh.creation.box([1.8, 0.6, 0.4]), node_name="place.bench_1.on", geom_name="seat",
                       transform=seat)
    kerb = np.diag([0.5, 0.5, 1.0, 1.0])  # an empty: the cube -1..1 scaled to 1 x 1 (up) x 2 m
    kerb[:3, 3] = [1.0, 0.5, -2.0]
    scene.graph.update(frame_to="place.kerb_1.on", frame_from="world", matrix=kerb)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def _usd_environment_cm(path: Path) -> Path:
    """The same kind of corner as a Y-up USD file in centimetres: a floor (top at 0), a bay
    box turned 90° about the up axis, an empty named as a place and an Xform marked by the
    ``usdscene_place`` property."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/Env")
    stage.SetDefaultPrim(root.GetPrim())
    floor = UsdGeom.Mesh.Define(stage, "/Env/floor")
    lo, hi = (-500.0, -10.0, -400.0), (500.0, 0.0, 400.0)
    corners = [(x, y, z) for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])]
    floor.CreatePointsAttr(corners)
    floor.CreateFaceVertexCountsAttr([4] * 6)
    floor.CreateFaceVertexIndicesAttr([0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5])
    floor.CreateExtentAttr([lo, hi])
    bay = UsdGeom.Cube.Define(stage, "/Env/Marks/place_bay_02_on")  # how exporters write place.bay_02.on
    bay.CreateSizeAttr(1.0)
    xf = UsdGeom.Xformable(bay)
    xf.AddTranslateOp().Set(Gf.Vec3d(200.0, 100.0, 0.0))
    xf.AddRotateYOp().Set(90.0)
    xf.AddScaleOp().Set(Gf.Vec3d(250.0, 200.0, 500.0))
    walk = UsdGeom.Xform.Define(stage, "/Env/walk_marker")
    UsdGeom.Xformable(walk).AddTranslateOp().Set(Gf.Vec3d(-300.0, 50.0, 100.0))
    UsdGeom.Xformable(walk).AddScaleOp().Set(Gf.Vec3d(40.0, 50.0, 40.0))
    walk.GetPrim().CreateAttribute("userProperties:usdscene_place", Sdf.ValueTypeNames.String).Set("walkway_1.on")
    kerb = UsdGeom.Xform.Define(stage, "/Env/place_kerb_2_on")  # an empty of 1 x 1 (up) x 1 m
    UsdGeom.Xformable(kerb).AddTranslateOp().Set(Gf.Vec3d(-300.0, 50.0, -200.0))
    UsdGeom.Xformable(kerb).AddScaleOp().Set(Gf.Vec3d(50.0, 50.0, 50.0))
    stage.Save()
    return path


def _vehicle_usd_cm(path: Path) -> Path:
    """A Y-up centimetre vehicle with variant sets ``model`` (sedan, van) and ``paint`` (red,
    blue, white) on its default prim, each paint a UsdPreviewSurface colour."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/Vehicle").GetPrim()
    stage.SetDefaultPrim(root)
    material = UsdShade.Material.Define(stage, "/Vehicle/Looks/Paint")
    shader = UsdShade.Shader.Define(stage, "/Vehicle/Looks/Paint/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    color = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    models = root.GetVariantSets().AddVariantSet("model")
    for name, (length, height, width) in {"sedan": (450.0, 140.0, 180.0), "van": (500.0, 200.0, 190.0)}.items():
        models.AddVariant(name)
        models.SetVariantSelection(name)
        with models.GetVariantEditContext():
            body = UsdGeom.Cube.Define(stage, "/Vehicle/Body")
            body.CreateSizeAttr(1.0)
            ops = UsdGeom.Xformable(body)
            ops.AddTranslateOp().Set(Gf.Vec3d(0.0, height / 2 + 15.0, 0.0))  # 15 cm ground clearance
            ops.AddScaleOp().Set(Gf.Vec3d(length, height, width))
            UsdShade.MaterialBindingAPI.Apply(body.GetPrim()).Bind(material)
    models.SetVariantSelection("sedan")
    paints = root.GetVariantSets().AddVariantSet("paint")
    for name, rgb in {"red": (0.6, 0.05, 0.04), "blue": (0.05, 0.1, 0.5), "white": (0.8, 0.8, 0.8)}.items():
        paints.AddVariant(name)
        paints.SetVariantSelection(name)
        with paints.GetVariantEditContext():
            color.Set(Gf.Vec3f(*rgb))
    paints.SetVariantSelection("white")
    stage.Save()
    return path


@pytest.fixture()
def workdir(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "assets").mkdir()
    return tmp_path


def _region(entry, place: str, relation: str = "is_on"):
    region = entry.places[place].regions[relation]
    return region.pose.as_array(), np.array(region.size_m)


def test_places_from_a_y_up_glb_and_obj(workdir):
    _glb_environment(workdir / "corner.glb")
    entry = import_asset("corner.glb", "corner", "assets", ImportOptions(kind="environment"))
    assert sorted(entry.places) == ["bay_01", "bench_1", "kerb_1"]
    assert {p.kind for p in entry.places.values()} == {"bay", "bench", "kerb"}
    # Y up → Z up: file (x, y, z) is (x, -z, y); the box's bottom face is the support surface.
    pose, size = _region(entry, "bay_01")
    np.testing.assert_allclose(pose, [[1, 0, 0, -2.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-9)
    np.testing.assert_allclose(size, [2.5, 5.0, 2.0])
    pose, size = _region(entry, "bench_1")
    np.testing.assert_allclose(pose[:3, 3], [3.0, -3.0, BENCH_TOP_M], atol=1e-9)
    np.testing.assert_allclose(size, [1.8, 0.4, 0.6])
    pose, size = _region(entry, "kerb_1")  # the empty
    np.testing.assert_allclose(pose[:3, 3], [1.0, 2.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(size, [1.0, 2.0, 1.0])
    # The place boxes are not scenery: the asset is the floor and the bench only.
    np.testing.assert_allclose(entry.extent_max_m, (5.0, 4.0, BENCH_TOP_M), atol=1e-4)
    # ... and the asset carries the places for any USD tool, as the shipped cabin does.
    from pxr import Usd

    stage = Usd.Stage.Open(str(entry.usd_path))
    assert stage.GetPrimAtPath(f"{stage.GetDefaultPrim().GetPath()}/Places/bay_01/on").IsValid()
    assert len([p for p in stage.Traverse() if p.GetTypeName() == "Mesh"]) == 2  # floor and bench colours

    (workdir / "hall.obj").write_text(
        "o floor\nv -5 0 -4\nv 5 0 -4\nv 5 0 4\nv -5 0 4\nf 1 3 2\nf 1 4 3\n"
        "o place.gate_3.in_front\nv 0 0 0\nv 2 0 0\nv 2 2 5\nv 0 2 5\nf 5 6 7\nf 5 7 8\n")
    assert main(["assets", "add", "hall.obj", "--class", "hall", "--kind", "environment",
                 "--catalog", "assets"]) == 0
    hall = load_catalog(["assets"], include_default=False)["hall"]
    pose, size = _region(hall, "gate_3", "is_in_front_of")
    np.testing.assert_allclose(pose[:3, 3], [1.0, -2.5, 0.0], atol=1e-9)
    np.testing.assert_allclose(size, [2.0, 5.0, 2.0])


def test_places_from_a_y_up_centimetre_usd_file(workdir):
    _usd_environment_cm(workdir / "corner_cm.usda")
    entry = import_asset("corner_cm.usda", "corner_cm", "assets", ImportOptions(kind="environment"))
    assert sorted(entry.places) == ["bay_02", "kerb_2", "walkway_1"]
    pose, size = _region(entry, "bay_02")
    # 90° about the file's up axis is +90° about Z; centimetres become metres.
    np.testing.assert_allclose(pose, [[0, -1, 0, 2.0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-9)
    np.testing.assert_allclose(size, [2.5, 5.0, 2.0])
    pose, size = _region(entry, "walkway_1")  # an Xform without geometry, marked by its property
    np.testing.assert_allclose(pose[:3, 3], [-3.0, -1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(size, [0.8, 0.8, 1.0])
    np.testing.assert_allclose(entry.extent_max_m, (5.0, 4.0, 0.0), atol=1e-4)  # place boxes inactive


def test_bad_place_boxes_are_named_and_nothing_is_written(workdir, capsys):
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box([4.0, 0.1, 4.0]), node_name="floor", geom_name="floor")
    scene.add_geometry(trimesh.creation.box([1.0, 1.0, 1.0]), node_name="place.bay_01.onn", geom_name="typo")
    scene.add_geometry(trimesh.creation.box([1.0, 1.0, 1.0]), node_name="place.bay_02.undr", geom_name="typo2")
    (workdir / "typo.glb").write_bytes(scene.export(file_type="glb"))
    assert main(["assets", "add", "typo.glb", "--class", "typo", "--kind", "environment",
                 "--catalog", "assets"]) == 1
    err = capsys.readouterr().err
    assert "usdscene: error:" in err and "place.bay_01.onn" in err and "in_front" in err
    assert "place.bay_02.undr" in err  # every misspelt place at once, not the first only
    assert not (workdir / "assets" / "catalog.json").exists()

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box([4.0, 0.1, 4.0]), node_name="floor", geom_name="floor")
    scene.add_geometry(trimesh.creation.box([1.0, 1.0, 1.0]), node_name="place.bay_01.on", geom_name="a")
    flat = np.diag([1.0, 0.0, 1.0, 1.0])
    scene.add_geometry(trimesh.creation.box([1.0, 1.0, 1.0]), node_name="place_bay_01_on", geom_name="b",
                       transform=flat)
    (workdir / "twice.glb").write_bytes(scene.export(file_type="glb"))
    with pytest.raises(AssetError) as info:
        import_asset("twice.glb", "twice", "assets", ImportOptions(kind="environment"))
    assert "no volume" in str(info.value) or "already has" in str(info.value)


def test_variant_sets_of_an_added_usd_file_are_document_appearances(workdir):
    from pxr import Usd

    _vehicle_usd_cm(workdir / "vehicle.usda")
    entry = import_asset("vehicle.usda", "vehicle", "assets", ImportOptions())
    combos = ("sedan-blue", "sedan-red", "sedan-white", "van-blue", "van-red", "van-white")  # USD sorts names
    assert entry.variants == {"appearance": combos}
    assert entry.default_variants == {"appearance": "sedan-white"}
    # Centimetres and Y up converted; the default sedan is 4.5 m long and 1.4 m high, its
    # lowest point (not the file's origin 15 cm below it) at the asset origin.
    np.testing.assert_allclose(entry.extent_min_m, (-2.25, -0.9, 0.0), atol=1e-4)
    np.testing.assert_allclose(entry.extent_max_m, (2.25, 0.9, 1.4), atol=1e-4)
    stage = Usd.Stage.Open(str(entry.usd_path))
    root = stage.GetDefaultPrim()
    source = root.GetChild("Source")
    root.GetVariantSet("appearance").SetVariantSelection("van-blue")
    assert source.GetVariantSet("model").GetVariantSelection() == "van"
    assert source.GetVariantSet("paint").GetVariantSelection() == "blue"
    shader = stage.GetPrimAtPath(source.GetPath().AppendPath("Looks/Paint/Surface"))
    np.testing.assert_allclose(shader.GetAttribute("inputs:diffuseColor").Get(), (0.05, 0.1, 0.5), atol=1e-6)


def _setup_document(path: Path, environment: str) -> Path:
    from usdscene.converters.openlabel import write_document, write_openlabel

    camera = m.Camera(name="cam", intrinsics=m.Intrinsics(
        lens=m.LensModel.PERSPECTIVE, width_px=64, height_px=48, fx_px=30.0, fy_px=30.0, cx_px=31.5, cy_px=23.5,
        sensor_width_mm=6.4), pose=look_at_cv((0.0, -9.0, 6.0), (0.0, 0.0, 0.3)))
    sun = m.Light(uid="0", name="sun", kind=m.LightKind.SUN, power_w=4.0,
                  pose=m.Pose.from_rotation_translation(np.eye(3), (0.0, 0.0, 10.0)))
    setup = m.SceneSpec(name=f"{environment}_setup", cameras=(camera,), lights=(sun,), environment=environment,
                        asset_paths=("assets",), seed=3,
                        render=m.RenderSettings(samples=2, denoise=False, resolution_px=(64, 48)))
    write_document(path, write_openlabel(setup))
    return path


@pytest.mark.blender
@pytest.mark.parametrize("source", ["glb", "usd_cm"])
def test_dcc_environment_to_labels_of_objects_resting_on_their_places(workdir, source):
    from pxr import Usd, UsdGeom

    from usdscene.pipeline import run_pipeline

    if source == "glb":
        _glb_environment(workdir / "env.glb")
        env_file = "env.glb"
    else:
        _usd_environment_cm(workdir / "env.usda")
        env_file = "env.usda"
    _vehicle_usd_cm(workdir / "vehicle.usda")
    assert main(["assets", "add", env_file, "--class", "corner", "--kind", "environment", "--catalog", "assets"]) == 0
    assert main(["assets", "add", "vehicle.usda", "--class", "vehicle", "--catalog", "assets"]) == 0
    _setup_document(workdir / "setup.openlabel.json", "corner")
    assert main(["generate", "appearance", "--setup", "setup.openlabel.json", "-o", "doc.openlabel.json",
                 "--frames", "1", "--classes", "vehicle", "backpack", "trolley_suitcase", "--seed", "5"]) == 0
    summary = run_pipeline(workdir / "doc.openlabel.json", workdir / "out", progress=False)
    assert summary.images_written == 1
    assert {"vehicle", "backpack", "trolley_suitcase"} <= set(summary.labels_per_class)

    # Every object rests on the support surface of the place its relation names: its lowest
    # point is the region's z = 0 plane (not floating, not sunk) and it stands inside the box.
    catalog = load_catalog(["assets"], base_dir=workdir)
    places = catalog.places("corner")
    doc = json.loads((workdir / "doc.openlabel.json").read_text())["openlabel"]
    names = {uid: o["name"] for uid, o in doc["objects"].items()}
    stage = Usd.Stage.Open(str(workdir / "out" / "stage" / "scene.usda"))
    cache = UsdGeom.BBoxCache(Usd.TimeCode(0), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    checked = 0
    for relation in doc["relations"].values():
        subject = relation["rdf_subjects"][0]["uid"]
        place = places[names[relation["rdf_objects"][0]["uid"]]]
        region = place.regions[relation["type"]]
        prim = next(p for p in stage.Traverse() if p.GetCustomDataByKey("usdscene:uid") == subject)
        box = cache.ComputeWorldBound(prim).ComputeAlignedRange()
        lo, hi = np.array(box.GetMin()), np.array(box.GetMax())
        local = np.linalg.inv(region.pose.as_array())
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        inside = (local @ corners.T).T[:, :3]
        assert abs(inside[:, 2].min()) < 2e-3, (prim.GetPath(), inside[:, 2].min())
        centre = inside[:, :2].mean(axis=0)
        assert np.all(np.abs(centre) <= np.array(region.size_m[:2]) / 2 + 1e-6), (prim.GetPath(), centre)
        checked += 1
    assert checked == 3


BLEND_SCENE = """
import sys
import bpy

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_plane_add(size=10, location=(0, 0, 0))
bpy.context.active_object.name = "floor"
# a box named by the convention: 2.4 x 5.0 x 0.5 m, bottom face on the floor
bpy.ops.mesh.primitive_cube_add(size=2, location=(1, 2, 0.25))
box = bpy.context.active_object
box.name = "place.bay_01.on"
box.scale = (1.2, 2.5, 0.25)
# an empty marked by the custom property instead of its name: the 1 m cube around it
bpy.ops.object.empty_add(type="CUBE", location=(-3, 0, 0.5))
empty = bpy.context.active_object
empty.name = "marker"
empty.scale = (0.5, 0.5, 0.5)
empty["usdscene_place"] = "kerb_01.on"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
"""


@pytest.mark.blender
def test_places_from_a_blend_file(tmp_path):
    """A Blender project goes through Blender's USD export in a worker process, then the USD
    path: a named box and a property-marked empty become places, in metres, Z up."""
    import subprocess
    import sys

    from usdscene.assetgen.asset_import import ImportOptions, import_asset

    blend = tmp_path / "garage.blend"
    subprocess.run([sys.executable, "-c", BLEND_SCENE, str(blend)], check=True, capture_output=True)
    entry = import_asset(blend, "garage", tmp_path / "catalog", ImportOptions(kind="environment"),
                         allowed_roots=[tmp_path])
    assert sorted(entry.places) == ["bay_01", "kerb_01"]
    bay = entry.places["bay_01"].regions["is_on"]
    assert np.allclose(bay.size_m, (2.4, 5.0, 0.5), atol=1e-6)
    assert np.allclose(bay.pose.as_array()[:3, 3], (1.0, 2.0, 0.0), atol=1e-6)
    kerb = entry.places["kerb_01"].regions["is_on"]
    assert np.allclose(kerb.size_m, (1.0, 1.0, 1.0), atol=1e-6)
    assert np.allclose(entry.extent_max_m[:2], (5.0, 5.0), atol=1e-6)  # the floor, not the markers
    assert (tmp_path / "catalog" / "imported" / "garage.blend.usda").is_file()
    assert not list((tmp_path / "catalog").rglob("*.partial.usda"))


@pytest.mark.blender
def test_a_broken_blend_file_is_one_error(tmp_path):
    from usdscene.assetgen.asset_import import ImportOptions, import_asset
    from usdscene.errors import AssetError

    broken = tmp_path / "broken.blend"
    broken.write_text("not a Blender file")
    with pytest.raises(AssetError) as error:
        import_asset(broken, "broken", tmp_path / "catalog", ImportOptions(kind="environment"),
                     allowed_roots=[tmp_path])
    assert str(broken) in str(error.value)
    assert not (tmp_path / "catalog" / "catalog.json").exists()
