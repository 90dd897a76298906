""".blend projects for interactive camera design, and back to a SceneSpec.

* :func:`write_blend`: the composed stage as a Blender project: every object (presence
  keyframed, pass index = mask id), one Blender camera per stage camera with its exact
  calibration kept in custom properties, render settings as for ``usdscene render``.
* :func:`scene_from_blend`: a (possibly edited) .blend back to a SceneSpec, through Blender's
  USD export and :func:`usdscene.converters.usd_stage.scene_from_stage`. Blender's USD exporter writes
  only perspective cameras, so cameras (pose per frame and lens) are read from the .blend
  itself. A camera whose Blender lens settings are unchanged keeps its exact calibration
  (including OpenCV distortion); an edited one gets the model of its Blender settings.

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

from usdscene.errors import RenderError
from usdscene.document.model import Camera, FrameInterval, Intrinsics, LensModel, Pose, SceneSpec, usd_pose_to_cv_pose

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
    from usdscene.render.stage_reader import read_stage_plan

    prepare_output_file(blend_path, what="Blender file")
    plan = read_stage_plan(stage_path)
    frames = list(plan.frames)
    job = {
        "mode": "blend",
        "stage": str(plan.stage_path),
        "blend": str(Path(blend_path).resolve()),
        "out_dir": str(Path(blend_path).resolve().parent),
        # Everything but the stage's cameras (the project gets real Blender cameras instead).
        "prim_path_mask": ",".join([*plan.shared_prims, *(o.prim_path for o in plan.objects)])
                          or "/World/__nothing__",
        "settings": resolve_settings(plan.settings, None),
        "objects": [{"uid": o.uid, "mask_id": o.mask_id, "prim": o.prim_path,
                     "visible_frames": list(o.visible_frames),
                     **({"pose_frames": {v: list(fs) for v, fs in o.pose_frames}} if o.pose_frames else {})}
                    for o in plan.objects],
        "cameras": camera_jobs(plan, [c.name for c in plan.cameras], frames),
        "frame_start": plan.frame_start,
        "frame_end": plan.frame_end,
    }
    run_job(job, str(blend_path))
    return Path(blend_path)


def scene_from_blend(path: str | Path) -> SceneSpec:
    """Read a .blend (written by :func:`write_blend`, maybe edited) into a SceneSpec.

    Raises:
        RenderError: the file is missing or Blender failed.
        DocumentError: the exported stage is malformed (from ``scene_from_stage``).
    """
    from usdscene.converters.usd_stage import scene_from_stage

    from usdscene.render.driver import run_job

    path = Path(path)
    if not path.is_file():
        raise RenderError(f".blend file {str(path)!r} not found", where=str(path))
    with tempfile.TemporaryDirectory(prefix="usdscene-blend-") as tmp:
        usd = Path(tmp) / "scene.usda"
        info_path = Path(tmp) / "cameras.json"
        run_job({"mode": "inspect_blend", "blend": str(path.resolve()), "usd": str(usd),
                 "json": str(info_path)}, str(path))
        info = json.loads(info_path.read_text())
        scene = scene_from_stage(usd)
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
    return dataclasses.replace(scene, cameras=cameras, objects=objects, provenance=provenance)


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
