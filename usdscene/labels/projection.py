"""Camera projection for every lens model, and the remap grids of lenses Blender lacks. Pure.

numpy only (no pxr, no bpy, no cv2): with the lens classes of :mod:`usdscene.lens` (one per
:class:`usdscene.document.model.LensModel`, looked up by name), the functions here are the
*definition* of each model; tests check them against OpenCV's ``cv2.projectPoints`` and
``cv2.fisheye.projectPoints``, and the renderer is checked against them.

Pixel convention (see :class:`usdscene.document.model.Intrinsics`): x right, y down, pixel centres at
integer coordinates. Camera frames are OpenCV (x right, y down, z forward).

Models, with ``(x, y, z)`` a point in the camera frame, ``ρ = √(x² + y²)`` and
``θ = atan2(ρ, z)`` its angle off the optical axis:

* ``perspective``: ``u = fx·x/z + cx``; valid when ``z > 0``.
* ``orthographic``: ``u = fx·x + cx`` (fx in pixels per metre); valid when ``z > 0``.
* ``fisheye_equidistant``: image radius ``r = f·θ``; valid when ``θ ≤ fov/2``.
* ``fisheye_equisolid``: ``r = 2f·sin(θ/2)``; valid when ``θ ≤ fov/2``.
* ``opencv_pinhole``: pinhole + Brown-Conrady (k1 k2 p1 p2 [k3 [k4 k5 k6]]), exactly
  ``cv2.projectPoints``; valid when ``z > 0`` and the radial distortion has not folded back
  (the distorted radius still grows with the undistorted one).
* ``opencv_fisheye``: Kannala-Brandt ``θd = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)``, exactly
  ``cv2.fisheye.projectPoints`` for ``z > 0``; valid when ``θ ≤ fov/2`` (``fov_deg`` unset:
  ``z > 0``) and ``θd`` still grows with ``θ``.
* ``kannala``: the same ``θd`` with the normalised coefficients d1..d4 of VCD's kannala lens.
* ``radial_poly``: ``θd = θ(1 + d1θ + d2θ² + d3θ³ [+ d4θ⁴])``, any powers of ``θ``.

The radial models map ``θ`` to ``r = f·θd``; a ray is valid only where ``θd`` still grows
with ``θ`` (so any monotonic part of ``r(θ)`` is rendered, through :func:`remap_grids`).
Without a ``fov_deg``, fisheye models accept every direction up to 180° off the axis
(``opencv_fisheye``: 90°, where ``cv2.fisheye`` ends).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from usdscene.document.model import Camera, Intrinsics, LensModel
from usdscene.lens import LENSES, lens_for

__all__ = [
    "project_points",
    "project_camera_points",
    "project_camera_points_with_angle",
    "pixel_rays",
    "remap_grids",
    "undistorted_render_intrinsics",
    "native_renderable",
    "NATIVE_LENSES",
]

# Lens models Blender/Cycles renders directly; the others are rendered through a native lens
# and remapped (see remap_grids). Read from the lens registry (usdscene.lens) when imported.
NATIVE_LENSES = frozenset(name for name, lens in LENSES.items() if lens.native)


def project_points(camera: Camera, points_world: np.ndarray,
                   frame: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Project world points into a camera's image.

    Args:
        camera: the camera (intrinsics and camera → world pose in OpenCV axes).
        points_world: (N, 3) points in world coordinates, metres.
        frame: frame whose pose to use (``camera.pose_at(frame)``); None = ``camera.pose``.

    Returns:
        ``(uv, valid)``: (N, 2) float64 pixel coordinates (OpenCV convention, pixel centres at
        integers; meaningless where ``valid`` is False) and (N,) bool, True where the point is
        in front of the camera and inside the lens's field of view. Points outside the image
        rectangle but inside the field of view are valid.
    """
    pose = camera.pose if frame is None else camera.pose_at(frame)
    pts = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    m = pose.as_array()
    # world → camera: R^T (p - t), written for row vectors.
    points_cam = (pts - m[:3, 3]) @ m[:3, :3]
    return project_camera_points(camera.intrinsics, points_cam)


def project_camera_points(intrinsics: Intrinsics,
                          points_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project (N, 3) camera-frame points (OpenCV axes, metres) → ``(uv (N, 2), valid (N,))``.

    See :func:`project_points`.
    """
    return project_camera_points_with_angle(intrinsics, points_cam)[:2]


def project_camera_points_with_angle(intrinsics: Intrinsics, points_cam: np.ndarray
                                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`project_camera_points`, and for the fisheye models the angle ``θ`` of each
    point off the optical axis (radians, (N,)), which they compute anyway; None for the
    other models."""
    p = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
    x, y, z = np.ascontiguousarray(p.T)  # contiguous columns: the element-wise passes run faster
    fx, fy, cx, cy = intrinsics.fx_px, intrinsics.fy_px, intrinsics.cx_px, intrinsics.cy_px
    with np.errstate(divide="ignore", invalid="ignore"):
        xn, yn, valid, theta = lens_for(intrinsics).project(intrinsics, x, y, z)
        uv = np.empty((len(p), 2))
        uv[:, 0] = fx * xn + cx
        uv[:, 1] = fy * yn + cy
        valid = valid & np.isfinite(uv[:, 0]) & np.isfinite(uv[:, 1])
    return uv, valid, theta


# Lens models whose image radius is a polynomial r = f·θd(θ) (usdscene.lens.fisheye.PolynomialLens).
RADIAL_POLYNOMIAL_LENSES = frozenset(name for name, lens in LENSES.items() if lens.polynomial)


def pixel_rays(intrinsics: Intrinsics, uv: np.ndarray,
               iterations: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Unit viewing rays of pixel positions (the inverse of :func:`project_camera_points`).

    Args:
        intrinsics: the camera model.
        uv: (N, 2) pixel coordinates (OpenCV convention).
        iterations: fixed-point / Newton iterations for distorted models.

    Returns:
        ``(rays, valid)``: (N, 3) float64 unit directions in the camera frame (OpenCV axes;
        for ORTHOGRAPHIC the ray direction is +z for every pixel) and (N,) bool, False where
        the pixel has no ray (outside a fisheye's image circle, or the inversion of the
        distortion did not converge to 1e-6 px).
    """
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    xd = (uv[:, 0] - intrinsics.cx_px) / intrinsics.fx_px
    yd = (uv[:, 1] - intrinsics.cy_px) / intrinsics.fy_px
    return lens_for(intrinsics).unproject(intrinsics, xd, yd, iterations)


def native_renderable(intrinsics: Intrinsics) -> bool:
    """Whether Blender renders this camera directly: a native lens with square pixels, and for
    fisheyes a centred principal point (Cycles' panoramic cameras ignore lens shift)."""
    lens = lens_for(intrinsics)
    if not lens.native or abs(intrinsics.fx_px - intrinsics.fy_px) > 1e-9 * intrinsics.fx_px:
        return False
    if lens.centred:
        return (abs(intrinsics.cx_px - (intrinsics.width_px - 1) / 2) < 1e-6
                and abs(intrinsics.cy_px - (intrinsics.height_px - 1) / 2) < 1e-6)
    return True


def undistorted_render_intrinsics(intrinsics: Intrinsics, *, max_scale: float = 3.0) -> Intrinsics:
    """The native lens to render before remapping to a camera Blender cannot render directly.

    That is every ``opencv_pinhole`` / ``opencv_fisheye`` / ``kannala`` / ``radial_poly`` camera,
    and native lenses with
    non-square pixels or (fisheyes) an off-centre principal point. The render has square
    pixels with the larger focal length of the output (so no region loses pixel density
    near the axis), a centred principal point, and is just large enough to contain the ray of
    every output pixel, plus a two-pixel margin for bilinear interpolation. It is a
    perspective view for pinhole models and for radial polynomial lenses up to 60° off the axis,
    otherwise a fisheye (equisolid for an equisolid output, equidistant for the others).

    Args:
        intrinsics: the output camera.
        max_scale: cap on render size / output size per axis (strong distortion at the
            corners would otherwise ask for huge renders; rays beyond the cap stay black).

    Returns:
        Intrinsics of a natively renderable lens; ``intrinsics`` itself when it is one.

    Raises:
        ValueError: an orthographic camera with non-square pixels (not supported).
    """
    lens = lens_for(intrinsics)
    if native_renderable(intrinsics):
        return intrinsics
    if lens.orthographic:
        raise ValueError(f"orthographic camera with non-square pixels (fx {intrinsics.fx_px} px/m, "
                         f"fy {intrinsics.fy_px} px/m) is not supported")
    w, h = intrinsics.width_px, intrinsics.height_px
    rays, valid = pixel_rays(intrinsics, _border_pixels(w, h))
    rays = rays[valid]
    if not valid.all() and intrinsics.fov_deg is not None:
        # Border pixels beyond the image circle: where the circle lies inside the image, its
        # rim is the edge of what the render must contain.
        theta = math.radians(intrinsics.fov_deg) / 2.0
        phi = np.linspace(0.0, 2.0 * math.pi, 720, endpoint=False)
        rim = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                        np.full_like(phi, np.cos(theta))], axis=1)
        uv, imaged = project_camera_points(intrinsics, rim)
        inside = imaged & (uv[:, 0] >= -0.5) & (uv[:, 0] <= w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= h - 0.5)
        rays = np.concatenate([rays, rim[inside]])
    if rays.size == 0:
        rays = np.array([[0.0, 0.0, 1.0]])
    theta_max = float(np.max(np.arctan2(np.hypot(rays[:, 0], rays[:, 1]), rays[:, 2])))
    f = max(intrinsics.fx_px, intrinsics.fy_px)
    pinhole_like = lens.pinhole or (lens.polynomial and theta_max < math.radians(60.0))
    if pinhole_like:
        tx = np.abs(rays[:, 0] / rays[:, 2])
        ty = np.abs(rays[:, 1] / rays[:, 2])
        half_w = min(f * float(tx.max()) + 2.0, max_scale * w / 2.0)
        half_h = min(f * float(ty.max()) + 2.0, max_scale * h / 2.0)
        # The render's principal point has the output's sub-pixel phase, so that where the
        # map is a pure translation it is an integer one and nearest-neighbour (masks) does
        # not shift anything.
        rw, rh = 2 * math.ceil(half_w) + 2, 2 * math.ceil(half_h) + 2
        cx = math.floor((rw - 1) / 2.0) + (intrinsics.cx_px - math.floor(intrinsics.cx_px))
        cy = math.floor((rh - 1) / 2.0) + (intrinsics.cy_px - math.floor(intrinsics.cy_px))
        return replace(intrinsics, lens=LensModel.PERSPECTIVE, width_px=rw, height_px=rh, fx_px=f, fy_px=f,
                       cx_px=cx, cy_px=cy, distortion=(), fov_deg=None,
                       sensor_width_mm=intrinsics.sensor_width_mm * rw / w)
    # A native fisheye renders itself (off centre); any other, through an equidistant one.
    render_lens = LensModel(lens.name) if lens.native and lens.radial else LensModel.FISHEYE_EQUIDISTANT
    radius = lens_for(render_lens).render_radius_px(f, theta_max)
    half = min(radius + 2.0, max_scale * max(w, h) / 2.0)
    # Native fisheyes are centred: pick each side's parity so the centre's sub-pixel phase
    # (integer or half) is the closest to the output's (see the pinhole case).
    def side(c: float) -> int:
        n = 2 * math.ceil(half) + 1  # odd: centre on a pixel
        phase = c - math.floor(c)
        return n if phase < 0.25 or phase > 0.75 else n + 1
    rw, rh = side(intrinsics.cx_px), side(intrinsics.cy_px)
    fov = min(360.0, math.degrees(2.0 * theta_max) + 2.0)
    return replace(intrinsics, lens=render_lens, width_px=rw, height_px=rh,
                   fx_px=f, fy_px=f, cx_px=(rw - 1) / 2.0, cy_px=(rh - 1) / 2.0,
                   distortion=(), fov_deg=fov, sensor_width_mm=intrinsics.sensor_width_mm * rw / w)


def _border_pixels(width: int, height: int) -> np.ndarray:
    """(N, 2) positions along the outer edge of the image (pixel edges, not centres)."""
    xs = np.linspace(-0.5, width - 0.5, max(2, width + 1))
    ys = np.linspace(-0.5, height - 0.5, max(2, height + 1))
    return np.concatenate([
        np.stack([xs, np.full_like(xs, -0.5)], 1), np.stack([xs, np.full_like(xs, height - 0.5)], 1),
        np.stack([np.full_like(ys, -0.5), ys], 1), np.stack([np.full_like(ys, width - 0.5), ys], 1),
    ])


def remap_grids(intrinsics: Intrinsics, render_intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` that turn a render through ``render_intrinsics`` into the image
    of ``intrinsics`` (same camera pose).

    ``output[v, u] = rendered[map_y[v, u], map_x[v, u]]``: bilinear for the RGB image, nearest
    for the mask, with the same maps so labels stay exact. Pixels without a ray, or whose ray
    the render does not see, map to ``-1`` (black / background with ``BORDER_CONSTANT``).

    Args:
        intrinsics: the output camera (any model; normally opencv_pinhole / opencv_fisheye).
        render_intrinsics: the native lens that was rendered (perspective, fisheye).

    Returns:
        ``(map_x, map_y)``: float32 arrays of shape (height_px, width_px) of ``intrinsics``,
        in pixel coordinates of the rendered image (OpenCV convention, as ``cv2.remap``).
    """
    h, w = intrinsics.height_px, intrinsics.width_px
    vs, us = np.mgrid[0:h, 0:w]
    uv = np.stack([us.ravel(), vs.ravel()], axis=1).astype(np.float64)
    rays, valid = pixel_rays(intrinsics, uv)
    src, seen = project_camera_points(render_intrinsics, rays)
    ok = valid & seen
    src[~ok] = -1.0
    map_x = src[:, 0].reshape(h, w).astype(np.float32)
    map_y = src[:, 1].reshape(h, w).astype(np.float32)
    return map_x, map_y
