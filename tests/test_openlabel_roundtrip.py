"""Scenes built in code: write → official schema → read gives the same scene; friendly
camera maths; VCD conversion; catalog checks; atomic writes."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.converters.openlabel import (
    EQUISOLID_KB_COEFFS,
    load_document,
    read_openlabel,
    schema_problems,
    write_document,
    write_openlabel,
)
from usdscene.scene.catalog import AssetEntry, Catalog, Place
from usdscene.errors import DocumentError
from usdscene.document.model import (
    Camera,
    FrameInterval,
    Intrinsics,
    LensModel,
    Light,
    LightKind,
    PlaceRef,
    Pose,
    Provenance,
    Randomization,
    Relation,
    RenderSettings,
    SceneObject,
    SceneSpec,
)

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "minimal" / "scene.openlabel.json"


def _pose(yaw_deg: float, t) -> Pose:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return Pose.from_rotation_translation([[c, -s, 0], [s, c, 0], [0, 0, 1]], t)


def _intrinsics(lens: LensModel, **kw) -> Intrinsics:
    base = dict(lens=lens, width_px=64, height_px=48, fx_px=40.0, fy_px=41.0, cx_px=31.5, cy_px=23.25,
                sensor_width_mm=4.8)
    base.update(kw)
    return Intrinsics(**base)


def full_scene() -> SceneSpec:
    cams = (
        Camera("persp", _intrinsics(LensModel.PERSPECTIVE), pose=_pose(10, (1, 2, 3)),
               frame_poses=((1, _pose(20, (1, 2, 3))), (2, _pose(30, (1, 2, 3.5)))),
               clip_near_m=0.05, clip_far_m=40.0, model_name="Axis M3068-P", description="dome",
               custom={"ir_cut": True, "mount": [1, 2]}),
        Camera("ortho", _intrinsics(LensModel.ORTHOGRAPHIC, fx_px=100.0, fy_px=100.0)),
        Camera("equidistant", _intrinsics(LensModel.FISHEYE_EQUIDISTANT, fx_px=64 / math.pi, fy_px=64 / math.pi,
                                          fov_deg=180.0)),
        Camera("equisolid", _intrinsics(LensModel.FISHEYE_EQUISOLID, fov_deg=118.0)),
        Camera("brown5", _intrinsics(LensModel.OPENCV_PINHOLE, distortion=(0.1, -0.02, 0.001, 0.002, 0.003))),
        Camera("brown8", _intrinsics(LensModel.OPENCV_PINHOLE, distortion=(0.1, -0.02, 0.0, 0.0, 0.003, 0.01, 0.0, 0.0))),
        Camera("brown4", _intrinsics(LensModel.OPENCV_PINHOLE, distortion=(0.1, -0.02, 0.0, 0.001))),
        Camera("kb", _intrinsics(LensModel.OPENCV_FISHEYE, distortion=(-0.01, 0.002, 0.0, 0.0001), fov_deg=190.0)),
        Camera("kannala", _intrinsics(LensModel.KANNALA, distortion=(-0.01, 0.002, 0.0, 0.0001))),
        Camera("radial", _intrinsics(LensModel.RADIAL_POLY, distortion=(0.05, -0.03, 0.001), fov_deg=200.0)),
        Camera("world", _intrinsics(LensModel.PERSPECTIVE)),  # a camera named like the root
    )
    lights = (
        Light("10", "key", LightKind.SPOT, pose=_pose(45, (0, 0, 2.5)), power_w=250.0, color_rgb=(1.0, 0.9, 0.8),
              radius_m=0.02, spot_angle_deg=60.0, spot_blend=0.3, frame_intervals=(FrameInterval(0, 1),)),
        Light("11", "sun", LightKind.SUN, power_w=3.0, sun_angle_deg=1.0),
        Light("12", "panel", LightKind.AREA, size_m=(1.0, 0.25)),
    )
    places = (PlaceRef("20", "seat_01A"), PlaceRef("21", "bin_01L"))
    objects = (
        SceneObject("30", "bag", "backpack", frame_intervals=(FrameInterval(0, 2),), appearance="red",
                    randomization=Randomization(0.02, 15.0, True, True)),
        SceneObject("31", "laptop", "laptop", frame_intervals=(FrameInterval(1, 1), FrameInterval(3, 4)),
                    pose=_pose(90, (1, -0.3, 0.45)), color_rgb=(0.1, 0.2, 0.3)),
        SceneObject("-2", "walker", "passenger", frame_intervals=(FrameInterval(0, 4),),
                    frame_poses=tuple((f, _pose(0, (f * 0.5, 0, 0))) for f in (0, 1, 2, 4))),
        SceneObject("0b4f6c1e-3f0c-4e7a-9d57-2c9a4b0c9e11", "", "suitcase"),
    )
    relations = (
        Relation("0", "is_below", "30", "20", frame_intervals=(FrameInterval(0, 1),)),
        Relation("1", "is_on", "30", "20", frame_intervals=(FrameInterval(2, 2),)),
        Relation("2", "is_in", "0b4f6c1e-3f0c-4e7a-9d57-2c9a4b0c9e11", "21"),
        Relation("3", "looks_at", "-2", "31"),
    )
    return SceneSpec(name="full", frame_start=0, frame_end=4, cameras=cams, lights=lights, objects=objects,
                     places=places, relations=relations,
                     render=RenderSettings(engine="cycles", device="gpu", samples=64, adaptive_threshold=0.01,
                                           denoise=False, denoiser="optix", max_bounces=6, caustics=True,
                                           tile_size_px=256, resolution_px=(1280, 960), seed=5, fast_gi=True,
                                           fast_gi_method="add", fast_gi_ao_bounces=3, fast_gi_distance_m=2.5,
                                           scrambling_distance=0.25, auto_scrambling_distance=True),
                     seed=1234, environment="aircraft_cabin", asset_paths=("extra_assets",),
                     exports=("coco", "yolo", "rois"), roi_rules={"is_below": "correct", "is_on": "incorrect"},
                     roi_ignore=("passenger",),
                     description="every feature once")


def test_full_scene_round_trip(openlabel_schema_path):
    scene = full_scene()
    document = write_openlabel(scene)
    text = json.dumps(document, allow_nan=False)
    assert schema_problems(json.loads(text), openlabel_schema_path) == []
    again = read_openlabel(json.loads(text))
    assert dataclasses.replace(again, provenance=Provenance()) == scene
    assert again.provenance.source_format == "openlabel" and again.provenance.source == ""


def test_writer_normal_form():
    body = write_openlabel(full_scene())["openlabel"]
    # camera "world" exists, so the root coordinate system is renamed
    assert body["coordinate_systems"]["world_1"]["parent"] == ""
    props = body["streams"]["equisolid"]["stream_properties"]
    assert props["intrinsics_fisheye"]["lens_coeffs"] == list(EQUISOLID_KB_COEFFS)
    assert props["usdscene"]["model"] == "fisheye_equisolid"
    assert body["streams"]["equidistant"]["stream_properties"]["intrinsics_fisheye"]["lens_coeffs"] == [0.0] * 4
    assert len(body["streams"]["persp"]["stream_properties"]["intrinsics_pinhole"]["distortion_coeffs"]) == 5
    assert body["streams"]["ortho"]["stream_properties"]["intrinsics_custom"]["model"] == "orthographic"
    # root frame intervals: union of the scene range and every element
    assert body["frame_intervals"] == [{"frame_start": 0, "frame_end": 4}]
    # unique data names per element, each with a pointer (per-frame data has one too)
    for uid, obj in body["objects"].items():
        names = [d["name"] for items in obj.get("object_data", {}).values() for d in items]
        assert len(names) == len(set(names)) and set(names) <= set(obj.get("object_data_pointers", {})), uid
    assert body["objects"]["-2"]["object_data_pointers"]["pose_matrix4x4"]["frame_intervals"] == [
        {"frame_start": 0, "frame_end": 2}, {"frame_start": 4, "frame_end": 4}]
    assert body["frames"]["1"]["frame_properties"]["transforms"]["persp_to_world_1"]["dst"] == "world_1"


def test_equisolid_taylor_coefficients_are_exact_enough():
    theta = np.linspace(0.0, 1.1, 2001)
    k1, k2, k3, k4 = EQUISOLID_KB_COEFFS
    kb = theta * (1 + k1 * theta**2 + k2 * theta**4 + k3 * theta**6 + k4 * theta**8)
    assert np.max(np.abs(kb - 2 * np.sin(theta / 2))) < 1e-10


def test_non_integer_uids_are_renumbered(openlabel_schema_path):
    scene = SceneSpec(
        places=(PlaceRef("seat_01A", "seat_01A"),),
        objects=(SceneObject("backpack_001", "backpack_001", "backpack"), SceneObject("7", "laptop", "laptop")),
        lights=(Light("light_01", "ceiling", LightKind.POINT),),
        relations=(Relation("rel_001", "is_below", "backpack_001", "seat_01A"),))
    document = write_openlabel(scene)
    assert schema_problems(document, openlabel_schema_path) == []
    body = document["openlabel"]
    assert sorted(body["objects"]) == ["0", "1", "2", "7"]  # 7 kept, the others numbered around it
    again = read_openlabel(document)
    (rel,) = again.relations
    assert again.object_by_uid()[rel.subject_uid].name == "backpack_001"
    assert again.place_by_uid()[rel.object_uid].name == "seat_01A"
    assert write_openlabel(scene) == document  # deterministic


def test_writer_rejects_dangling_relation():
    scene = SceneSpec(objects=(SceneObject("1", "a", "backpack"),), relations=(Relation("0", "is_on", "1", "9"),))
    with pytest.raises(DocumentError) as info:
        write_openlabel(scene)
    assert "relations.0.object_uid" in str(info.value)


# ---- friendly camera form --------------------------------------------------------------


def _camera(**friendly):
    doc = {"openlabel": {"metadata": {"schema_version": "1.0.0"},
                         "streams": {"c": {"type": "camera", "stream_properties": {"usdscene": friendly}}}}}
    return read_openlabel(doc).camera("c")


def test_friendly_perspective_any_two_of_three():
    by_fov = _camera(model="perspective", resolution_px=[640, 480], fov_deg=90.0, sensor_size_mm=[4.0, 3.0])
    assert by_fov.intrinsics.fx_px == pytest.approx(320.0)
    assert by_fov.intrinsics.focal_length_mm == pytest.approx(2.0)
    by_focal = _camera(model="perspective", resolution_px=[640, 480], focal_length_mm=2.0, sensor_size_mm=[4.0, 3.0])
    assert by_focal.intrinsics.fx_px == pytest.approx(320.0)
    by_fov_focal = _camera(model="perspective", resolution_px=[640, 480], focal_length_mm=2.0, fov_deg=90.0)
    assert by_fov_focal.intrinsics.sensor_width_mm == pytest.approx(4.0)
    all_three = _camera(model="perspective", resolution_px=[640, 480], focal_length_mm=2.0, fov_deg=90.3,
                        sensor_size_mm=[4.0, 3.0])  # within 0.5°
    assert all_three.intrinsics.fx_px == pytest.approx(640 / (2 * math.tan(math.radians(90.3) / 2)))
    assert (by_fov.intrinsics.cx_px, by_fov.intrinsics.cy_px) == (319.5, 239.5)


def test_friendly_fov_mismatch_names_the_fisheye():
    with pytest.raises(DocumentError) as info:
        _camera(model="perspective", resolution_px=[640, 480], focal_length_mm=2.13, fov_deg=118.0,
                sensor_size_mm=[4.0, 3.0])
    (problem,) = info.value.problems
    assert problem.where == "openlabel.streams.c.stream_properties.usdscene.fov_deg"
    assert "86.4°" in problem.message and "112.0°" in problem.message and "'fisheye_equisolid'" in problem.message


def test_friendly_fisheyes_follow_blender():
    equidistant = _camera(model="fisheye_equidistant", resolution_px=[640, 480], fov_deg=180.0).intrinsics
    assert equidistant.fx_px == pytest.approx(640 / math.pi)  # fisheye_fov spans the sensor width
    assert equidistant.fov_deg == 180.0 and equidistant.distortion == ()
    equisolid = _camera(model="fisheye_equisolid", resolution_px=[640, 480], focal_length_mm=2.13,
                        sensor_size_mm=[4.0, 3.0], fov_deg=118.0).intrinsics
    assert equisolid.fx_px == pytest.approx(2.13 * 640 / 4.0)  # r_mm = 2 f sin(θ/2) on the sensor
    assert equisolid.fov_deg == 118.0  # crops the image circle only
    kb = _camera(model="opencv_fisheye", focal_length_mm=2.0, sensor_size_mm=[4.0, 3.0],
                 distortion=[0.1, 0.0, 0.0, 0.0]).intrinsics
    assert kb.distortion == (0.1, 0.0, 0.0, 0.0) and kb.width_px == RenderSettings().resolution_px[0]
    ortho = _camera(model="orthographic", resolution_px=[200, 100], ortho_width_m=4.0).intrinsics
    assert ortho.fx_px == 50.0


def test_calibrated_fisheye_readings():
    def fisheye(**kw):
        block = {"width_px": 640, "height_px": 480, "focal_length_x": 200.0, "focal_length_y": 200.0,
                 "center_x": 320.0, "center_y": 240.0, **kw}
        doc = {"openlabel": {"metadata": {"schema_version": "1.0.0"},
                             "streams": {"c": {"type": "camera", "stream_properties": {"intrinsics_fisheye": block}}}}}
        return read_openlabel(doc).camera("c").intrinsics

    # VCD kannala: r = f·(k1θ + k2θ³ + k3θ⁵ + k4θ⁷ + k5θ⁹), all five read (not OpenCV's k1 = 1)
    k = [0.9, -0.05, 0.004, -0.0002, 0.00001]
    kannala = fisheye(model="kannala", lens_coeffs_1xN=k)
    assert kannala.lens is LensModel.KANNALA and kannala.fx_px == pytest.approx(200.0 * 0.9)
    theta = np.radians([0.0, 10.0, 35.0, 60.0, 85.0])
    textbook = 200.0 * sum(c * theta ** (2 * i + 1) for i, c in enumerate(k))
    np.testing.assert_allclose(_radius(kannala, theta), textbook, rtol=0, atol=1e-9)
    # at 60° off the axis, by hand: 200·(0.9·1.047198 - 0.05·1.148381 + 0.004·1.259218
    # - 0.0002·1.380754 + 0.00001·1.514) = 177.967 px (the old OpenCV reading of the same numbers: 404.6 px)
    assert _radius(kannala, np.radians([60.0]))[0] == pytest.approx(177.967, abs=1e-3)
    # four coefficients: the θ⁹ term is absent
    four = fisheye(model="kannala", lens_coeffs=k[:4])
    np.testing.assert_allclose(_radius(four, theta), textbook - 200.0 * k[4] * theta ** 9, rtol=0, atol=1e-9)

    # radial_poly: r = f·(c1θ + c2θ² + c3θ³ + c4θ⁴), even powers included; f from focal_length_x
    c = [20.0, 1.0, -0.5, 0.05]
    radial = fisheye(model="radial_poly", lens_coeffs=c, focal_length_x=2.0, focal_length_y=2.0)
    assert (radial.lens, radial.fx_px) == (LensModel.RADIAL_POLY, 40.0)
    textbook = 2.0 * sum(ci * theta ** (i + 1) for i, ci in enumerate(c))
    np.testing.assert_allclose(_radius(radial, theta), textbook, rtol=0, atol=1e-9)


def _radius(intr: Intrinsics, theta: np.ndarray) -> np.ndarray:
    """Image radius (px) along +x of rays ``theta`` (rad) off the axis, by usdscene.labels.projection."""
    from usdscene.labels.projection import project_camera_points

    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
    uv, valid = project_camera_points(intr, rays)
    assert valid.all()
    return uv[:, 0] - intr.cx_px


def test_vcd_polynomial_lenses_are_written_back_in_their_own_model(openlabel_schema_path):
    """kannala and radial_poly come back as themselves, and every sample ray lands on the same
    pixel (1e-9 px) after write → read."""
    from usdscene.labels.projection import pixel_rays, project_camera_points

    def doc(model, coeffs):
        block = {"width_px": 640, "height_px": 480, "focal_length_x": 190.0, "focal_length_y": 195.0,
                 "center_x": 321.5, "center_y": 238.25, "lens_coeffs": coeffs, "model": model}
        return {"openlabel": {"metadata": {"schema_version": "1.0.0"},
                              "streams": {"c": {"type": "camera", "stream_properties": {"intrinsics_fisheye": block}}},
                              "coordinate_systems": {"c": {"type": "sensor_cs", "parent": ""}}}}

    for model, coeffs in (("kannala", [1.1, -0.04, 0.003, -0.0001, 0.00002]),
                          ("radial_poly", [0.95, 0.02, -0.03, 0.002, 0.0001])):
        first = read_openlabel(doc(model, coeffs))
        written = write_openlabel(first)
        assert schema_problems(written, openlabel_schema_path) == []
        block = written["openlabel"]["streams"]["c"]["stream_properties"]["intrinsics_fisheye"]
        assert block["model"] == model and len(block["lens_coeffs"]) == 5
        again = read_openlabel(written)
        a, b = first.camera("c").intrinsics, again.camera("c").intrinsics
        assert b.lens is a.lens
        vs, us = np.mgrid[0:480:37, 0:640:41]
        rays, valid = pixel_rays(a, np.stack([us.ravel(), vs.ravel()], 1).astype(float))
        uv_a, ok_a = project_camera_points(a, rays[valid])
        uv_b, ok_b = project_camera_points(b, rays[valid])
        assert ok_a.all() and ok_b.all() and valid.sum() > 100
        np.testing.assert_allclose(uv_b, uv_a, rtol=0, atol=1e-9)


# ---- VCD, catalog, files -----------------------------------------------------------------


def test_vcd_43_is_converted(tmp_path):
    m = _pose(90, (1, 2, 3)).matrix
    vcd = {"vcd": {
        "metadata": {"schema_version": "4.3.0"},
        "coordinate_systems": {"odom": {"type": "scene_cs", "parent": "", "children": ["cam"]},
                               "cam": {"type": "sensor_cs", "parent": "odom", "children": [], "pose_wrt_parent": list(m)}},
        "streams": {"cam": {"type": "camera", "uri": "", "stream_properties": {"intrinsics_pinhole": {
            "width_px": 64, "height_px": 48, "camera_matrix_3x4": [50, 0, 32, 0, 0, 50, 24, 0, 0, 0, 1, 0],
            "distortion_coeffs_1xN": [0.1, 0.0, 0.0, 0.0, 0.0]}}}},
        "frames": {"5": {"frame_properties": {"transforms": {"cam_to_odom": {
            "src": "cam", "dst": "odom", "transform_src_to_dst_4x4": list(_pose(0, (0, 0, 1)).matrix)}}}}},
    }}
    path = tmp_path / "legacy.vcd.json"
    path.write_text(json.dumps(vcd))
    assert load_document(path)["openlabel"]["metadata"]["schema_version"] == "1.0.0"
    scene = read_openlabel(path)
    cam = scene.camera("cam")
    assert cam.pose.matrix == m and cam.intrinsics.distortion == (0.1, 0.0, 0.0, 0.0)
    assert cam.pose_at(5).translation_m.tolist() == [0.0, 0.0, 1.0]
    assert scene.provenance.source_format == "vcd"
    assert vcd["vcd"]["coordinate_systems"]["cam"]["pose_wrt_parent"] == list(m)  # input untouched


def _catalog() -> Catalog:
    cabin = AssetEntry("aircraft_cabin", "environment", Path("cabin.usda"),
                       places={"seat_01A": Place("seat_01A", "seat")})
    return Catalog({"aircraft_cabin": cabin,
                    "backpack": AssetEntry("backpack", "object", Path("b.usda"), relations=("is_on", "is_below")),
                    "laptop": AssetEntry("laptop", "object", Path("l.usda"), relations=("is_on",)),
                    "passenger": AssetEntry("passenger", "passenger", Path("p.usda"), relations=("is_on",))})


def test_catalog_checks():
    assert len(read_openlabel(EXAMPLE, catalog=_catalog()).objects) == 3
    doc = load_document(EXAMPLE)
    body = doc["openlabel"]
    body["objects"]["3"]["type"] = "laptop"        # laptop does not support is_below
    body["objects"]["5"]["type"] = "pasenger"      # typo
    body["objects"]["2"]["name"] = "seat_99Z"      # not in the cabin
    with pytest.raises(DocumentError) as info:
        read_openlabel(doc, catalog=_catalog())
    wheres = {p.where: p.message for p in info.value.problems}
    assert "did you mean 'passenger'" in wheres["openlabel.objects.5.type"]
    assert "seat_99Z" in wheres["openlabel.objects.2.name"]
    assert "is_below" in wheres["openlabel.relations.0.type"]
    read_openlabel(doc)  # without a catalog these checks are skipped


def test_example_reads_as_documented():
    scene = read_openlabel(EXAMPLE)
    assert [c.intrinsics.lens for c in scene.cameras] == [LensModel.PERSPECTIVE, LensModel.OPENCV_FISHEYE]
    assert [o.class_name for o in scene.objects] == ["backpack", "laptop", "passenger"]
    assert [p.name for p in scene.places] == ["seat_01A"] and scene.environment == "aircraft_cabin"
    assert (scene.frame_start, scene.frame_end, scene.seed) == (0, 2, 7)
    laptop = scene.objects[1]
    assert [f for f, _ in laptop.frame_poses] == [1, 2]
    assert laptop.frame_poses[1][1].translation_m.tolist() == [1.1, -0.3, 0.45]


def test_write_document_is_atomic_and_refuses_nan(tmp_path):
    target = tmp_path / "scene.json"
    write_document(target, write_openlabel(read_openlabel(EXAMPLE)))
    before = target.read_bytes()
    bad = {"openlabel": {"metadata": {"schema_version": "1.0.0"}, "x": float("nan")}}
    with pytest.raises(DocumentError):
        write_document(target, bad)
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json"]


def test_valid_documents_of_others_are_read(openlabel_schema_path):
    """Valid OpenLABEL that other datasets write: an object with an empty type, object data
    names outside usdscene's vocabulary (also repeated), a sensor coordinate system without a
    stream. They read, and the scene writes back schema-valid."""
    doc = {"openlabel": {
        "metadata": {"schema_version": "1.0.0"},
        "coordinate_systems": {"odom": {"type": "scene_cs", "parent": ""},
                               "lidar": {"type": "sensor_cs", "parent": "odom"}},
        "objects": {
            "0": {"name": "thing", "type": ""},
            "1": {"name": "train", "type": "train", "object_data": {
                "vec": [{"name": "Position", "val": [1.0, 2.0, 3.0]}],
                "num": [{"name": "speed", "val": 3.0}, {"name": "speed", "val": 4.0}],
                "text": [{"name": "note", "val": "a"}, {"name": "note", "val": "b"}]}}}}}
    assert schema_problems(doc, openlabel_schema_path) == []
    scene = read_openlabel(doc)
    assert [(o.uid, o.class_name, o.pose) for o in scene.objects] == [("0", "", None), ("1", "train", None)]
    assert schema_problems(write_openlabel(scene), openlabel_schema_path) == []
    # usdscene's own names stay checked: a lower-case near miss is a typo, a repeat is ambiguous
    doc["openlabel"]["objects"]["1"]["object_data"]["vec"] = [{"name": "position", "val": [1.0, 2.0, 3.0]}]
    with pytest.raises(DocumentError, match="did you mean 'position_m'"):
        read_openlabel(doc)
    doc["openlabel"]["objects"]["1"]["object_data"]["vec"] = [{"name": "position_m", "val": [1.0, 2.0, 3.0]},
                                                              {"name": "position_m", "val": [1.0, 2.0, 3.0]}]
    with pytest.raises(DocumentError, match="duplicate object data name 'position_m'"):
        read_openlabel(doc)
