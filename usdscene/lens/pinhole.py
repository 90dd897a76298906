"""Lenses onto a plane: the ideal pinhole, OpenCV's pinhole with Brown-Conrady distortion, and
the parallel (orthographic) projection."""

from __future__ import annotations

import numpy as np

from usdscene.lens.base import Lens


def distortion_coefficients(coeffs: tuple[float, ...], count: int) -> np.ndarray:
    """The first ``count`` coefficients of ``coeffs`` (float64), zeros after the given ones."""
    out = np.zeros(count)
    values = np.asarray(coeffs, dtype=np.float64)[:count]
    out[: values.size] = values
    return out


def brown_conrady(xn: np.ndarray, yn: np.ndarray, coeffs: tuple[float, ...]):
    """OpenCV's distortion of normalised coordinates → (xd, yd, radius_still_growing)."""
    k1, k2, p1, p2, k3, k4, k5, k6 = distortion_coefficients(coeffs, 8)
    r2 = xn * xn + yn * yn
    num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = num / den
    xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    # d(r·radial)/dr = radial + r · d radial/dr; d radial/d(r²) by the quotient rule.
    dnum = k1 + r2 * (2 * k2 + 3 * k3 * r2)
    dden = k4 + r2 * (2 * k5 + 3 * k6 * r2)
    growing = (radial + 2 * r2 * (dnum * den - num * dden) / (den * den)) > 0
    return xd, yd, growing & (den > 0)


def _undistort_brown_conrady(xd, yd, intrinsics, iterations: int):
    # The same fixed-point scheme as cv2.undistortPoints, run long enough to converge; the
    # residual check rejects pixels outside the region where the distortion is invertible.
    k1, k2, p1, p2, k3, k4, k5, k6 = distortion_coefficients(intrinsics.distortion, 8)
    xn, yn = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = xn * xn + yn * yn
        icdist = (1 + r2 * (k4 + r2 * (k5 + r2 * k6))) / (1 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        dy = p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
        xn, yn = (xd - dx) * icdist, (yd - dy) * icdist
    xr, yr, growing = brown_conrady(xn, yn, intrinsics.distortion)
    err = np.hypot((xr - xd) * intrinsics.fx_px, (yr - yd) * intrinsics.fy_px)
    # A converged pixel reprojects to within far less than 1e-3 px.
    valid = np.isfinite(err) & (err < 1e-3) & growing
    return xn, yn, valid


class Perspective(Lens):
    """``perspective``: the ideal pinhole, ``u = fx·x/z + cx``; valid when ``z > 0``."""

    name = "perspective"
    pinhole = True
    straight = True
    native = True
    calibration_family = "perspective"

    def from_calibration(self, coefficients, where, problems):
        if coefficients:
            problems.add(f"{where}", "lens model 'perspective' has no distortion; use 'opencv_pinhole' or "
                                     f"zero coefficients (got {list(coefficients)})")
            return None
        return coefficients

    def _distort(self, xn, yn, intrinsics):
        return xn, yn, None

    def project(self, intrinsics, x, y, z):
        valid = z > 0
        zs = np.where(valid, z, 1.0)
        xn, yn, growing = self._distort(x / zs, y / zs, intrinsics)
        if growing is not None:
            valid &= growing
        return xn, yn, valid, None

    def _undistort(self, xd, yd, intrinsics, iterations):
        return xd.copy(), yd.copy(), np.ones(len(xd), dtype=bool)

    def unproject(self, intrinsics, xd, yd, iterations):
        xn, yn, valid = self._undistort(xd, yd, intrinsics, iterations)
        rays = np.stack([xn, yn, np.ones_like(xn)], axis=1)
        return rays / np.linalg.norm(rays, axis=1, keepdims=True), valid

    def opencv_distortion(self, intrinsics):
        return "pinhole", np.zeros(5)

    def openlabel_calibration(self, intrinsics, size: dict, where: str, problems) -> dict:
        k = intrinsics
        dist = self._openlabel_distortion(k, where, problems)
        # The schema asks for at least 5 coefficients: pad k3 (and zeros for no distortion).
        dist = dist + [0.0] * (5 - len(dist)) if len(dist) < 5 else dist
        return {"intrinsics_pinhole": {
            **size,
            "camera_matrix": [float(k.fx_px), 0.0, float(k.cx_px), 0.0, 0.0, float(k.fy_px), float(k.cy_px), 0.0,
                              0.0, 0.0, 1.0, 0.0],
            "distortion_coeffs": dist}}

    def _openlabel_distortion(self, intrinsics, where, problems) -> list:
        return []

    def blender_camera(self, intrinsics) -> dict:
        return {"type": "PERSP", "lens": intrinsics.fx_px * intrinsics.sensor_width_mm / intrinsics.width_px}


class OpenCVPinhole(Perspective):
    """``opencv_pinhole``: pinhole + Brown-Conrady (k1 k2 p1 p2 [k3 [k4 k5 k6]]), exactly
    ``cv2.projectPoints``; valid when ``z > 0`` and the radial distortion has not folded back
    (the distorted radius still grows with the undistorted one). Rendered through a perspective
    view and remapped."""

    name = "opencv_pinhole"
    straight = False
    native = False
    brown_conrady = True
    distortion_lengths = (0, 4, 5, 8, 12, 14)
    catalog = False
    from_calibration = Lens.from_calibration

    def _distort(self, xn, yn, intrinsics):
        return brown_conrady(xn, yn, intrinsics.distortion)

    def _undistort(self, xd, yd, intrinsics, iterations):
        return _undistort_brown_conrady(xd, yd, intrinsics, iterations)

    def _openlabel_distortion(self, intrinsics, where, problems) -> list:
        dist = [float(v) for v in intrinsics.distortion]
        if dist and len(dist) not in (4, 5, 8):
            problems.add(f"{where}.distortion", f"OpenCV pinhole distortion has 4, 5 or 8 coefficients, got {len(dist)}")
        return dist

    def opencv_distortion(self, intrinsics):
        d = list(intrinsics.distortion) + [0.0] * max(0, 5 - len(intrinsics.distortion))
        return "pinhole", np.asarray(d[:8] if len(d) > 5 else d[:5], dtype=np.float64)

    blender_camera = Lens.blender_camera


class Orthographic(Lens):
    """``orthographic``: ``u = fx·x + cx`` (fx in pixels per metre); valid when ``z > 0``; every
    pixel's ray is +z."""

    name = "orthographic"
    orthographic = True
    straight = True
    native = True
    calibration_family = "orthographic"
    catalog = False

    def project(self, intrinsics, x, y, z):
        return x, y, z > 0, None

    def unproject(self, intrinsics, xd, yd, iterations):
        return np.tile([0.0, 0.0, 1.0], (len(xd), 1)), np.ones(len(xd), dtype=bool)

    def openlabel_calibration(self, intrinsics, size: dict, where: str, problems) -> dict:
        k = intrinsics
        return {"intrinsics_custom": {
            "model": "orthographic", **size, "scale_x_px_per_m": float(k.fx_px),
            "scale_y_px_per_m": float(k.fy_px), "center_x_px": float(k.cx_px), "center_y_px": float(k.cy_px)}}

    def blender_camera(self, intrinsics) -> dict:
        return {"type": "ORTHO", "ortho_scale": intrinsics.width_px / intrinsics.fx_px}  # metres across

