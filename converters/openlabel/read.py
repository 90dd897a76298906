"""OpenLABEL 1.0.0 / VCD 4.3 documents → :class:`usdscene.document.model.SceneSpec`. Pure module.

The vocabulary is documented in ``docs/scene-format.md``. Every problem of a document is
collected with its JSON path (``openlabel.streams.cam_01.stream_properties.usdscene.fov_deg``)
and raised once as a :class:`DocumentError`.

This module ties the section readers together, in this order:

* ``openlabel_load``: the file, JSON, VCD 4.3 → OpenLABEL 1.0.0, provenance;
* ``openlabel_metadata``: name, seed, environment, render settings;
* ``openlabel_cameras`` (with ``openlabel_poses`` and ``openlabel_intrinsics``): camera streams,
  coordinate systems and calibrations;
* ``openlabel_objects``: lights, places and dynamic objects;
* ``openlabel_relations``: relations and per-frame relation markers;
* then the scene's frame range and, with a catalog, the checks against the asset library.

Content that the scene model does not represent is read past without error and kept in the
``extra`` fields for the writer (``openlabel_carry``): non-camera streams, bounding boxes /
cuboids / polygons and other geometric object data, per-frame stream properties (per-frame
intrinsics, sync), actions, events, contexts, tags, ontologies, unknown metadata keys, and
relations that involve actions, events or contexts (their uids are still checked).
"""

from __future__ import annotations

import bisect

import difflib
import os
import re
from typing import TYPE_CHECKING, Iterable, Mapping

from usdscene.bulk import paused_collection
from usdscene.errors import DocumentError, Problem
from usdscene.document.model import PLACEMENT_RELATIONS, FrameInterval, LightKind, Provenance, SceneSpec, union_intervals

from usdscene.converters.openlabel.cameras import read_cameras
from usdscene.converters.openlabel.carry import scene_residue
from usdscene.converters.openlabel.load import DocumentBody, load_with_provenance
from usdscene.converters.openlabel.metadata import read_metadata
from usdscene.converters.openlabel.objects import read_objects
from usdscene.converters.openlabel.relations import check_frame_relations, read_relations
from usdscene.converters.openlabel.values import read_intervals, suggest

if TYPE_CHECKING:
    from usdscene.scene.catalog import Catalog

ROOT_KEYS = frozenset({"metadata", "streams", "coordinate_systems", "objects", "relations", "frames",
                       "frame_intervals", "actions", "events", "contexts", "ontologies", "resources",
                       "tags"})


@paused_collection()  # a document holds up to millions of containers (see usdscene.bulk)
def read_openlabel(source: str | os.PathLike | Mapping, *, catalog: Catalog | None = None) -> SceneSpec:
    """Read a scene document into a :class:`SceneSpec`.

    Args:
        source: path of an OpenLABEL 1.0.0 / VCD 4.3 JSON file, or the parsed document.
        catalog: a :class:`usdscene.scene.catalog.Catalog`; when given, object classes, place names
            and placement relations are checked against it. Without one those checks are
            skipped.

    Returns:
        The scene, with ``provenance`` describing the document that was read (path, sha256 of
        its bytes — of its canonical JSON for a mapping —, ``openlabel`` or ``vcd``, toolkit
        version).

    Raises:
        DocumentError: every problem of the document at once, each with its JSON path.
    """
    document, provenance = load_with_provenance(source)
    return read_loaded(document, provenance, catalog=catalog)


def read_loaded(document: dict, provenance: Provenance, *, catalog: Catalog | None = None) -> SceneSpec:
    """:func:`read_openlabel` of a document returned by :func:`load_with_provenance`."""
    doc = DocumentBody(document["openlabel"], provenance.source_format)
    R = doc.root
    for key in doc.body:
        if key not in ROOT_KEYS:
            doc.add(f"{R}.{key}", f"unknown key {key!r} in the {R} object{suggest(key, ROOT_KEYS)}")
    settings = read_metadata(doc)
    doc.frames()  # frame keys are reported first, before the sections that walk the frames
    cameras = read_cameras(doc, settings["render"])
    lights, places, objects, uids = read_objects(doc)
    relations = read_relations(doc, uids)
    check_frame_relations(doc)
    frame_start, frame_end = _frame_range(doc, settings["frame_range"], (*lights, *objects, *relations))
    scene = dict(
        name=settings["name"], frame_start=frame_start, frame_end=frame_end,
        cameras=tuple(cameras), lights=tuple(lights), objects=tuple(objects), places=tuple(places),
        relations=tuple(relations), render=settings["render"], seed=settings["seed"],
        environment=settings["environment"], asset_paths=settings["asset_paths"],
        exports=settings["exports"], roi_rules=settings["roi_rules"], roi_ignore=settings["roi_ignore"],
        split_rule=settings["split_rule"], split_seed=settings["split_seed"], fps=settings["fps"],
        description=settings["description"], world=settings["world"],
        extra=scene_residue(doc.body, doc.frames(), cameras, relations))
    if settings["world"] is not None and settings["world"].sky and not any(
            light.kind is LightKind.SUN for light in lights):
        doc.add(f"{R}.metadata.usdscene.world.sky", f"a physical sky ({settings['world'].sky!r}) stands its sun where "
                                                     "the document's sun light comes from, and there is no light of "
                                                     "kind 'sun'; add one")
    if catalog is not None:
        _check_catalog(doc, catalog, scene)
    doc.problems.raise_if_any(DocumentError)
    return SceneSpec(**{**scene, "provenance": provenance})


def _frame_range(doc: DocumentBody, explicit: FrameInterval | None, elements) -> tuple[int, int]:
    """The scene's closed frame range: ``metadata.usdscene.frame_range``, else the root
    ``frame_intervals``, else the span of every element's intervals and of the frames; (0, 0)
    for a document with none of them."""
    root_intervals = None
    if "frame_intervals" in doc.body:
        root_intervals = read_intervals(doc.body["frame_intervals"], f"{doc.root}.frame_intervals", doc.problems)
    if root_intervals:
        _check_frames_inside(doc, root_intervals)
    if explicit is not None:
        return explicit.frame_start, explicit.frame_end
    if root_intervals:
        return min(iv.frame_start for iv in root_intervals), max(iv.frame_end for iv in root_intervals)
    intervals = [iv for element in elements for iv in element.frame_intervals]
    intervals += [FrameInterval(f, f) for f in doc.frames()]
    merged = union_intervals(intervals)
    if not merged:
        return 0, 0
    return merged[0].frame_start, merged[-1].frame_end


def _check_frames_inside(doc: DocumentBody, root_intervals: list[FrameInterval]) -> None:
    """One problem when ``frames`` holds frames outside the root ``frame_intervals``: OpenLABEL's
    root intervals are the frames the document has, and a reader that trusts them (ours did,
    reporting a 250,000-frame document as "frames 0..1") would silently drop the rest."""
    merged = union_intervals(root_intervals)
    starts = [iv.frame_start for iv in merged]
    outside = []
    for frame in doc.frames():
        k = bisect.bisect_right(starts, frame) - 1
        if k < 0 or frame > merged[k].frame_end:
            outside.append(frame)
    if outside:
        spans = ", ".join(f"{iv.frame_start}..{iv.frame_end}" for iv in merged[:5])
        more = f" and {len(merged) - 5} more" if len(merged) > 5 else ""
        doc.add(f"{doc.root}.frames",
                f"{len(outside)} frame(s) lie outside the root frame_intervals ({spans}{more}), "
                f"first {min(outside)}, last {max(outside)}: widen frame_intervals or drop those frames")


def roi_ignored_classes(names: Iterable[str], catalog: Catalog, where: str) -> tuple[frozenset[str], list[Problem]]:
    """The object classes that ``metadata.usdscene.roi_ignore`` means, and a problem for each
    name that means none.

    A name is an object class (``passenger``) or a catalog kind (every class of that kind, e.g.
    ``passenger`` or ``object``). Environments are neither: no place region holds one.

    Args:
        names: the document's ``roi_ignore``.
        catalog: the asset catalog the document is read with.
        where: JSON path of ``roi_ignore``; a problem names ``where[index]`` and the value.
    """
    objects = {c: catalog[c].kind for c in catalog.classes() if catalog[c].kind != "environment"}
    kinds = sorted(set(objects.values()))
    classes: set[str] = set()
    problems = []
    for index, name in enumerate(names):
        meant = {c for c, kind in objects.items() if name in (c, kind)}
        if not meant:
            problems.append(Problem(f"{where}[{index}]", (
                f"{name!r} is no object class or kind of the asset catalog{suggest(name, [*kinds, *objects])}; "
                f"kinds: {', '.join(kinds)}; classes: {', '.join(sorted(objects))}")))
        classes |= meant
    return frozenset(classes), problems


def _check_catalog(doc: DocumentBody, catalog: Catalog, scene: dict) -> None:
    """Environment, object classes, places, placement relations and the ROI rules' ignored
    classes exist in ``catalog``."""
    R = doc.root
    doc.problems.extend(roi_ignored_classes(scene["roi_ignore"], catalog, f"{R}.metadata.usdscene.roi_ignore")[1])
    environment = scene["environment"]
    where_env = f"{R}.metadata.usdscene.environment"
    env_places = None
    if environment is not None:
        if environment not in catalog:
            doc.add(where_env, f"environment {environment!r} is not in the asset catalog"
                               f"{suggest(environment, catalog.classes('environment'))}")
        elif catalog[environment].kind != "environment":
            doc.add(where_env, f"{environment!r} is a {catalog[environment].kind}, not an environment")
        else:
            env_places = catalog.places(environment)
    for obj in scene["objects"]:
        if obj.class_name not in catalog:
            doc.add(f"{R}.objects.{obj.uid}.type",
                    f"unknown object class {obj.class_name!r}{suggest(obj.class_name, catalog.classes())}; "
                    f"the catalog has: {', '.join(c for c in catalog.classes() if catalog[c].kind != 'environment')}")
    for place in scene["places"]:
        where = f"{R}.objects.{place.uid}.name"
        if environment is None:
            doc.add(where, f"place {place.name!r} needs metadata.usdscene.environment")
        elif env_places is not None and place.name not in env_places and not place.regions:
            doc.add(where, f"place {place.name!r} is not in environment {environment!r}"
                           f"{suggest(place.name, env_places)}; declare it with a cuboid per relation "
                           "(docs/scene-format.md) if the asset lacks it")
    classes = {o.uid: o.class_name for o in scene["objects"]}
    placed = {rel.subject_uid for rel in scene["relations"] if rel.type in PLACEMENT_RELATIONS}
    unposed = {o.uid for o in scene["objects"] if o.pose is None and not o.frame_poses} - placed
    for rel in scene["relations"]:
        if rel.type not in PLACEMENT_RELATIONS:
            if rel.subject_uid in unposed:
                _check_relation_type(doc, catalog, rel, classes[rel.subject_uid])
            continue
        cls = classes.get(rel.subject_uid)
        if cls in catalog and catalog[cls].relations and rel.type not in catalog[cls].relations:
            doc.add(f"{R}.relations.{rel.uid}.type",
                    f"class {cls!r} does not support {rel.type!r}; it supports "
                    f"{', '.join(catalog[cls].relations)}")


def _check_relation_type(doc: DocumentBody, catalog: Catalog, rel, cls: str) -> None:
    """A relation type that only misspells a placement relation (``IS_BELOW``, ``is below``,
    ``is_inside``) would leave its unposed subject at the world origin: name the intended one.

    Relation types of other vocabularies pass: only a near miss of one of the types the
    subject's catalog class supports (all placement relations when it lists none) is refused.
    """
    supported = (catalog[cls].relations if cls in catalog else ()) or tuple(sorted(PLACEMENT_RELATIONS))
    normalised = re.sub(r"[\s-]+", "_", rel.type.strip().lower())
    close = difflib.get_close_matches(normalised, supported, n=1, cutoff=0.7)
    if normalised in supported or (close and normalised.startswith(close[0])):
        intended = normalised if normalised in supported else close[0]
        doc.add(f"{doc.root}.relations.{rel.uid}.type",
                f"relation type {rel.type!r} is not a placement relation (did you mean {intended!r}?); "
                f"object {rel.subject_uid!r} has no pose and would stay at the world origin. "
                f"Class {cls!r} supports: {', '.join(supported)}")
