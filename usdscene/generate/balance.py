"""The balance report: what a dataset built from a scene document holds.

Instance-frames per class, class × relation, relation, place and place kind
(:func:`balance_report`); ``usdscene stats DOC`` prints it and ``usdscene generate`` writes it
into ``DOC.report.json``.
"""

from __future__ import annotations

import collections
from typing import Mapping

from usdscene.generate.laps import lap_place_name
from usdscene.document.model import PLACEMENT_RELATIONS, FrameInterval, SceneSpec
from usdscene.scene.catalog import Catalog

REPORT_FORMAT = "usdscene-sequence-report"


def balance_report(scene: SceneSpec, catalog: Catalog | None = None) -> dict:
    """Counts of a scene document: what a dataset built from it holds.

    An *instance-frame* is one object present in one frame. Objects placed on another object
    count at the place and relation their chain of relations ends at; with a catalog, an object
    on another object's declared support place (a magazine on a passenger's lap) counts with
    its own relation at ``<place>/<support place>`` (``seat_03A/lap``, kind ``lap``).

    Args:
        scene: the scene.
        catalog: when given, per place *kind* counts too (``seat``, ``bin``, ...).

    Returns:
        ``{"format", "frames", "cameras", "images", "objects", "instance_frames",
        "classes": {class: {"objects", "instance_frames"}},
        "class_relation": {class: {relation: instance-frames}}, "relations": {relation: n},
        "places": {place: n}, "place_kinds": {kind: n}}``, every mapping sorted by key.
        ``relation`` is ``"none"`` for objects without a placement relation in that frame.
    """
    from usdscene.converters.openlabel.annotations import resolve_places_over

    place_names = {p.uid: p.name for p in scene.places}
    kinds: Mapping[str, str] = {}
    if catalog is not None and scene.environment in catalog:
        kinds = {name: place.kind for name, place in catalog.places(scene.environment).items()}
    classes: dict[str, dict[str, int]] = {}
    matrix: dict[str, collections.Counter] = {}
    places: collections.Counter = collections.Counter()
    place_kinds: collections.Counter = collections.Counter()
    relations: collections.Counter = collections.Counter()
    total = 0
    for obj in scene.objects:
        classes.setdefault(obj.class_name, {"objects": 0, "instance_frames": 0})["objects"] += 1
    resolved_at = resolve_places_over(scene, scene.frames)
    on_support = _declared_supports(scene, catalog) if catalog is not None else {}
    for obj in scene.objects:
        intervals = obj.frame_intervals or (FrameInterval(scene.frame_start, scene.frame_end),)
        frames = sorted({f for iv in intervals for f in iv.frames() if f in resolved_at})
        for frame in frames:
            resolved = resolved_at[frame]
            total += 1
            classes[obj.class_name]["instance_frames"] += 1
            place_uid, relation = resolved.get(obj.uid, (None, "none"))
            support = on_support.get((frame, obj.uid))
            if support is not None and place_uid is not None:
                relation = support[0]
            matrix.setdefault(obj.class_name, collections.Counter())[relation] += 1
            relations[relation] += 1
            if place_uid is not None:
                name = place_names.get(place_uid, place_uid)
                kind = kinds.get(name)
                if support is not None:
                    name, kind = lap_place_name(name, support[1]), support[2]
                places[name] += 1
                if kind is not None:
                    place_kinds[kind] += 1
    n_frames = len(scene.frames)
    return {
        "format": REPORT_FORMAT, "version": 1, "scene": scene.name,
        "frames": n_frames, "cameras": len(scene.cameras), "images": n_frames * len(scene.cameras),
        "objects": len(scene.objects), "instance_frames": total,
        "classes": dict(sorted(classes.items())),
        "class_relation": {c: dict(sorted(matrix.get(c, {}).items())) for c in sorted(classes)},
        "relations": dict(sorted(relations.items())),
        "places": dict(sorted(places.items())),
        "place_kinds": dict(sorted(place_kinds.items())),
    }


def _declared_supports(scene: SceneSpec, catalog: Catalog) -> dict[tuple[int, str], tuple[str, str, str]]:
    """(frame, uid) → (relation, support place name, its kind) for objects whose first
    placement relation in that frame relates them to an object that declares a support place
    for it (:meth:`usdscene.scene.catalog.AssetEntry.support_region`)."""
    from usdscene.scene.placement import object_variants

    objects = scene.object_by_uid()
    out: dict[tuple[int, str], tuple[str, str, str]] = {}
    first: set[tuple[int, str]] = set()
    every = set(scene.frames)
    for rel in scene.relations:
        subject = objects.get(rel.subject_uid)
        if rel.type not in PLACEMENT_RELATIONS or subject is None:
            continue
        intervals = rel.frame_intervals or subject.frame_intervals
        frames = {f for iv in intervals for f in iv.frames()} & every if intervals else every
        target = objects.get(rel.object_uid)
        found = None
        if target is not None and target.class_name in catalog:
            entry = catalog[target.class_name]
            found = entry.support_region(rel.type, object_variants(target))
        for frame in frames:
            if (frame, rel.subject_uid) in first:
                continue
            first.add((frame, rel.subject_uid))
            if found is not None:
                name = found[0]
                out[(frame, rel.subject_uid)] = (rel.type, name, entry.places_for(object_variants(target))[name].kind)
    return out
