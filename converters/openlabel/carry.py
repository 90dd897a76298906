"""Other people's data: what a document holds that the scene model does not represent. Pure module.

A converted document must not lose the annotations it came with. The reader keeps what it
reads past as canonical JSON text in the ``extra`` fields of :class:`usdscene.document.model.SceneSpec`,
:class:`~usdscene.document.model.Camera`, :class:`~usdscene.document.model.SceneObject`,
:class:`~usdscene.document.model.PlaceRef` and :class:`~usdscene.document.model.Relation`
(:func:`usdscene.document.model.canonical_json`), the writer merges it back unchanged, and the
composed stage keeps it (``usdscene.scene.compose``, read back by ``usdscene.converters.stage.usd_stage``):

* per object: object data of names outside usdscene's vocabulary (bboxes, cuboids, poly2d, a
  vec ``Position``, ...), their ``object_data_pointers``, other keys of the element
  (``coordinate_system``, ``ontology_uid``, ...), and the same of ``frames[f].objects[uid]``;
* per relation between two objects: keys of the element usdscene does not read (a ``name``
  that is not empty, ``ontology_uid``, ``resource_uid``, ...);
* per camera stream: keys of the stream and of its ``stream_properties`` that usdscene does
  not read (``uri``, ``sync``, ...);
* per scene: ``metadata`` keys other than ``schema_version``, ``name``, ``comment`` and
  ``usdscene``; streams that are not cameras usdscene reads; ``actions``, ``events``,
  ``contexts``, ``ontologies``, ``resources``, ``tags``; relations the scene does not model;
  per frame everything but object poses and coordinate-system transforms.

Coordinate systems are not carried: the writer's normal form replaces them by one world
system with the cameras under it (camera poses are resolved through the original chain).
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping

from usdscene.document.model import Camera, Relation, canonical_json, extra_data

# Keys the readers consume; everything else is carried.
OBJECT_KEYS = frozenset({"name", "type", "frame_intervals", "object_data", "object_data_pointers"})
FRAME_OBJECT_KEYS = frozenset({"object_data"})
RELATION_KEYS = frozenset({"type", "rdf_subjects", "rdf_objects", "frame_intervals"})
STREAM_KEYS = frozenset({"type", "description", "stream_properties"})
CAMERA_PROPERTY_KEYS = frozenset({"intrinsics_pinhole", "intrinsics_fisheye", "intrinsics_custom", "usdscene"})
METADATA_KEYS = frozenset({"schema_version", "name", "comment", "usdscene"})
ROOT_CARRIED = ("actions", "events", "contexts", "ontologies", "resources", "tags")
FRAME_KEYS = frozenset({"objects", "frame_properties"})
FRAME_PROPERTY_KEYS = frozenset({"transforms"})


def element_residue(element: Mapping, known_data: Mapping[str, str], consumed: frozenset) -> str:
    """What usdscene does not read of an object element (or of a ``frames[f].objects[uid]``
    entry), as canonical JSON text ("" when nothing is left).

    Args:
        element: the element's JSON object.
        known_data: object data names usdscene reads → their kind; items of other names are
            carried, in document order.
        consumed: the element's keys usdscene reads (all but ``object_data``/``object_data_pointers``
            are carried verbatim when not in it).
    """
    out: dict[str, Any] = {key: value for key, value in element.items() if key not in consumed}
    data = element.get("object_data")
    if isinstance(data, dict):
        carried = {}
        for kind, items in data.items():
            kept = [item for item in items if not _is_known(item, known_data)] if isinstance(items, list) else items
            if kept:
                carried[kind] = kept
        if carried:
            out["object_data"] = carried
    pointers = element.get("object_data_pointers")
    if isinstance(pointers, dict):
        kept_pointers = {name: p for name, p in pointers.items() if name not in known_data}
        if kept_pointers:
            out["object_data_pointers"] = kept_pointers
    return canonical_json(out)


def _is_known(item: Any, known_data: Mapping[str, str]) -> bool:
    """Whether an object data item is one usdscene reads (by its name; any JSON may be there)."""
    return isinstance(item, dict) and isinstance(item.get("name"), str) and item["name"] in known_data


def relation_residue(relation: Mapping) -> str:
    """What usdscene does not read of a relation it models: other keys of the element (``name``
    only when not empty, the writer's default), as canonical JSON text ("" when none)."""
    return canonical_json({key: value for key, value in relation.items()
                           if key not in RELATION_KEYS and not (key == "name" and value == "")})


def stream_residue(stream: Mapping) -> str:
    """What usdscene does not read of a camera stream: other keys of the stream (``uri`` only
    when not empty, the writer's default) and of its ``stream_properties``."""
    out = {key: value for key, value in stream.items()
           if key not in STREAM_KEYS and not (key == "uri" and value == "")}
    props = stream.get("stream_properties")
    if isinstance(props, dict):
        kept = {key: value for key, value in props.items() if key not in CAMERA_PROPERTY_KEYS}
        if kept:
            out["stream_properties"] = kept
    return canonical_json(out)


def scene_residue(body: Mapping, frames: Mapping[int, Mapping], cameras: Iterable[Camera],
                  relations: Iterable[Relation]) -> str:
    """The document-level content the scene does not model (see the module docstring), as
    canonical JSON text of a partial OpenLABEL body ("" when nothing is left).

    Args:
        body: the ``openlabel`` object.
        frames: frame number → frame object, as :meth:`DocumentBody.frames` returns them.
        cameras: the cameras that were read (their streams are not carried here).
        relations: the relations that were read (the others are carried).
    """
    out: dict[str, Any] = {}
    meta = body.get("metadata")
    if isinstance(meta, dict):
        kept = {key: value for key, value in meta.items() if key not in METADATA_KEYS}
        if kept:
            out["metadata"] = kept
    read_cameras = {c.name for c in cameras}
    streams = body.get("streams")
    if isinstance(streams, dict):
        kept = {name: s for name, s in streams.items() if name not in read_cameras}
        if kept:
            out["streams"] = kept
    for key in ROOT_CARRIED:
        if body.get(key):
            out[key] = body[key]
    read_relations = {r.uid for r in relations}
    rels = body.get("relations")
    if isinstance(rels, dict):
        kept = {uid: r for uid, r in rels.items() if uid not in read_relations}
        if kept:
            out["relations"] = kept
    # With a stated frame rate the timestamps are f / fps, which the writer derives again.
    usdscene_meta = meta.get("usdscene") if isinstance(meta, dict) else None
    owned_props = (FRAME_PROPERTY_KEYS | {"timestamp"}
                   if isinstance(usdscene_meta, dict) and "fps" in usdscene_meta else FRAME_PROPERTY_KEYS)
    carried_frames = {}
    for number in sorted(frames):
        frame = frames[number]
        kept = {key: value for key, value in frame.items() if key not in FRAME_KEYS and value}
        props = frame.get("frame_properties")
        if isinstance(props, dict):
            kept_props = {key: value for key, value in props.items() if key not in owned_props}
            if kept_props:
                kept["frame_properties"] = kept_props
        if kept:
            carried_frames[str(number)] = kept
    if carried_frames:
        out["frames"] = carried_frames
    return canonical_json(out)


def merge_stream(stream: dict, text: str) -> None:
    """A camera stream's carried keys (``Camera.extra``) into the written stream."""
    carried = extra_data(text)
    stream["stream_properties"].update(
        {k: v for k, v in carried.pop("stream_properties", {}).items() if k not in stream["stream_properties"]})
    stream.update(carried)


def frame_residues(frame_entries: Iterable[tuple[int, Mapping]], known_data: Mapping[str, str]
                   ) -> tuple[tuple[int, str], ...]:
    """``(frame, text)`` of :func:`element_residue` for an object's ``frames[f].objects[uid]``
    entries, leaving out frames with nothing to carry."""
    out = []
    for number, entry in frame_entries:
        text = element_residue(entry, known_data, FRAME_OBJECT_KEYS)
        if text:
            out.append((number, text))
    return tuple(out)


def merge_element(element: dict, text: str) -> None:
    """Merge carried element content (:func:`element_residue` text) into a written element:
    carried object data after usdscene's own of the same kind, pointers and other keys added."""
    carried = extra_data(text)
    for kind, items in carried.pop("object_data", {}).items():
        element.setdefault("object_data", {}).setdefault(kind, []).extend(items)
    if "object_data_pointers" in carried:
        element.setdefault("object_data_pointers", {}).update(carried.pop("object_data_pointers"))
    for key, value in carried.items():
        element.setdefault(key, value)


def merge_scene(body: dict, frames: dict[int, dict], text: str, problems, where: str = "extra") -> None:
    """Merge the scene's carried content into a document under construction.

    Args:
        body: the ``openlabel`` object being written (metadata, streams, relations present).
        frames: frame number → frame object being written (carried frames are merged here so
            that the root ``frame_intervals`` covers them).
        text: :attr:`SceneSpec.extra`.
        problems: a :class:`usdscene.errors.ProblemCollector`; a carried stream or relation
            whose key usdscene also writes is a problem (it would replace one of them).
    """
    carried = extra_data(text)
    for key, value in carried.pop("metadata", {}).items():
        body["metadata"].setdefault(key, value)
    for section in ("streams", "relations"):
        for key, value in carried.pop(section, {}).items():
            target = body.setdefault(section, {})
            if key in target:
                problems.add(f"{where}.{section}.{key}", f"carried {section[:-1]} {key!r} has the key of one "
                                                         f"the scene writes")
                continue
            target[key] = value
    for number, frame in carried.pop("frames", {}).items():
        target = frames.setdefault(int(number), {})
        for key, value in frame.items():
            if key == "frame_properties":
                props = target.setdefault("frame_properties", {})
                for pkey, pvalue in value.items():
                    props.setdefault(pkey, pvalue)
            else:
                target.setdefault(key, value)
    for key, value in carried.items():
        body.setdefault(key, value)

