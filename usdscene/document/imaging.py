"""What surrounds the scene and what the camera's sensor does to its image: the world
(``metadata.usdscene.world``) and the per-camera sensor (``stream_properties.usdscene.sensor``).
Pure module (stdlib + numpy).

Both are optional. A document without them renders exactly what it rendered before they
existed: a black world, the ``Standard`` view transform, a clean image.

* :class:`World`: a background colour and strength; or a physical sky (Blender's Nishita model,
  called ``SINGLE_SCATTERING`` in Blender 5.0, or its ``MULTIPLE_SCATTERING`` successor) whose
  sun stands where the document's sun light comes from; or an equirectangular HDRI from the
  asset folders; plus the exposure and the view transform of the picture.
* :class:`Sensor`: what a surveillance camera adds after the light reaches it: exposure bias,
  vignetting, shot and read noise at a gain (ISO), the shutter (Cycles motion blur), JPEG or
  H.264-like compression, and the infrared night mode (monochrome, lit by an IR illuminator at
  the camera). Render-time parts (shutter, IR illuminator) go to Blender; the rest is an image
  operation (:mod:`usdscene.sensor`) seeded per (document seed, camera, frame).

Both may carry ``per_frame`` overrides (what ``usdscene generate`` draws from ``randomize``
ranges, see :func:`draw_per_frame`).
"""

from __future__ import annotations

import json
import math
import os
import zlib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

# A sun light without a stated power: irradiance in W/m² (Blender's sun "Strength") that gives a
# daylight picture under the Standard view transform with exposure 0: a surface of albedo 0.5
# facing the sun reaches 0.5 · 4 / π ≈ 0.64 linear (sRGB 0.82), below clipping. Measured on the
# shipped car park, docs/sensors.md.
DEFAULT_SUN_IRRADIANCE_W_M2 = 4.0
# The physical sky is scaled to the sun light: Blender's Nishita sky has a mean radiance of about
# 2 over the upper hemisphere (sun disc off). Scaled by sun irradiance / 40 (0.1 for the 4 W/m²
# sun), its irradiance on a horizontal surface is roughly 15 % of a high sun's, the share of
# diffuse skylight on a clear day (an estimate from those figures).
SKY_PER_SUN_IRRADIANCE = 1.0 / 40.0

SKY_KINDS = {"nishita": "SINGLE_SCATTERING", "multiple_scattering": "MULTIPLE_SCATTERING"}
VIEW_TRANSFORMS = {"standard": "Standard", "agx": "AgX", "filmic": "Filmic"}
COMPRESSIONS = ("jpeg", "h264_like")
# Auto exposure metering (usdscene.sensor.exposure): the plain mean, a centre-weighted mean, or
# the mean over a rectangle of the image (``metering_region``).
METERING_MODES = ("average", "centre_weighted", "region")
HDRI_SUFFIXES = (".hdr", ".exr", ".png", ".jpg", ".jpeg", ".tif", ".tiff")
# Light a 50 % grey surface at the illuminator's range receives, so that it shows at 0.05
# linear (sRGB ≈ 63 of 255): the edge of the useful range of a real IR illuminator.
IR_RANGE_EDGE_LINEAR = 0.05
# Near-infrared response of a monochrome night camera as weights of the linear RGB render
# (red-heavy: foliage and skin are bright in NIR, blue paint dark). An approximation, not a
# spectral model.
IR_RGB_WEIGHTS = (0.6, 0.3, 0.1)


@dataclass(frozen=True)
class World:
    """The scene's surroundings and picture settings (``metadata.usdscene.world``).

    Attributes:
        color_rgb: background colour, linear RGB (used when there is no sky and no HDRI).
        strength: multiplier of the background, the sky or the HDRI (Blender's Background
            "Strength"); the sky is further scaled by the sun's irradiance, see
            :data:`SKY_PER_SUN_IRRADIANCE`.
        sky: ``""`` (none), ``nishita`` or ``multiple_scattering``.
        air_density, aerosol_density, ozone_density: the sky's atmosphere (1 = clear day).
        altitude_m: height of the viewer above sea level for the sky, metres.
        hdri: equirectangular image as written in the document ("" = none); resolved against
            the document's folder and inside the asset folders (``usdscene.document.containment``).
        hdri_rotation_deg: rotation of the HDRI about world Z, degrees.
        exposure_ev: exposure of the picture in stops (Blender's colour management exposure).
        view_transform: ``standard`` (sRGB curve, what images had before), ``agx`` or ``filmic``.
        per_frame: ``(frame, ((field, value), ...))`` overrides, frames ascending.
        randomize: ``(field, (low, high))`` ranges that ``usdscene generate`` draws per frame.
    """

    color_rgb: tuple[float, float, float] = (0.0, 0.0, 0.0)
    strength: float = 1.0
    sky: str = ""
    air_density: float = 1.0
    aerosol_density: float = 1.0
    ozone_density: float = 1.0
    altitude_m: float = 0.0
    hdri: str = ""
    hdri_rotation_deg: float = 0.0
    exposure_ev: float = 0.0
    view_transform: str = "standard"
    per_frame: tuple[tuple[int, tuple[tuple[str, Any], ...]], ...] = ()
    randomize: tuple[tuple[str, tuple[float, float]], ...] = ()

    def at_frame(self, frame: int) -> "World":
        """The world of ``frame``: this one with that frame's overrides applied."""
        return _at_frame(self, frame)


@dataclass(frozen=True)
class Sensor:
    """What one camera's sensor, optics and encoder do (``stream_properties.usdscene.sensor``).

    Attributes:
        exposure_bias_ev: exposure bias in stops, applied to the linear image.
        vignetting: share of light lost at the image corners (0 = none, < 1); falls off as
            ``1 - vignetting · ρ²`` with ρ the distance from the image centre over the
            half-diagonal.
        iso: gain as ISO (100 = base gain); None = no noise. Shot noise (Poisson, as Gaussian)
            and read noise are drawn in electrons: a linear value x holds
            ``x · full_well_e · 100 / iso`` electrons.
        full_well_e: electrons a pixel holds at linear 1.0 and base gain.
        read_noise_e: read noise, electrons RMS (before gain).
        shutter_frames: open shutter time in frames (Cycles motion blur, centred on the frame
            time, where the labels are); 0 = no motion blur.
        compression: ``""`` (none), ``jpeg`` or ``h264_like`` (16 x 16 macroblocks, 4:2:0
            chroma, a flat quantiser: the blockiness of a low-bitrate video stream).
        quality: compression quality, 1 (worst) to 100 (best).
        ir_night: infrared night mode: a monochrome image (:data:`IR_RGB_WEIGHTS`) lit by an
            IR illuminator at the camera.
        ir_range_m: range of the illuminator, metres (see :func:`ir_illuminator_power_w`).
        profile: name of a camera profile (:mod:`usdscene.document.camera_profiles`) whose
            values are this sensor's defaults ("" = none); the fields given beside it win.
        auto_exposure: meter the linear render before the tone curve and scale it so that the
            metered luminance lands on ``target_grey`` (:mod:`usdscene.sensor.exposure`).
        metering: ``average``, ``centre_weighted`` or ``region``.
        metering_region: ``(x0, y0, x1, y1)`` fractions of the image width and height (0-1,
            origin top left) that ``region`` metering averages; () = none.
        target_grey: linear luminance (0-1) the metered mean is brought to (0.18 = mid grey).
        exposure_min_ev, exposure_max_ev: limits of the automatic exposure, stops relative to
            the render.
        exposure_speed: share of the remaining error corrected per frame, (0, 1]; 1 = instant.
        wdr_stops: wide dynamic range: the tone curve keeps ``wdr_stops`` stops above white
            and lifts the shadows (:mod:`usdscene.sensor.tone`); 0 = the plain sRGB curve.
        mtf50_cy_px: lens sharpness as the spatial frequency (cycles per pixel) where the
            modulation falls to 50 %; a Gaussian blur of the linear image. None = a sharp lens.
        psf_sigma_px: the same blur given as the Gaussian PSF's sigma in pixels (give one of the
            two). None = a sharp lens.
        sharpen: unsharp-mask edge enhancement amount (0 = none; 1 adds the full high-pass).
        sharpen_radius_px: sigma of the unsharp mask's blur, pixels.
        chroma_420: halve the chroma resolution both ways (4:2:0), as a video stream does.
        per_frame: ``(frame, ((field, value), ...))`` overrides, frames ascending.
        randomize: ``(field, (low, high))`` ranges that ``usdscene generate`` draws per frame.
    """

    exposure_bias_ev: float = 0.0
    vignetting: float = 0.0
    iso: float | None = None
    full_well_e: float = 20000.0
    read_noise_e: float = 3.0
    shutter_frames: float = 0.0
    compression: str = ""
    quality: int = 75
    ir_night: bool = False
    ir_range_m: float = 15.0
    profile: str = ""
    auto_exposure: bool = False
    metering: str = "average"
    metering_region: tuple[float, ...] = ()
    target_grey: float = 0.18
    exposure_min_ev: float = -10.0
    exposure_max_ev: float = 10.0
    exposure_speed: float = 1.0
    wdr_stops: float = 0.0
    mtf50_cy_px: float | None = None
    psf_sigma_px: float | None = None
    sharpen: float = 0.0
    sharpen_radius_px: float = 1.0
    chroma_420: bool = False
    per_frame: tuple[tuple[int, tuple[tuple[str, Any], ...]], ...] = ()
    randomize: tuple[tuple[str, tuple[float, float]], ...] = ()

    def at_frame(self, frame: int) -> "Sensor":
        """The sensor of ``frame``: this one with that frame's overrides applied."""
        return _at_frame(self, frame)


# Fields ``randomize`` may name, with how a drawn value is rounded (int fields draw integers).
WORLD_RANDOMIZABLE = ("strength", "exposure_ev", "air_density", "aerosol_density", "ozone_density",
                      "hdri_rotation_deg")
SENSOR_RANDOMIZABLE = ("exposure_bias_ev", "vignetting", "iso", "read_noise_e", "quality")
INTEGER_FIELDS = ("quality",)


def _at_frame(spec, frame: int):
    for f, overrides in spec.per_frame:
        if f == frame:
            return replace(spec, **dict(overrides), per_frame=(), randomize=())
    return replace(spec, per_frame=(), randomize=()) if spec.per_frame or spec.randomize else spec


# ------------------------------------------------------------------------------------------
# JSON form (the document's and the stage's)

def _field_json(value: Any) -> Any:
    if isinstance(value, tuple):
        return [_field_json(v) for v in value]
    return value


def spec_to_json(spec: World | Sensor) -> dict:
    """The document form of a world or sensor: only the fields that differ from the defaults,
    ``per_frame`` as ``{"<frame>": {field: value}}`` and ``randomize`` as
    ``{field: [low, high]}``."""
    default = _baseline(type(spec), getattr(spec, "profile", ""))
    out: dict[str, Any] = {}
    for f in fields(spec):
        value = getattr(spec, f.name)
        if value == getattr(default, f.name) and f.name != "profile":
            continue
        if f.name == "profile" and not value:
            continue
        if f.name == "per_frame":
            out["per_frame"] = {str(frame): {k: _field_json(v) for k, v in overrides} for frame, overrides in value}
        elif f.name == "randomize":
            out["randomize"] = {k: [float(lo), float(hi)] for k, (lo, hi) in value}
        else:
            out[f.name] = _field_json(value)
    return out


def spec_from_json(kind: type, data: Mapping[str, Any]):
    """Inverse of :func:`spec_to_json` for data already checked by the document reader."""
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key == "per_frame":
            kwargs["per_frame"] = tuple(sorted(
                (int(frame), tuple(sorted((k, _tupled(v)) for k, v in overrides.items())))
                for frame, overrides in value.items()))
        elif key == "randomize":
            kwargs["randomize"] = tuple(sorted((k, (float(v[0]), float(v[1]))) for k, v in value.items()))
        else:
            kwargs[key] = _tupled(value)
    return replace(_baseline(kind, kwargs.get("profile", "")), **kwargs)


def _baseline(kind: type, profile: str):
    """The defaults a spec's document form is written against: its camera profile's sensor,
    else the class's defaults."""
    if kind is Sensor and profile:
        return profile_sensor(profile)
    return kind()


def profile_sensor(name: str) -> Sensor:
    """The sensor of camera profile ``name`` (:mod:`usdscene.document.camera_profiles`),
    ``profile`` set; KeyError when unknown (the document reader refuses unknown names first)."""
    from usdscene.document.camera_profiles import profile_fields

    return Sensor(**profile_fields(name), profile=name)


def _tupled(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


# ------------------------------------------------------------------------------------------
# Sun, sky, IR illuminator, seeds

def sun_sky_angles(sun_rotation: np.ndarray) -> tuple[float, float]:
    """Sky angles of a sun light: ``(elevation, rotation)`` in radians as Blender's sky texture
    takes them, from the light's (3, 3) world rotation (it shines along its local -Z axis, so
    the sun stands along +Z). Blender's rotation is measured about the zenith from +Y towards
    +X (checked by rendering: tests/test_world_sensor_render.py, the sky is brightest towards the
    sun light)."""
    to_sun = np.asarray(sun_rotation, dtype=np.float64)[:, 2]
    to_sun = to_sun / np.linalg.norm(to_sun)
    elevation = math.asin(max(-1.0, min(1.0, float(to_sun[2]))))
    rotation = math.atan2(float(to_sun[0]), float(to_sun[1]))
    return elevation, rotation


def ir_illuminator_power_w(range_m: float) -> float:
    """Power (W, Blender's spot power) of an IR illuminator whose light makes a 50 % grey
    surface at ``range_m`` show at :data:`IR_RANGE_EDGE_LINEAR`: Blender's spot of power P has
    radiant intensity P / 4π, so the irradiance at d is P / (4π d²) and the surface's radiance
    0.5 · E / π."""
    irradiance = IR_RANGE_EDGE_LINEAR * math.pi / 0.5
    return 4.0 * math.pi * range_m * range_m * irradiance


def image_seed(document_seed: int, camera: str, frame: int) -> list[int]:
    """Entropy of the sensor's generator for one image: (document seed, CRC-32 of the camera
    name, frame). Independent of rendering order, workers and executors."""
    return [int(document_seed), zlib.crc32(camera.encode("utf-8")), int(frame) & 0xFFFFFFFF]


def draw_per_frame(spec: World | Sensor, frames: Sequence[int], rng: np.random.Generator) -> World | Sensor:
    """Draw the ``randomize`` fields of ``spec`` uniformly in their ranges for every frame.

    Returns:
        ``spec`` with ``per_frame`` overrides for ``frames`` (existing overrides of a frame
        are kept and the drawn fields added) and no ``randomize``; ``spec`` itself when it has
        no ranges.
    """
    if not spec.randomize:
        return spec
    existing = {f: dict(o) for f, o in spec.per_frame}
    per_frame = []
    for frame in frames:
        overrides = dict(existing.pop(frame, {}))
        for name, (low, high) in spec.randomize:
            if name in INTEGER_FIELDS:
                overrides[name] = int(rng.integers(int(math.ceil(low)), int(math.floor(high)) + 1))
            else:
                overrides[name] = round(float(rng.uniform(low, high)), 6)
        per_frame.append((int(frame), tuple(sorted(overrides.items()))))
    per_frame += [(f, tuple(sorted(o.items()))) for f, o in existing.items()]
    return replace(spec, per_frame=tuple(sorted(per_frame)), randomize=())


def hdri_path(world: World, document_folder: str | os.PathLike | None) -> Path:
    """The HDRI's absolute, resolved path (a relative one is relative to the document's folder,
    else to the working folder)."""
    path = Path(world.hdri)
    if not path.is_absolute():
        path = Path(document_folder if document_folder is not None else Path.cwd()) / path
    return path.resolve()


def world_stage_json(scene) -> str:
    """What the renderer needs of a SceneSpec's world, as the canonical JSON text of the stage's
    ``usdscene:render:worldJson``: the world's document form, the HDRI's absolute path and the
    sky's sun (elevation and rotation in radians, irradiance in W/m²) from the first sun light."""
    from usdscene.document.model import LightKind

    world = scene.world
    source = scene.provenance.source
    folder = Path(source).parent if source and "://" not in source else None
    sun = None
    for light in scene.lights:
        if light.kind is LightKind.SUN:
            elevation, rotation = sun_sky_angles(light.pose.rotation)
            sun = {"elevation_rad": elevation, "rotation_rad": rotation, "irradiance_w_m2": float(light.power_w)}
            break
    return json.dumps({"world": spec_to_json(world), "hdri_path": str(hdri_path(world, folder)) if world.hdri else "",
                       "sun": sun}, sort_keys=True)


def randomize_scene(scene, rng: np.random.Generator):
    """Draw the ``randomize`` ranges of a scene's world (per frame) and of each camera's sensor
    (per camera and frame) into ``per_frame`` overrides, for ``usdscene generate``.

    Args:
        scene: a SceneSpec.
        rng: the generator; draws go world first, then cameras in document order, frames
            ascending within each.

    Returns:
        ``(scene, drawn)``: the scene without ``randomize`` ranges and with the drawn
        overrides; ``drawn`` is ``{"world": {"<frame>": {field: value}}, "sensors": {camera:
        {"<frame>": {field: value}}}}`` holding only what was drawn (empty dicts when nothing).
    """
    frames = list(scene.frames)
    drawn: dict[str, Any] = {"world": {}, "sensors": {}}
    world = scene.world
    if world is not None and world.randomize:
        names = [name for name, _ in world.randomize]
        world = draw_per_frame(world, frames, rng)
        drawn["world"] = {str(f): {k: v for k, v in o if k in names} for f, o in world.per_frame}
    cameras = []
    for cam in scene.cameras:
        sensor = cam.sensor
        if sensor is not None and sensor.randomize:
            names = [name for name, _ in sensor.randomize]
            sensor = draw_per_frame(sensor, frames, rng)
            drawn["sensors"][cam.name] = {str(f): {k: v for k, v in o if k in names} for f, o in sensor.per_frame}
            cam = replace(cam, sensor=sensor)
        cameras.append(cam)
    return replace(scene, world=world, cameras=tuple(cameras)), drawn
