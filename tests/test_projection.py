"""usdscene.labels.projection against OpenCV and against itself (project ∘ unproject = identity)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel, Pose, euler_zyx_to_rotation
from usdscene.labels.projection import (pixel_rays, project_camera_points, project_points, remap_grids,
                                 undistorted_render_intrinsics)

EQUISOLID_KB = (-1 / 24, 1 / 1920, -1 / 322560, 1 / 92897280)


def _intr(lens, **kw):
    base = dict(lens=lens, width_px=160, height_px=120, fx_px=100.0, fy_px=100.0, cx_px=81.3,
                cy_px=58.1)
    base.update(kw)
    return Intrinsics(**base)


def _camera(intr):
    rot = euler_zyx_to_rotation(0.3, -0.2, 0.1)
    return Camera("cam", intr, pose=Pose.from_rotation_translation(rot, [1.0, -2.0, 0.5]))


def _points_in_front(camera, n=200, seed=0, max_angle_deg=60.0):
    rng = np.random.default_rng(seed)
    theta = np.radians(rng.uniform(0, max_angle_deg, n))
    phi = rng.uniform(-math.pi, math.pi, n)
    depth = rng.uniform(0.5, 5.0, n)
    cam_pts = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    cam_pts *= depth[:, None]
    return camera.pose.transform_points(cam_pts), cam_pts


def _cv_rt(camera):
    world_to_cam = camera.pose.inverse().as_array()
    rvec, _ = cv2.Rodrigues(world_to_cam[:3, :3])
    return rvec, world_to_cam[:3, 3].copy()


@pytest.mark.parametrize("distortion", [(), (-0.2, 0.05, 0.001, -0.002),
                                        (-0.1, 0.02, 0.001, 0.0005, -0.003),
                                        (0.1, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002)])
def test_opencv_pinhole_matches_cv2(distortion):
    intr = _intr(LensModel.OPENCV_PINHOLE, distortion=distortion, fy_px=102.0)
    cam = _camera(intr)
    world, _ = _points_in_front(cam, max_angle_deg=40)
    uv, valid = project_points(cam, world)
    rvec, tvec = _cv_rt(cam)
    ref, _ = cv2.projectPoints(world, rvec, tvec, intr.camera_matrix(), np.array(distortion or (0.0,) * 4))
    assert valid.all()
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-9)


@pytest.mark.parametrize("lens,coeffs", [(LensModel.OPENCV_FISHEYE, (0.05, -0.01, 0.002, -0.0003)),
                                         (LensModel.KANNALA, (0.05, -0.01, 0.002, -0.0003)),
                                         (LensModel.FISHEYE_EQUIDISTANT, (0.0,) * 4),
                                         (LensModel.FISHEYE_EQUISOLID, EQUISOLID_KB)])
def test_fisheyes_match_cv2_fisheye(lens, coeffs):
    distortion = coeffs if lens in (LensModel.OPENCV_FISHEYE, LensModel.KANNALA) else ()
    intr = _intr(lens, distortion=distortion, fov_deg=170.0)
    cam = _camera(intr)
    world, _ = _points_in_front(cam, max_angle_deg=80)
    uv, valid = project_points(cam, world)
    rvec, tvec = _cv_rt(cam)
    ref, _ = cv2.fisheye.projectPoints(world.reshape(-1, 1, 3), rvec, tvec, intr.camera_matrix(),
                                       np.array(coeffs))
    assert valid.all()
    # The equisolid series is truncated at θ⁹: exact to well under a pixel up to 80°.
    tol = 1e-9 if lens is not LensModel.FISHEYE_EQUISOLID else 0.05
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=tol)


def test_radial_poly_by_hand():
    """r = f·θ(1 + d1θ + d2θ² + d3θ³ + d4θ⁴), every power of θ, written out term by term."""
    d = (0.04, -0.02, 0.002, -0.0001)
    intr = _intr(LensModel.RADIAL_POLY, distortion=d, fx_px=45.0, fy_px=47.0, fov_deg=200.0)
    rng = np.random.default_rng(3)
    theta = rng.uniform(0.0, math.radians(99.0), 300)
    phi = rng.uniform(-math.pi, math.pi, 300)
    rays = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1) * 2.5
    uv, valid = project_camera_points(intr, rays)
    theta_d = theta + d[0] * theta ** 2 + d[1] * theta ** 3 + d[2] * theta ** 4 + d[3] * theta ** 5
    expected = np.stack([45.0 * theta_d * np.cos(phi) + 81.3, 47.0 * theta_d * np.sin(phi) + 58.1], 1)
    assert valid.all()
    np.testing.assert_allclose(uv, expected, rtol=0, atol=1e-9)
    # beyond the image circle (100°) no ray is valid
    behind = np.array([[math.sin(math.radians(101.0)), 0.0, math.cos(math.radians(101.0))]])
    assert not project_camera_points(intr, behind)[1][0]


def test_perspective_and_orthographic_by_hand():
    cam_pts = np.array([[0.0, 0.0, 2.0], [1.0, -0.5, 2.0], [0.3, 0.2, -1.0]])
    uv, valid = project_camera_points(_intr(LensModel.PERSPECTIVE), cam_pts)
    np.testing.assert_allclose(uv[:2], [[81.3, 58.1], [131.3, 33.1]])
    assert valid.tolist() == [True, True, False]
    uv, valid = project_camera_points(_intr(LensModel.ORTHOGRAPHIC, fx_px=40.0, fy_px=40.0), cam_pts)
    np.testing.assert_allclose(uv[1], [121.3, 38.1])
    assert valid.tolist() == [True, True, False]


def test_fisheye_field_of_view_limits_validity():
    intr = _intr(LensModel.FISHEYE_EQUIDISTANT, fov_deg=90.0)
    angles = np.radians([10.0, 44.0, 46.0, 120.0])
    pts = np.stack([np.sin(angles), np.zeros(4), np.cos(angles)], 1)
    uv, valid = project_camera_points(intr, pts)
    assert valid.tolist() == [True, True, False, False]
    np.testing.assert_allclose(uv[0, 0] - intr.cx_px, 100.0 * angles[0])
    wide = _intr(LensModel.FISHEYE_EQUIDISTANT, fov_deg=250.0)
    assert project_camera_points(wide, pts)[1].tolist() == [True] * 4


def test_frame_pose_is_used():
    intr = _intr(LensModel.PERSPECTIVE)
    moved = Pose.from_rotation_translation(np.eye(3), [1.0, 0.0, 0.0])
    cam = Camera("c", intr, frame_poses=((5, moved),))
    p = np.array([[1.0, 0.0, 2.0]])
    assert project_points(cam, p)[0][0, 0] == pytest.approx(81.3 + 50.0)
    assert project_points(cam, p, frame=5)[0][0, 0] == pytest.approx(81.3)
    assert project_points(cam, p, frame=4)[0][0, 0] == pytest.approx(81.3 + 50.0)


@pytest.mark.parametrize("intr", [
    _intr(LensModel.OPENCV_PINHOLE, distortion=(-0.25, 0.06, 0.001, -0.001, -0.005)),
    _intr(LensModel.OPENCV_PINHOLE, distortion=(0.15, 0.01, 0.0, 0.0)),
    _intr(LensModel.OPENCV_FISHEYE, distortion=(0.05, -0.01, 0.002, -0.0003), fx_px=40.0, fy_px=40.0),
    _intr(LensModel.OPENCV_FISHEYE, distortion=(0.02, 0.0, 0.0, 0.0)),
    _intr(LensModel.KANNALA, distortion=(-0.03, 0.004, 0.0, 0.0), fx_px=45.0, fy_px=46.0),
    _intr(LensModel.RADIAL_POLY, distortion=(0.04, -0.02, 0.002), fx_px=45.0, fy_px=45.0, fov_deg=200.0),
    _intr(LensModel.RADIAL_POLY, distortion=(0.1, 0.0, 0.0), fx_px=200.0, fy_px=200.0),
    _intr(LensModel.FISHEYE_EQUISOLID, fx_px=50.0, fy_px=50.0, fov_deg=180.0),
])
def test_rays_round_trip_and_remap_lands_on_the_same_ray(intr):
    vs, us = np.mgrid[0:intr.height_px:7, 0:intr.width_px:7]
    uv = np.stack([us.ravel(), vs.ravel()], 1).astype(float)
    rays, valid = pixel_rays(intr, uv)
    assert valid.mean() > 0.5
    back, ok = project_camera_points(intr, rays[valid])
    assert ok.all()
    np.testing.assert_allclose(back, uv[valid], atol=1e-4)

    render = undistorted_render_intrinsics(intr)
    map_x, map_y = remap_grids(intr, render)
    assert map_x.shape == (intr.height_px, intr.width_px) and map_x.dtype == np.float32
    src = np.stack([map_x[vs, us].ravel(), map_y[vs, us].ravel()], 1).astype(float)
    inside = valid & (src[:, 0] >= 0)
    assert inside.sum() == valid.sum()  # the render covers every output ray
    src_rays, _ = pixel_rays(render, src[inside])
    np.testing.assert_allclose(src_rays, rays[inside], atol=1e-5)


def test_undistorted_render_uses_fisheye_beyond_60_degrees():
    wide = _intr(LensModel.OPENCV_FISHEYE, distortion=(0.01, 0.0, 0.0, 0.0), fx_px=40.0, fy_px=40.0)
    assert undistorted_render_intrinsics(wide).lens is LensModel.FISHEYE_EQUIDISTANT
    narrow = _intr(LensModel.OPENCV_FISHEYE, distortion=(0.01, 0.0, 0.0, 0.0), fx_px=200.0, fy_px=200.0)
    render = undistorted_render_intrinsics(narrow)
    assert render.lens is LensModel.PERSPECTIVE
    assert render.width_px > narrow.width_px
    assert render.cx_px % 1 == pytest.approx(narrow.cx_px % 1)  # same sub-pixel phase
