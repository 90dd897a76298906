import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usdscene.document import model as m

angles = st.floats(min_value=-math.pi + 1e-3, max_value=math.pi - 1e-3)
half_angles = st.floats(min_value=-math.pi / 2 + 1e-3, max_value=math.pi / 2 - 1e-3)


@given(rz=angles, ry=half_angles, rx=angles)
@settings(max_examples=200)
def test_pose_forms_agree(rz, ry, rx):
    r = m.euler_zyx_to_rotation(rz, ry, rx)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
    q = m.rotation_to_quaternion(r)
    assert np.allclose(m.quaternion_to_rotation(q), r, atol=1e-9)
    assert np.allclose(m.euler_zyx_to_rotation(*m.rotation_to_euler_zyx(r)), r, atol=1e-9)
    pose = m.Pose.from_quaternion(q, (1.0, 2.0, 3.0))
    assert np.allclose(pose.as_array(), m.Pose.from_rotation_translation(r, (1, 2, 3)).as_array(), atol=1e-9)
    assert np.allclose(pose.compose(pose.inverse()).as_array(), np.eye(4), atol=1e-9)


@given(rz=angles, ry=half_angles, rx=angles)
def test_cv_usd_camera_axes_round_trip_and_look_direction(rz, ry, rx):
    r_cv = m.euler_zyx_to_rotation(rz, ry, rx)
    r_usd = m.cv_to_usd_camera_rotation(r_cv)
    assert np.allclose(m.usd_to_cv_camera_rotation(r_usd), r_cv)
    # OpenCV looks along +z, USD along -z: same world direction.
    assert np.allclose(r_cv @ [0, 0, 1], r_usd @ [0, 0, -1])
    # OpenCV image "down" (+y) is USD "-up" (-y).
    assert np.allclose(r_cv @ [0, 1, 0], r_usd @ [0, -1, 0])


def test_union_intervals_merges_overlapping_and_adjacent():
    ivs = [m.FrameInterval(5, 7), m.FrameInterval(0, 2), m.FrameInterval(3, 3), m.FrameInterval(10, 12)]
    assert m.union_intervals(ivs) == (m.FrameInterval(0, 3), m.FrameInterval(5, 7), m.FrameInterval(10, 12))


def test_zero_quaternion_is_rejected():
    with pytest.raises(ValueError):
        m.quaternion_to_rotation((0, 0, 0, 0))
