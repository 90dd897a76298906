"""Camera intrinsics of an OpenLABEL stream: calibrations and the friendly form. Pure module.

A camera stream's ``stream_properties`` hold one calibration, in either key dialect (VCD's
``camera_matrix_3x4`` / ``distortion_coeffs_1xN`` / ``lens_coeffs_1xN`` / ``center_x_px`` or
the schema's ``camera_matrix`` / ``distortion_coeffs`` / ``lens_coeffs`` / ``center_x``):

* ``intrinsics_pinhole``: 3x4 camera matrix and OpenCV (Brown-Conrady) distortion;
* ``intrinsics_fisheye``: ``opencv_fisheye``, ``kannala`` or ``radial_poly`` lenses (the two
  polynomial lenses without ``focal_length_x``/``_y``: coefficients in pixels, f = 1);
* ``intrinsics_custom`` with ``model: "orthographic"``: pixels per metre.

Instead of a calibration, the friendly block ``stream_properties.usdscene`` describes a camera
as people do (lens model, resolution, sensor size mm, focal length mm, FOV deg); the block also
names the lens model of a calibration (``fisheye_equidistant``, ``fisheye_equisolid``) and
carries ``fov_deg``, the image circle of a fisheye. :func:`read_intrinsics` turns either into
:class:`usdscene.document.model.Intrinsics` (pixels).
"""

from __future__ import annotations

import logging
import math
from typing import Any, Mapping

from usdscene.errors import ProblemCollector
from usdscene.document.model import FISHEYE_LENSES, Intrinsics, LensModel, RenderSettings
from usdscene.lens import lens_for
from usdscene.lens.fisheye import EQUISOLID_KB_COEFFS  # noqa: F401  (the package exports it)

from usdscene.converters.openlabel.values import (
    IMAGE_SIDE_LIMIT,
    INVALID,
    describe,
    read_int,
    read_number,
    read_numbers,
    read_resolution,
    read_text,
    suggest,
)

log = logging.getLogger(__name__)


# The friendly camera block ``stream_properties.usdscene``.
FRIENDLY_KEYS = ("model", "model_name", "resolution_px", "sensor_size_mm", "focal_length_mm", "fov_deg",
                 "distortion", "principal_point_px", "ortho_width_m", "position_m", "orientation_deg",
                 "target_m", "clip_range_m", "custom", "sensor")
# Friendly keys that define optics; they may not be combined with calibrated intrinsics.
FRIENDLY_OPTICS = ("resolution_px", "focal_length_mm", "distortion", "principal_point_px", "ortho_width_m")
DEFAULT_SENSOR_WIDTH_MM = 36.0  # Blender's default sensor width
FOV_TOLERANCE_DEG = 0.5


def read_intrinsics(props: Mapping, friendly: Mapping, where: str, render: RenderSettings,
                    problems: ProblemCollector):
    """The intrinsics of one camera stream.

    Args:
        props: the stream's ``stream_properties``.
        friendly: its ``usdscene`` block ({} when absent).
        where: JSON path of ``stream_properties``.
        render: the scene's render settings (their ``resolution_px`` is the friendly default).

    Returns:
        Intrinsics (pixels); None when the stream has no intrinsics usdscene can use; INVALID
        when they are present but bad (the problem is recorded).
    """
    where_f = f"{where}.usdscene"
    custom = props.get("intrinsics_custom")
    ortho_custom = isinstance(custom, dict) and custom.get("model") == "orthographic"
    present = [k for k in ("intrinsics_pinhole", "intrinsics_fisheye") if k in props]
    if ortho_custom:
        present.append("intrinsics_custom")
    if len(present) > 1:
        problems.add(f"{where}.{present[1]}", f"give one calibration, not {' and '.join(present)}")
        return INVALID
    model = _friendly_model(friendly, where_f, problems)
    if model is INVALID:
        return INVALID
    sensor_w = _sensor_width(friendly, where_f, problems)
    if sensor_w is INVALID:
        return INVALID
    if not present:
        if not friendly:
            return None
        return _friendly_intrinsics(friendly, where_f, model, sensor_w, render, problems)
    mixed = [k for k in FRIENDLY_OPTICS if k in friendly]
    if mixed:
        problems.add(f"{where_f}.{mixed[0]}", f"{mixed[0]!r} cannot be combined with {present[0]}: give the "
                                              f"calibration or the friendly optics, not both")
        return INVALID
    kind = present[0]
    block = props[kind]
    here = f"{where}.{kind}"
    if not isinstance(block, dict):
        problems.add(here, f"expected a JSON object, got {describe(block)}")
        return INVALID
    fov = None
    if "fov_deg" in friendly:
        fov = read_number(friendly["fov_deg"], f"{where_f}.fov_deg", problems, positive=True)
        if fov is None:
            return INVALID
    result = {"intrinsics_pinhole": _pinhole, "intrinsics_fisheye": _fisheye,
              "intrinsics_custom": _orthographic}[kind](block, here, problems)
    if result is None:
        return INVALID
    lens, w, h, fx, fy, cx, cy, dist = result
    if model is not None:
        allowed = calibration_family(lens)
        if model not in allowed:
            problems.add(f"{where_f}.model", f"lens model {model.value!r} does not match {kind} "
                                             f"(expected {' or '.join(m.value for m in allowed)})")
            return INVALID
        dist = lens_for(model).from_calibration(dist, here, problems)
        if dist is None:
            return INVALID
        lens = model
    if fov is not None and lens not in FISHEYE_LENSES:
        problems.add(f"{where_f}.fov_deg", f"with {kind}, fov_deg is the image circle of a fisheye lens; "
                                           f"lens model {lens.value!r} has none")
        return INVALID
    return Intrinsics(lens=lens, width_px=w, height_px=h, fx_px=fx, fy_px=fy, cx_px=cx, cy_px=cy,
                      distortion=dist, fov_deg=fov,
                      sensor_width_mm=sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM)


def _friendly_model(friendly: Mapping, where: str, problems: ProblemCollector):
    """The lens model the friendly block names (``where``: its JSON path); None without one,
    INVALID when unknown (the problem is recorded)."""
    if "model" not in friendly:
        return None
    text = read_text(friendly["model"], f"{where}.model", problems)
    if text is None:
        return INVALID
    try:
        return LensModel(text)
    except ValueError:
        names = [m.value for m in LensModel]
        problems.add(f"{where}.model", f"unknown lens model {text!r}{suggest(text, names)}; "
                                       f"expected one of {', '.join(names)}")
        return INVALID


def _sensor_width(friendly: Mapping, where: str, problems: ProblemCollector):
    """The friendly ``sensor_size_mm`` width (mm); None without one, INVALID when bad."""
    if "sensor_size_mm" not in friendly:
        return None
    size = read_numbers(friendly["sensor_size_mm"], f"{where}.sensor_size_mm", problems,
                        lengths=(2,), what="sensor [width, height] in mm")
    if size is None:
        return INVALID
    if size[0] <= 0 or size[1] <= 0:
        problems.add(f"{where}.sensor_size_mm", f"sensor size must be positive, got {list(size)}")
        return INVALID
    return size[0]


def calibration_family(lens: LensModel) -> list[LensModel]:
    """The models that may name a calibration read as ``lens`` (:attr:`usdscene.lens.Lens.calibration_family`):
    the family's own model first, then the others in :class:`LensModel` order. The two Blender
    fisheyes are written as opencv_fisheye; VCD's polynomials name themselves."""
    family = lens_for(lens).calibration_family
    return sorted((m for m in LensModel if lens_for(m).calibration_family == family), key=lambda m: m.value != family)


def _size(block: Mapping, where: str, problems: ProblemCollector) -> tuple[int, int] | None:
    for key in ("width_px", "height_px"):
        if key not in block:
            problems.add(f"{where}.{key}", f"missing {key!r}")
            return None
    w = read_int(block["width_px"], f"{where}.width_px", problems, positive=True, maximum=IMAGE_SIDE_LIMIT)
    h = read_int(block["height_px"], f"{where}.height_px", problems, positive=True, maximum=IMAGE_SIDE_LIMIT)
    return (w, h) if w is not None and h is not None else None


def _dialect(block: Mapping, where: str, keys: tuple[str, str], problems: ProblemCollector,
             required: bool = True):
    """The value of one of two dialect keys (VCD ``..._3x4`` vs schema name); INVALID if both."""
    found = [k for k in keys if k in block]
    if len(found) == 2:
        problems.add(f"{where}.{found[1]}", f"give {keys[0]!r} or {keys[1]!r}, not both")
        return INVALID, found[1]
    if not found:
        if required:
            problems.add(f"{where}.{keys[1]}", f"missing {keys[1]!r} (or {keys[0]!r})")
            return INVALID, keys[1]
        return None, keys[1]
    return block[found[0]], found[0]


def _pinhole(block: Mapping, where: str, problems: ProblemCollector):
    """``intrinsics_pinhole`` → (lens, width, height, fx, fy, cx, cy, distortion) or None."""
    size = _size(block, where, problems)
    raw, key = _dialect(block, where, ("camera_matrix_3x4", "camera_matrix"), problems)
    if raw is INVALID:
        return None
    here = f"{where}.{key}"
    if isinstance(raw, list) and len(raw) == 9:
        problems.add(here, "a 3x3 matrix (9 numbers) was given where the 3x4 camera matrix (12 numbers, "
                           "row-major) is expected")
        return None
    k = read_numbers(raw, here, problems, lengths=(12,))
    raw_d, dkey = _dialect(block, where, ("distortion_coeffs_1xN", "distortion_coeffs"), problems,
                           required=False)
    if raw_d is INVALID:
        return None
    dist = opencv_distortion(raw_d, f"{where}.{dkey}", problems) if raw_d is not None else ()
    if k is None or size is None or dist is None:
        return None
    fx, skew, cx, fy, cy = k[0], k[1], k[2], k[5], k[6]
    ok = True
    for index, value in ((0, fx), (5, fy)):
        if value <= 0:
            problems.add(f"{here}[{index}]", f"focal length must be positive, got {value}")
            ok = False
    if skew != 0:
        problems.add(f"{here}[1]", f"skew {skew} is not supported (the camera matrix must have 0 there)")
        ok = False
    if k[4] != 0 or k[8] != 0 or k[9] != 0 or k[10] != 1:
        problems.add(here, f"not a camera matrix: expected [fx 0 cx t; 0 fy cy t; 0 0 1 t], got {list(k)}")
        ok = False
    if not ok:
        return None
    if k[3] or k[7] or k[11]:
        # Rectified stereo files (KITTI) fold the baseline into the 4th column; the camera's
        # position comes from its coordinate system, so the column is not used.
        log.warning("%s: the 4th column %s of the camera matrix is ignored (the pose comes from "
                    "the coordinate system)", here, [k[3], k[7], k[11]])
    lens = LensModel.OPENCV_PINHOLE if any(dist) else LensModel.PERSPECTIVE
    return lens, size[0], size[1], fx, fy, cx, cy, (dist if any(dist) else ())


def opencv_distortion(raw: Any, where: str, problems: ProblemCollector) -> tuple[float, ...] | None:
    """OpenCV (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [τx τy]]]]) → canonical: the shortest of
    4, 5, 8 coefficients that keeps every non-zero one."""
    values = read_numbers(raw, where, problems, lengths=(0, 4, 5, 8, 12, 14))
    if values is None:
        return None
    if len(values) > 8 and any(values[8:]):
        problems.add(f"{where}[8]", f"thin-prism and tilt coefficients (index 8 and up) are not supported; "
                                    f"got {list(values[8:])}")
        return None
    values = values[:8]
    if len(values) == 8 and not any(values[5:]):
        values = values[:5]
    if len(values) == 5 and values[4] == 0:
        values = values[:4]
    return values


def _fisheye(block: Mapping, where: str, problems: ProblemCollector):
    """``intrinsics_fisheye`` → (lens, width, height, fx, fy, cx, cy, coefficients) or None."""
    size = _size(block, where, problems)
    model = block.get("model", "opencv_fisheye")
    out = {}
    for names in (("focal_length_x", "focal_length_x_px"), ("focal_length_y", "focal_length_y_px"),
                  ("center_x", "center_x_px"), ("center_y", "center_y_px")):
        focal = names[0].startswith("focal")
        # VCD's polynomial lenses may leave out the focal lengths: their coefficients are then
        # in pixels, r_px = c1·θ + c2·θ² + ..., which is f = 1 exactly.
        optional = focal and model in ("kannala", "radial_poly") and not any(
            k in block for k in ("focal_length_x", "focal_length_x_px", "focal_length_y", "focal_length_y_px"))
        raw, key = _dialect(block, where, names, problems, required=not optional)
        if raw is INVALID:
            return None
        out[names[0]] = 1.0 if raw is None else read_number(raw, f"{where}.{key}", problems, positive=focal)
    raw_c, ckey = _dialect(block, where, ("lens_coeffs_1xN", "lens_coeffs"), problems)
    if raw_c is INVALID:
        return None
    coeffs = read_numbers(raw_c, f"{where}.{ckey}", problems, lengths=(4, 5))
    if model not in ("opencv_fisheye", "kannala", "radial_poly"):
        problems.add(f"{where}.model", f"unknown fisheye model {describe(model)}; expected 'opencv_fisheye', "
                                       f"'kannala' or 'radial_poly'")
        return None
    if size is None or coeffs is None or None in out.values():
        return None
    fx, fy, cx, cy = out["focal_length_x"], out["focal_length_y"], out["center_x"], out["center_y"]
    if model in ("kannala", "radial_poly"):
        # VCD's polynomials r = f·(c1θ + ...) read exactly: f·c1 is the focal length near the
        # axis and the other coefficients are taken relative to c1 (see LensModel).
        c1 = coeffs[0]
        if c1 <= 0:
            problems.add(f"{where}.{ckey}[0]", f"the first {model} coefficient is the slope of r(θ)/f at the "
                                               f"axis and must be positive, got {c1!r}")
            return None
        relative = tuple(c / c1 for c in coeffs[1:])
        if model == "kannala":
            relative += (0.0,) * (4 - len(relative))
            lens = LensModel.KANNALA
        else:
            lens = LensModel.RADIAL_POLY
        return lens, size[0], size[1], fx * c1, fy * c1, cx, cy, relative
    if len(coeffs) == 5:
        if coeffs[4] != 0:
            problems.add(f"{where}.{ckey}[4]", f"a fifth lens coefficient ({coeffs[4]}) is not supported by "
                                               f"the opencv_fisheye model (k1..k4); VCD's model 'kannala' has five")
            return None
        coeffs = coeffs[:4]
    return LensModel.OPENCV_FISHEYE, size[0], size[1], fx, fy, cx, cy, coeffs


def _orthographic(block: Mapping, where: str, problems: ProblemCollector):
    """Orthographic ``intrinsics_custom`` → (lens, width, height, sx, sy, cx, cy, ()) or None."""
    size = _size(block, where, problems)
    values = {}
    for key in ("scale_x_px_per_m", "scale_y_px_per_m", "center_x_px", "center_y_px"):
        if key not in block:
            problems.add(f"{where}.{key}", f"orthographic intrinsics_custom needs {key!r}")
            return None
        values[key] = read_number(block[key], f"{where}.{key}", problems, positive=key.startswith("scale"))
    if size is None or None in values.values():
        return None
    return (LensModel.ORTHOGRAPHIC, size[0], size[1], values["scale_x_px_per_m"], values["scale_y_px_per_m"],
            values["center_x_px"], values["center_y_px"], ())


def _friendly_intrinsics(friendly: Mapping, where: str, model: LensModel | None,
                         sensor_w: float | None, render: RenderSettings, problems: ProblemCollector):
    """Intrinsics from the friendly optics (no calibration given), or INVALID."""
    P = problems
    if model is None:
        problems.add(f"{where}.model", f"missing 'model' (one of {', '.join(m.value for m in LensModel)})")
        return INVALID
    if "resolution_px" in friendly:
        resolution = read_resolution(friendly["resolution_px"], f"{where}.resolution_px", P)
        if resolution is None:
            return INVALID
    else:
        resolution = render.resolution_px
    w, h = resolution
    spec = lens_for(model)
    focal = fov = None
    if "focal_length_mm" in friendly:
        focal = read_number(friendly["focal_length_mm"], f"{where}.focal_length_mm", P, positive=True)
        if focal is None:
            return INVALID
    if "fov_deg" in friendly:
        fov = read_number(friendly["fov_deg"], f"{where}.fov_deg", P, positive=True)
        if fov is None:
            return INVALID
        limit = 180.0 if spec.pinhole else 360.0
        if fov >= limit:
            problems.add(f"{where}.fov_deg", f"a {model.value} lens needs fov_deg < {limit:g}, got {fov:g}")
            return INVALID
    dist: tuple[float, ...] = ()
    if "distortion" in friendly:
        if spec.brown_conrady:
            dist = opencv_distortion(friendly["distortion"], f"{where}.distortion", P)
        elif spec.distortion_lengths:
            dist = read_numbers(friendly["distortion"], f"{where}.distortion", P, lengths=spec.distortion_lengths,
                                what=spec.distortion_what)
        else:
            problems.add(f"{where}.distortion", f"lens model {model.value!r} has no distortion coefficients; "
                                                f"use 'opencv_pinhole', 'opencv_fisheye', 'kannala' or "
                                                f"'radial_poly'")
            return INVALID
        if dist is None:
            return INVALID
    else:
        dist = spec.default_distortion
    if "ortho_width_m" in friendly and not spec.orthographic:
        problems.add(f"{where}.ortho_width_m", f"ortho_width_m is for the orthographic model, not {model.value!r}")
        return INVALID
    sensor = sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM
    circle = None
    if spec.orthographic:
        if "ortho_width_m" not in friendly:
            problems.add(f"{where}.ortho_width_m", "the orthographic model needs ortho_width_m (view width in metres)")
            return INVALID
        width_m = read_number(friendly["ortho_width_m"], f"{where}.ortho_width_m", P, positive=True)
        if width_m is None:
            return INVALID
        for key in ("focal_length_mm", "fov_deg"):
            if key in friendly:
                problems.add(f"{where}.{key}", f"{key} has no meaning for an orthographic camera")
                return INVALID
        fx = w / width_m
    elif spec.pinhole:
        fx_or_none = _pinhole_focal(where, focal, fov, sensor_w, w, P)
        if fx_or_none is None:
            return INVALID
        fx, sensor = fx_or_none
    elif spec.fov_spans_width:
        # Blender maps fisheye_fov across the full sensor width: r_px = θ · w / fov_rad.
        if fov is None and focal is None:
            problems.add(f"{where}.fov_deg", "a fisheye_equidistant lens needs fov_deg (or focal_length_mm)")
            return INVALID
        if fov is not None and focal is not None and sensor_w is not None:
            implied = math.degrees(sensor_w / focal)
            if abs(implied - fov) > FOV_TOLERANCE_DEG:
                problems.add(f"{where}.fov_deg", f"focal_length_mm {focal:g} on a {sensor_w:g} mm wide sensor "
                                                 f"implies a horizontal FOV of {implied:.1f}° for a fisheye_equidistant "
                                                 f"lens, not {fov:g}°")
                return INVALID
        if fov is not None:
            fx = w / math.radians(fov)
            if focal is not None and sensor_w is None:
                sensor = focal * math.radians(fov)
        else:
            fx = focal * w / sensor
            fov = math.degrees(w / fx)
        circle = fov
    else:  # the equisolid fisheye and the radial polynomials: r = f·g(θ) on the sensor; fov crops the circle
        if focal is None:
            problems.add(f"{where}.focal_length_mm", f"a {model.value} lens needs focal_length_mm "
                                                     f"(and sensor_size_mm, default {DEFAULT_SENSOR_WIDTH_MM:g} mm wide)")
            return INVALID
        fx = focal * w / sensor
        circle = fov
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    if "principal_point_px" in friendly:
        pp = read_numbers(friendly["principal_point_px"], f"{where}.principal_point_px", P, lengths=(2,))
        if pp is None:
            return INVALID
        cx, cy = pp
    return Intrinsics(lens=model, width_px=w, height_px=h, fx_px=fx, fy_px=fx, cx_px=cx, cy_px=cy,
                      distortion=tuple(dist), fov_deg=circle, sensor_width_mm=sensor)


def _pinhole_focal(where: str, focal: float | None, fov: float | None, sensor_w: float | None, w: int,
                   problems: ProblemCollector) -> tuple[float, float] | None:
    """(fx_px, sensor_width_mm) of a pinhole from any two of focal, FOV, sensor width."""
    if focal is None and fov is None:
        problems.add(f"{where}.fov_deg", "a pinhole camera needs fov_deg or focal_length_mm "
                                         "(with sensor_size_mm)")
        return None
    if focal is not None and fov is not None and sensor_w is not None:
        implied = math.degrees(2 * math.atan(sensor_w / (2 * focal)))
        if abs(implied - fov) > FOV_TOLERANCE_DEG:
            problems.add(f"{where}.fov_deg", fov_mismatch_message(focal, sensor_w, fov, implied))
            return None
    if focal is not None and fov is not None and sensor_w is None:
        sensor = 2 * focal * math.tan(math.radians(fov) / 2)
        return w / (2 * math.tan(math.radians(fov) / 2)), sensor
    sensor = sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM
    if fov is not None:
        return w / (2 * math.tan(math.radians(fov) / 2)), sensor
    return focal * w / sensor, sensor


def fov_mismatch_message(focal_mm: float, sensor_w_mm: float, fov_deg: float, implied_deg: float) -> str:
    """The message for an over-determined pinhole whose FOV disagrees with focal and sensor.

    It gives the FOV the numbers imply for a perspective lens and for the two fisheye
    projections, and names the lens model that makes the three consistent: the equidistant
    fisheye when its FOV matches, else the equisolid fisheye, whose ``fov_deg`` is the image
    circle (it only crops), so any FOV is consistent with its focal length and sensor.
    """
    ratio = sensor_w_mm / focal_mm
    equidistant = math.degrees(ratio)
    text = (f"focal_length_mm {focal_mm:g} on sensor_size_mm {sensor_w_mm:g} implies a horizontal FOV of "
            f"{implied_deg:.1f}° for a perspective lens, not {fov_deg:g}°; across the sensor width a "
            f"fisheye_equidistant lens gives {equidistant:.1f}°")
    if ratio / 4 <= 1:
        text += f" and a fisheye_equisolid lens gives {math.degrees(4 * math.asin(ratio / 4)):.1f}°"
    if abs(equidistant - fov_deg) <= FOV_TOLERANCE_DEG:
        hint = "model 'fisheye_equidistant' makes the three consistent"
    else:
        hint = ("model 'fisheye_equisolid' makes the three consistent (its fov_deg is the image circle, "
                "which only crops)")
    return f"{text}. If this is a fisheye lens, {hint}; otherwise give only two of focal_length_mm, " \
           f"sensor_size_mm, fov_deg"

