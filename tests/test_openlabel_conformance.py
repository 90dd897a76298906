"""Third-party OpenLABEL files: read, write back, validate against the official schema, and
read → write → read gives an equal scene.

What the scene model does not represent (bounding boxes, cuboids, poly2d contours and other
geometric object data; non-camera streams; per-frame stream properties; actions, events,
contexts, ontologies, and relations that involve them; camera streams without intrinsics
usdscene can use, which are skipped as cameras with a warning) is carried in the ``extra``
fields and written back unchanged: ``tests/test_openlabel_carry.py`` checks that.
"""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from usdscene.converters.openlabel import load_document, read_openlabel, schema_problems, write_openlabel
from usdscene.document.model import LensModel, Provenance

CONFORMANCE_FILES = [
    "openlabel100_test_VCD420_to_OpenLABEL100_dmd.json",
    "openlabel100_test_bbox_simple_attributes.json",
    "openlabel100_test_contours.json",
    "openlabel100_test_create_streams_simple.json",
    "openlabel100_test_intrinsics.json",
    "openlabel100_test_poses.json",
    "openlabel100_test_relations_2.json",
    "openlabel100_test_scene_KITTI_Tracking_3.json",
    "openlabel100_test_semantics.json",
    "raillabel_openlabel_v1_short.json",
]


def _no_provenance(scene):
    return dataclasses.replace(scene, provenance=Provenance())


def test_every_conformance_file_is_listed(openlabel_conformance: Path):
    assert sorted(p.name for p in openlabel_conformance.glob("*.json")) == sorted(CONFORMANCE_FILES)


@pytest.mark.parametrize("name", CONFORMANCE_FILES)
def test_conformance_round_trip(name, openlabel_conformance: Path, openlabel_schema_path: Path):
    path = openlabel_conformance / name
    assert schema_problems(load_document(path), openlabel_schema_path) == []  # the input is valid
    scene = read_openlabel(path)
    assert scene.provenance.source == str(path) and len(scene.provenance.source_sha256) == 64
    document = write_openlabel(scene)
    serialised = json.loads(json.dumps(document, allow_nan=False))
    assert schema_problems(serialised, openlabel_schema_path) == []
    again = read_openlabel(serialised)
    assert _no_provenance(again) == _no_provenance(scene)
    # a second write is identical: the normal form is a fixed point
    assert write_openlabel(again) == document


def _read(openlabel_conformance, name):
    return read_openlabel(openlabel_conformance / name)


def test_kitti_cameras_follow_the_vehicle(openlabel_conformance):
    scene = _read(openlabel_conformance, "openlabel100_test_scene_KITTI_Tracking_3.json")
    assert [c.name for c in scene.cameras] == ["CAM_LEFT", "CAM_RIGHT"]
    left = scene.camera("CAM_LEFT")
    assert left.intrinsics.lens is LensModel.PERSPECTIVE
    assert left.intrinsics.fx_px == pytest.approx(721.5377)
    assert (scene.frame_start, scene.frame_end) == (0, 143)
    assert len(left.frame_poses) == 144
    # The camera looks forward (vehicle +x) and rides 0.76 m forward, 1.73 m up on the roof
    # rig; the odometry transform (vehicle → odom) moves it ~172 m by the last frame.
    first, last = left.pose_at(0), left.pose_at(143)
    assert first.rotation[:, 2] @ np.array([1.0, 0.0, 0.0]) > 0.99
    assert first.translation_m[2] == pytest.approx(1.73 - 0.0723, abs=1e-3)
    assert last.translation_m[0] > 170
    # Only object-object relations are modelled (the rest involve actions and events).
    assert {r.type for r in scene.relations} == {"isPartOf"}
    assert {o.uid for o in scene.objects} >= {"-1", "-2"}


def test_raillabel_schema_dialect_and_quaternions(openlabel_conformance):
    scene = _read(openlabel_conformance, "raillabel_openlabel_v1_short.json")
    rgb = scene.camera("rgb_middle")
    assert rgb.intrinsics.lens is LensModel.OPENCV_PINHOLE
    assert rgb.intrinsics.distortion == (0.49, 0.69, 0.31, 0.81, 0.99)
    assert rgb.pose.translation_m.tolist() == [0.0, 1.0, 2.0]
    r = rgb.pose.rotation
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-7)
    assert any(len(o.uid) == 36 for o in scene.objects)  # UUID keys


def test_intrinsics_file_fisheye_and_vcd_dialect(openlabel_conformance):
    scene = _read(openlabel_conformance, "openlabel100_test_intrinsics.json")
    assert [c.name for c in scene.cameras] == ["CAM_PINHOLE", "CAM_FISHEYE"]  # CAM_CUSTOM skipped
    fisheye = scene.camera("CAM_FISHEYE").intrinsics
    assert fisheye.lens is LensModel.OPENCV_FISHEYE
    assert (fisheye.fx_px, fisheye.fy_px) == (24.0, 32.0)
    assert fisheye.distortion == (333.437012, 0.307729989, 2.4235599, 11.0495005)


def test_relation_frame_intervals(openlabel_conformance):
    scene = _read(openlabel_conformance, "openlabel100_test_relations_2.json")
    (relation,) = scene.relations
    assert (relation.type, relation.subject_uid, relation.object_uid) == ("isNear", "0", "1")
    assert [(iv.frame_start, iv.frame_end) for iv in relation.frame_intervals] == [(7, 9)]


def test_poses_file_matrix_equals_euler(openlabel_conformance):
    """The poses file states one pose as ``matrix4x4`` and as ZYX euler angles [rz, ry, rx].
    Its cameras have no intrinsics, so a friendly lens is added to read them as cameras."""
    document = copy.deepcopy(load_document(openlabel_conformance / "openlabel100_test_poses.json"))
    for stream in document["openlabel"]["streams"].values():
        stream["stream_properties"] = {"usdscene": {"model": "perspective", "fov_deg": 60.0}}
    scene = read_openlabel(document)
    a, b = scene.camera("CAM_1").pose, scene.camera("CAM_2").pose
    assert np.allclose(a.as_array(), b.as_array(), atol=1e-12)
    assert a.translation_m.tolist() == [2.3, 0.0, 1.3]


def test_per_frame_transform_direction(openlabel_conformance):
    """``transform_src_to_dst`` maps src coordinates to dst coordinates (X_dst = M X_src):
    here src is the parent (vehicle) and dst the camera, so the camera pose is M⁻¹."""
    scene = _read(openlabel_conformance, "openlabel100_test_create_streams_simple.json")
    cam = scene.camera("Camera1")
    assert cam.pose.translation_m.tolist() == [0.0, 0.0, 0.0]
    frames = dict(cam.frame_poses)
    assert np.allclose(frames[0].translation_m, [-0.1, -0.1, 0.0])
    # Frame 6 also moves the vehicle (odom → vehicle, src = parent): both cameras follow it.
    (frame, pose), = scene.camera("Camera2").frame_poses
    assert frame == 6 and np.allclose(pose.translation_m, [-20.0, -20.0, 0.0])
    assert np.allclose(frames[6].translation_m, [-20.1, -20.1, 0.0])
