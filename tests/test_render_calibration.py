"""Calibration guarantee: for every lens model, the sphere centres found in the rendered masks
agree with an independent OpenCV projection of the written calibration within 1 px, and every
mask pixel has its object's colour in the RGB image of the same render."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
from usdscene.labels.projection import native_renderable, project_points

pytestmark = [pytest.mark.usd, pytest.mark.blender]

W, H = 240, 180
EQUISOLID_KB = (-1 / 24, 1 / 1920, -1 / 322560, 1 / 92897280)
PALETTE = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 0.5, 0),
           (0.5, 0, 1), (0, 0.5, 1), (1, 1, 1), (0.5, 1, 0), (1, 0, 0.5), (0, 1, 0.5),
           (0.5, 0.5, 1), (1, 0.5, 0.5), (0.5, 1, 0.5), (0.25, 0.75, 1), (1, 0.75, 0.25)]

# Camera at 1.5 m height looking along world +x: OpenCV x = world -y, y = world -z, z = world +x.
R_CV = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
POSE = Pose.from_rotation_translation(R_CV, [0.0, 0.0, 1.5])

CAMERAS = {
    "persp": Intrinsics(LensModel.PERSPECTIVE, W, H, 160.0, 160.0, 126.3, 84.2),
    "ortho": Intrinsics(LensModel.ORTHOGRAPHIC, W, H, 40.0, 40.0, 117.0, 93.5),
    "equidistant": Intrinsics(LensModel.FISHEYE_EQUIDISTANT, W, H, 60.0, 60.0, (W - 1) / 2, (H - 1) / 2,
                              fov_deg=170.0),
    "equisolid": Intrinsics(LensModel.FISHEYE_EQUISOLID, W, H, 62.0, 62.0, (W - 1) / 2, (H - 1) / 2,
                            fov_deg=170.0),
    "brown": Intrinsics(LensModel.OPENCV_PINHOLE, W, H, 150.0, 150.0, 121.7, 88.1,
                        distortion=(-0.22, 0.05, 0.001, -0.0015, -0.004)),
    "kannala": Intrinsics(LensModel.OPENCV_FISHEYE, W, H, 64.0, 64.0, 118.2, 90.6,
                          distortion=(0.03, -0.01, 0.002, -0.0005)),
    # VCD's polynomials, normalised (see LensModel): remapped like the OpenCV models.
    "vcd_kannala": Intrinsics(LensModel.KANNALA, W, H, 62.0, 62.0, 121.4, 87.9,
                              distortion=(-0.02, 0.003, -0.0002, 0.00001)),
    "radial_poly": Intrinsics(LensModel.RADIAL_POLY, W, H, 60.0, 60.0, 117.3, 91.8,
                              distortion=(0.03, -0.02, 0.002), fov_deg=180.0),
    # Not natively renderable: remapped from a centred / square-pixel render.
    "equidistant_offset": Intrinsics(LensModel.FISHEYE_EQUIDISTANT, W, H, 58.0, 58.0, 131.2, 83.7,
                                     fov_deg=170.0),
    "persp_nonsquare": Intrinsics(LensModel.PERSPECTIVE, W, H, 160.0, 148.0, 118.6, 91.2),
}


def _sphere_points():
    """World centres (N, 3) and radii (N,): directions up to 75° off the camera axis at 3-4 m,
    angular radius 0.03 rad (small enough that the silhouette centroid is the centre's image
    to ~0.2 px), plus a grid at 0° for the orthographic camera."""
    centres, radii = [], []
    for theta_deg, phis in ((0, [0]), (15, [0, 120, 240]), (30, [45, 165, 285]), (50, [10, 130, 250]),
                            (72, [70, 190, 310])):
        for k, phi_deg in enumerate(phis):
            t, p = math.radians(theta_deg), math.radians(phi_deg)
            d = 3.0 + 0.3 * k
            cam = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]) * d
            centres.append(POSE.transform_points(cam)[0])
            radii.append(0.03 * d)
    return np.array(centres), np.array(radii)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    root = tmp_path_factory.mktemp("calibration")
    centres, radii = _sphere_points()
    spheres = tuple(SphereSpec(f"s{i:02d}", tuple(c), float(r), PALETTE[i % len(PALETTE)], i + 1)
                    for i, (c, r) in enumerate(zip(centres, radii)))
    cameras = tuple(Camera(name, intr, POSE) for name, intr in CAMERAS.items())
    stage = write_synthetic_stage(SyntheticScene(cameras=cameras, spheres=spheres), root / "stage")
    out = root / "out"
    report = render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False)
    return out, cameras, spheres, centres, report


def _opencv_projection(intr: Intrinsics, centres: np.ndarray) -> np.ndarray:
    """Independent projection of the written calibration through OpenCV (or by hand for the
    orthographic camera and the radial_poly lens, which OpenCV lacks)."""
    w2c = POSE.inverse().as_array()
    rvec, _ = cv2.Rodrigues(w2c[:3, :3])
    tvec = w2c[:3, 3].copy()
    k = intr.camera_matrix()
    if intr.lens is LensModel.ORTHOGRAPHIC:
        cam = centres @ w2c[:3, :3].T + tvec
        return np.stack([intr.fx_px * cam[:, 0] + intr.cx_px, intr.fy_px * cam[:, 1] + intr.cy_px], 1)
    if intr.lens is LensModel.RADIAL_POLY:
        cam = centres @ w2c[:3, :3].T + tvec
        rho = np.hypot(cam[:, 0], cam[:, 1])
        theta = np.arctan2(rho, cam[:, 2])
        theta_d = theta + sum(d * theta ** (i + 2) for i, d in enumerate(intr.distortion))
        scale = theta_d / np.where(rho > 0, rho, 1.0)  # a ray on the axis lands on the centre
        return np.stack([intr.fx_px * scale * cam[:, 0] + intr.cx_px, intr.fy_px * scale * cam[:, 1] + intr.cy_px], 1)
    if intr.lens in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE):
        dist = np.array(intr.distortion or (0.0,) * 4)
        return cv2.projectPoints(centres, rvec, tvec, k, dist)[0].reshape(-1, 2)
    kb = {LensModel.FISHEYE_EQUIDISTANT: (0.0,) * 4, LensModel.FISHEYE_EQUISOLID: EQUISOLID_KB,
          LensModel.OPENCV_FISHEYE: intr.distortion, LensModel.KANNALA: intr.distortion}[intr.lens]
    return cv2.fisheye.projectPoints(centres.reshape(-1, 1, 3), rvec, tvec, k, np.array(kb))[0].reshape(-1, 2)


def test_render_reports_every_pair(rendered):
    out, cameras, *_ , report = rendered
    assert report.pairs_rendered == len(cameras) and report.pairs_skipped == 0
    for cam in cameras:
        image = cv2.imread(str(layout.image_path(out, cam.name, 0)), cv2.IMREAD_UNCHANGED)
        mask = cv2.imread(str(layout.mask_path(out, cam.name, 0)), cv2.IMREAD_UNCHANGED)
        assert image.shape == (H, W, 3) and image.dtype == np.uint8
        assert mask.shape == (H, W) and mask.dtype == np.uint16


@pytest.mark.parametrize("name", list(CAMERAS))
def test_mask_centroids_match_opencv_projection(rendered, name):
    out, cameras, spheres, centres, _ = rendered
    intr = CAMERAS[name]
    mask = cv2.imread(str(layout.mask_path(out, name, 0)), cv2.IMREAD_UNCHANGED)
    expected = _opencv_projection(intr, centres)
    _, valid = project_points(Camera(name, intr, POSE), centres)
    checked = 0
    for i, sphere in enumerate(spheres):
        u, v = expected[i]
        margin = 8
        if not valid[i] or not (margin <= u <= W - 1 - margin and margin <= v <= H - 1 - margin):
            continue
        ys, xs = np.nonzero(mask == sphere.mask_id)
        assert xs.size > 0, f"{name}: sphere {sphere.uid} expected at ({u:.1f}, {v:.1f}) is missing"
        error = math.hypot(xs.mean() - u, ys.mean() - v)
        assert error < 1.0, f"{name}: sphere {sphere.uid} centroid off by {error:.2f} px"
        checked += 1
    assert checked >= (3 if intr.lens is LensModel.ORTHOGRAPHIC else 6)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_masks_agree_with_rgb(rendered, name):
    out, cameras, spheres, *_ = rendered
    image = cv2.imread(str(layout.image_path(out, name, 0)))[:, :, ::-1].astype(int)
    mask = cv2.imread(str(layout.mask_path(out, name, 0)), cv2.IMREAD_UNCHANGED)
    colours = {s.mask_id: np.round(255 * np.array(s.color_rgb) ** (1 / 2.4) * 1.055 - 0.055 * 255)
               for s in spheres}
    remapped = not native_renderable(CAMERAS[name])
    assert set(np.unique(mask)) - {0} <= set(colours)
    if not remapped:
        # One sample per pixel: the colour and the id come from the same ray, exactly.
        assert (image[mask == 0] == 0).all()
    for mask_id in np.unique(mask)[1:]:
        pixels = image[mask == mask_id]
        nearest = np.argmin([np.abs(pixels - c).sum(1) for c in [np.zeros(3), *colours.values()]], axis=0)
        ids = np.array([0, *colours.keys()])[nearest]
        if remapped:  # bilinear image, nearest mask: edges blend, the bulk must match
            assert (ids == mask_id).mean() >= 0.5, f"{name}: id {mask_id} region shows another colour"
        else:
            assert (ids == mask_id).all(), f"{name}: id {mask_id} region shows another colour"
