"""What the renderer needs from a composed stage, read with pxr in the parent process.

The Blender worker imports the geometry itself but never opens the stage with pxr (Blender
bundles its own USD): cameras, per-frame presence, mask ids and render settings come from here
and travel in the job file.
"""

from __future__ import annotations

import bisect
import dataclasses
import json
import logging
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import NamedTuple

from usdscene.document import stage_schema as names
from usdscene.errors import Problem, RenderError, usd_error_text
from usdscene.document.model import (Camera, Intrinsics, LensModel, Pose, RenderSettings,
                            usd_pose_to_cv_pose)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ObjectEntry:
    """One labelled object prim.

    Attributes:
        uid: OpenLABEL uid (``userProperties:usdscene_uid``, else customData, else prim name).
        class_name: asset class.
        prim_path: prim path under ``/World/Objects``.
        mask_id: value in the masks (``usdscene:maskId``), 1..65535; objects never visible on
            a common frame may share one (per-frame ids, ``output_layout.mask_ids``).
        visible_frames: frames of the stage range where the prim is visible, ascending.
        pose_frames: for an object whose pose changes per frame (a walker), ``(variant,
            frames)`` per pose child prim (``stage_schema.POSE_CHILD_PREFIX``): the frames of
            ``visible_frames`` that show that pose; empty for every other object.
    """

    uid: str
    class_name: str
    prim_path: str
    mask_id: int
    visible_frames: tuple[int, ...]
    pose_frames: tuple[tuple[str, tuple[int, ...]], ...] = ()


@dataclass(frozen=True)
class StagePlan:
    """Everything the driver needs besides the geometry.

    Attributes:
        stage_path: the root layer.
        frame_start, frame_end: closed frame range (start/end time codes).
        cameras: calibrated cameras; ``frame_poses`` holds every frame when the camera moves.
        objects: labelled objects in prim order.
        settings: render settings (``/Render/Settings`` attributes over the defaults).
        shared_prims: prims every shard imports (environment, lights, looks; not cameras,
            not objects).
        world: the ``usdscene:render:worldJson`` of ``/Render/Settings`` decoded
            (:func:`usdscene.document.imaging.world_stage_json`), None when the stage has none.
        sensors: camera name → ``usdscene:camera:sensorJson`` decoded (``{"sensor", "seed"}``),
            for the cameras that have one.
    """

    stage_path: Path
    frame_start: int
    frame_end: int
    cameras: tuple[Camera, ...]
    objects: tuple[ObjectEntry, ...]
    settings: RenderSettings
    shared_prims: tuple[str, ...]
    world: dict | None = None
    sensors: dict = dataclasses.field(default_factory=dict)

    @property
    def frames(self) -> range:
        """The frames to render, ``frame_start`` to ``frame_end`` included."""
        return range(self.frame_start, self.frame_end + 1)


def read_stage_plan(stage_path: str | Path) -> StagePlan:
    """Open the composed stage and read cameras, objects, presence and render settings.

    Raises:
        RenderError: the stage cannot be opened, or cameras/objects are malformed (every
            problem listed, with its prim path).
    """
    from pxr import Usd

    path = Path(stage_path).resolve()
    try:
        stage = Usd.Stage.Open(str(path)) if path.is_file() else None
    except Exception as exc:  # pxr raises Tf.ErrorException for files that are not USD
        raise RenderError(f"cannot open USD stage: {usd_error_text(exc)}", where=str(stage_path)) from None
    if stage is None:
        raise RenderError(f"cannot open USD stage {str(stage_path)!r}", where=str(stage_path))
    problems: list[Problem] = []
    start = int(stage.GetStartTimeCode()) if stage.HasAuthoredTimeCodeRange() else 0
    end = int(stage.GetEndTimeCode()) if stage.HasAuthoredTimeCodeRange() else start
    frames = list(range(start, end + 1))
    settings = _read_settings(stage, problems)
    cameras = _read_cameras(stage, frames, settings, problems)
    objects = _read_objects(stage, frames, problems)
    shared = []
    for prim in stage.GetPseudoRoot().GetChildren():
        if prim.GetPath().pathString == names.WORLD:
            for child in prim.GetChildren():
                if child.GetPath().pathString not in (names.CAMERAS, names.OBJECTS):
                    shared.append(child.GetPath().pathString)
        elif not prim.GetPath().pathString.startswith("/Render"):
            shared.append(prim.GetPath().pathString)
    world = _json_attr(stage.GetPrimAtPath(names.RENDER_SETTINGS), names.ATTR_RENDER_WORLD, problems)
    sensors = {}
    for camera in cameras:
        prim = stage.GetPrimAtPath(names.CAMERAS).GetChild(camera.name)
        sensor = _json_attr(prim, names.ATTR_CAMERA_SENSOR, problems) if prim else None
        if sensor is not None:
            sensors[camera.name] = sensor
    if problems:
        raise RenderError(problems)
    return StagePlan(path, start, end, tuple(cameras), tuple(objects), settings, tuple(shared), world, sensors)


def _json_attr(prim, name: str, problems: list[Problem]) -> dict | None:
    """A string attribute holding a JSON object (None when the prim or attribute is absent)."""
    if not prim:
        return None
    text = _attr(prim, name)
    if text is None:
        return None
    try:
        value = json.loads(str(text))
    except ValueError as exc:
        problems.append(Problem(f"{prim.GetPath()}.{name}", f"not JSON: {exc}"))
        return None
    if not isinstance(value, dict):
        problems.append(Problem(f"{prim.GetPath()}.{name}", "expected a JSON object"))
        return None
    return value


def recorded_source(stage_path: str | Path) -> tuple[Path | None, str]:
    """The scene document a composed stage was made from, as its root layer records it.

    Returns:
        ``(path or None when none is recorded, its sha256 at composition or "")``; the file may
        have changed or gone since.
    """
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(stage_path)) if Path(stage_path).is_file() else None
    data = (layer.customLayerData or {}).get(names.LAYER_DATA_KEY, {}) if layer else {}
    source = data.get("source", "")
    return (Path(source) if source else None), str(data.get("sourceSha256", ""))


class StageFiles(NamedTuple):
    """What :func:`stage_dependencies` finds.

    Attributes:
        files: absolute paths of existing files, root layer first (the HDRI among them).
        unresolved: asset paths that could not be resolved (as written in the layers).
        hdri: the world's HDRI when it exists (also in ``files``), else None.
    """

    files: list[Path]
    unresolved: list[str]
    hdri: Path | None


def stage_dependencies(stage_path: str | Path) -> StageFiles:
    """Every file a render of the stage reads: its layers, the layers they reference or
    sublayer (assets) and other assets they name (textures), found by following composition,
    and the world's HDRI (:func:`world_hdri_path`)."""
    from pxr import UsdUtils

    layers, assets, unresolved_paths = UsdUtils.ComputeAllDependencies(str(Path(stage_path).resolve()))
    unresolved = [str(u) for u in unresolved_paths]
    files: list[Path] = []
    for item in [layer.realPath for layer in layers] + [str(a) for a in assets]:
        path = Path(item).resolve()
        if item and path.is_file() and path not in files:
            files.append(path)
    hdri = world_hdri_path(layers)
    if hdri is not None and not hdri.is_file():
        unresolved.append(str(hdri))
        hdri = None
    if hdri is not None and hdri not in files:
        files.append(hdri)
    return StageFiles(files, unresolved, hdri)


def world_hdri_path(layers) -> Path | None:
    """The HDRI file of the stage's world (``hdri_path`` of ``usdscene:render:worldJson`` on
    ``/Render/Settings``, an absolute path written by compose), read from the layer specs
    without composing the stage; None when no layer authors an HDRI world.

    The HDRI is named in that JSON, not as a USD asset path, so composition does not find it:
    without this the digest would miss an edited HDRI and a Ray task would not receive it."""
    from pxr import Sdf

    attribute = Sdf.Path(names.RENDER_SETTINGS).AppendProperty(names.ATTR_RENDER_WORLD)
    for layer in layers:
        spec = layer.GetAttributeAtPath(attribute)
        if spec is None or not spec.default:
            continue
        try:
            hdri = json.loads(spec.default).get("hdri_path") or ""
        except (ValueError, AttributeError):
            return None  # read_stage_plan reports a malformed world
        return Path(hdri).resolve() if hdri else None
    return None


def stage_digest(stage_path: str | Path) -> str:
    """sha256 over every file a render of the stage reads (:func:`stage_dependencies`: its
    layers, the asset layers they reference, textures), names and bytes in composition order:
    an edited asset changes it, a moved output folder does not."""
    import hashlib

    digest = hashlib.sha256()
    for path in stage_dependencies(stage_path).files:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _read_settings(stage, problems: list[Problem]) -> RenderSettings:
    settings = RenderSettings()
    prim = stage.GetPrimAtPath(names.RENDER_SETTINGS)
    if not prim:
        return settings
    attrs = {
        "engine": names.ATTR_RENDER_ENGINE, "device": names.ATTR_RENDER_DEVICE,
        "samples": names.ATTR_RENDER_SAMPLES, "adaptive_threshold": names.ATTR_RENDER_ADAPTIVE_THRESHOLD,
        "denoise": names.ATTR_RENDER_DENOISE, "denoiser": names.ATTR_RENDER_DENOISER,
        "denoising_quality": names.ATTR_RENDER_DENOISING_QUALITY,
        "denoising_prefilter": names.ATTR_RENDER_DENOISING_PREFILTER,
        "adaptive_min_samples": names.ATTR_RENDER_ADAPTIVE_MIN_SAMPLES,
        "denoising_input_passes": names.ATTR_RENDER_DENOISING_INPUT_PASSES,
        "light_tree": names.ATTR_RENDER_LIGHT_TREE, "path_guiding": names.ATTR_RENDER_PATH_GUIDING,
        "clamp_indirect": names.ATTR_RENDER_CLAMP_INDIRECT,
        "sampling_pattern": names.ATTR_RENDER_SAMPLING_PATTERN,
        "fast_gi": names.ATTR_RENDER_FAST_GI, "fast_gi_method": names.ATTR_RENDER_FAST_GI_METHOD,
        "fast_gi_ao_bounces": names.ATTR_RENDER_FAST_GI_AO_BOUNCES,
        "fast_gi_distance_m": names.ATTR_RENDER_FAST_GI_DISTANCE,
        "scrambling_distance": names.ATTR_RENDER_SCRAMBLING_DISTANCE,
        "auto_scrambling_distance": names.ATTR_RENDER_AUTO_SCRAMBLING_DISTANCE,
        "max_bounces": names.ATTR_RENDER_MAX_BOUNCES, "caustics": names.ATTR_RENDER_CAUSTICS,
        "tile_size_px": names.ATTR_RENDER_TILE_SIZE, "resolution_px": names.ATTR_RENDER_RESOLUTION,
        "seed": names.ATTR_RENDER_SEED, "depth": names.ATTR_RENDER_DEPTH,
    }
    types = {f.name: type(getattr(settings, f.name)) for f in fields(RenderSettings)}
    types["depth"] = str
    values = {}
    for field_name, attr_name in attrs.items():
        attr = prim.GetAttribute(attr_name)
        if not attr or not attr.HasAuthoredValue():
            continue
        value = attr.Get()
        try:
            if field_name == "resolution_px":
                value = (int(value[0]), int(value[1]))
            else:
                value = types[field_name](value)
        except (TypeError, ValueError, IndexError):
            problems.append(Problem(f"{names.RENDER_SETTINGS}.{attr_name}",
                                    f"cannot read {value!r} as {types[field_name].__name__}"))
            continue
        values[field_name] = value
    return replace(settings, **values)


def _attr(prim, name, default=None):
    attr = prim.GetAttribute(name)
    if attr and attr.HasAuthoredValue():
        return attr.Get()
    return default


def _read_cameras(stage, frames, settings: RenderSettings, problems) -> list[Camera]:
    from pxr import Usd, UsdGeom

    root = stage.GetPrimAtPath(names.CAMERAS)
    cameras: list[Camera] = []
    if not root:
        return cameras
    cache = UsdGeom.XformCache()
    for prim in Usd.PrimRange(root):
        if not prim.IsA(UsdGeom.Camera):
            continue
        where = prim.GetPath().pathString
        geom = UsdGeom.Camera(prim)
        try:
            intr = _intrinsics(prim, geom, settings)
        except (ValueError, TypeError) as exc:
            problems.append(Problem(where, str(exc)))
            continue

        def pose_at(time):
            cache.SetTime(Usd.TimeCode(time))
            m = cache.GetLocalToWorldTransform(prim)
            usd = Pose.from_matrix([[m[c][r] for c in range(4)] for r in range(4)])
            # Normalise away any scale so the rotation stays orthonormal.
            import numpy as np
            u, _, vt = np.linalg.svd(usd.rotation)
            return usd_pose_to_cv_pose(Pose.from_rotation_translation(u @ vt, usd.translation_m))

        moving = any(UsdGeom.Xformable(p).TransformMightBeTimeVarying()
                     for p in _self_and_ancestors(prim) if p.IsA(UsdGeom.Xformable))
        base = pose_at(Usd.TimeCode.Default().GetValue() if not moving else frames[0])
        frame_poses = tuple((f, pose_at(f)) for f in frames) if moving else ()
        clip = _attr(prim, getattr(names, "ATTR_CAMERA_CLIPPING", ""), None)  # exact doubles
        if clip is None:
            clip = geom.GetClippingRangeAttr().Get() or (0.01, 1000.0)
        cameras.append(Camera(name=prim.GetName(), intrinsics=intr, pose=base, frame_poses=frame_poses,
                              clip_near_m=float(clip[0]), clip_far_m=float(clip[1]),
                              model_name=str(_attr(prim, names.ATTR_CAMERA_MODEL_NAME, "") or "")))
    return cameras


def _self_and_ancestors(prim):
    while prim and not prim.IsPseudoRoot():
        yield prim
        prim = prim.GetParent()


def _intrinsics(prim, geom, settings: RenderSettings) -> Intrinsics:
    from pxr import UsdGeom

    model = _attr(prim, names.ATTR_LENS_MODEL)
    width = _attr(prim, names.ATTR_LENS_WIDTH)
    height = _attr(prim, names.ATTR_LENS_HEIGHT)
    width = int(width) if width is not None else settings.resolution_px[0]
    height = int(height) if height is not None else settings.resolution_px[1]
    if width <= 0 or height <= 0:
        raise ValueError(f"resolution {width}x{height} px must be positive")
    sensor_w = float(_attr(prim, names.ATTR_LENS_SENSOR_WIDTH, geom.GetHorizontalApertureAttr().Get() or 36.0))
    if model is None:  # a plain USD camera: derive a pinhole/orthographic model from USD attributes
        ortho = geom.GetProjectionAttr().Get() == UsdGeom.Tokens.orthographic
        aperture = float(geom.GetHorizontalApertureAttr().Get())
        if ortho:
            # USD apertures of orthographic cameras are in tenths of a scene unit.
            fx = width / (aperture / 10.0)
            return Intrinsics(LensModel.ORTHOGRAPHIC, width, height, fx, fx, (width - 1) / 2, (height - 1) / 2)
        fx = float(geom.GetFocalLengthAttr().Get()) * width / aperture
        return Intrinsics(LensModel.PERSPECTIVE, width, height, fx, fx, (width - 1) / 2, (height - 1) / 2,
                          sensor_width_mm=aperture)
    try:
        lens = LensModel(str(model))
    except ValueError:
        raise ValueError(f"{names.ATTR_LENS_MODEL} {str(model)!r} is not one of "
                         f"{[m.value for m in LensModel]}") from None
    fx = _attr(prim, names.ATTR_LENS_FX)
    fy = _attr(prim, names.ATTR_LENS_FY, fx)
    if fx is None or float(fx) <= 0 or float(fy) <= 0:
        raise ValueError(f"{names.ATTR_LENS_FX} {fx!r} must be a positive number of pixels")
    cx = float(_attr(prim, names.ATTR_LENS_CX, (width - 1) / 2))
    cy = float(_attr(prim, names.ATTR_LENS_CY, (height - 1) / 2))
    distortion = tuple(float(v) for v in (_attr(prim, names.ATTR_LENS_DISTORTION, ()) or ()))
    fov = _attr(prim, names.ATTR_LENS_FOV)
    return Intrinsics(lens, width, height, float(fx), float(fy), cx, cy, distortion,
                      float(fov) if fov is not None else None, sensor_w)


def _read_objects(stage, frames, problems) -> list[ObjectEntry]:
    from pxr import UsdGeom

    root = stage.GetPrimAtPath(names.OBJECTS)
    if not root:
        return []
    # Presence of the parents (rarely animated), evaluated once per frame.
    parent_visible = {f: UsdGeom.Imageable(root).ComputeVisibility(f) != UsdGeom.Tokens.invisible
                      for f in frames} if root.IsA(UsdGeom.Imageable) else {f: True for f in frames}
    entries: list[ObjectEntry] = []
    seen_ids: dict[int, list[tuple[str, frozenset]]] = {}
    for prim in root.GetChildren():
        where = prim.GetPath().pathString
        uid = _attr(prim, names.ATTR_USER_UID) or prim.GetCustomDataByKey(names.CUSTOM_UID) or prim.GetName()
        cls = _attr(prim, names.ATTR_USER_CLASS) or prim.GetCustomDataByKey(names.CUSTOM_CLASS) or ""
        mask_id = _attr(prim, names.ATTR_MASK_ID)
        if mask_id is None:
            problems.append(Problem(where, f"object prim has no {names.ATTR_MASK_ID} attribute"))
            continue
        mask_id = int(mask_id)
        if not 1 <= mask_id <= 65535:
            problems.append(Problem(where, f"{names.ATTR_MASK_ID} {mask_id} is outside 1..65535"))
            continue
        visible = tuple(f for f in _visible_frames(prim, frames) if parent_visible[f])
        # Ids are per frame (output_layout.mask_ids): objects never visible together may share one.
        clash = next((other for other, shown in seen_ids.get(mask_id, ()) if not shown.isdisjoint(visible)), None)
        if clash is not None:
            problems.append(Problem(where, f"{names.ATTR_MASK_ID} {mask_id} is also used by {clash}"))
            continue
        seen_ids.setdefault(mask_id, []).append((where, frozenset(visible)))
        pose_frames = []
        for child in prim.GetChildren():
            variant = _attr(child, names.ATTR_USER_POSE)
            if variant is not None:
                shows = set(_visible_frames(child, frames))
                pose_frames.append((str(variant), tuple(f for f in visible if f in shows)))
        entries.append(ObjectEntry(str(uid), str(cls), where, mask_id, visible, tuple(pose_frames)))
    return entries


def _visible_frames(prim, frames) -> list[int]:
    """Frames where the prim's own visibility is not ``invisible`` (held interpolation)."""
    from pxr import UsdGeom

    attr = UsdGeom.Imageable(prim).GetVisibilityAttr()
    samples = attr.GetTimeSamples() if attr else []
    if not samples:
        value = attr.Get() if attr else UsdGeom.Tokens.inherited
        return list(frames) if value != UsdGeom.Tokens.invisible else []
    values = [attr.Get(t) for t in samples]
    out = []
    for f in frames:
        i = max(0, bisect.bisect_right(samples, f) - 1)
        if values[i] != UsdGeom.Tokens.invisible:
            out.append(f)
    return out
