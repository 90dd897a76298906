"""Property tests of the pose encodings: the same pose written as ``matrix4x4``, quaternion
``(x, y, z, w)`` + translation, or euler angles + translation reads to the same Pose; the
reference rotations come from OpenCV's Rodrigues formula, not from usdscene."""

from __future__ import annotations

import math

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from usdscene.converters.openlabel import friendly_camera_rotation, read_openlabel, write_openlabel
from usdscene.document.model import rotation_to_euler_zyx

finite = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False, allow_infinity=False)
angle = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)
unit_axis = st.tuples(finite, finite, finite).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
    lambda v: np.asarray(v) / np.linalg.norm(v))
AXES = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}
SEQUENCES = [a + b + c for a in "XYZ" for b in "XYZ" for c in "XYZ" if a != b and b != c]


def rodrigues(axis, theta) -> np.ndarray:
    r, _ = cv2.Rodrigues(np.asarray(axis, float).reshape(3, 1) * theta)
    return r


def _doc(poses: dict) -> dict:
    """Cameras named after ``poses`` (each a pose_wrt_parent) under one root."""
    systems = {"root": {"type": "scene_cs", "parent": "", "children": list(poses)}}
    streams = {}
    for name, pose in poses.items():
        systems[name] = {"type": "sensor_cs", "parent": "root", "children": [], "pose_wrt_parent": pose}
        streams[name] = {"type": "camera", "stream_properties": {"usdscene": {"model": "perspective", "fov_deg": 60}}}
    return {"openlabel": {"metadata": {"schema_version": "1.0.0"}, "coordinate_systems": systems, "streams": streams}}


@settings(max_examples=60, deadline=None)
@given(axis=unit_axis, theta=angle, t=st.tuples(finite, finite, finite))
def test_matrix_quaternion_euler_agree(axis, theta, t):
    rotation = rodrigues(axis, theta)
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rotation, t
    q = [*(axis * math.sin(theta / 2)), math.cos(theta / 2)]
    rz, ry, rx = rotation_to_euler_zyx(rotation)
    scene = read_openlabel(_doc({
        "m": {"matrix4x4": m.reshape(16).tolist()},
        "q": {"quaternion": q, "translation": list(t)},
        "qneg": {"quaternion": [-v for v in q], "translation": list(t)},  # q and -q: same rotation
        "e": {"euler_angles": [rz, ry, rx], "translation": list(t), "sequence": "ZYX"},
        "e_default": {"euler_angles": [rz, ry, rx], "translation": list(t)},
    }))
    reference = scene.camera("m").pose.as_array()
    assert np.array_equal(reference, m)  # matrix4x4 is kept bit for bit
    for name in ("q", "qneg", "e", "e_default"):
        assert np.allclose(scene.camera(name).pose.as_array(), reference, atol=1e-9, rtol=0), name


@settings(max_examples=60, deadline=None)
@given(sequence=st.sampled_from(SEQUENCES), angles=st.tuples(angle, angle, angle), t=st.tuples(finite, finite, finite))
def test_euler_sequences_apply_first_axis_outermost(sequence, angles, t):
    expected = np.eye(3)
    for axis, value in zip(sequence, angles):
        expected = expected @ rodrigues(AXES[axis], value)
    scene = read_openlabel(_doc({"e": {"euler_angles": list(angles), "translation": list(t), "sequence": sequence}}))
    pose = scene.camera("e").pose
    assert np.allclose(pose.rotation, expected, atol=1e-9, rtol=0)
    assert np.allclose(pose.translation_m, t, atol=0, rtol=0)


@settings(max_examples=40, deadline=None)
@given(axis=unit_axis, theta=angle, t=st.tuples(finite, finite, finite))
def test_object_pose_data_forms_agree(axis, theta, t):
    """Lights and objects: pose_matrix4x4 vs position_m + rotation_quaternion_xyzw vs
    position_m + rotation_xyz_deg (Blender XYZ Euler: R = Rz · Ry · Rx)."""
    rotation = rodrigues(axis, theta)
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rotation, t
    q = [*(axis * math.sin(theta / 2)), math.cos(theta / 2)]
    rz, ry, rx = rotation_to_euler_zyx(rotation)
    forms = {
        "0": [{"name": "pose_matrix4x4", "val": m.reshape(16).tolist()}],
        "1": [{"name": "position_m", "val": list(t)}, {"name": "rotation_quaternion_xyzw", "val": q}],
        "2": [{"name": "position_m", "val": list(t)},
              {"name": "rotation_xyz_deg", "val": [math.degrees(rx), math.degrees(ry), math.degrees(rz)]}],
    }
    objects = {uid: {"name": f"bag{uid}", "type": "backpack", "object_data": {"vec": vec}} for uid, vec in forms.items()}
    objects.update({str(10 + int(uid)): {"name": f"lamp{uid}", "type": "light",
                                         "object_data": {"text": [{"name": "kind", "val": "spot"}], "vec": vec}}
                    for uid, vec in forms.items()})
    scene = read_openlabel({"openlabel": {"metadata": {"schema_version": "1.0.0"}, "objects": objects}})
    for element in (*scene.objects, *scene.lights):
        assert np.allclose(element.pose.as_array(), m, atol=1e-9, rtol=0), element.name


@settings(max_examples=40, deadline=None)
@given(axis=unit_axis, theta=angle, t=st.tuples(finite, finite, finite))
def test_per_frame_transform_either_direction(axis, theta, t):
    """child → parent with M and parent → child with M⁻¹ give the same camera pose."""
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rodrigues(axis, theta), t
    doc = _doc({"c": {"matrix4x4": np.eye(4).reshape(16).tolist()}})
    doc["openlabel"]["frames"] = {
        "3": {"frame_properties": {"transforms": {"up": {"src": "c", "dst": "root",
                                                         "transform_src_to_dst": {"matrix4x4": m.reshape(16).tolist()}}}}},
        "4": {"frame_properties": {"transforms": {"down": {"src": "root", "dst": "c",
                                                           "transform_src_to_dst": {"matrix4x4": np.linalg.inv(m).reshape(16).tolist()}}}}},
    }
    poses = dict(read_openlabel(doc).camera("c").frame_poses)
    assert np.array_equal(poses[3].as_array(), m)
    assert np.allclose(poses[4].as_array(), m, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(axis=unit_axis, theta=angle, t=st.tuples(finite, finite, finite), mount=st.tuples(finite, finite, finite))
def test_per_frame_transform_through_the_graph(axis, theta, t, mount):
    """A transform between systems that are not parent and child (camera → world across a
    vehicle, world → camera) places the camera as if the chain had been written out."""
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rodrigues(axis, theta), t
    rig = np.eye(4)
    rig[:3, 3] = mount
    doc = _doc({"vehicle": {"matrix4x4": np.eye(4).reshape(16).tolist()}})
    body = doc["openlabel"]
    body["coordinate_systems"]["c"] = {"type": "sensor_cs", "parent": "vehicle",
                                       "pose_wrt_parent": {"matrix4x4": rig.reshape(16).tolist()}}
    body["streams"]["c"] = body["streams"]["vehicle"]
    body["coordinate_systems"]["lidar"] = {"type": "sensor_cs", "parent": "vehicle"}  # a sensor with no stream
    body["frames"] = {
        "3": {"frame_properties": {"transforms": {"t": {"src": "c", "dst": "root",
                                                        "transform_src_to_dst": {"matrix4x4": m.reshape(16).tolist()}}}}},
        "4": {"frame_properties": {"transforms": {"t": {"src": "root", "dst": "c",
                                                        "transform_src_to_dst": {"matrix4x4": np.linalg.inv(m).reshape(16).tolist()}}}}},
    }
    scene = read_openlabel(doc)
    camera = scene.camera("c")
    assert np.allclose(camera.pose.as_array(), rig, atol=1e-12)  # the static chain is unchanged
    poses = dict(camera.frame_poses)
    assert np.allclose(poses[3].as_array(), m, atol=1e-9)
    assert np.allclose(poses[4].as_array(), m, atol=1e-9)
    assert scene.camera("vehicle").frame_poses == ()  # the camera moved, not the vehicle


@settings(max_examples=40, deadline=None)
@given(yaw=st.floats(-180, 180), pitch=st.floats(-80, 80), position=st.tuples(finite, finite, finite))
def test_friendly_target_equals_orientation(yaw, pitch, position):
    y, p = math.radians(yaw), math.radians(pitch)
    forward = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p)])
    target = (np.asarray(position) + 3.0 * forward).tolist()
    streams = {
        "a": {"type": "camera", "stream_properties": {"usdscene": {"model": "perspective", "fov_deg": 70,
                                                                   "position_m": list(position), "orientation_deg": [yaw, pitch, 0]}}},
        "b": {"type": "camera", "stream_properties": {"usdscene": {"model": "perspective", "fov_deg": 70,
                                                                   "position_m": list(position), "target_m": target}}},
    }
    scene = read_openlabel({"openlabel": {"metadata": {"schema_version": "1.0.0"}, "streams": streams}})
    a, b = scene.camera("a").pose.as_array(), scene.camera("b").pose.as_array()
    assert np.allclose(a, b, atol=1e-7)
    assert np.allclose(a[:3, 2], forward, atol=1e-9)  # OpenCV z = viewing direction
    assert a[:3, 1] @ np.array([0, 0, 1.0]) <= 1e-9  # image down never points up (no roll)
    # written back and read again: the same pose exactly (the writer uses matrix4x4)
    assert read_openlabel(write_openlabel(scene)).camera("a").pose == scene.camera("a").pose


def test_friendly_orientation_conventions():
    def axes(yaw, pitch, roll):
        return friendly_camera_rotation(math.radians(yaw), math.radians(pitch), math.radians(roll))

    r = axes(0, 0, 0)  # columns: camera right, down, forward in world
    assert np.allclose(r, [[0, 0, 1], [-1, 0, 0], [0, -1, 0]])
    assert np.allclose(axes(90, 0, 0)[:, 2], [0, 1, 0])  # yaw +90 looks along +Y
    assert axes(0, 30, 0)[2, 2] > 0.49  # pitch up
    assert np.allclose(axes(0, 0, 90)[:, 0], [0, 0, -1])  # roll +90: the camera's right points down
