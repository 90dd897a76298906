"""Lenses that map the angle ``θ`` off the axis to an image radius ``r = f·g(θ)``: the
equidistant and equisolid fisheyes Blender renders, and the radial polynomials (OpenCV's
fisheye, VCD's kannala and radial_poly) rendered through one and remapped.

A ray is valid only where ``g`` still grows with ``θ`` (so any monotonic part of ``r(θ)`` is
rendered) and within ``fov_deg / 2`` of the axis.
"""

from __future__ import annotations

import math

import numpy as np

from usdscene.lens.base import Lens
from usdscene.lens.pinhole import distortion_coefficients

class RadialLens(Lens):
    """A lens ``r = f·g(θ)``; subclasses give :meth:`radius` and :meth:`angle`."""

    radial = True

    def radius(self, theta: np.ndarray, coeffs: tuple[float, ...]):
        """``(g(θ), whether g still grows)`` for angles ``theta`` (radians), arrays shaped alike."""
        raise NotImplementedError

    def angle(self, radius: np.ndarray, intrinsics, iterations: int):
        """``(θ, valid)`` of normalised image radii (the inverse of :meth:`radius`)."""
        raise NotImplementedError

    def render_radius_px(self, f_px: float, theta: float) -> float:
        """Image radius in pixels of the angle ``theta`` with focal length ``f_px`` (a native fisheye)."""
        raise NotImplementedError

    def openlabel_coeffs(self, intrinsics, where: str, problems) -> tuple[str, list]:
        """``(model, lens_coeffs)`` of the OpenLABEL ``intrinsics_fisheye`` that reproduces the lens."""
        return "opencv_fisheye", [0.0, 0.0, 0.0, 0.0]

    def openlabel_calibration(self, intrinsics, size: dict, where: str, problems) -> dict:
        k = intrinsics
        fisheye_model, coeffs = self.openlabel_coeffs(k, where, problems)
        return {"intrinsics_fisheye": {
            **size, "focal_length_x": float(k.fx_px), "focal_length_y": float(k.fy_px),
            "center_x_px": float(k.cx_px), "center_y_px": float(k.cy_px), "lens_coeffs": coeffs,
            "model": fisheye_model}}

    def project(self, intrinsics, x, y, z):
        rho = np.hypot(x, y)
        theta = np.arctan2(rho, z)
        radius, growing = self.radius(theta, intrinsics.distortion)
        valid = growing & (theta <= self.half_fov_rad(intrinsics)) & (rho + np.abs(z) > 0)
        safe_rho = np.where(rho > 0, rho, 1.0)
        xn = np.where(rho > 0, radius * x / safe_rho, 0.0)
        yn = np.where(rho > 0, radius * y / safe_rho, 0.0)
        return xn, yn, valid, theta

    def unproject(self, intrinsics, xd, yd, iterations):
        radius = np.hypot(xd, yd)
        theta, valid = self.angle(radius, intrinsics, iterations)
        valid &= theta <= self.half_fov_rad(intrinsics)
        safe = np.where(radius > 0, radius, 1.0)
        s = np.sin(theta)
        rays = np.stack([np.where(radius > 0, s * xd / safe, 0.0),
                         np.where(radius > 0, s * yd / safe, 0.0), np.cos(theta)], axis=1)
        return rays, valid


def _fisheye_fov_rad(intrinsics) -> float:
    return math.radians(min(intrinsics.fov_deg or 360.0, 360.0))


class EquidistantFisheye(RadialLens):
    """``fisheye_equidistant``: ``r = f·θ``; valid when ``θ ≤ fov/2``."""

    name = "fisheye_equidistant"
    native = True
    centred = True
    calibration_family = "opencv_fisheye"
    fov_spans_width = True

    def from_calibration(self, coefficients, where, problems):
        if any(coefficients):
            problems.add(where, f"lens model 'fisheye_equidistant' needs zero lens coefficients, got {list(coefficients)}")
            return None
        return ()

    def radius(self, theta, coeffs):
        return theta, np.ones_like(theta, dtype=bool)

    def angle(self, radius, intrinsics, iterations):
        return radius, np.ones(len(radius), dtype=bool)

    def render_radius_px(self, f_px, theta):
        return f_px * theta

    def opencv_distortion(self, intrinsics):
        return "fisheye", np.zeros(4)

    def blender_camera(self, intrinsics) -> dict:
        # θ = -(k0 + k1·r) with r in millimetres on the sensor: equidistant is k1 = -1/f.
        return {"type": "PANO", "panorama_type": "FISHEYE_LENS_POLYNOMIAL", "fisheye_polynomial_k0": 0.0,
                "fisheye_polynomial_k1": -intrinsics.width_px / (intrinsics.fx_px * intrinsics.sensor_width_mm),
                "fisheye_polynomial_k2": 0.0, "fisheye_polynomial_k3": 0.0, "fisheye_polynomial_k4": 0.0,
                "fisheye_fov": _fisheye_fov_rad(intrinsics)}


EQUISOLID_KB_COEFFS = (-1.0 / 24.0, 1.0 / 1920.0, -1.0 / 322560.0, 1.0 / 92897280.0)
"""Kannala-Brandt (OpenCV fisheye) coefficients of the equisolid projection r = 2 f sin(θ/2):
the Taylor series 2 sin(θ/2) = θ (1 - θ²/24 + θ⁴/1920 - θ⁶/322560 + θ⁸/92897280 - ...), exact to
1e-10 rad for θ <= 1.1 rad (the OpenLABEL writer's fit and the lens's OpenCV export)."""


class EquisolidFisheye(RadialLens):
    """``fisheye_equisolid``: ``r = 2f·sin(θ/2)``; valid when ``θ ≤ fov/2``."""

    name = "fisheye_equisolid"
    native = True
    centred = True
    calibration_family = "opencv_fisheye"

    def from_calibration(self, coefficients, where, problems):
        if len(coefficients) != 4 or any(abs(a - b) > 1e-12 + 1e-9 * abs(b)
                                         for a, b in zip(coefficients, EQUISOLID_KB_COEFFS)):
            problems.add(where, "lens model 'fisheye_equisolid' is written as opencv_fisheye with the "
                                f"coefficients {list(EQUISOLID_KB_COEFFS)}, got {list(coefficients)}")
            return None
        return ()

    def opencv_distortion(self, intrinsics):
        # OpenCV has no equisolid model: its fisheye model with the Taylor fit above
        # (usdscene.converters.exports.multiview.equisolid_fit_error_px states the error).
        return "fisheye", np.asarray(EQUISOLID_KB_COEFFS, dtype=np.float64)

    def opencv_fit_error_px(self, intrinsics) -> float:
        # over the field of view (``fov_deg``; 180° when unset), sampled finely in θ
        half = math.radians(min(intrinsics.fov_deg or 180.0, 180.0)) / 2.0
        theta = np.linspace(0.0, half, 2001)
        fit = theta * (1.0 + sum(c * theta ** (2 * (n + 1)) for n, c in enumerate(EQUISOLID_KB_COEFFS)))
        return float(np.max(np.abs(fit - 2.0 * np.sin(theta / 2.0))) * max(intrinsics.fx_px, intrinsics.fy_px))

    def radius(self, theta, coeffs):
        return 2.0 * np.sin(theta / 2.0), theta < math.pi

    def angle(self, radius, intrinsics, iterations):
        valid = np.ones(len(radius), dtype=bool)
        valid &= radius <= 2.0
        return 2.0 * np.arcsin(np.clip(radius / 2.0, 0.0, 1.0)), valid

    def render_radius_px(self, f_px, theta):
        return 2 * f_px * math.sin(theta / 2)

    def openlabel_coeffs(self, intrinsics, where, problems):
        return "opencv_fisheye", list(EQUISOLID_KB_COEFFS)

    def blender_camera(self, intrinsics) -> dict:
        return {"type": "PANO", "panorama_type": "FISHEYE_EQUISOLID",
                "fisheye_lens": intrinsics.fx_px * intrinsics.sensor_width_mm / intrinsics.width_px,
                "fisheye_fov": _fisheye_fov_rad(intrinsics)}


class PolynomialLens(RadialLens):
    """``r = f·θd(θ)`` with a polynomial ``θd``; subclasses give :meth:`theta_d`."""

    polynomial = True

    def theta_d(self, theta: np.ndarray, coeffs: tuple[float, ...]):
        """``(θd, dθd/dθ)`` of angles ``theta`` (radians, any shape), arrays shaped alike."""
        raise NotImplementedError

    def radius(self, theta, coeffs):
        theta_d, slope = self.theta_d(theta, coeffs)
        return theta_d, slope > 0

    def angle(self, radius, intrinsics, iterations):
        coeffs = intrinsics.distortion
        theta = radius.copy()
        for _ in range(iterations):  # Newton on θd(θ) - θd = 0
            value, slope = self.theta_d(theta, coeffs)
            theta = theta - (value - radius) / np.where(np.abs(slope) > 1e-12, slope, 1e-12)
            theta = np.clip(theta, 0.0, math.pi)
        value, growing = self.radius(theta, coeffs)
        ok = np.isfinite(theta) & (np.abs(value - radius) < 1e-9) & growing
        valid = np.ones(len(radius), dtype=bool)
        valid &= ok
        return theta, valid


class OpenCVFisheye(PolynomialLens):
    """``opencv_fisheye``: Kannala-Brandt ``θd = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)``, exactly
    ``cv2.fisheye.projectPoints`` for ``z > 0``; without ``fov_deg`` valid up to 90° off the
    axis, where ``cv2.fisheye`` ends."""

    name = "opencv_fisheye"
    default_half_fov_rad = math.pi / 2.0
    calibration_family = "opencv_fisheye"
    distortion_lengths = (4,)
    distortion_what = "Kannala-Brandt coefficients k1..k4"
    default_distortion = (0.0, 0.0, 0.0, 0.0)
    catalog = False

    def theta_d(self, theta, coeffs):
        k1, k2, k3, k4 = distortion_coefficients(coeffs, 4)
        t2 = theta * theta
        theta_d = theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
        slope = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
        return theta_d, slope

    def opencv_distortion(self, intrinsics):
        d = list(intrinsics.distortion) + [0.0] * 4
        return "fisheye", np.asarray(d[:4], dtype=np.float64)

    def openlabel_coeffs(self, intrinsics, where, problems):
        coeffs = [float(v) for v in intrinsics.distortion]
        if len(coeffs) != 4:
            problems.add(f"{where}.distortion", f"{self.name} has 4 coefficients k1..k4, got {len(coeffs)}")
        return "opencv_fisheye", coeffs


class KannalaFisheye(OpenCVFisheye):
    """``kannala``: the Kannala-Brandt ``θd`` with the normalised coefficients d1..d4 of VCD's
    kannala lens, any ``θ`` up to 180° off the axis."""

    name = "kannala"
    default_half_fov_rad = math.pi
    calibration_family = "kannala"
    catalog = True

    def openlabel_coeffs(self, intrinsics, where, problems):
        # VCD's own form r = f (k1θ + k2θ³ + ...) with k1 = 1 is the normalised lens as it is
        _, coeffs = super().openlabel_coeffs(intrinsics, where, problems)
        return "kannala", [1.0, *coeffs]


class RadialPolynomial(PolynomialLens):
    """``radial_poly``: ``θd = θ(1 + d1θ + d2θ² + d3θ³ [+ d4θ⁴])``, any powers of ``θ``."""

    name = "radial_poly"
    calibration_family = "radial_poly"
    distortion_lengths = (3, 4)
    distortion_what = "radial_poly coefficients d1..d3 [d4] of θ(1 + d1θ + d2θ² + ...)"
    default_distortion = (0.0, 0.0, 0.0)

    def openlabel_coeffs(self, intrinsics, where, problems):
        coeffs = [float(v) for v in intrinsics.distortion]
        if len(coeffs) not in (3, 4):
            problems.add(f"{where}.distortion", f"radial_poly has 3 or 4 coefficients d1..d4, got {len(coeffs)}")
        return "radial_poly", [1.0, *coeffs]

    def theta_d(self, theta, coeffs):
        # Horner from the highest power: q = d1θ + d2θ² + ..., q' = 2d1 + 3d2θ + ...
        q = np.zeros_like(theta)
        q_slope = np.zeros_like(theta)
        for power, d in reversed(list(enumerate(coeffs, start=2))):
            q = theta * (q + d)
            q_slope = theta * q_slope + power * d
        return theta * (1 + q), 1 + theta * q_slope
