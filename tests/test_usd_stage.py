"""Scene2VCD: document → stage → SceneSpec round trips, DCC-edited stages, Y-up/centimetre
stages and stages exported by Blender's USD exporter."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from test_compose_support import (assert_scenes_close, build_test_catalog, load_test_catalog, look_at_cv,
                                  pose_difference, scene_differences, small_scene)
from usdscene.document import model as m
from usdscene.scene.compose import compose_stage

pytestmark = pytest.mark.usd


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("usd_stage")
    build_test_catalog(root / "cat")
    return root


@pytest.fixture(scope="module")
def catalog(workdir):
    return load_test_catalog(workdir / "cat")


# --------------------------------------------------------------------------------------------
# Random scenes


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    return m.quaternion_to_rotation(rng.normal(size=4))


def _random_pose(rng: np.random.Generator, spread_m: float = 5.0) -> m.Pose:
    return m.Pose.from_rotation_translation(_random_rotation(rng), rng.uniform(-spread_m, spread_m, 3))


def _random_intervals(rng, start, end):
    a = int(rng.integers(start, end + 1))
    b = int(rng.integers(a, end + 1))
    return (m.FrameInterval(a, b),)


@st.composite
def random_scenes(draw) -> m.SceneSpec:
    """Scenes with every lens model, light kind, explicit and relation placed objects."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    start = draw(st.integers(0, 3))
    end = start + draw(st.integers(0, 4))
    frames = range(start, end + 1)
    cameras = []
    for i in range(draw(st.integers(1, 3))):
        lens = draw(st.sampled_from(list(m.LensModel)))
        w, h = int(rng.integers(16, 200)), int(rng.integers(16, 200))
        distortion = {m.LensModel.OPENCV_PINHOLE: tuple(rng.normal(0, 0.05, draw(st.sampled_from([4, 5, 8])))),
                      m.LensModel.OPENCV_FISHEYE: tuple(rng.normal(0, 0.01, 4))}.get(lens, ())
        fx = float(rng.uniform(10, 300))
        intr = m.Intrinsics(lens, w, h, fx, fx * float(rng.uniform(0.8, 1.2)),
                            float(rng.uniform(0, w - 1)), float(rng.uniform(0, h - 1)), distortion,
                            float(rng.uniform(90, 220)) if "fisheye" in lens.value else None,
                            float(rng.uniform(2.0, 36.0)))
        frame_poses = ()
        if draw(st.booleans()):
            frame_poses = tuple((f, _random_pose(rng)) for f in frames if rng.random() < 0.6)
        cameras.append(m.Camera(f"cam_{i}", intr, _random_pose(rng), frame_poses,
                                float(rng.uniform(0.001, 0.5)), float(rng.uniform(10, 5000)),
                                model_name=f"model {i}", description="random", custom={"k": i, "tags": ["a"]}))
    lights = []
    for i in range(draw(st.integers(0, 3))):
        kind = draw(st.sampled_from(list(m.LightKind)))
        lights.append(m.Light(f"l{i}", f"light_{i}", kind, _random_pose(rng), float(rng.uniform(0.1, 1000)),
                              tuple(float(c) for c in rng.random(3)), float(rng.uniform(0, 0.3)),
                              float(rng.uniform(1, 170)), float(rng.random()),
                              (float(rng.uniform(0.1, 2)), float(rng.uniform(0.1, 2))), float(rng.uniform(0, 5)),
                              _random_intervals(rng, start, end) if rng.random() < 0.5 else ()))
    places = (m.PlaceRef("p_hall", "hall"), m.PlaceRef("p_seat", "seat_01A"), m.PlaceRef("p_aisle", "aisle_01"))
    objects, relations = [], []
    box_uid = None
    for i in range(draw(st.integers(1, 6))):
        uid = f"obj{i}"
        cls = draw(st.sampled_from(["box", "cup", "bag"]))
        mode = draw(st.sampled_from(["pose", "frame_poses", "hall", "seat", "on_box"]))
        randomization = m.Randomization(float(rng.uniform(0, 0.05)), float(rng.uniform(0, 20)),
                                        draw(st.booleans()), draw(st.booleans()))
        intervals = _random_intervals(rng, start, end) if rng.random() < 0.7 else ()
        pose, frame_poses = None, ()
        if mode == "pose":
            pose = _random_pose(rng)
        elif mode == "frame_poses":
            pose = _random_pose(rng)
            frame_poses = tuple((f, _random_pose(rng)) for f in frames if rng.random() < 0.5)
        elif mode == "hall":
            relations.append(m.Relation(f"r{i}", "is_on", uid, "p_hall"))
        elif mode == "seat":
            cls = "cup"
            relations.append(m.Relation(f"r{i}a", "is_on", uid, "p_seat", (m.FrameInterval(start, start),)))
            relations.append(m.Relation(f"r{i}b", "is_on", uid, "p_aisle", (m.FrameInterval(start + 1, end),)))
        elif mode == "on_box" and box_uid is not None:
            cls, intervals = "cup", ()
            relations.append(m.Relation(f"r{i}", "is_on", uid, box_uid))
        else:
            pose = _random_pose(rng)
        if mode == "hall" and cls == "box" and not intervals:
            box_uid = uid
        colour = tuple(float(c) for c in rng.random(3)) if rng.random() < 0.3 else None
        objects.append(m.SceneObject(uid, f"object {i}", cls, intervals, pose, frame_poses, None, colour, randomization))
    render = m.RenderSettings(engine="cycles", device="cpu", samples=int(rng.integers(1, 64)),
                              adaptive_threshold=float(rng.uniform(0, 0.1)), denoise=draw(st.booleans()),
                              max_bounces=int(rng.integers(0, 12)), caustics=draw(st.booleans()),
                              tile_size_px=int(rng.integers(16, 4096)),
                              resolution_px=(int(rng.integers(16, 4000)), int(rng.integers(16, 4000))),
                              seed=int(rng.integers(0, 1000)), fast_gi=draw(st.booleans()),
                              fast_gi_method=draw(st.sampled_from(["replace", "add"])),
                              fast_gi_ao_bounces=int(rng.integers(0, 8)), fast_gi_distance_m=float(rng.uniform(0, 20)),
                              scrambling_distance=float(rng.uniform(0, 1)), auto_scrambling_distance=draw(st.booleans()))
    return m.SceneSpec(name="random", frame_start=start, frame_end=end, cameras=tuple(cameras), lights=tuple(lights),
                       objects=tuple(objects), places=places, relations=tuple(relations), render=render,
                       seed=int(rng.integers(0, 2**31)), environment="test_cabin", asset_paths=("cat",),
                       exports=("coco", "yolo"), roi_rules={"is_on": "ok"},
                       roi_ignore=draw(st.sampled_from([(), ("passenger",), ("cup", "object")])), description="random scene")


@given(scene=random_scenes())
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_random_scene_stage_round_trip(catalog, scene):
    from usdscene.converters.stage.usd_stage import scene_from_stage

    with tempfile.TemporaryDirectory() as tmp:
        result = compose_stage(scene, catalog, Path(tmp) / "stage")
        back = scene_from_stage(result.root_layer)
    assert_scenes_close(result.resolved, back)
    assert back.provenance.source_format == "usd"


def test_tolerance_helper_sees_small_differences():
    pose = m.Pose.from_rotation_translation(np.eye(3), (1, 2, 3))
    moved = m.Pose.from_rotation_translation(np.eye(3), (1, 2, 3 + 2e-6))
    turned = m.Pose.from_rotation_translation(m.euler_zyx_to_rotation(math.radians(2e-4), 0, 0), (1, 2, 3))
    assert scene_differences(pose, pose) == []
    assert scene_differences(pose, moved) and scene_differences(pose, turned)
    assert pose_difference(pose, turned)[1] == pytest.approx(2e-4, rel=1e-3)
    assert scene_differences(small_scene(), dataclasses.replace(small_scene(), seed=8))


def test_document_to_stage_to_document(tmp_path, workdir, catalog):
    """OpenLABEL document → SceneSpec → stage → SceneSpec → OpenLABEL document → SceneSpec."""
    from usdscene.converters.openlabel import read_openlabel, write_document, write_openlabel
    from usdscene.converters.stage.usd_stage import scene_from_stage

    write_document(tmp_path / "in.json", write_openlabel(dataclasses.replace(small_scene(), roi_ignore=("passenger",))))
    scene = read_openlabel(tmp_path / "in.json")
    result = compose_stage(scene, catalog, tmp_path / "stage")
    back = scene_from_stage(result.root_layer)
    write_document(tmp_path / "out.json", write_openlabel(back))
    again = read_openlabel(tmp_path / "out.json")
    assert_scenes_close(result.resolved, again)
    assert back.roi_ignore == again.roi_ignore == ("passenger",)  # the ROI rules judge the same objects
    assert again.objects[0].color_rgb is not None  # the drawn colour is now explicit


def test_export_openlabel_command(tmp_path, catalog, capsys):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.cli import main

    result = compose_stage(small_scene(), catalog, tmp_path / "stage")
    assert main(["export-openlabel", str(result.root_layer), "-o", str(tmp_path / "doc.json")]) == 0
    assert "2 cameras" in capsys.readouterr().out
    doc = read_openlabel(tmp_path / "doc.json")
    assert [o.class_name for o in doc.objects] == ["bag", "box", "cup", "cup"]
    assert main(["export-openlabel", str(result.stage_dir), "-o", str(tmp_path / "folder.json")]) == 0
    assert read_openlabel(tmp_path / "folder.json").objects == doc.objects
    assert main(["export-openlabel", str(tmp_path / "nothing.usda"), "-o", str(tmp_path / "x.json")]) == 1
    assert main(["export-openlabel", str(tmp_path / "doc.json"), "-o", str(tmp_path / "x.json")]) == 1
    assert "unsupported file type" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# Stages edited in a DCC tool


def test_stage_edited_in_a_dcc_tool(tmp_path, catalog):
    """Edits saved as a new strongest sublayer (what usdview/Maya/Houdini do): a moved and
    re-lensed camera, a light re-posed with TRS ops, a moved object."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    from usdscene.converters.stage.usd_stage import scene_from_stage

    result = compose_stage(small_scene(), catalog, tmp_path / "stage")
    edits = Sdf.Layer.CreateNew(str(tmp_path / "stage" / "edits.usda"))
    root = Sdf.Layer.FindOrOpen(str(result.root_layer))
    root.subLayerPaths.insert(0, "./edits.usda")
    root.Save()
    stage = Usd.Stage.Open(str(result.root_layer))
    stage.SetEditTarget(Usd.EditTarget(edits))

    new_cam = look_at_cv((0.0, -3.0, 2.0), (1.0, 0.0, 0.5))
    cam = stage.GetPrimAtPath("/World/Cameras/cam_fish")
    cam.GetAttribute("xformOp:transform").Set(Gf.Matrix4d(m.cv_pose_to_usd_pose(new_cam).as_array().T.tolist()))
    cam.GetAttribute("focalLength").Set(0.03)  # 3 mm: the user zoomed
    light = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Lights/cabin_light"))
    light.ClearXformOpOrder()
    light.AddTranslateOp().Set(Gf.Vec3d(1.0, 2.0, 2.5))
    light.AddRotateXYZOp().Set(Gf.Vec3f(0.0, 0.0, 90.0))
    box = stage.GetPrimAtPath("/World/Objects/box_o2")
    box_pose = m.Pose.from_rotation_translation(m.euler_zyx_to_rotation(0.3, 0, 0), (4.0, 4.0, 0.0))
    box.GetAttribute("xformOp:transform").Set(Gf.Matrix4d(box_pose.as_array().T.tolist()))
    stage.GetPrimAtPath("/World/Lights/reading_spot").GetAttribute("inputs:intensity").Set(100.0)
    edits.Save()

    back = scene_from_stage(result.root_layer)
    fish = back.camera("cam_fish")
    assert pose_difference(fish.pose, new_cam)[0] < 1e-9 and pose_difference(fish.pose, new_cam)[1] < 1e-6
    assert fish.intrinsics.lens == m.LensModel.OPENCV_FISHEYE  # model kept from the lens attributes
    assert fish.intrinsics.fx_px == pytest.approx(0.03 / 0.064 * 64, rel=1e-6)  # focal from USD: 30 px
    assert fish.intrinsics.distortion == (0.01, -0.002, 0.0, 0.0)
    aisle = back.camera("cam_aisle")
    assert aisle.intrinsics == small_scene().camera("cam_aisle").intrinsics  # untouched: exact
    cabin = next(lt for lt in back.lights if lt.name == "cabin_light")
    assert np.allclose(cabin.pose.translation_m, (1.0, 2.0, 2.5))
    assert np.allclose(cabin.pose.rotation @ [1, 0, 0], (0, 1, 0), atol=1e-6)
    spot = next(lt for lt in back.lights if lt.name == "reading_spot")
    assert spot.power_w == pytest.approx(100.0 * math.pi, rel=1e-6)  # edited intensity wins
    box_back = next(o for o in back.objects if o.uid == "o2")
    assert pose_difference(box_back.pose, box_pose) == pytest.approx((0.0, 0.0), abs=1e-9)
    cup = next(o for o in back.objects if o.uid == "o3")
    assert cup.pose == result.resolved.objects[2].pose  # the cup is its own prim: not moved


def test_y_up_centimetre_stage(tmp_path):
    """A Y-up stage in centimetres: poses come back Z-up in metres. Only the world axes are
    converted; object frames are asset frames (Z up), cameras and lights look down their -Z."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

    from usdscene.converters.stage.usd_stage import scene_from_stage

    stage = Usd.Stage.CreateNew(str(tmp_path / "yup.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    thing = UsdGeom.Xform.Define(stage, "/root/thing")
    thing.AddTranslateOp().Set(Gf.Vec3d(50.0, 20.0, -100.0))
    thing.AddRotateYOp().Set(30.0)
    for name, value in (("usdscene_uid", "t1"), ("usdscene_class", "bag")):
        thing.GetPrim().CreateAttribute(f"userProperties:{name}", Sdf.ValueTypeNames.String).Set(value)
    cam = UsdGeom.Camera.Define(stage, "/root/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, 150.0, 300.0))
    cam.AddRotateXOp().Set(-20.0)
    cam.CreateFocalLengthAttr(5.0)          # tenths of a cm = mm: a 5 mm lens
    cam.CreateHorizontalApertureAttr(6.4)
    cam.CreateVerticalApertureAttr(4.8)
    UsdLux.DomeLight.Define(stage, "/root/env_light")  # like Blender's exported world: not a scene light
    light = UsdLux.SphereLight.Define(stage, "/root/lamp")
    light.CreateIntensityAttr(10.0)
    light.CreateRadiusAttr(5.0)
    light.AddTranslateOp().Set(Gf.Vec3d(0.0, 250.0, 0.0))
    stage.Save()

    scene = scene_from_stage(tmp_path / "yup.usda")
    y_to_z = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
    (obj,) = scene.objects
    assert (obj.uid, obj.class_name, scene.frame_start, scene.frame_end) == ("t1", "bag", 1, 3)
    # Any point of the object lands where the stage puts it, converted to Z-up metres.
    world_y = np.asarray(UsdGeom.Xformable(thing).ComputeLocalToWorldTransform(1)).T
    for local in ([0, 100, 0], [30, 0, 10]):
        expected = y_to_z @ (world_y @ np.r_[local, 1.0])[:3] * 0.01
        got = obj.pose.transform_points(np.asarray(local, float) * 0.01)[0]
        assert np.allclose(got, expected, atol=1e-9)
    assert obj.pose.translation_m == pytest.approx((0.5, 1.0, 0.2))
    (camera,) = scene.cameras
    assert camera.pose.translation_m == pytest.approx((0.0, -3.0, 1.5))
    # It looks 20° down from the stage's -Z (= scene +Y) direction.
    forward = camera.pose.rotation @ [0, 0, 1]
    assert forward == pytest.approx((0.0, math.cos(math.radians(20)), -math.sin(math.radians(20))))
    assert camera.intrinsics.fx_px == pytest.approx(5.0 / 6.4 * scene.render.resolution_px[0])
    assert camera.intrinsics.sensor_width_mm == pytest.approx(6.4)
    (lamp,) = scene.lights
    assert lamp.kind == m.LightKind.POINT and lamp.radius_m == pytest.approx(0.05)
    assert lamp.pose.translation_m == pytest.approx((0.0, 0.0, 2.5))
    assert lamp.power_w == pytest.approx(10.0 * math.pi)


def test_transform_authored_only_as_one_time_sample(tmp_path):
    """Blender's exporter writes a still object's transform as a single time sample and no
    default value: it must read back as that transform, not as the identity."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    from usdscene.converters.stage.usd_stage import scene_from_stage

    stage = Usd.Stage.CreateNew(str(tmp_path / "sampled.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(4)
    thing = UsdGeom.Xform.Define(stage, "/root/thing")
    thing.AddTranslateOp().Set(Gf.Vec3d(1.5, -2.0, 0.25), 1.0)  # time sample only
    for name, value in (("usdscene_uid", "t1"), ("usdscene_class", "bag")):
        thing.GetPrim().CreateAttribute(f"userProperties:{name}", Sdf.ValueTypeNames.String).Set(value)
    stage.Save()

    (obj,) = scene_from_stage(tmp_path / "sampled.usda").objects
    assert obj.pose.translation_m == pytest.approx((1.5, -2.0, 0.25))
    assert obj.frame_poses == ()


# --------------------------------------------------------------------------------------------
# Blender


_BLENDER_SCRIPT = textwrap.dedent("""
    import json, sys
    import bpy
    stage, out_dir = sys.argv[1], sys.argv[2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=stage)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    report = {"cameras": {}, "lights": {}}
    for ob in bpy.data.objects:
        if ob.type == "CAMERA":
            c = ob.data
            report["cameras"][ob.name] = {"lens_mm": c.lens, "sensor_mm": c.sensor_width, "shift_x": c.shift_x,
                                          "shift_y": c.shift_y}
        if ob.type == "LIGHT":
            report["lights"][ob.name] = {"type": ob.data.type, "energy_w": ob.data.energy}
        if "usdscene_uid" in ob.keys() and ob.get("usdscene_class") not in ("camera", "light", "environment"):
            colours = []
            for child in ob.children_recursive:
                for slot in getattr(child, "material_slots", []):
                    for node in (slot.material.node_tree.nodes if slot.material and slot.material.node_tree else []):
                        if node.type == "BSDF_PRINCIPLED":
                            colours.append(list(node.inputs["Base Color"].default_value[:3]))
            report.setdefault("colours", {})[ob["usdscene_uid"]] = colours
    with open(out_dir + "/report.json", "w") as handle:
        json.dump(report, handle)
    bpy.ops.wm.usd_export(filepath=out_dir + "/z_up_m.usda", export_animation=True)
    bpy.ops.wm.usd_export(filepath=out_dir + "/y_up_cm.usda", export_animation=True, convert_orientation=True,
                          export_global_forward_selection="NEGATIVE_Z", export_global_up_selection="Y",
                          convert_scene_units="CENTIMETERS")
""")


@pytest.mark.blender
def test_blender_import_and_export(tmp_path, catalog):
    """A real Blender 5.0 round: Blender's importer reads the focal length in tenths of a metre,
    the light intensities as the document's watts and the colour opinions and appearance
    variants into the materials; the stages Blender exports (Z-up metres and Y-up centimetres)
    read back to the same cameras, lights and objects."""
    from usdscene.converters.stage.usd_stage import scene_from_stage

    scene = small_scene()
    result = compose_stage(scene, catalog, tmp_path / "stage")
    script = tmp_path / "blender_round.py"
    script.write_text(_BLENDER_SCRIPT)
    # Blender runs in its own process: bpy bundles its own USD libraries.
    run = subprocess.run([sys.executable, str(script), str(result.root_layer), str(tmp_path)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    report = json.loads((tmp_path / "report.json").read_text())
    for cam in scene.cameras:
        got = report["cameras"][cam.name]
        assert got["lens_mm"] == pytest.approx(cam.intrinsics.focal_length_mm, rel=1e-5)
        assert got["sensor_mm"] == pytest.approx(cam.intrinsics.sensor_width_mm, rel=1e-5)
    assert report["cameras"]["cam_aisle"]["shift_x"] == pytest.approx((31.5 - 30.0) / 64, rel=1e-4)
    for light in scene.lights:
        assert report["lights"][light.name]["energy_w"] == pytest.approx(light.power_w, rel=1e-5)
    # Colour opinions and appearance variants reach Blender's materials.
    colours = report["colours"]
    assert colours["o3"] == [pytest.approx([0.9, 0.1, 0.1], abs=1e-6)]
    assert colours["o1"] == [pytest.approx(list(result.resolved.objects[0].color_rgb), abs=1e-6)]
    assert colours["o2"] == [pytest.approx([0.8, 0.2, 0.2], abs=1e-6)]  # variant "striped"

    expected = result.resolved
    for name in ("z_up_m.usda", "y_up_cm.usda"):
        back = scene_from_stage(tmp_path / name)
        assert (back.frame_start, back.frame_end) == (expected.frame_start, expected.frame_end)
        assert sorted(o.uid for o in back.objects) == sorted(o.uid for o in expected.objects)
        for obj in back.objects:
            want = next(o for o in expected.objects if o.uid == obj.uid)
            assert (obj.class_name, obj.name) == (want.class_name, want.name)
            for frame in range(expected.frame_start, expected.frame_end + 1):
                dt, da = pose_difference(_pose_at(obj, frame), _pose_at(want, frame))
                assert dt < 1e-5 and da < 1e-3, (name, obj.uid, frame, dt, da)
        for cam in back.cameras:
            want = expected.camera(cam.name)
            # Blender exports no resolution: intrinsics come back up to the image scale.
            scale = cam.intrinsics.width_px / want.intrinsics.width_px
            assert cam.intrinsics.fx_px / scale == pytest.approx(want.intrinsics.fx_px, rel=1e-5)
            assert cam.intrinsics.fy_px / scale == pytest.approx(want.intrinsics.fy_px, rel=1e-5)
            assert (cam.intrinsics.cx_px + 0.5) / scale == pytest.approx(want.intrinsics.cx_px + 0.5, rel=1e-5)
            for frame in range(expected.frame_start, expected.frame_end + 1):
                dt, da = pose_difference(cam.pose_at(frame), want.pose_at(frame))
                assert dt < 1e-5 and da < 1e-3, (name, cam.name, frame, dt, da)
        for light in back.lights:
            want = next(lt for lt in expected.lights if lt.name == light.name)
            assert light.kind == want.kind
            assert light.power_w == pytest.approx(want.power_w, rel=1e-5)
            dt, da = pose_difference(light.pose, want.pose)
            assert dt < 1e-5 and da < 1e-3


@pytest.mark.blender
def test_export_openlabel_reads_a_blend_project(tmp_path, catalog):
    """``usdscene export-openlabel scene.blend`` goes through the Blender project reader."""
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.cli import main
    from usdscene.render.blend_io import write_blend

    result = compose_stage(small_scene(), catalog, tmp_path / "stage")
    blend = write_blend(result.root_layer, tmp_path / "scene.blend")
    assert main(["export-openlabel", str(blend), "-o", str(tmp_path / "doc.json")]) == 0
    doc = read_openlabel(tmp_path / "doc.json")
    assert sorted(o.name for o in doc.objects) == sorted(o.name for o in result.resolved.objects)
    assert sorted(c.name for c in doc.cameras) == ["cam_aisle", "cam_fish"]
    assert sorted(lt.name for lt in doc.lights) == ["cabin_light", "reading_spot", "sun"]


def _pose_at(obj: m.SceneObject, frame: int) -> m.Pose:
    for f, pose in obj.frame_poses:
        if f == frame:
            return pose
    return obj.pose


# --------------------------------------------------------------------------------------------
# Shipped examples

EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("**/*.openlabel.json"))


@pytest.mark.parametrize("document", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_shipped_example_document_to_stage_to_document(tmp_path, document):
    """Every shipped example composes with the shipped library and comes back equal."""
    from usdscene.converters.openlabel import read_openlabel, write_document, write_openlabel
    from usdscene.converters.stage.usd_stage import scene_from_stage
    from usdscene.scene.catalog import load_catalog

    scene = read_openlabel(document)
    result = compose_stage(scene, load_catalog(scene.asset_paths, base_dir=document.parent), tmp_path / "stage")
    write_document(tmp_path / "back.json", write_openlabel(scene_from_stage(result.root_layer)))
    back = read_openlabel(tmp_path / "back.json")
    # A walker's pose per frame comes back from its pose children, frame by frame.
    walking = {o.uid: _walk_poses(o) for o in result.resolved.objects if _walk_poses(o)}
    assert {o.uid: _walk_poses(o) for o in back.objects if _walk_poses(o)} == walking
    # Content carried for others (the moving example's per-frame ground positions and track
    # notes) comes back from the prims' customData. A walker's own pose_variant is only its pose
    # where no frame names one, which no frame of it lacks.
    expected = result.resolved
    back = dataclasses.replace(back, objects=tuple(
        dataclasses.replace(o, pose_variant=(result.resolved.object_by_uid()[o.uid].pose_variant
                                             if o.uid in walking else o.pose_variant))
        for o in back.objects))
    assert_scenes_close(expected, back)


def _walk_poses(obj: m.SceneObject) -> dict[int, str]:
    """frame → the walk pose variant an object's per-frame data names (empty if none)."""
    poses = {}
    for frame, text in obj.frame_extra:
        for item in json.loads(text).get("object_data", {}).get("text", []):
            if item.get("name") == "walk_pose_variant":
                poses[frame] = item["val"]
    return poses
