""".blend projects for interactive camera design, and back to a SceneSpec.

* :func:`write_blend`: the composed stage as a Blender project: every object (presence
  keyframed, pass index = mask id), one Blender camera per stage camera with its exact
  calibration kept in custom properties, render settings as for ``usdscene render``. The
  OpenLABEL document of the scene the stage gives back (``scene_from_stage``) rides along as a
  custom property of the Blender scene (``stage_schema.BLEND_DOCUMENT``): Blender's USD
  exporter writes neither customData nor customLayerData, where the stage keeps places,
  relations, ROI rules, render settings, world, sensors and other people's content.
* :func:`scene_from_blend`: a (possibly edited) .blend back to a SceneSpec, through Blender's
  USD export and :func:`usdscene.converters.stage.usd_stage.scene_from_stage`. Blender's USD exporter writes
  only perspective cameras, so cameras (pose per frame and lens) are read from the .blend
  itself. A camera whose Blender lens settings are unchanged keeps its exact calibration
  (including OpenCV distortion); an edited one gets the model of its Blender settings. The
  project's cameras, lights and objects (poses, presence, lenses, what was deleted or added)
  are then joined with the carried document: everything Blender does not show comes from it,
  matched by the camera's name in the document (custom property
  ``stage_schema.BLEND_CAMERA_NAME``, so a renamed camera keeps it) and by uid; values Blender
  shows unchanged (up to its float32 rounding) keep the document's exact value. A .blend
  without the document (not written by ``usdscene blend``) reads as Blender exports it.

Both run Blender in a worker process (this module never imports bpy).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import tempfile
from pathlib import Path

import numpy as np

from usdscene.document import stage_schema as ss
from usdscene.errors import DocumentError, RenderError
from usdscene.document.model import (Camera, FrameInterval, Intrinsics, LensModel, Pose, SceneObject, SceneSpec,
                                     union_intervals, usd_pose_to_cv_pose)

log = logging.getLogger(__name__)


def write_blend(stage_path: str | Path, blend_path: str | Path) -> Path:
    """Write ``blend_path`` from a composed stage (which must stay where it is: the .blend
    reads animated transforms from it).

    Raises:
        RenderError: the stage is unusable or Blender failed.
        OutputError: ``blend_path`` cannot be written (a folder, its parent is a file...).
    """
    from usdscene.files import prepare_output_file
    from usdscene.render.driver import camera_jobs, resolve_settings, run_job
    from usdscene.render.job import BlendJob, JobObject
    from usdscene.render.stage_reader import read_stage_plan

    prepare_output_file(blend_path, what="Blender file")
    plan = read_stage_plan(stage_path)
    frames = list(plan.frames)
    job = BlendJob(
        stage=str(plan.stage_path),
        blend=str(Path(blend_path).resolve()),
        out_dir=str(Path(blend_path).resolve().parent),
        # Everything but the stage's cameras (the project gets real Blender cameras instead).
        prim_path_mask=",".join([*plan.shared_prims, *(o.prim_path for o in plan.objects)]) or "/World/__nothing__",
        settings=resolve_settings(plan.settings, None),
        objects=tuple(JobObject.of(o) for o in plan.objects),
        cameras=camera_jobs(plan, [c.name for c in plan.cameras], frames),
        frame_start=plan.frame_start,
        frame_end=plan.frame_end,
        document=_stage_document(plan.stage_path),
    )
    run_job(job, str(blend_path))
    return Path(blend_path)


def _stage_document(stage_path: Path) -> str | None:
    """What the stage route (``export-openlabel STAGE``) gives back, as compact JSON text for
    the .blend to keep; None (and a warning) for a stage that route cannot read: the project
    still serves camera design, and reads back as Blender exports it."""
    from usdscene.converters.openlabel import write_openlabel
    from usdscene.converters.stage.usd_stage import scene_from_stage

    try:
        return json.dumps(write_openlabel(scene_from_stage(stage_path)), separators=(",", ":"))
    except DocumentError as exc:
        log.warning("%s: the .blend will not carry the scene's document (places, relations, ROI rules, "
                    "carried content): %s", stage_path, exc)
        return None


def scene_from_blend(path: str | Path) -> SceneSpec:
    """Read a .blend (written by :func:`write_blend`, maybe edited) into a SceneSpec.

    Raises:
        RenderError: the file is missing or Blender failed.
        DocumentError: the exported stage is malformed (from ``scene_from_stage``), or the
            document the .blend carries (``stage_schema.BLEND_DOCUMENT``) is unreadable.
    """
    from usdscene.converters.stage.usd_stage import scene_from_stage

    from usdscene.render.driver import run_job
    from usdscene.render.job import InspectBlendJob

    path = Path(path)
    if not path.is_file():
        raise RenderError(f".blend file {str(path)!r} not found", where=str(path))
    with tempfile.TemporaryDirectory(prefix="usdscene-blend-") as tmp:
        usd = Path(tmp) / "scene.usda"
        info_path = Path(tmp) / "cameras.json"
        run_job(InspectBlendJob(blend=str(path.resolve()), usd=str(usd), json=str(info_path)), str(path))
        info = json.loads(info_path.read_text())
        scene = scene_from_stage(usd)
    carried = _carried_scene(info.get("document"), path)
    cameras = tuple(_camera_from_blend(name, cam, info) for name, cam in sorted(info["cameras"].items()))
    # Presence is keyframed render visibility, which the USD exporter does not write.
    # Poses come from Blender's evaluated matrices too (the exporter writes time samples only,
    # so a static object has no default transform in the exported stage).
    presence = info.get("presence", {})
    matrices = info.get("object_matrices", {})
    objects = []
    for o in scene.objects:
        if o.uid in presence:
            visible = presence[o.uid]
            poses = {int(f): _rigid(m[o.uid]) for f, m in matrices.items() if o.uid in m}
            first = visible[0] if visible else min(poses, default=None)
            if first is not None and first in poses:
                base = poses[first]
                moved = tuple((f, poses[f]) for f in visible
                              if f in poses and not np.allclose(poses[f].as_array(), base.as_array(), atol=1e-6))
                o = dataclasses.replace(o, pose=base, frame_poses=moved)
            o = dataclasses.replace(o, frame_intervals=_intervals(visible))
        objects.append(o)
    objects = tuple(objects)
    provenance = dataclasses.replace(scene.provenance, source=str(path), source_format="blend")
    scene = dataclasses.replace(scene, cameras=cameras, objects=objects, provenance=provenance)
    if carried is None:
        return scene
    # A camera's name in the carried document (its Blender name for one written before).
    origins = [str(cam.get("custom", {}).get(ss.BLEND_CAMERA_NAME, name))
               for name, cam in sorted(info["cameras"].items())]
    return _join(carried, scene, origins)


def _carried_scene(text: str | None, path: Path) -> SceneSpec | None:
    """The scene of the document a .blend carries (``stage_schema.BLEND_DOCUMENT``), or None
    when it carries none."""
    from usdscene.converters.openlabel import read_openlabel

    if text is None:
        log.info("%s carries no %s (not written by 'usdscene blend'): places, relations, ROI rules and "
                 "carried content come back only as far as Blender's USD export keeps them", path, ss.BLEND_DOCUMENT)
        return None
    where = f"{path}: custom property {ss.BLEND_DOCUMENT} of the Blender scene"
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DocumentError(f"expected the JSON text of a scene document, got {text[:60]!r}: {exc} "
                            f"(delete the property to read the project as Blender exports it)", where=where) from None
    if not isinstance(document, dict):
        raise DocumentError(f"expected a JSON object (an OpenLABEL document), got {text[:60]!r}", where=where)
    try:
        return read_openlabel(document)
    except DocumentError as exc:
        raise DocumentError([dataclasses.replace(p, where=f"{where}: {p.where}") for p in exc.problems]) from None


# Blender keeps transforms, lens settings and light values in float32: a value that differs
# from the document's by less than this was not edited.
_ATOL, _RTOL = 1e-5, 1e-6


def _close(a, b) -> bool:
    """``a`` and ``b`` equal up to Blender's float32 rounding (numbers, tuples, dataclasses)."""
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str):
        return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(a - b) <= _ATOL + _RTOL * max(abs(a), abs(b))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        return all(_close(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    return a == b


def _same_path(stored, seen, frames) -> bool:
    """Whether two elements (cameras or objects) have the same pose on every frame of ``frames``."""
    def pose_at(element, frame):
        return dict(element.frame_poses).get(frame, element.pose)

    return all(_close(pose_at(stored, f), pose_at(seen, f)) for f in frames)


def _join(carried: SceneSpec, seen: SceneSpec, origins: list[str]) -> SceneSpec:
    """The project as Blender shows it (``seen``: cameras with their names in the carried
    document, ``origins``; lights; objects with their poses and presence; the frame range)
    joined with the document the .blend carries (``carried``): everything else, and the
    carried exact value of everything Blender shows unchanged."""
    frames = range(seen.frame_start, seen.frame_end + 1)
    carried_cameras = {c.name: c for c in carried.cameras}
    cameras = []
    for origin, cam in zip(origins, seen.cameras):
        was = carried_cameras.get(origin)
        if was is None:  # added in Blender
            cameras.append(cam)
            continue
        if _same_path(was, cam, frames):
            cam = dataclasses.replace(cam, pose=was.pose, frame_poses=was.frame_poses)
        cameras.append(dataclasses.replace(
            was, name=cam.name, intrinsics=cam.intrinsics, pose=cam.pose, frame_poses=cam.frame_poses,
            clip_near_m=was.clip_near_m if _close(was.clip_near_m, cam.clip_near_m) else cam.clip_near_m,
            clip_far_m=was.clip_far_m if _close(was.clip_far_m, cam.clip_far_m) else cam.clip_far_m))
    carried_lights = {light.uid: light for light in carried.lights}
    lights = []
    for light in seen.lights:
        was = carried_lights.get(light.uid)
        if was is not None:
            light = dataclasses.replace(was, **{f.name: getattr(light, f.name) for f in dataclasses.fields(light)
                                                if not _close(getattr(was, f.name), getattr(light, f.name))})
        lights.append(light)
    carried_objects = {o.uid: o for o in carried.objects}
    objects = tuple(_join_object(carried_objects.get(o.uid), o, frames) for o in seen.objects)
    cameras = _carried_order(cameras, origins, list(carried_cameras))
    lights = _carried_order(lights, [light.uid for light in lights], list(carried_lights))
    objects = tuple(_carried_order(list(objects), [o.uid for o in objects], list(carried_objects)))
    kept = {o.uid for o in objects} | {light.uid for light in lights}
    deleted = ({o.uid for o in carried.objects} | set(carried_lights)) - kept
    relations = tuple(r for r in carried.relations if not {r.subject_uid, r.object_uid} & deleted)
    if len(relations) < len(carried.relations):
        log.info("%d relations dropped: their objects were deleted in Blender", len(carried.relations) - len(relations))
    return dataclasses.replace(carried, frame_start=seen.frame_start, frame_end=seen.frame_end,
                               cameras=tuple(cameras), lights=tuple(lights), objects=objects, relations=relations,
                               provenance=seen.provenance)


def _carried_order(elements: list, keys: list[str], carried: list[str]) -> list:
    """``elements`` (identified by ``keys``) in the carried document's order (``carried``), then
    those Blender added in their own order: the stage route's order."""
    position = {key: i for i, key in enumerate(carried)}
    ranked = sorted(range(len(elements)), key=lambda i: position.get(keys[i], len(position) + i))
    return [elements[i] for i in ranked]


def _join_object(was: SceneObject | None, seen: SceneObject, frames: range) -> SceneObject:
    """An object of the project (pose, presence) joined with its carried self (the rest)."""
    if was is None:
        return seen
    present = [f for iv in seen.frame_intervals for f in range(iv.frame_start, iv.frame_end + 1)]
    pose, frame_poses = (was.pose, was.frame_poses) if _same_path(was, seen, present) else (seen.pose, seen.frame_poses)
    # The project shows presence over its frame range only; the document's frames outside it stay.
    outside = [FrameInterval(max(iv.frame_start, frames.stop), iv.frame_end) for iv in was.frame_intervals
               if iv.frame_end >= frames.stop]
    outside += [FrameInterval(iv.frame_start, min(iv.frame_end, frames.start - 1)) for iv in was.frame_intervals
                if iv.frame_start < frames.start]
    intervals = union_intervals([*seen.frame_intervals, *outside])
    frame_extra = tuple((f, text) for f, text in was.frame_extra
                        if any(iv.frame_start <= f <= iv.frame_end for iv in intervals))
    return dataclasses.replace(was, pose=pose, frame_poses=frame_poses, frame_intervals=intervals,
                               frame_extra=frame_extra)


def _rigid(matrix) -> Pose:
    """A Blender float32 world matrix → rigid Pose (scale dropped, rotation re-orthonormalised,
    float32 noise below 1e-6 rounded away)."""
    m = np.asarray(matrix, dtype=np.float64)
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    return Pose.from_rotation_translation(np.round(r, 6) + 0.0, np.round(m[:3, 3], 6) + 0.0)


def _intervals(frames: list[int]) -> tuple[FrameInterval, ...]:
    out: list[FrameInterval] = []
    for f in sorted(frames):
        if out and f == out[-1].frame_end + 1:
            out[-1] = FrameInterval(out[-1].frame_start, f)
        else:
            out.append(FrameInterval(f, f))
    return tuple(out)


def _camera_from_blend(name: str, cam: dict, info: dict) -> Camera:
    from usdscene.render.job import intrinsics_from_json

    poses = {int(f): usd_pose_to_cv_pose(_rigid(m)) for f, m in cam["poses"].items()}
    frames = sorted(poses)
    base = poses[frames[0]] if frames else Pose()
    moving = any(not np.allclose(poses[f].as_array(), base.as_array(), atol=1e-9) for f in frames)
    custom = cam.get("custom", {})
    intr = None
    if "usdscene_lens" in custom and "usdscene_blender_lens" in custom:
        stored = json.loads(custom["usdscene_blender_lens"])
        if _same_lens(stored, cam["data"]):
            intr = intrinsics_from_json(json.loads(custom["usdscene_lens"]))
    if intr is None:
        width, height = info["resolution_px"]
        if "usdscene_lens" in custom:  # keep the camera's own resolution and sensor
            original = intrinsics_from_json(json.loads(custom["usdscene_lens"]))
            width, height = original.width_px, original.height_px
        intr = _intrinsics_from_blender(cam["data"], width, height)
        log.info("camera %s: lens edited in Blender; calibration taken from its Blender settings (%s)",
                 name, intr.lens.value)
    return Camera(name=name, intrinsics=intr, pose=base,
                  frame_poses=tuple((f, poses[f]) for f in frames) if moving else (),
                  clip_near_m=float(f"{cam['clip_m'][0]:.6g}"), clip_far_m=float(f"{cam['clip_m'][1]:.6g}"))


def _same_lens(a: dict, b: dict) -> bool:
    for key, value in a.items():
        other = b.get(key)
        if isinstance(value, float) and isinstance(other, (int, float)):
            if abs(value - other) > 1e-5 * max(1.0, abs(value)):
                return False
        elif value != other:
            return False
    return True


def _intrinsics_from_blender(data: dict, width: int, height: int) -> Intrinsics:
    """Intrinsics of a Blender camera with horizontal sensor fit (the inverse of the worker's
    ``apply_intrinsics``)."""
    sensor = data["sensor_width"]
    cx = (width - 1) / 2.0 - data["shift_x"] * width
    cy = (height - 1) / 2.0 + data["shift_y"] * width
    if data["type"] == "ORTHO":
        f = width / data["ortho_scale"]
        return Intrinsics(LensModel.ORTHOGRAPHIC, width, height, f, f, cx, cy, sensor_width_mm=sensor)
    if data["type"] == "PANO" and data["panorama_type"] == "FISHEYE_EQUISOLID":
        f = data["fisheye_lens"] * width / sensor
        return Intrinsics(LensModel.FISHEYE_EQUISOLID, width, height, f, f, (width - 1) / 2, (height - 1) / 2,
                          fov_deg=math.degrees(data["fisheye_fov"]), sensor_width_mm=sensor)
    if data["type"] == "PANO" and data["panorama_type"] == "FISHEYE_LENS_POLYNOMIAL" and data["k1"] < 0:
        f = width / (-data["k1"] * sensor)
        return Intrinsics(LensModel.FISHEYE_EQUIDISTANT, width, height, f, f, (width - 1) / 2, (height - 1) / 2,
                          fov_deg=math.degrees(data["fisheye_fov"]), sensor_width_mm=sensor)
    if data["type"] == "PANO" and data["panorama_type"] == "FISHEYE_EQUIDISTANT":
        # Blender's own equidistant fisheye fits the image circle to the sensor width.
        f = width / data["fisheye_fov"]
        return Intrinsics(LensModel.FISHEYE_EQUIDISTANT, width, height, f, f, (width - 1) / 2, (height - 1) / 2,
                          fov_deg=math.degrees(data["fisheye_fov"]), sensor_width_mm=sensor)
    f = data["lens"] * width / sensor
    return Intrinsics(LensModel.PERSPECTIVE, width, height, f, f, cx, cy, sensor_width_mm=sensor)
