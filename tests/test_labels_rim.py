"""Amodal labels agree with the render where objects leave the image: cut by a fisheye's image
circle or by the image border, on every lens family. For every label the amodal box contains
the visible box (within 1 px) and the visible fraction is consistent with both."""

from __future__ import annotations

import math

import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

W, H = 160, 120
# Camera at 1.5 m height looking along world +x (OpenCV axes: x = world -y, y = world -z).
POSE = Pose.from_rotation_translation(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]),
                                      [0.0, 0.0, 1.5])
CAMERAS = {
    # image circle of radius 2·70·sin(29.5°) ≈ 69 px: inside the image left and right, cut
    # by the top and bottom border
    "equisolid": Intrinsics(LensModel.FISHEYE_EQUISOLID, W, H, 70.0, 70.0, (W - 1) / 2, (H - 1) / 2,
                            fov_deg=118.0),
    "equidistant": Intrinsics(LensModel.FISHEYE_EQUIDISTANT, W, H, 66.0, 66.0, (W - 1) / 2, (H - 1) / 2,
                              fov_deg=118.0),
    "kannala": Intrinsics(LensModel.OPENCV_FISHEYE, W, H, 64.0, 64.0, 81.2, 58.6,
                          distortion=(0.03, -0.01, 0.002, -0.0005), fov_deg=118.0),
    "perspective": Intrinsics(LensModel.PERSPECTIVE, W, H, 90.0, 90.0, (W - 1) / 2, (H - 1) / 2),
    "brown": Intrinsics(LensModel.OPENCV_PINHOLE, W, H, 90.0, 90.0, 80.7, 60.1,
                        distortion=(-0.22, 0.05, 0.001, -0.0015, -0.004)),
}


def _spheres():
    """Centres (N, 3) and radii (N,): spheres straddling 59° off the axis (the fisheye circle)
    and 42-45° (the perspective image border) at several azimuths, plus one on the axis."""
    out = [((0.0, 0.0), 0.25)]
    for theta_deg in (44.0, 59.0):
        for phi_deg in range(0, 360, 45):
            out.append(((theta_deg, phi_deg), 0.35))
    centres, radii = [], []
    for k, ((theta_deg, phi_deg), radius) in enumerate(out):
        t, p = math.radians(theta_deg), math.radians(phi_deg)
        d = 3.0 + 0.1 * (k % 3)
        cam = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]) * d
        centres.append(POSE.transform_points(cam)[0])
        radii.append(radius)
    return np.array(centres), np.array(radii)


@pytest.fixture(scope="module")
def labels(tmp_path_factory):
    from usdscene.dataset.annotation import annotate_output
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    root = tmp_path_factory.mktemp("rim")
    centres, radii = _spheres()
    spheres = tuple(SphereSpec(f"s{i:02d}", tuple(c), float(r), (0.8, 0.3 + 0.02 * i, 0.2), i + 1)
                    for i, (c, r) in enumerate(zip(centres, radii)))
    cameras = tuple(Camera(name, intr, POSE) for name, intr in CAMERAS.items())
    out = root / "out"
    stage = write_synthetic_stage(SyntheticScene(cameras=cameras, spheres=spheres), out / "stage")
    render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False)
    return annotate_output(out, epsilon_px=0)[1]


def test_every_amodal_box_contains_its_visible_box(labels):
    checked = 0
    for image in labels:
        for label in image.objects:
            if label.box is None:
                continue
            a, v = label.amodal_box, label.box
            where = f"{image.camera} {label.uid}: visible {v}, amodal {a}"
            assert a is not None, where
            # Cycles jitters its one sample per pixel inside the pixel filter, so a boundary
            # shifts by up to about a pixel across itself; along a sliver of one or two rows
            # cut by the image border (boundary nearly parallel to the border) that becomes
            # a few pixels along it.
            slack = 1 if min(v.x_max - v.x_min, v.y_max - v.y_min) >= 2 else 3
            assert (a.x_min <= v.x_min + slack and a.y_min <= v.y_min + slack
                    and a.x_max >= v.x_max - slack and a.y_max >= v.y_max - slack), where
            assert 0.0 < label.visible_fraction <= 1.0, where
            # nothing occludes these spheres: the visible pixels are (almost) the whole projection;
            # on a sliver along the border the boundary tolerance is a few pixels of a handful
            missing = round(label.amodal_pixel_count * (1.0 - label.visible_fraction))
            assert label.visible_fraction > 0.85 or (slack == 3 and missing <= slack), (where, missing)
            checked += 1
    assert checked >= 40


def test_objects_cut_by_the_image_circle_keep_their_inner_part(labels):
    fisheye = {image.camera: image for image in labels if image.camera == "equisolid"}["equisolid"]
    cut = [label for label in fisheye.objects if label.truncated and label.box is not None]
    # the spheres at 59° off the axis straddle the 118° circle; those at 90° and 270° azimuth
    # are beyond the top and bottom of the image
    assert len(cut) == 6
    for label in cut:
        assert label.amodal_pixel_count >= label.pixel_count * 0.9
