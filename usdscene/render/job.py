"""The jobs handed from the parent process to a Blender worker: typed, frozen, no pxr, no bpy.

Four kinds, one per thing a worker does:

- :class:`RenderJob`: one shard of a render call: the stage to import and the prims it needs,
  the objects with their mask ids and the frames where they are visible, the cameras with
  intrinsics and per-frame poses, the render settings and the ordered (frame, camera) pairs
  to render. The worker never opens the stage with pxr: everything it must know besides the
  geometry is in here.
- :class:`BlendJob`: the whole stage written as a Blender project for camera design.
- :class:`BlendToUsdJob` and :class:`InspectBlendJob`: a .blend exported to USD (``usdscene
  assets add``), and read back with its cameras and presence (``scene_from_blend``).
- :class:`BakeWorldJob`: a document's world alone rendered into an equirectangular image.

The parent builds them (:func:`usdscene.render.shards.shard_job`,
:func:`usdscene.render.blend_io.write_blend` ...), the executors add the machine-specific
fields (``out_dir``, ``scratch_dir``, ``parent_pid``) with :func:`dataclasses.replace`, and the
worker reads fields. JSON exists only at the process boundary: :func:`to_json` writes a job
file and :func:`from_json` reads one, both here. A file with a field this version does not
know, or without one it needs (written by another usdscene version), is refused with one
message naming the field.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import asdict, dataclass
from functools import cached_property
from typing import Any, Mapping

from usdscene.document.model import Intrinsics, LensModel, Pose, cv_pose_to_usd_pose
from usdscene.errors import RenderError


def intrinsics_to_json(intr: Intrinsics) -> dict[str, Any]:
    """Intrinsics as JSON values for a worker job (the lens model by name)."""
    data = asdict(intr)
    data["lens"] = LensModel(intr.lens).value
    data["distortion"] = list(intr.distortion)
    return data


def intrinsics_from_json(data: Mapping[str, Any]) -> Intrinsics:
    """Inverse of :func:`intrinsics_to_json`."""
    values = dict(data)
    values["lens"] = LensModel(values["lens"])
    values["distortion"] = tuple(values.get("distortion", ()))
    return Intrinsics(**values)


def usd_camera_matrix(pose_cv_rowmajor) -> list[list[float]]:
    """4x4 camera → world matrix in Blender/USD camera axes (looking down -Z) of an OpenCV-axes
    camera pose given as 16 row-major numbers."""
    return cv_pose_to_usd_pose(Pose(tuple(pose_cv_rowmajor))).as_array().tolist()


@dataclass(frozen=True)
class JobObject:
    """One labelled object of a job.

    Attributes:
        uid: the object's document uid (``usdscene_uid`` of its Blender objects).
        mask_id: its value in the masks (Blender ``pass_index``), 1..65535.
        prim: its prim path in the stage.
        visible_frames: frames where it is present (those of the job only, ascending).
        pose_frames: for an object whose pose changes per frame: pose variant name → the
            frames that variant shows; None for every other object.
    """

    uid: str
    mask_id: int
    prim: str
    visible_frames: tuple[int, ...]
    pose_frames: Mapping[str, frozenset[int]] | None = None

    @classmethod
    def of(cls, planned, frames: frozenset[int] | None = None) -> "JobObject":
        """The job object of a stage plan's object (:class:`usdscene.render.stage_reader.PlannedObject`),
        its frames cut to ``frames`` (None: all of them)."""
        def keep(fs):
            return tuple(f for f in fs if frames is None or f in frames)

        return cls(planned.uid, planned.mask_id, planned.prim_path, keep(planned.visible_frames),
                   {v: frozenset(keep(fs)) for v, fs in planned.pose_frames} if planned.pose_frames else None)

    @cached_property
    def visible(self) -> frozenset[int]:
        """:attr:`visible_frames` as a set (presence is looked up per frame)."""
        return frozenset(self.visible_frames)

    def _to_json(self) -> dict:
        data = {"uid": self.uid, "mask_id": self.mask_id, "prim": self.prim, "visible_frames": list(self.visible_frames)}
        if self.pose_frames is not None:
            data["pose_frames"] = {v: sorted(fs) for v, fs in self.pose_frames.items()}
        return data

    @classmethod
    def _from_json(cls, data: Mapping, where: str) -> "JobObject":
        values = _checked_fields(cls, data, where)
        values["visible_frames"] = tuple(int(f) for f in values["visible_frames"])
        if values.get("pose_frames") is not None:
            values["pose_frames"] = {str(v): frozenset(int(f) for f in fs) for v, fs in values["pose_frames"].items()}
        return cls(**values)


@dataclass(frozen=True)
class JobCamera:
    """One camera of a job.

    Attributes:
        intrinsics: the calibrated lens of the output images (pixels of the delivered image).
        render_intrinsics: the native lens Blender renders (a wider undistorted view for
            OpenCV models, remapped to ``intrinsics`` afterwards; equal to it otherwise).
        pose: camera → world, OpenCV axes, 16 row-major numbers (metres), when no per-frame
            pose is given.
        poses: frame → pose (as ``pose``) for the job's frames where the camera moves.
        clip_m: near and far clipping distances, metres.
        sensor: the camera's sensor as the stage stores it (``{"sensor": ..., "seed": ...}``,
            :mod:`usdscene.document.imaging`); None for a clean image.
    """

    intrinsics: Intrinsics
    render_intrinsics: Intrinsics
    pose: tuple[float, ...]
    poses: Mapping[int, tuple[float, ...]]
    clip_m: tuple[float, float]
    sensor: Mapping[str, Any] | None = None

    def pose_at(self, frame: int) -> tuple[float, ...]:
        """The pose (16 row-major numbers, OpenCV axes) at ``frame``."""
        return self.poses.get(frame, self.pose)

    @property
    def remapped(self) -> bool:
        """The render is remapped to the output lens (an OpenCV model rendered undistorted)."""
        return self.render_intrinsics != self.intrinsics

    def to_json(self) -> dict:
        """JSON values (also what the render manifest's fingerprint holds of a camera)."""
        data = {"intrinsics": intrinsics_to_json(self.intrinsics),
                "render_intrinsics": intrinsics_to_json(self.render_intrinsics),
                "pose": list(self.pose), "poses": {str(f): list(p) for f, p in self.poses.items()},
                "clip_m": list(self.clip_m)}
        # Only cameras with a sensor carry the key: the manifest fingerprint of the others
        # stays what it was before sensors existed.
        if self.sensor is not None:
            data["sensor"] = self.sensor
        return data

    @classmethod
    def _from_json(cls, data: Mapping, where: str) -> "JobCamera":
        values = _checked_fields(cls, data, where)
        values["intrinsics"] = intrinsics_from_json(values["intrinsics"])
        values["render_intrinsics"] = intrinsics_from_json(values["render_intrinsics"])
        values["pose"] = tuple(float(v) for v in values["pose"])
        values["poses"] = {int(f): tuple(float(v) for v in p) for f, p in values["poses"].items()}
        values["clip_m"] = tuple(float(v) for v in values["clip_m"])
        return cls(**values)


@dataclass(frozen=True, kw_only=True)
class _WorkerJob:
    """Fields every job has: those an executor sets at the process boundary.

    Attributes:
        scratch_dir: the worker's scratch folder (its EXR and display images), None until set.
        parent_pid: the process that started the worker; the worker dies with it (Linux).
    """

    scratch_dir: str | None = None
    parent_pid: int | None = None


@dataclass(frozen=True, kw_only=True)
class _SceneJob(_WorkerJob):
    """Fields of the jobs that import a stage into a Blender scene (:class:`RenderJob`,
    :class:`BlendJob`).

    Attributes:
        stage: path of the stage's root layer.
        prim_path_mask: the prims to import, comma-separated (Blender's ``prim_path_mask``).
        settings: the render settings (:func:`usdscene.render.driver.resolve_settings`).
        objects: the labelled objects to show.
        cameras: camera name → camera.
        out_dir: output folder; None until the executor sets it.
        world: the stage's world (:func:`usdscene.document.imaging.world_stage_json` decoded),
            None for the black world of a stage without one.
    """

    stage: str
    prim_path_mask: str
    settings: Mapping[str, Any]
    objects: tuple[JobObject, ...]
    cameras: Mapping[str, JobCamera]
    out_dir: str | None = None
    world: Mapping[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class RenderJob(_SceneJob):
    """One render shard (see the module docstring).

    Attributes:
        pairs: the (frame, camera) pairs to render, in order.
        threads: Cycles threads (None: all cores).
        keep_clean: sensor cameras also write the image before the sensor's effects.
    """

    pairs: tuple[tuple[int, str], ...]
    threads: int | None = None
    keep_clean: bool = False


@dataclass(frozen=True, kw_only=True)
class BlendJob(_SceneJob):
    """A Blender project of a whole stage for camera design.

    Attributes:
        blend: the .blend path to write.
        frame_start, frame_end: the stage's frame range (closed).
        document: the scene's OpenLABEL document as compact JSON text, kept in the .blend;
            None when the stage route cannot read it.
    """

    blend: str
    frame_start: int
    frame_end: int
    document: str | None = None


@dataclass(frozen=True, kw_only=True)
class BlendToUsdJob(_WorkerJob):
    """A .blend exported to a USD file for ``usdscene assets add``.

    Attributes:
        blend: the .blend path to open.
        usd: the USD file to write.
    """

    blend: str
    usd: str


@dataclass(frozen=True, kw_only=True)
class InspectBlendJob(_WorkerJob):
    """A .blend exported to USD with its cameras, presence and document dumped as JSON.

    Attributes:
        blend: the .blend path to open.
        usd: the USD file to write.
        json: the JSON file to write (cameras, presence, object matrices, the document).
    """

    blend: str
    usd: str
    json: str


@dataclass(frozen=True, kw_only=True)
class BakeWorldJob(_WorkerJob):
    """A document's world rendered alone into an equirectangular radiance image.

    Attributes:
        world: the stage's world, as in a render job.
        frame: the frame whose per-frame values of the world apply.
        size_px: (width, height) of the image, pixels.
        samples: Cycles samples per pixel.
        out: the ``.hdr`` path to write.
    """

    world: Mapping[str, Any]
    frame: int
    size_px: tuple[int, int]
    samples: int
    out: str


# The job file's "mode" → its kind (the names job files had before they were typed).
JOB_KINDS: dict[str, type] = {"render": RenderJob, "blend": BlendJob, "export_usd": BlendToUsdJob,
                              "inspect_blend": InspectBlendJob, "bake_world": BakeWorldJob}
_MODES = {kind: mode for mode, kind in JOB_KINDS.items()}
_ANOTHER_VERSION = "the job was written by another usdscene version than the worker's"


def _checked_fields(cls, data: Mapping, where: str) -> dict:
    """``data``'s values of ``cls``'s fields, every field without a default present.

    Raises:
        RenderError: an unknown field, or a missing one (the first of each, sorted).
    """
    if not isinstance(data, Mapping):
        raise RenderError(f"expected a JSON object, got {type(data).__name__}; {_ANOTHER_VERSION}?", where=where)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise RenderError(f"unknown field {unknown[0]!r} in a {cls.__name__}; {_ANOTHER_VERSION}?", where=where)
    missing = sorted(name for name, f in fields.items() if name not in data
                     and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)
    if missing:
        raise RenderError(f"a {cls.__name__} needs the field {missing[0]!r}; {_ANOTHER_VERSION}?", where=where)
    return dict(data)


def to_json(job) -> str:
    """The job file's text of ``job`` (any kind): one JSON object with its ``mode``; fields
    left at None (and a false ``keep_clean``) are left out."""
    data: dict[str, Any] = {"mode": _MODES[type(job)]}
    for field in dataclasses.fields(job):
        value = getattr(job, field.name)
        if value is None or (field.name == "keep_clean" and not value):
            continue
        if field.name == "objects":
            value = [o._to_json() for o in value]
        elif field.name == "cameras":
            value = {name: cam.to_json() for name, cam in value.items()}
        elif isinstance(value, tuple):
            value = [list(v) if isinstance(v, tuple) else v for v in value]
        data[field.name] = value
    return json.dumps(data)


def from_json(text: str, where: str = "job") -> Any:
    """The job of a job file's text (inverse of :func:`to_json`).

    Raises:
        RenderError: not JSON, an unknown mode, or a field unknown or missing (a job file of
            another usdscene version); the message names it, ``where`` says which file.
    """
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RenderError(f"not a job file (JSON): {exc}", where=where) from None
    if not isinstance(data, dict):
        raise RenderError(f"not a job file: expected a JSON object, got {type(data).__name__}", where=where)
    mode = data.pop("mode", "render")
    kind = JOB_KINDS.get(mode)
    if kind is None:
        raise RenderError(f"unknown job mode {mode!r}; known: {sorted(JOB_KINDS)}; {_ANOTHER_VERSION}?", where=where)
    values = _checked_fields(kind, data, where)
    if "objects" in values:
        values["objects"] = tuple(JobObject._from_json(o, f"{where}: objects[{i}]")
                                  for i, o in enumerate(values["objects"]))
    if "cameras" in values:
        values["cameras"] = {name: JobCamera._from_json(c, f"{where}: cameras.{name}")
                             for name, c in values["cameras"].items()}
    if "pairs" in values:
        values["pairs"] = tuple((int(f), str(c)) for f, c in values["pairs"])
    if "size_px" in values:
        values["size_px"] = tuple(int(v) for v in values["size_px"])
    return kind(**values)
