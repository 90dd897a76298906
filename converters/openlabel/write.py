""":class:`usdscene.document.model.SceneSpec` → OpenLABEL 1.0.0 document. Pure module.

The output validates against the official OpenLABEL 1.0.0 JSON schema, serialises with
``allow_nan=False`` and reads back into an equal scene (``read_openlabel(write_openlabel(s))
== s`` except ``provenance``, which always describes the document actually read).

Normal form (what ``usdscene convert`` writes):

* one root coordinate system ``world`` (``scene_cs``; renamed ``world_1``... if a camera is
  called ``world``) with one ``sensor_cs`` per camera whose ``pose_wrt_parent`` is a
  ``matrix4x4``; per-frame camera poses are ``frames[f].frame_properties.transforms``
  ``<camera>_to_world`` (``src`` the camera, ``dst`` the world: X_world = M · X_camera);
* calibrations in the schema dialect (``camera_matrix``, ``distortion_coeffs``,
  ``lens_coeffs``, ``center_x_px``) plus the ``usdscene`` block that names the lens model;
* poses of lights and objects as the vec ``pose_matrix4x4`` (exact; no angle round-off);
* ``object_data_pointers`` for every object data entry, closed frame intervals, and the root
  ``frame_intervals`` as the union of the scene range and every element's intervals;
* what the scene carries for others (the ``extra`` fields, ``openlabel_carry``) merged back
  unchanged: their object data after usdscene's, their streams, actions, events, ...
"""

from __future__ import annotations

import logging
import os
from typing import Any, Iterable, Mapping

from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import (
    FrameInterval,
    Light,
    PlaceRef,
    Pose,
    RenderSettings,
    SceneObject,
    SceneSpec,
    extra_data,
    union_intervals,
)

from usdscene.converters.openlabel.carry import merge_element, merge_scene, merge_stream
from usdscene.converters.openlabel.load import SCHEMA_VERSION
from usdscene.lens import lens_for
from usdscene.converters.openlabel.objects import LIGHT_TYPE, PLACE_TYPE, UID_PATTERN

log = logging.getLogger(__name__)



def _matrix(pose: Pose) -> list[float]:
    return [float(v) for v in pose.matrix]


def _intervals(intervals: Iterable[FrameInterval]) -> list[dict]:
    return [{"frame_start": int(iv.frame_start), "frame_end": int(iv.frame_end)} for iv in intervals]


def _frames_to_intervals(frames: Iterable[int]) -> tuple[FrameInterval, ...]:
    return union_intervals(FrameInterval(f, f) for f in frames)


def write_openlabel(scene: SceneSpec) -> dict:
    """Write ``scene`` as an OpenLABEL 1.0.0 document.

    Args:
        scene: the scene; its uids must be integer strings or UUIDs (the schema's rule).

    Returns:
        ``{"openlabel": {...}}``: plain JSON data (dicts, lists, str, int, float, bool).

    Raises:
        DocumentError: the scene cannot be written as valid OpenLABEL (bad or duplicate uids,
            negative frame numbers in per-frame data, non-finite numbers, a distortion
            vector of a length the lens model does not have).
    """
    problems = ProblemCollector()
    body: dict[str, Any] = {"metadata": _metadata(scene)}
    frames: dict[int, dict] = {}  # frame → its per-frame content, filled by every step
    if scene.cameras:
        body["coordinate_systems"], body["streams"] = _cameras(scene, frames, problems)
    uid_map = openlabel_uids([*(e.uid for e in scene.lights), *(e.uid for e in scene.places),
                              *(e.uid for e in scene.objects)])
    owners: dict[str, str] = {}  # uid → what it names, for duplicates and relations
    objects = _elements(scene, uid_map, owners, frames, problems)
    if objects:
        body["objects"] = objects
    relations = _relations(scene, uid_map, owners, problems)
    if relations:
        body["relations"] = relations
    _timestamps(scene, frames)
    if scene.extra:
        merge_scene(body, frames, scene.extra, problems)
    if frames:
        body["frames"] = {str(f): frames[f] for f in sorted(frames)}
    body["frame_intervals"] = _intervals(_document_intervals(scene, frames))
    problems.raise_if_any(DocumentError)
    return {"openlabel": body}


def _cameras(scene: SceneSpec, frames: dict[int, dict], problems: ProblemCollector) -> tuple[dict, dict]:
    """``(coordinate_systems, streams)`` of the cameras: a world root (named apart from every
    camera) with one sensor system per camera, one stream each; per-frame camera poses go into
    ``frames`` as transforms."""
    names = {c.name for c in scene.cameras}
    root = "world"
    index = 1
    while root in names:
        root = f"world_{index}"
        index += 1
    systems: dict[str, Any] = {root: {"type": "scene_cs", "parent": "", "children": [c.name for c in scene.cameras]}}
    streams: dict[str, Any] = {}
    for cam in scene.cameras:
        systems[cam.name] = {"type": "sensor_cs", "parent": root, "children": [],
                             "pose_wrt_parent": {"matrix4x4": _matrix(cam.pose)}}
        streams[cam.name] = {"type": "camera", "description": cam.description, "uri": "",
                             "stream_properties": _calibration(cam, problems)}
        if cam.extra:
            merge_stream(streams[cam.name], cam.extra)
        for frame, pose in cam.frame_poses:
            if frame < 0:
                problems.add(f"cameras.{cam.name}.frame_poses", f"frame {frame} is negative")
                continue
            transforms = frames.setdefault(frame, {}).setdefault("frame_properties", {}).setdefault("transforms", {})
            transforms[f"{cam.name}_to_{root}"] = {"src": cam.name, "dst": root,
                                                   "transform_src_to_dst": {"matrix4x4": _matrix(pose)}}
    return systems, streams


def _elements(scene: SceneSpec, uid_map: dict[str, str], owners: dict[str, str], frames: dict[int, dict],
              problems: ProblemCollector) -> dict[str, Any]:
    """The ``objects`` section: lights, places, then dynamic objects, each uid once (a uid
    used twice is a problem; ``owners`` records who holds each)."""
    def claim(uid: str, what: str) -> bool:
        if uid in owners:
            problems.add(f"{what}.uid", f"uid {uid!r} is also used by {owners[uid]}")
            return False
        owners[uid] = what
        return True

    objects: dict[str, Any] = {}
    for light in scene.lights:
        if claim(light.uid, f"lights.{light.name}"):
            objects[uid_map[light.uid]] = _light_element(light)
    for place in scene.places:
        if claim(place.uid, f"places.{place.name}"):
            objects[uid_map[place.uid]] = _place_element(place)
    for obj in scene.objects:
        if claim(obj.uid, f"objects.{obj.uid}"):
            objects[uid_map[obj.uid]] = _object_element(obj, uid_map[obj.uid], frames, problems)
    return objects


def _light_element(light: Light) -> dict:
    """A light as an object of type ``light`` with its kind, power, size, colour and pose."""
    data = _Data()
    data.add("text", "kind", light.kind.value)
    for key in ("power_w", "radius_m", "spot_angle_deg", "spot_blend", "sun_angle_deg"):
        data.add("num", key, float(getattr(light, key)))
    data.add("vec", "color_rgb", [float(v) for v in light.color_rgb])
    data.add("vec", "size_m", [float(v) for v in light.size_m])
    data.add("vec", "pose_matrix4x4", _matrix(light.pose))
    return _element(light.name, LIGHT_TYPE, light.frame_intervals, data)


def _place_element(place: PlaceRef) -> dict:
    """A place as an object of type ``place``; regions it declares itself as cuboids named by
    their relation."""
    element: dict[str, Any] = {"name": place.name, "type": PLACE_TYPE}
    if place.regions:
        element["object_data"] = {"cuboid": [{"name": r.relation, "val": r.to_cuboid()} for r in place.regions]}
    merge_element(element, place.extra)
    return element


def _object_element(obj: SceneObject, key: str, frames: dict[int, dict], problems: ProblemCollector) -> dict:
    """A dynamic object: appearance, colour, randomization knobs and pose as static data;
    per-frame poses and carried per-frame content into ``frames`` under ``key`` (its uid in
    the document)."""
    data = _Data()
    if obj.appearance is not None:
        data.add("text", "appearance", obj.appearance)
    if obj.pose_variant is not None:
        data.add("text", "pose_variant", obj.pose_variant)
    if obj.color_rgb is not None:
        data.add("vec", "color_rgb", [float(v) for v in obj.color_rgb])
    knobs = obj.randomization
    if knobs.position_noise_m:
        data.add("num", "position_noise_m", float(knobs.position_noise_m))
    if knobs.rotation_noise_deg:
        data.add("num", "rotation_noise_deg", float(knobs.rotation_noise_deg))
    if knobs.random_color:
        data.add("boolean", "random_color", True)
    if knobs.random_appearance:
        data.add("boolean", "random_appearance", True)
    if obj.pose is not None:
        data.add("vec", "pose_matrix4x4", _matrix(obj.pose))
    element = _element(obj.name, obj.class_name, obj.frame_intervals, data)
    if obj.frame_poses:
        for frame, pose in obj.frame_poses:
            if frame < 0:
                problems.add(f"objects.{obj.uid}.frame_poses", f"frame {frame} is negative")
                continue
            entry = frames.setdefault(frame, {}).setdefault("objects", {})
            entry[key] = {"object_data": {"vec": [{"name": "pose_matrix4x4", "val": _matrix(pose)}]}}
        pointers = element.setdefault("object_data_pointers", {})
        pointers["pose_matrix4x4"] = {
            "type": "vec",
            "frame_intervals": _intervals(_frames_to_intervals(f for f, _ in obj.frame_poses if f >= 0))}
    if obj.extra:
        merge_element(element, obj.extra)
    for frame, text in obj.frame_extra:
        if frame < 0:
            problems.add(f"objects.{obj.uid}.frame_extra", f"frame {frame} is negative")
            continue
        merge_element(frames.setdefault(frame, {}).setdefault("objects", {}).setdefault(key, {}), text)
    return element


def _relations(scene: SceneSpec, uid_map: dict[str, str], owners: Mapping[str, str],
               problems: ProblemCollector) -> dict[str, Any]:
    """The ``relations`` section; a relation whose subject or object is no element of the
    scene (``owners``) is a problem."""
    relation_uids = openlabel_uids([r.uid for r in scene.relations])
    relations: dict[str, Any] = {}
    for rel in scene.relations:
        if relation_uids[rel.uid] in relations:
            problems.add(f"relations.{rel.uid}.uid", f"duplicate relation uid {rel.uid!r}")
            continue
        dangling = [(side, uid) for side, uid in (("subject_uid", rel.subject_uid), ("object_uid", rel.object_uid))
                    if uid not in owners]
        for side, uid in dangling:
            problems.add(f"relations.{rel.uid}.{side}", f"relation {rel.uid} refers to {uid!r}, which is "
                                                        f"not a light, place or object of the scene")
        if dangling:
            continue
        carried = extra_data(rel.extra)
        entry: dict[str, Any] = {"name": carried.pop("name", ""), "type": rel.type,
                                 "rdf_subjects": [{"uid": uid_map[rel.subject_uid], "type": "object"}],
                                 "rdf_objects": [{"uid": uid_map[rel.object_uid], "type": "object"}]}
        if rel.frame_intervals:
            entry["frame_intervals"] = _intervals(rel.frame_intervals)
        entry.update((key, value) for key, value in carried.items() if key not in entry)
        relations[relation_uids[rel.uid]] = entry
    return relations


def _document_intervals(scene: SceneSpec, frames: Mapping[int, dict]) -> list[FrameInterval]:
    """The root ``frame_intervals``: the scene's range united with every element's and every
    frame that holds content."""
    every = [FrameInterval(scene.frame_start, scene.frame_end)]
    for element in (*scene.lights, *scene.objects, *scene.relations):
        every.extend(element.frame_intervals)
    every.extend(FrameInterval(f, f) for f in frames)
    return union_intervals(every)


def _timestamps(scene: SceneSpec, frames: dict[int, dict]) -> None:
    """A moving sequence (``fps`` given): every frame of the scene's range carries its OpenLABEL
    ``frame_properties.timestamp`` in seconds."""
    if scene.fps is None:
        return
    for frame in scene.frames:
        if frame >= 0:
            props = frames.setdefault(frame, {}).setdefault("frame_properties", {})
            props["timestamp"] = frame_timestamp(frame, scene.fps)


def frame_timestamp(frame: int, fps: float) -> float:
    """OpenLABEL ``timestamp`` of a frame: seconds since frame 0, ``frame / fps``."""
    return float(frame) / float(fps)


def openlabel_uids(uids: Iterable[str]) -> dict[str, str]:
    """uid → the uid written to OpenLABEL.

    The schema only allows integer strings and UUIDs as element keys. Such uids are kept;
    any other uid (e.g. ``"backpack_003"`` from a scene built in code) gets the smallest
    unused non-negative integer, in scene order, so the same scene always gets the same
    numbers. Element names are written unchanged. Duplicates map to the first assignment
    (the caller reports them).
    """
    uids = list(uids)
    used = {u for u in uids if isinstance(u, str) and UID_PATTERN.match(u)}
    out: dict[str, str] = {}
    counter = 0
    for uid in uids:
        if uid in out:
            continue
        if uid in used:
            out[uid] = uid
            continue
        while str(counter) in used:
            counter += 1
        out[uid] = str(counter)
        used.add(str(counter))
    if any(k != v for k, v in out.items()):
        log.info("uids that are not integers or UUIDs were renumbered for OpenLABEL: %s",
                 {k: v for k, v in out.items() if k != v})
    return out


class _Data:
    """object_data under construction, with its pointers (names are unique per element)."""

    def __init__(self) -> None:
        self.data: dict[str, list] = {}
        self.pointers: dict[str, dict] = {}

    def add(self, kind: str, name: str, value: Any) -> None:
        self.data.setdefault(kind, []).append({"name": name, "val": value})
        self.pointers[name] = {"type": kind, "frame_intervals": []}


def _element(name: str, otype: str, intervals, data: _Data) -> dict:
    element: dict[str, Any] = {"name": name, "type": otype}
    if intervals:
        element["frame_intervals"] = _intervals(intervals)
    if data.data:
        element["object_data"] = data.data
        element["object_data_pointers"] = data.pointers
    return element


def _metadata(scene: SceneSpec) -> dict:
    render: RenderSettings = scene.render
    block: dict[str, Any] = {"seed": int(scene.seed)}
    if scene.environment is not None:
        block["environment"] = scene.environment
    block["asset_paths"] = list(scene.asset_paths)
    block["render"] = {
        "engine": render.engine, "device": render.device, "samples": int(render.samples),
        "adaptive_threshold": float(render.adaptive_threshold), "denoise": bool(render.denoise),
        "denoiser": render.denoiser, "denoising_quality": render.denoising_quality,
        "denoising_prefilter": render.denoising_prefilter,
        "denoising_input_passes": render.denoising_input_passes,
        "adaptive_min_samples": int(render.adaptive_min_samples), "light_tree": bool(render.light_tree),
        "path_guiding": bool(render.path_guiding), "clamp_indirect": float(render.clamp_indirect),
        "sampling_pattern": render.sampling_pattern,
        "fast_gi": bool(render.fast_gi), "fast_gi_method": render.fast_gi_method,
        "fast_gi_ao_bounces": int(render.fast_gi_ao_bounces), "fast_gi_distance_m": float(render.fast_gi_distance_m),
        "scrambling_distance": float(render.scrambling_distance),
        "auto_scrambling_distance": bool(render.auto_scrambling_distance),
        "max_bounces": int(render.max_bounces), "caustics": bool(render.caustics),
        "tile_size_px": int(render.tile_size_px), "resolution_px": [int(v) for v in render.resolution_px],
        "seed": int(render.seed)}
    if render.depth is not None:  # absent when off: documents without depth keep their bytes
        block["render"]["depth"] = render.depth
    block["exports"] = list(scene.exports)
    block["roi_rules"] = dict(scene.roi_rules)
    if scene.roi_ignore:
        block["roi_ignore"] = list(scene.roi_ignore)
    if scene.split_rule:
        block["split"] = {"rule": scene.split_rule, "seed": int(scene.split_seed)}
    block["frame_range"] = {"frame_start": int(scene.frame_start), "frame_end": int(scene.frame_end)}
    if scene.fps is not None:
        block["fps"] = float(scene.fps)
    if scene.world is not None:
        from usdscene.converters.openlabel.imaging import world_json

        block["world"] = world_json(scene.world)
    meta: dict[str, Any] = {"schema_version": SCHEMA_VERSION, "name": scene.name}
    if scene.description:
        meta["comment"] = scene.description
    meta["usdscene"] = block
    return meta


def _calibration(cam, problems: ProblemCollector) -> dict:
    """stream_properties of a camera: the calibration that reproduces its image + the usdscene
    block that names the exact lens model."""
    k = cam.intrinsics
    where = f"cameras.{cam.name}.intrinsics"
    friendly: dict[str, Any] = {"model": k.lens.value,
                                "sensor_size_mm": [float(k.sensor_width_mm), float(k.sensor_height_mm)]}
    props: dict[str, Any] = {}
    size = {"width_px": int(k.width_px), "height_px": int(k.height_px)}
    lens = lens_for(k)
    props.update(lens.openlabel_calibration(k, size, where, problems))
    if lens.radial and k.fov_deg is not None:
        friendly["fov_deg"] = float(k.fov_deg)
    if cam.model_name:
        friendly["model_name"] = cam.model_name
    friendly["clip_range_m"] = [float(cam.clip_near_m), float(cam.clip_far_m)]
    if cam.custom:
        friendly["custom"] = dict(cam.custom)
    if cam.sensor is not None:
        from usdscene.converters.openlabel.imaging import sensor_json

        friendly["sensor"] = sensor_json(cam.sensor)
    props["usdscene"] = friendly
    return props


def write_document(path: str | os.PathLike, document: dict, *, schema: str | os.PathLike | None = None):
    """Write a document atomically as canonical JSON (:func:`document_text`: 2-space indent, one
    line per frame, no NaN/Infinity).

    Args:
        path: the file.
        document: the ``{"openlabel": ...}`` document.
        schema: official schema file the document must pass first (None: no check); usdscene
            never writes an output document that the official schema rejects.

    Raises:
        DocumentError: the document holds a non-finite number or a value JSON cannot hold.
        OutputError: the document fails ``schema`` (every violation listed).
        Nothing is written in either case.
    """
    from usdscene.errors import OutputError
    from usdscene.files import write_text_atomic

    if schema is not None:
        from usdscene.converters.openlabel.checks import schema_problems

        problems = schema_problems(document, schema)
        if problems:
            raise OutputError(problems)

    try:
        return write_text_atomic(path, document_text(document))
    except (ValueError, TypeError) as exc:
        raise DocumentError(f"cannot write the document as JSON: {exc}", where=str(path)) from None


def document_text(document: dict) -> str:
    """The JSON text :func:`write_document` writes: 2-space indent, except that each entry of
    ``openlabel.frames`` is one line without spaces (``"<frame>": {...}``).

    Per-frame data is most of a long sequence's document (poses of every person on every frame);
    indented, its whitespace and line breaks were two thirds of the bytes. One line per frame
    is the same JSON value (any reader loads it), a third of the size, and a tool can read or
    ``grep`` a frame by its line.

    Raises:
        ValueError: a NaN or infinite float. TypeError: a value JSON cannot hold.
    """
    from usdscene.files import dumps_json

    body = document.get("openlabel") if isinstance(document, dict) else None
    frames = body.get("frames") if isinstance(body, dict) else None
    if not isinstance(frames, dict) or not frames:
        return dumps_json(document)
    head = dumps_json({**document, "openlabel": {**body, "frames": {}}})
    marker = '\n    "frames": {}'
    assert head.count(marker) == 1  # the body's own keys are the only ones at this indent
    lines = ",\n".join(frame_line(key, value) for key, value in frames.items())
    return head.replace(marker, '\n    "frames": {\n' + lines + "\n    }")


def frame_line(key, frame: dict) -> str:
    """One entry of ``openlabel.frames`` as :func:`document_text` writes it (no line break):
    ``      "<key>": {...}``, the frame without spaces.

    Raises:
        ValueError: a NaN or infinite float. TypeError: a value JSON cannot hold.
    """
    import json

    return (f"      {json.dumps(str(key), ensure_ascii=False)}: "
            f"{json.dumps(frame, ensure_ascii=False, allow_nan=False, separators=(',', ':'))}")
