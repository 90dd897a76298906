"""``metadata.usdscene.world`` and ``stream_properties.usdscene.sensor`` →
:class:`usdscene.document.imaging.World` / :class:`usdscene.document.imaging.Sensor`, and back. Pure module.

Every value is checked against what the renderer and the post-process accept, so that what
``usdscene validate`` accepts renders; a bad value is a problem naming the JSON path and the
value. Whether an HDRI file exists, is an image and lies inside the asset folders is checked
by :func:`hdri_problems` (it needs the document's folder).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

from usdscene.errors import Problem, ProblemCollector
from usdscene.document.imaging import (
    COMPRESSIONS,
    HDRI_SUFFIXES,
    METERING_MODES,
    SENSOR_RANDOMIZABLE,
    SKY_KINDS,
    VIEW_TRANSFORMS,
    WORLD_RANDOMIZABLE,
    Sensor,
    World,
    hdri_path,
    spec_from_json,
    spec_to_json,
)

from usdscene.document.camera_profiles import PROFILES
from usdscene.converters.openlabel.values import describe, is_number, read_object, suggest

# name → (kind, low, high, low is exclusive); kinds: number, int, bool, text, rgb.
# The ranges are Blender's own limits where Blender has one (sky densities 0..10, altitude
# 0..60 km, colour management exposure -32..32).
WORLD_FIELDS: dict[str, tuple] = {
    "color_rgb": ("rgb", 0.0, None, False), "strength": ("number", 0.0, 1e6, False),
    "sky": ("choice", tuple(SKY_KINDS), None, False),
    "air_density": ("number", 0.0, 10.0, False), "aerosol_density": ("number", 0.0, 10.0, False),
    "ozone_density": ("number", 0.0, 10.0, False), "altitude_m": ("number", 0.0, 60000.0, False),
    "hdri": ("text", None, None, False), "hdri_rotation_deg": ("number", -3600.0, 3600.0, False),
    "exposure_ev": ("number", -32.0, 32.0, False),
    "view_transform": ("choice", tuple(VIEW_TRANSFORMS), None, False),
}
SENSOR_FIELDS: dict[str, tuple] = {
    "exposure_bias_ev": ("number", -16.0, 16.0, False), "vignetting": ("number", 0.0, 0.95, False),
    "iso": ("number", 0.0, 409600.0, True), "full_well_e": ("number", 0.0, 1e7, True),
    "read_noise_e": ("number", 0.0, 1e4, False), "shutter_frames": ("number", 0.0, 10.0, False),
    "compression": ("choice", COMPRESSIONS, None, False), "quality": ("int", 1, 100, False),
    "ir_night": ("bool", None, None, False), "ir_range_m": ("number", 0.0, 1e4, True),
    "profile": ("choice", tuple(PROFILES), None, False),
    "auto_exposure": ("bool", None, None, False), "metering": ("choice", METERING_MODES, None, False),
    "metering_region": ("box", None, None, False),
    "target_grey": ("number", 0.01, 0.9, False),
    "exposure_min_ev": ("number", -16.0, 16.0, False), "exposure_max_ev": ("number", -16.0, 16.0, False),
    "exposure_speed": ("number", 0.0, 1.0, True), "wdr_stops": ("number", 0.0, 8.0, False),
    # MTF50 above 0.5 cycles per pixel (Nyquist) is a lens sharper than the pixels: no blur.
    "mtf50_cy_px": ("number", 0.0, 1.0, True), "psf_sigma_px": ("number", 0.0, 20.0, True),
    "sharpen": ("number", 0.0, 5.0, False), "sharpen_radius_px": ("number", 0.0, 10.0, True),
    "chroma_420": ("bool", None, None, False),
}
BLOCK_KEYS = ("per_frame", "randomize")


def read_world(value: Any, where: str, problems: ProblemCollector) -> World | None:
    """``metadata.usdscene.world`` → World (None when it has problems, each recorded)."""
    data = _read_block(value, where, problems, WORLD_FIELDS, WORLD_RANDOMIZABLE, "world")
    if data is None:
        return None
    if data.get("sky") and data.get("hdri"):
        problems.add(where, "give either 'sky' or 'hdri', not both (the HDRI is the sky)")
        return None
    return spec_from_json(World, data)


def read_sensor(value: Any, where: str, problems: ProblemCollector) -> Sensor | None:
    """``stream_properties.usdscene.sensor`` → Sensor (None when it has problems)."""
    data = _read_block(value, where, problems, SENSOR_FIELDS, SENSOR_RANDOMIZABLE, "sensor")
    if data is None:
        return None
    profile = PROFILES.get(data.get("profile", ""), {})
    if "quality" in data and "compression" not in data and not profile.get("compression"):
        data["compression"] = "jpeg"  # a quality alone means the common case
    if "mtf50_cy_px" in data and "psf_sigma_px" in data:
        problems.add(f"{where}.psf_sigma_px", "give either 'mtf50_cy_px' or 'psf_sigma_px', not both "
                                              "(both state the lens blur)")
        return None
    merged = {**profile, **data}
    if merged.get("metering") == "region" and not merged.get("metering_region"):
        problems.add(f"{where}.metering", "metering 'region' needs 'metering_region': [x0, y0, x1, y1] "
                                          "as fractions of the image")
        return None
    low, high = merged.get("exposure_min_ev", -10.0), merged.get("exposure_max_ev", 10.0)
    if low > high:
        problems.add(f"{where}.exposure_min_ev", f"exposure_min_ev {low:g} is above exposure_max_ev {high:g}")
        return None
    return spec_from_json(Sensor, data)


def world_json(world: World) -> dict:
    """The document form of a world (defaults left out)."""
    return spec_to_json(world)


def sensor_json(sensor: Sensor) -> dict:
    """The document form of a sensor (defaults left out)."""
    return spec_to_json(sensor)


def _read_block(value: Any, where: str, problems: ProblemCollector, table: dict, randomizable: Sequence[str],
                what: str) -> dict | None:
    block = read_object(value, where, problems)
    if block is None:
        return None
    before = len(problems.problems)
    out: dict[str, Any] = {}
    for key, item in block.items():
        here = f"{where}.{key}"
        if key == "per_frame":
            frames = read_object(item, here, problems) or {}
            parsed = {}
            for frame, overrides in frames.items():
                if not (isinstance(frame, str) and frame.lstrip("-").isdigit()):
                    problems.add(f"{here}.{frame}", f"expected a frame number as key, got {describe(frame)}")
                    continue
                fields = read_object(overrides, f"{here}.{frame}", problems) or {}
                checked = {}
                for name, v in fields.items():
                    if name not in randomizable:
                        problems.add(f"{here}.{frame}.{name}",
                                     f"{what} field {name!r} cannot change per frame; these can: "
                                     f"{', '.join(randomizable)}")
                        continue
                    parsed_value = _read_field(name, v, f"{here}.{frame}.{name}", problems, table)
                    if parsed_value is not None:
                        checked[name] = parsed_value
                parsed[str(int(frame))] = checked
            out["per_frame"] = parsed
        elif key == "randomize":
            ranges = read_object(item, here, problems) or {}
            parsed_ranges = {}
            for name, pair in ranges.items():
                at = f"{here}.{name}"
                if name not in randomizable:
                    problems.add(at, f"{what} field {name!r} cannot be randomized{suggest(name, randomizable)}; "
                                     f"these can: {', '.join(randomizable)}")
                    continue
                if not (isinstance(pair, list) and len(pair) == 2):
                    problems.add(at, f"expected [low, high], got {describe(pair)}")
                    continue
                low = _read_field(name, pair[0], f"{at}[0]", problems, table)
                high = _read_field(name, pair[1], f"{at}[1]", problems, table)
                if low is not None and high is not None:
                    if low > high:
                        problems.add(at, f"low {low:g} is above high {high:g}")
                    else:
                        parsed_ranges[name] = [low, high]
            out["randomize"] = parsed_ranges
        elif key in table:
            parsed_value = _read_field(key, item, here, problems, table)
            if parsed_value is not None:
                out[key] = parsed_value
        else:
            known = [*table, *BLOCK_KEYS]
            problems.add(here, f"unknown {what} key {key!r}{suggest(key, known)}; known: {', '.join(known)}")
    return out if len(problems.problems) == before else None


def _read_field(name: str, value: Any, where: str, problems: ProblemCollector, table: dict) -> Any:
    kind, low, high, exclusive = table[name]
    if kind == "bool":
        if not isinstance(value, bool):
            problems.add(where, f"expected true or false, got {describe(value)}")
            return None
        return value
    if kind in ("text", "choice"):
        if not isinstance(value, str) or not value:
            problems.add(where, f"expected a non-empty string, got {describe(value)}")
            return None
        if kind == "choice" and value not in low:
            label = "sky kind" if name == "sky" else name
            problems.add(where, f"unknown {label} {value!r}{suggest(value, low)}; expected one of {', '.join(low)}")
            return None
        return value
    if kind == "rgb":
        if not (isinstance(value, list) and len(value) == 3 and all(is_number(v) and v >= 0 for v in value)):
            problems.add(where, f"expected three numbers >= 0 (linear RGB), got {describe(value)}")
            return None
        return [float(v) for v in value]
    if kind == "box":
        if not (isinstance(value, list) and len(value) == 4 and all(is_number(v) and 0 <= v <= 1 for v in value)
                and value[0] < value[2] and value[1] < value[3]):
            problems.add(where, f"expected [x0, y0, x1, y1], fractions of the image from 0 to 1 with "
                                f"x0 < x1 and y0 < y1, got {describe(value)}")
            return None
        return [float(v) for v in value]
    if kind == "int" and (not isinstance(value, int) or isinstance(value, bool)):
        problems.add(where, f"expected an integer from {low} to {high}, got {describe(value)}")
        return None
    if not is_number(value) or value != value or value in (float("inf"), float("-inf")):
        problems.add(where, f"expected a number, got {describe(value)}")
        return None
    below = value <= low if exclusive else value < low
    if below or (high is not None and value > high):
        left = "(" if exclusive else "["
        problems.add(where, f"{name} {describe(value)} is out of range; expected a value in {left}{low:g}, {high:g}]")
        return None
    return int(value) if kind == "int" else float(value)


def hdri_problems(world: World | None, where: str, document_folder: str | os.PathLike | None,
                  roots: Sequence[Path]) -> list[Problem]:
    """The HDRI of ``world`` must lie inside ``roots`` (checked before it is opened), exist and
    be an image (by its first bytes: Radiance HDR, OpenEXR, PNG, JPEG or TIFF).

    Args:
        world: the document's world (None: nothing to check).
        where: JSON path of the ``hdri`` field.
        document_folder: folder a relative path is relative to (None: the working folder).
        roots: reading roots (:func:`usdscene.document.containment.reading_roots`).
    """
    from usdscene.document.containment import is_inside, outside_problem

    if world is None or not world.hdri:
        return []
    path = hdri_path(world, document_folder)
    if not is_inside(path, roots):
        return [outside_problem(where, world.hdri, "HDRI", anchor=document_folder)]
    if not path.is_file():
        return [Problem(where, f"HDRI {world.hdri!r} (resolved {str(path)!r}) does not exist or is not a file")]
    try:
        with open(path, "rb") as handle:
            head = handle.read(16)
    except OSError as exc:
        return [Problem(where, f"HDRI {world.hdri!r} cannot be read: {exc.strerror or exc}")]
    if not _is_image(head):
        return [Problem(where, f"HDRI {world.hdri!r} is not an image (expected an equirectangular "
                               f"{' / '.join(s.lstrip('.') for s in HDRI_SUFFIXES)} file)")]
    return []


def _is_image(head: bytes) -> bool:
    return (head.startswith(b"#?RADIANCE") or head.startswith(b"#?RGBE") or head.startswith(b"\x76\x2f\x31\x01")
            or head.startswith(b"\x89PNG\r\n\x1a\n") or head.startswith(b"\xff\xd8\xff")
            or head.startswith(b"II*\x00") or head.startswith(b"MM\x00*"))


def document_hdri_problems(scene, document_path: str | os.PathLike) -> list[Problem]:
    """:func:`hdri_problems` of a read document: its world's HDRI against the reading roots of
    the document's folder (``usdscene.document.containment.reading_roots``)."""
    from usdscene.document.containment import reading_roots

    if scene is None or scene.world is None or not scene.world.hdri:
        return []
    folder = Path(document_path).resolve().parent
    return hdri_problems(scene.world, "openlabel.metadata.usdscene.world.hdri", folder, reading_roots(folder))
