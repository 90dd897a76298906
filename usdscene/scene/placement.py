"""Placement from relations: where every dynamic object stands in every frame.

Pure module (numpy only). :func:`place_objects` turns the spatial relations of a
:class:`~usdscene.document.model.SceneSpec` (``backpack is_below seat_03A``, ``cup is_on tray_box``)
into one object → world pose per object and frame, grouped in spans of consecutive frames that
share a pose.

Rules, in order of precedence:

1. An explicit pose in the document wins: ``frame_poses`` for that frame, else ``pose``.
2. Otherwise the first placement relation (document order) that holds in the frame places
   the object in a *support region*: a box whose z = 0 plane is the support surface.

   * Relation to a place: the region ``catalog.places(env)[place].regions[relation]``.
   * Relation to another object ``T`` whose catalog entry declares a support place for the
     relation (a passenger's ``lap`` for ``is_on``; per pose variant, see
     :meth:`usdscene.scene.catalog.AssetEntry.places_for`): that region, carried by T's pose of that
     frame; the object lies there as modelled (upright or turned a quarter, never on a side).
     A class that declares the relation for some variants but not for T's refuses it.
   * Relation to another object (``T`` with asset extent ``[lo, hi]``, pose of that frame)
     declaring nothing for the relation: ``is_on`` → T's top face (z = hi.z, footprint = T's x/y extent, unlimited height);
     ``is_in`` → T's inside (z = lo.z, footprint and height of T's extent);
     ``is_in_front_of`` → a strip of depth :data:`FRONT_DEPTH_M` in front of T on T's
     support plane (z = lo.z). An asset's *front* is its -Y side, as in Blender's front view.
     ``is_below`` another object is refused (the floor under an object is unknown).

3. Inside the region the object gets a yaw about the region's Z axis drawn from
   ``N(0, rotation_noise_deg)``, and a position whose footprint (asset x/y extent after the
   yaw) lies inside the region and whose lowest point (asset ``extent_min_m`` z) lies on the
   support surface, with its height within the region's clearance.

   * Orientation: upright if it fits (also turned a quarter, which is tried too when packing),
     else lying on a side (bags under seats and in bins lie down, as people put them), as far
     as the class's rule allows (``orientations`` in the catalog: ``upright`` = as modelled,
     ``upright_turned`` = also a quarter turn, ``any`` = also on a side).
   * Extent: the object's chosen appearance variant's, when the catalog gives variants
     extents of their own (``variant_extents``).
   * *Seated* assets, whose extent reaches below their origin (a passenger's origin is the hip
     contact on the cushion, the feet 0.45 m lower), rest on their origin instead: only the
     origin must lie inside the region, and only the part above the origin counts for
     clearance and collisions (the legs reach into the legroom by design), and that coarse box
     only against objects on the same support.
   * Position: an object alone in its region first tries the region centre displaced by
     ``N(0, position_noise_m)`` on x and y (clamped into the region), so it sits predictably in
     the middle of its place. Objects sharing a region are packed from the corners of the free
     range first, then tried at uniform random positions.
   * A try is rejected when the object's oriented box interpenetrates (by more than
     :data:`CONTACT_TOLERANCE_M`) any object already placed in that frame; after
     :data:`MAX_TRIES` rejections a :class:`CompositionError` names the object, the place,
     how full it is and what is in the way.
4. Without explicit pose or relation the object stays at the world origin (logged).

Over time an object keeps its sampled pose *relative to its support region* for as long as it
stays present under the same relation; it follows a support object that moves, and is
re-sampled when the relation changes, when it re-appears after an absence, or when following a
moving support would make it interpenetrate something.
"""

from __future__ import annotations

import collections
import functools
import logging
import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np

from usdscene.scene.catalog import AssetEntry, Catalog
from usdscene.errors import CompositionError, ProblemCollector
from usdscene.document.stage_schema import VARIANT_SET_APPEARANCE
from usdscene.document.model import PLACEMENT_RELATIONS, Pose, RelationType, SceneObject, SceneSpec

log = logging.getLogger(__name__)

MAX_TRIES = 200
"""Reject-and-resample budget per object and frame."""

CONTACT_TOLERANCE_M = 1e-6
"""Boxes may touch (a box resting on another) or overlap by this much without counting as
interpenetration."""

FRONT_DEPTH_M = 0.6
"""Depth of the strip in front of an object that ``is_in_front_of`` another object uses."""


_IDENTITY = Pose().matrix


@dataclass(frozen=True)
class PoseSpan:
    """One pose held over consecutive frames.

    Attributes:
        frame_start, frame_end: closed frame range of the span.
        pose: object → world.
        relation_uid: the relation that placed the object; None for an explicit pose (or an
            object without relation, left at the origin).
        support: human label of the support, e.g. ``place 'seat_03A' (is_below)`` or
            ``object 'o2' (is_on)``; "" for explicit poses.
        support_pose: support region frame → world (z = 0 is the support surface); None for
            explicit poses.
        support_size_m: (x, y, z) size of the support region in metres (z may be ``inf``).
    """

    frame_start: int
    frame_end: int
    pose: Pose
    relation_uid: str | None = None
    support: str = ""
    support_pose: Pose | None = None
    support_size_m: tuple[float, float, float] | None = None

    def frames(self) -> range:
        """The frames of the span, both ends included."""
        return range(self.frame_start, self.frame_end + 1)


@dataclass(frozen=True)
class ObjectPlacement:
    """Where one object is, frame by frame.

    Attributes:
        uid: object uid.
        class_name: asset class.
        spans: spans of the frames where the object is present, sorted, non-overlapping.
    """

    uid: str
    class_name: str
    spans: tuple[PoseSpan, ...] = ()

    def span_at(self, frame: int) -> PoseSpan | None:
        """The span holding ``frame``; None when the object is absent."""
        for span in self.spans:
            if span.frame_start <= frame <= span.frame_end:
                return span
        return None

    def pose_at(self, frame: int) -> Pose | None:
        """Pose at ``frame``; None when the object is absent."""
        span = self.span_at(frame)
        return span.pose if span is not None else None


# --------------------------------------------------------------------------------------------
# Oriented boxes


BOX_ROW = 15
"""Length of a packed oriented box: centre (3), axes (9, row-major 3 x 3 with the box axes as
columns), half sizes (3), metres. Placement keeps a frame's boxes as rows of one array, so the
compiled test takes two arrays instead of six."""


def object_box(entry: AssetEntry, pose_matrix: np.ndarray) -> np.ndarray:
    """World oriented box of an asset at a pose, packed (:data:`BOX_ROW`).

    Args:
        entry: catalog entry (its ``extent_min_m``/``extent_max_m`` bound the asset).
        pose_matrix: (4, 4) object → world.

    Returns:
        (15,) centre, axes (box axes as columns, row-major), half sizes, in metres; for a
        seated asset (extent below its origin) only the part above the origin.
    """
    centre, half = _asset_box(tuple(entry.extent_min_m), tuple(entry.extent_max_m))
    rot = pose_matrix[:3, :3]
    return np.concatenate((rot @ centre + pose_matrix[:3, 3], rot.reshape(9), half))


@functools.lru_cache(maxsize=1024)
def _asset_box(extent_min_m: tuple[float, ...], extent_max_m: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), half sizes (3,)) of an asset's collision box in its own frame, metres;
    cached because placement asks for every try of every object (callers must not change them)."""
    lo = np.asarray(extent_min_m, dtype=np.float64).copy()
    hi = np.asarray(extent_max_m, dtype=np.float64)
    lo[2] = max(lo[2], 0.0) if hi[2] > 0.0 else lo[2]  # seated assets: the part above the origin
    return (lo + hi) / 2.0, (hi - lo) / 2.0


def boxes_overlap(box: tuple, others: tuple, tolerance_m: float = CONTACT_TOLERANCE_M) -> np.ndarray:
    """Separating-axis test of one oriented box against K others.

    Args:
        box: ``(centre, axes, half)``: (3,) metres, (3, 3) axes as columns, (3,) half sizes.
        others: ``(centres, axes, halves)`` of the others: (K, 3), (K, 3, 3), (K, 3).
        tolerance_m: penetration depth still counted as contact.

    Returns:
        (K,) bool: True where the boxes interpenetrate by more than ``tolerance_m``.
    """
    (centre, axes, half), (centres, axes_k, halves) = box, others
    box = np.concatenate([np.asarray(centre, dtype=np.float64).reshape(3), np.asarray(axes, dtype=np.float64).reshape(9),
                          np.asarray(half, dtype=np.float64).reshape(3)])
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    others = np.concatenate([centres, np.asarray(axes_k, dtype=np.float64).reshape(-1, 9),
                             np.asarray(halves, dtype=np.float64).reshape(-1, 3)], axis=1)
    out = np.zeros(len(others), dtype=np.bool_)
    if len(others):
        _overlap_kernel()(box, others, len(others), float(tolerance_m), out)
    return out


@functools.cache
def _overlap_kernel():
    """The compiled separating-axis test behind :func:`boxes_overlap` (numba, cached on disk):
    ``overlap(box (15,), boxes (>= n, 15), n, tolerance_m, out (n,) bool) -> hits`` on packed
    boxes (:data:`BOX_ROW`); it sets ``out`` and returns how many are True."""
    from usdscene.compiled import njit

    @njit(nogil=True)
    def overlap(box, boxes, n, tolerance, out):
        # Packed: centre at 0, axes[r, c] at 3 + 3 r + c, half sizes at 12.
        radius = math.sqrt(box[12] ** 2 + box[13] ** 2 + box[14] ** 2)
        candidates = np.empty((15, 3))
        d = np.empty(3)
        hits = 0
        for k in range(n):
            for i in range(3):
                d[i] = boxes[k, i] - box[i]
            # Bounding spheres first: most boxes of a frame are far apart.
            other = math.sqrt(boxes[k, 12] ** 2 + boxes[k, 13] ** 2 + boxes[k, 14] ** 2)
            if math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2) >= radius + other - tolerance:
                continue
            # Candidate separating axes: the 3 + 3 box axes and their 9 cross products.
            for i in range(3):
                for j in range(3):
                    candidates[i, j] = box[3 + 3 * j + i]
                    candidates[3 + i, j] = boxes[k, 3 + 3 * j + i]
            c = 6
            for i in range(3):
                for j in range(3):
                    ax, ay, az = box[3 + i], box[6 + i], box[9 + i]
                    bx, by, bz = boxes[k, 3 + j], boxes[k, 6 + j], boxes[k, 9 + j]
                    candidates[c, 0] = ay * bz - az * by
                    candidates[c, 1] = az * bx - ax * bz
                    candidates[c, 2] = ax * by - ay * bx
                    c += 1
            separated = False
            for c in range(15):
                norm = math.sqrt(candidates[c, 0] ** 2 + candidates[c, 1] ** 2 + candidates[c, 2] ** 2)
                if norm <= 1e-9:
                    continue
                nx, ny, nz = candidates[c, 0] / norm, candidates[c, 1] / norm, candidates[c, 2] / norm
                r_a = 0.0
                r_b = 0.0
                for i in range(3):
                    r_a += abs(box[3 + i] * nx + box[6 + i] * ny + box[9 + i] * nz) * box[12 + i]
                    r_b += abs(boxes[k, 3 + i] * nx + boxes[k, 6 + i] * ny + boxes[k, 9 + i] * nz) * boxes[k, 12 + i]
                if abs(nx * d[0] + ny * d[1] + nz * d[2]) >= r_a + r_b - tolerance:
                    separated = True
                    break
            out[k] = not separated
            hits += not separated
        return hits

    return overlap


# --------------------------------------------------------------------------------------------
# Validation


def _frame_mask(intervals, frame_start: int, n_frames: int) -> np.ndarray:
    """(n_frames,) bool presence over the scene range; no intervals = every frame."""
    if not intervals:
        return np.ones(n_frames, dtype=bool)
    mask = np.zeros(n_frames, dtype=bool)
    for iv in intervals:
        lo = max(iv.frame_start - frame_start, 0)
        hi = min(iv.frame_end - frame_start, n_frames - 1)
        if lo <= hi:
            mask[lo:hi + 1] = True
    return mask


def check_placement_inputs(scene: SceneSpec, catalog: Catalog) -> None:
    """Refuse unknown classes, relations to missing places or objects and cyclic relations.

    Raises:
        CompositionError: every problem at once; each names the element uid.
    """
    from usdscene.scene.catalog import scene_catalog

    catalog = scene_catalog(catalog, scene)  # places the document declares itself
    problems = ProblemCollector()
    objects = scene.object_by_uid()
    places = scene.place_by_uid()
    env_places: Mapping = {}
    if scene.environment is not None:
        if scene.environment not in catalog:
            problems.add("environment", f"environment class {scene.environment!r} is not in the "
                                        f"asset catalog (known: {', '.join(catalog.classes('environment')) or 'none'})")
        else:
            env_places = catalog.places(scene.environment)
    _check_object_classes(scene, catalog, problems)
    for rel in scene.relations:
        if rel.type not in PLACEMENT_RELATIONS:
            continue
        where = f"relations.{rel.uid}"
        if rel.subject_uid not in objects:
            problems.add(where, f"relation {rel.uid!r} ({rel.type}) places {rel.subject_uid!r}, "
                                "which is not a dynamic object of the document")
            continue
        if rel.object_uid in places:
            place = places[rel.object_uid]
            if scene.environment is None:
                problems.add(where, f"relation {rel.uid!r}: object {rel.subject_uid!r} {rel.type} place "
                                    f"{place.name!r}, but the document names no environment")
            elif scene.environment in catalog and place.name not in env_places:
                problems.add(where, f"relation {rel.uid!r}: object {rel.subject_uid!r} {rel.type} place "
                                    f"{place.name!r}, which environment {scene.environment!r} lacks")
            elif place.name in env_places and rel.type not in env_places[place.name].regions:
                have = ", ".join(sorted(env_places[place.name].regions)) or "none"
                problems.add(where, f"relation {rel.uid!r}: place {place.name!r} has no region for "
                                    f"{rel.type!r} (it has: {have}); cannot place {rel.subject_uid!r}")
            elif place.name in env_places:
                region = env_places[place.name].regions[rel.type]
                _add_fit_problem(problems, objects[rel.subject_uid], catalog, tuple(float(v) for v in region.size_m),
                                 f"place {place.name!r} ({rel.type})", upright_only=False)
        elif rel.object_uid in objects:
            if rel.type == RelationType.IS_BELOW.value:
                problems.add(where, f"relation {rel.uid!r}: {rel.subject_uid!r} is_below another object "
                                    f"({rel.object_uid!r}) is not supported; relate it to a place")
            elif rel.object_uid == rel.subject_uid:
                problems.add(where, f"relation {rel.uid!r}: object {rel.subject_uid!r} is related to itself")
            elif objects[rel.object_uid].class_name in catalog:
                target = objects[rel.object_uid]
                entry = catalog[target.class_name]
                variants = object_variants(target)
                if entry.declares_support(rel.type) and entry.support_region(rel.type, variants) is None:
                    shown = ", ".join(f"{k} {v!r}" for k, v in sorted(variants.items())) or "its default variants"
                    problems.add(where, f"relation {rel.uid!r}: {rel.subject_uid!r} {rel.type} {rel.object_uid!r}, "
                                        f"but class {target.class_name!r} with {shown} offers no region for "
                                        f"{rel.type!r} (other variants do)")
                elif entry.kind != "environment":
                    # The region's size does not depend on where the support stands.
                    _, size = object_support_region(rel.type, entry.for_variants(variants), np.eye(4), variants)
                    _add_fit_problem(problems, objects[rel.subject_uid], catalog, size,
                                     f"object {rel.object_uid!r} ({rel.type})",
                                     upright_only=entry.declares_support(rel.type))
        else:
            problems.add(where, f"relation {rel.uid!r}: {rel.subject_uid!r} {rel.type} {rel.object_uid!r}, "
                                "which is neither a place nor an object of the document")
    _check_cycles(scene, objects, problems)
    problems.raise_if_any(CompositionError)


def _check_object_classes(scene: SceneSpec, catalog: Catalog, problems: ProblemCollector) -> None:
    """Every object's class is a placeable catalog class and its variants exist."""
    for obj in scene.objects:
        if obj.class_name not in catalog:
            problems.add(f"objects.{obj.uid}", f"object {obj.uid!r} has unknown class {obj.class_name!r} "
                                                f"(known classes: {', '.join(catalog.classes()) or 'none'})")
        elif catalog[obj.class_name].kind == "environment":
            problems.add(f"objects.{obj.uid}", f"object {obj.uid!r} has class {obj.class_name!r}, "
                                                "which is an environment, not a placeable object")
        else:
            for field_name, set_name, chosen in (("appearance", "appearance", obj.appearance),
                                                 ("pose_variant", "pose", obj.pose_variant)):
                choices = catalog[obj.class_name].variants.get(set_name, ())
                if chosen is not None and chosen not in choices:
                    problems.add(f"objects.{obj.uid}.{field_name}",
                                 f"object {obj.uid!r}: {set_name} {chosen!r} is not a variant of "
                                 f"class {obj.class_name!r} (variants: {', '.join(choices) or 'none'})")


def _check_cycles(scene: SceneSpec, objects: Mapping, problems: ProblemCollector) -> None:
    """No object rests on itself through object → object relations."""
    graph: dict[str, list[tuple[str, str]]] = {}
    for rel in scene.relations:
        if (rel.type in PLACEMENT_RELATIONS and rel.subject_uid in objects and rel.object_uid in objects
                and rel.subject_uid != rel.object_uid):
            graph.setdefault(rel.subject_uid, []).append((rel.object_uid, rel.uid))
    for cycle in _find_cycles(graph, [o.uid for o in scene.objects]):
        chain = " → ".join(repr(u) for u in cycle)
        problems.add(f"objects.{cycle[0]}", f"cyclic placement relations: {chain}; object "
                                            f"{cycle[0]!r} would rest on itself")


def _add_fit_problem(problems: ProblemCollector, obj: SceneObject, catalog: Catalog,
                     size: tuple[float, float, float], label: str, *, upright_only: bool) -> None:
    """The fit test of placement (:func:`_orientations`) before anything is drawn: an object
    that fits its support region in no orientation can never be placed there. An object whose
    appearance is drawn at composition (``random_appearance``) is left to composition when
    its variants differ in extent."""
    if obj.class_name not in catalog or catalog[obj.class_name].kind == "environment":
        return  # reported as an unknown class / not placeable
    base = catalog[obj.class_name]
    if obj.randomization.random_appearance and base.variant_extents:
        return
    entry = base.for_variants(object_variants(obj))
    if not _orientations(entry, size, upright_only):
        problems.add(f"objects.{obj.uid}", _no_fit_message(obj.uid, obj.class_name, entry, label, size))


def _find_cycles(graph: Mapping[str, list[tuple[str, str]]], order: list[str]) -> list[list[str]]:
    """Each elementary cycle reached by a depth-first search, as uid lists (first = last)."""
    state: dict[str, int] = {}  # 1 = on stack, 2 = done
    cycles: list[list[str]] = []
    for start in order:
        if state.get(start):
            continue
        stack: list[tuple[str, int]] = [(start, 0)]
        path: list[str] = [start]
        state[start] = 1
        while stack:
            node, index = stack[-1]
            edges = graph.get(node, [])
            if index < len(edges):
                stack[-1] = (node, index + 1)
                nxt = edges[index][0]
                if state.get(nxt) == 1:
                    cycles.append(path[path.index(nxt):] + [nxt])
                elif not state.get(nxt):
                    state[nxt] = 1
                    stack.append((nxt, 0))
                    path.append(nxt)
            else:
                state[node] = 2
                stack.pop()
                path.pop()
    return cycles


# --------------------------------------------------------------------------------------------
# Sampling


def object_variants(obj: SceneObject) -> dict[str, str]:
    """The variant selection an object asks for (variant set → variant; sets left to the
    asset's default are left out)."""
    from usdscene.document.stage_schema import VARIANT_SET_APPEARANCE, VARIANT_SET_POSE

    chosen = {VARIANT_SET_APPEARANCE: obj.appearance, VARIANT_SET_POSE: obj.pose_variant}
    return {k: v for k, v in chosen.items() if v is not None}


def _translation(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def object_support_region(relation: str, target: AssetEntry, target_pose: np.ndarray,
                          variants: Mapping[str, str] | None = None) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Support region that ``relation`` defines on another object (see the module docstring).

    Args:
        relation: ``is_on``, ``is_in`` or ``is_in_front_of``.
        target: catalog entry of the related object.
        target_pose: (4, 4) its object → world pose.
        variants: the related object's variant selection (variant set → variant; missing sets
            take the entry's defaults): it decides which declared support places apply.

    Returns:
        ``(region → world (4, 4), (x, y, z) size in metres)``; z may be ``inf``.

    Raises:
        ValueError: the entry declares the relation for other variants only.
    """
    declared = target.support_region(relation, variants)
    if declared is not None:
        region = declared[1]
        return target_pose @ region.pose.as_array(), tuple(float(v) for v in region.size_m)  # type: ignore[return-value]
    if target.declares_support(relation):
        raise ValueError(f"class {target.class_name!r} offers no {relation!r} region with variants {dict(variants or {})}")
    lo = np.asarray(target.extent_min_m, dtype=np.float64)
    hi = np.asarray(target.extent_max_m, dtype=np.float64)
    cx, cy = (lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0
    sx, sy = hi[0] - lo[0], hi[1] - lo[1]
    if relation == RelationType.IS_ON.value:
        local, size = _translation(cx, cy, hi[2]), (sx, sy, math.inf)
    elif relation == RelationType.IS_IN.value:
        local, size = _translation(cx, cy, lo[2]), (sx, sy, hi[2] - lo[2])
    elif relation == RelationType.IS_IN_FRONT_OF.value:
        local, size = _translation(cx, lo[1] - FRONT_DEPTH_M / 2.0, lo[2]), (sx, FRONT_DEPTH_M, math.inf)
    else:
        raise ValueError(f"no object support region for relation {relation!r}")
    return target_pose @ local, (float(size[0]), float(size[1]), float(size[2]))


@dataclass
class _Info:
    """Per object, fixed over the frames."""

    obj: SceneObject
    entry: AssetEntry
    present: np.ndarray            # (n_frames,) bool
    relation_index: np.ndarray     # (n_frames,) int, -1 = none; index into scene.relations
    level: int
    footprint_area_m2: float


@dataclass
class _State:
    """What an object was doing in the previous frame."""

    frame: int
    key: tuple
    local: np.ndarray | None       # (4, 4) object → region
    world: tuple[float, ...]       # 16 floats
    region: tuple[float, ...] | None
    label: str
    size: tuple[float, float, float] | None


def place_objects(scene: SceneSpec, catalog: Catalog, rng: np.random.Generator,
                  appearances: Mapping[str, str | None] | None = None) -> dict[str, ObjectPlacement]:
    """Resolve every object's pose in every frame it is present.

    Args:
        scene: the scene (relations, places, explicit poses, randomization knobs).
        catalog: asset catalog (extents of the classes, places of the environment).
        rng: the generator all random draws come from (draw order: frames ascending, then
            objects by support depth and document order).
        appearances: uid → the appearance variant composition chose (drawn ones included);
            objects left out use the document's ``appearance``. A variant with an extent of its
            own (:meth:`usdscene.scene.catalog.AssetEntry.for_variants`) is placed with it.

    Returns:
        uid → :class:`ObjectPlacement`, in document order.

    Raises:
        CompositionError: unknown class, relation to a missing place/object, cyclic or
            unsupported relation, an object that does not fit its region, an over-full place.
    """
    from usdscene.scene.catalog import scene_catalog

    catalog = scene_catalog(catalog, scene)  # places the document declares itself
    check_placement_inputs(scene, catalog)
    run = _Run(scene=scene, env_places=catalog.places(scene.environment) if scene.environment in catalog else {},
               infos=_object_infos(scene, catalog, appearances), objects=scene.object_by_uid(),
               places=scene.place_by_uid(), rng=rng,
               explicit={o.uid: {f: p.matrix for f, p in o.frame_poses} for o in scene.objects})
    order = sorted(run.infos.values(), key=lambda i: i.level)  # stable: document order per level
    n_frames = len(scene.frames)
    presence = np.array([info.present for info in order]).reshape(len(order), n_frames)  # (objects, frames)
    spans: dict[str, list[list]] = {o.uid: [] for o in scene.objects}
    states: dict[str, _State] = {}
    for fi in range(n_frames):
        frame = _Frame(fi, scene.frame_start + fi)
        present = [order[index] for index in np.flatnonzero(presence[:, fi]).tolist()]
        pending = _keep_unchanged(run, frame, present, states)
        _place_pending(run, frame, pending, states)
        run.problems.raise_if_any(CompositionError)
        _extend_spans(spans, frame, scene)
        states.update(frame.done)
    return _placements_from_spans(scene, spans)


@dataclass
class _Run:
    """What one :func:`place_objects` call reads and keeps across frames."""

    scene: SceneSpec
    env_places: Mapping
    infos: dict[str, "_Info"]
    objects: Mapping[str, SceneObject]
    places: Mapping
    rng: np.random.Generator
    explicit: dict[str, dict[int, tuple[float, ...]]]
    warned_unplaced: set[str] = field(default_factory=set)
    # (place name, relation) → (region → world (4, 4), size, label, that matrix as 16 floats):
    # places do not move, and a few hundred of them serve tens of thousands of placements.
    place_supports: dict = field(default_factory=dict)
    problems: ProblemCollector = field(default_factory=ProblemCollector)


@dataclass
class _Frame:
    """One frame being placed: its boxes, the objects done and every present object's key."""

    index: int
    frame: int
    boxes: "_FrameBoxes" = field(default_factory=lambda: _FrameBoxes())
    done: dict[str, "_State"] = field(default_factory=dict)
    keys: dict[str, tuple] = field(default_factory=dict)  # uid → _key of every present object
    shared: collections.Counter | None = None  # (target, relation) → users, on demand


def _object_infos(scene: SceneSpec, catalog: Catalog,
                  appearances: Mapping[str, str | None] | None) -> dict[str, "_Info"]:
    """Per object: its entry (with the chosen variant's extent), presence, relation per frame
    and support depth, in document order."""
    frame_start, n_frames = scene.frame_start, len(scene.frames)
    objects = scene.object_by_uid()
    # Placement relations per subject, in document order (one pass: generated sequences hold
    # thousands of relations).
    by_subject: dict[str, list[int]] = collections.defaultdict(list)
    for index, rel in enumerate(scene.relations):
        if rel.type in PLACEMENT_RELATIONS:
            by_subject[rel.subject_uid].append(index)
    infos: dict[str, _Info] = {}
    for obj in scene.objects:
        selection = object_variants(obj)
        if appearances is not None and appearances.get(obj.uid) is not None:
            selection[VARIANT_SET_APPEARANCE] = appearances[obj.uid]
        entry = catalog[obj.class_name].for_variants(selection)
        rel_index = np.full(n_frames, -1, dtype=np.int64)
        present = _frame_mask(obj.frame_intervals, frame_start, n_frames)
        # Reverse document order so the first relation that holds wins.
        for index in reversed(by_subject.get(obj.uid, ())):
            rel_index[_frame_mask(scene.relations[index].frame_intervals, frame_start, n_frames)] = index
        size = entry.size_m
        infos[obj.uid] = _Info(obj, entry, present, rel_index, 0, float(size[0] * size[1]))
    # Support depth: an object is placed after everything it rests on.
    memo: dict[str, int] = {}
    for info in infos.values():
        info.level = _level(info.obj.uid, scene, objects, memo, by_subject)
    return infos


def _keep_unchanged(run: _Run, frame: _Frame, present: list["_Info"],
                    states: Mapping[str, "_State"]) -> list["_Info"]:
    """Phase A: objects that keep exactly what they had (same key, support unchanged) are done;
    returns the others, in placement order."""
    pending = []
    for info in present:
        uid = info.obj.uid
        key = frame.keys[uid] = _key(info, frame.index, frame.frame, run.scene, run.explicit)
        prev = states.get(uid)
        if prev is not None and prev.frame == frame.frame - 1 and prev.key == key:
            ri = int(info.relation_index[frame.index])
            target = run.scene.relations[ri].object_uid if key[0] == "rel" else None
            # A support object counts as unchanged only when it was itself carried over.
            if target is None or target in run.places or target in frame.done:
                frame.done[uid] = _State(frame.frame, key, prev.local, prev.world, prev.region, prev.label, prev.size)
                frame.boxes.add(uid, info, np.asarray(prev.world).reshape(4, 4), prev.label)
                continue
        pending.append(info)
    return pending


def _place_pending(run: _Run, frame: _Frame, pending: list["_Info"], states: Mapping[str, "_State"]) -> None:
    """Phase B: every other object, supports first: explicit poses, the origin for objects
    without relation, and a sampled (or followed) pose in its support region."""
    for info in pending:
        uid = info.obj.uid
        key = frame.keys[uid]
        if key[0] == "explicit":
            frame.done[uid] = _State(frame.frame, key, None, key[1], None, "", None)
            frame.boxes.add(uid, info, np.asarray(key[1]).reshape(4, 4), "")
            continue
        if key[0] == "none":
            if uid not in run.warned_unplaced:
                log.warning("object %r has neither a pose nor a placement relation at frame %d; "
                            "it stays at the world origin", uid, frame.frame)
                run.warned_unplaced.add(uid)
            frame.done[uid] = _State(frame.frame, key, None, _IDENTITY, None, "", None)
            frame.boxes.add(uid, info, np.eye(4), "")
            continue
        rel = run.scene.relations[key[1]]
        support = _support_of(run, frame, uid, rel)
        if support is None:
            continue
        region_pose, size, label, region_values, exclude, upright_only = support
        orientations = _orientations(info.entry, size, upright_only)
        if not orientations:
            run.problems.add(f"objects.{uid}", _no_fit_message(uid, info.obj.class_name, info.entry, label, size))
            continue
        placed = _follow_support(frame, info, states.get(uid), key, region_pose, exclude, label)
        if placed is None:
            frame.boxes.blockers.clear()
            if frame.shared is None:
                frame.shared = _region_users(frame.keys.values(), run.scene)
            alone = frame.shared[(rel.object_uid, rel.type)] <= 1
            placed = _sample(info, orientations, region_pose, size, run.rng, frame.boxes, exclude, label, alone)
            if placed is None:
                run.problems.add(f"objects.{uid}", _overfull_message(uid, info, label, size, frame.frame, frame.boxes))
                run.problems.raise_if_any(CompositionError)
        local, world_m = placed
        if region_values is None:
            region_values = tuple(region_pose.reshape(16).tolist())
        frame.done[uid] = _State(frame.frame, key, local, tuple(world_m.reshape(16).tolist()), region_values,
                                 label, size)
        frame.boxes.add(uid, info, world_m, label)


def _support_of(run: _Run, frame: _Frame, uid: str, rel) -> tuple | None:
    """The support region of ``uid``'s relation in this frame: (region → world (4, 4), size,
    label, region matrix as 16 floats or None, uid to ignore in collisions, upright only);
    None (and a problem recorded) when the related object is absent."""
    if rel.object_uid in run.places:
        place_name = run.places[rel.object_uid].name
        if (place_name, rel.type) not in run.place_supports:
            region = run.env_places[place_name].regions[rel.type]
            pose_m = region.pose.as_array()
            run.place_supports[(place_name, rel.type)] = (
                pose_m, tuple(float(v) for v in region.size_m), f"place {place_name!r} ({rel.type})",
                tuple(pose_m.reshape(16).tolist()))
        region_pose, size, label, region_values = run.place_supports[(place_name, rel.type)]
        return region_pose, size, label, region_values, None, False
    target = frame.done.get(rel.object_uid)
    if target is None:
        run.problems.add(f"relations.{rel.uid}",
                         f"relation {rel.uid!r}: object {uid!r} {rel.type} object {rel.object_uid!r} "
                         f"at frame {frame.frame}, but {rel.object_uid!r} is not present in that frame")
        return None
    target_entry = run.infos[rel.object_uid].entry
    region_pose, size = object_support_region(rel.type, target_entry, np.asarray(target.world).reshape(4, 4),
                                              object_variants(run.objects[rel.object_uid]))
    # On a declared support place (a lap) objects lie as modelled, never on an edge.
    return (region_pose, size, f"object {rel.object_uid!r} ({rel.type})", None, rel.object_uid,
            target_entry.declares_support(rel.type))


def _follow_support(frame: _Frame, info: "_Info", prev: "_State | None", key: tuple, region_pose: np.ndarray,
                    exclude: str | None, label: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Keep the previous frame's pose relative to a moved support while that stays collision
    free: (object → region, object → world), or None."""
    if prev is None or prev.frame != frame.frame - 1 or prev.key != key or prev.local is None:
        return None
    world_m = region_pose @ prev.local
    if frame.boxes.collides(info, world_m, exclude, label):
        return None
    return prev.local, world_m


def _no_fit_message(uid: str, class_name: str, entry: AssetEntry, label: str,
                    size: tuple[float, float, float]) -> str:
    lo, hi = entry.extent_min_m, entry.extent_max_m
    dims = " × ".join(f"{h - l:.3f}" for l, h in zip(lo, hi))
    ways = {"upright": "upright", "upright_turned": "upright or turned",
            "any": "upright, turned or lying on a side"}[entry.orientations]
    return (f"object {uid!r} ({class_name}, {dims} m) does not fit {label} ({size[0]:.3f} × "
            f"{size[1]:.3f} m, {size[2]:.3f} m clearance) {ways}")


def _extend_spans(spans: dict[str, list[list]], frame: _Frame, scene: SceneSpec) -> None:
    """Append this frame's poses to the runs of equal poses per object."""
    for uid, state in frame.done.items():
        rel_uid = scene.relations[state.key[1]].uid if state.key[0] == "rel" else None
        runs = spans[uid]
        if runs and runs[-1][1] == frame.frame - 1 and runs[-1][2] == state.world and runs[-1][3] == rel_uid:
            runs[-1][1] = frame.frame
        else:
            runs.append([frame.frame, frame.frame, state.world, rel_uid, state.label, state.region, state.size])


def _placements_from_spans(scene: SceneSpec, spans: Mapping[str, list[list]]) -> dict[str, ObjectPlacement]:
    """uid → :class:`ObjectPlacement` in document order; one Pose per support region (places
    serve thousands)."""
    support_poses: dict[tuple[float, ...], Pose] = {}

    def support_pose(region: tuple[float, ...]) -> Pose:
        if region not in support_poses:
            support_poses[region] = Pose(region)
        return support_poses[region]

    return {
        o.uid: ObjectPlacement(
            uid=o.uid, class_name=o.class_name,
            spans=tuple(PoseSpan(frame_start=s, frame_end=e, pose=Pose(world), relation_uid=rel_uid,
                                 support=label, support_size_m=size,
                                 support_pose=None if region is None else support_pose(region))
                        for s, e, world, rel_uid, label, region, size in spans[o.uid]))
        for o in scene.objects}


def _level(uid: str, scene: SceneSpec, objects: Mapping[str, SceneObject], memo: dict[str, int],
           by_subject: Mapping[str, list[int]]) -> int:
    """Support depth (cycles were refused before)."""
    if uid in memo:
        return memo[uid]
    level = 0
    for index in by_subject.get(uid, ()):
        rel = scene.relations[index]
        if rel.object_uid in objects:
            level = max(level, 1 + _level(rel.object_uid, scene, objects, memo, by_subject))
    memo[uid] = level
    return level


def _key(info: _Info, fi: int, frame: int, scene: SceneSpec,
         explicit: Mapping[str, Mapping[int, tuple[float, ...]]]) -> tuple:
    obj = info.obj
    frame_pose = explicit[obj.uid].get(frame)
    if frame_pose is not None:
        return ("explicit", frame_pose)
    if obj.pose is not None:
        return ("explicit", obj.pose.matrix)
    ri = int(info.relation_index[fi])
    if ri < 0:
        return ("none",)
    return ("rel", ri)


def _region_users(keys: Iterable[tuple], scene: SceneSpec) -> collections.Counter:
    """(target uid, relation) → number of objects placed there in a frame, from the
    :func:`_key` of every object present in it."""
    users: collections.Counter = collections.Counter()
    for key in keys:
        if key[0] == "rel":
            rel = scene.relations[key[1]]
            users[(rel.object_uid, rel.type)] += 1
    return users


class _FrameBoxes:
    """Oriented boxes of the objects placed so far in one frame."""

    def __init__(self, capacity: int = 16) -> None:
        self.uids: list[str] = []
        self.labels: list[str] = []
        self.areas: list[float] = []
        self.blockers: collections.Counter[str] = collections.Counter()  # who was in the way
        # Rows [:len(uids)] hold the packed boxes (BOX_ROW); grown by doubling, so a frame of
        # n objects costs O(n) copies rather than one array rebuild per test.
        self._boxes = np.empty((capacity, BOX_ROW))
        self._seated = np.empty(capacity, dtype=np.bool_)
        self._any_seated = False
        # The last pose tested and its box: the pose a try accepts is added next.
        self._tested: tuple[np.ndarray, np.ndarray] | None = None

    def add(self, uid: str, info: _Info, world: np.ndarray, label: str) -> None:
        n = len(self.uids)
        if n == len(self._seated):
            self._boxes = np.concatenate([self._boxes, np.empty_like(self._boxes)])
            self._seated = np.concatenate([self._seated, np.empty_like(self._seated)])
        tested = self._tested
        self._boxes[n] = tested[1] if tested is not None and tested[0] is world else object_box(info.entry, world)
        seated = _seated(info.entry)
        self._seated[n] = seated
        self._any_seated |= seated
        self.uids.append(uid)
        self.labels.append(label)
        self.areas.append(info.footprint_area_m2)

    def collides(self, info: _Info, world: np.ndarray, exclude: str | None, label: str) -> bool:
        """Does the object at ``world`` interpenetrate a box of this frame?

        A seated asset's box (its part above the origin, thighs included) is far coarser
        than its body, so it only counts against objects on the same support (the seat).
        """
        if not self.uids:
            return False
        box = object_box(info.entry, world)
        self._tested = (world, box)
        n = len(self.uids)
        hits = np.zeros(n, dtype=np.bool_)
        if not _overlap_kernel()(box, self._boxes, n, CONTACT_TOLERANCE_M, hits):
            return False
        if exclude is not None:
            hits &= np.asarray([u != exclude for u in self.uids])
        if _seated(info.entry) or self._any_seated:
            same_support = np.asarray([lab == label for lab in self.labels])
            coarse = self._seated[:n] | _seated(info.entry)
            hits &= ~coarse | same_support
        if hits.any():
            self.blockers.update(u for u, hit in zip(self.uids, hits) if hit)
            return True
        return False


def _seated(entry: AssetEntry) -> bool:
    """An asset whose extent reaches below its origin rests on its origin (see module doc)."""
    return entry.extent_min_m[2] < 0.0


@dataclass(frozen=True)
class _Orientation:
    """How an object stands in a region before the yaw noise.

    Attributes:
        rotation: (3, 3) asset frame → upright frame (identity, or lying on a side).
        lo, hi: (3,) extent in the upright frame, metres.
        yaw_rad: base yaw about the region's Z axis (0 or a quarter turn).
        seated: rests on its origin (see the module docstring).
        corners_xy: the (x, y) points, metres, that must stay inside the region: the four
            footprint corners, or only the origin for a seated asset.
    """

    rotation: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    yaw_rad: float
    seated: bool
    corners_xy: tuple[tuple[float, float], ...] = ()


_QUARTER = math.pi / 2.0
# Upright first; then lying on a side (about the asset's X axis, then its Y axis).
_LAY_ROTATIONS = (np.eye(3),
                  np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
                  np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]))


def fits_region(entry: AssetEntry, size_m: tuple[float, float, float], upright_only: bool = False) -> bool:
    """Can an object of this class rest alone in a support region of this size?

    The same test :func:`place_objects` applies before sampling (upright, turned a quarter or
    lying on a side, as the class's orientation rule allows), so a region that passes holds one
    such object whatever the noise draws. Pass ``entry.for_variants(...)`` to test one variant.

    Args:
        entry: catalog entry of the object's class.
        size_m: (x, y, z) size of the region in metres (z may be ``inf``).
        upright_only: only as modelled (upright or turned a quarter): the rule for support
            places an object declares (a lap), where nothing stands on its edge.
    """
    return bool(_orientations(entry, tuple(float(v) for v in size_m), upright_only))  # type: ignore[arg-type]


def _orientations(entry: AssetEntry, size: tuple[float, float, float],
                  upright_only: bool = False) -> tuple[_Orientation, ...]:
    """Every orientation that fits the region, preferred first: upright, upright turned a
    quarter, then lying on a side (a bag too tall for the space under a seat is laid down, as
    people do), as far as the class's rule (``entry.orientations``) allows, and never lying
    with ``upright_only``. Seated assets stay upright and only their part above
    the origin counts for clearance.

    Cached per (extent, region size, rule): generating asks for the same few sizes tens of
    thousands of times. The orientations are shared; callers must not change them."""
    rule = "upright_turned" if upright_only and entry.orientations == "any" else entry.orientations
    return _orientations_of_extent(tuple(entry.extent_min_m), tuple(entry.extent_max_m), size, rule)


@functools.lru_cache(maxsize=4096)
def _orientations_of_extent(extent_min_m: tuple[float, ...], extent_max_m: tuple[float, ...],
                            size: tuple[float, float, float], rule: str) -> tuple[_Orientation, ...]:
    lo0 = np.asarray(extent_min_m, dtype=np.float64)
    hi0 = np.asarray(extent_max_m, dtype=np.float64)
    seated = bool(lo0[2] < 0.0)  # as _seated(entry)
    if seated:
        candidates = [(np.eye(3), lo0, hi0, yaw) for yaw in (0.0, _QUARTER)]
    else:
        corners = np.array([[x, y, z] for x in (lo0[0], hi0[0]) for y in (lo0[1], hi0[1]) for z in (lo0[2], hi0[2])])
        candidates = []
        for rot in _LAY_ROTATIONS:
            turned = corners @ rot.T
            candidates += [(rot, turned.min(axis=0), turned.max(axis=0), yaw) for yaw in (0.0, _QUARTER)]
    fitting = []
    for rot, lo, hi, yaw in candidates:
        height = hi[2] if seated else hi[2] - lo[2]
        if seated or height <= size[2] + 1e-9:
            # The footprint corners the yaw turns (only the origin for a seated asset).
            corners = ((0.0, 0.0),) if seated else tuple(
                (float(x), float(y)) for x, y in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])))
            orientation = _Orientation(rot, lo, hi, yaw, seated, corners)
            if _footprint_range(orientation, 0.0, size) is not None:
                fitting.append(orientation)
    # Lying down is only for objects that do not fit upright, and only for classes whose rule
    # allows it (a vehicle on its side is no training image).
    upright = tuple(o for o in fitting if o.rotation is _LAY_ROTATIONS[0] or o.seated)
    if rule == "upright":
        return tuple(o for o in upright if o.yaw_rad == 0.0)
    return upright if upright or rule != "any" else tuple(fitting)


def _footprint_range(orientation: _Orientation, yaw_rad: float, size: tuple[float, float, float]):
    """Allowed origin x/y range in the region for an extra yaw, or None when it does not fit.

    Plain floats on the four corners: the same arithmetic as array code, without its per-call
    cost (this runs for every try of every object)."""
    angle = orientation.yaw_rad + yaw_rad
    c, s = math.cos(angle), math.sin(angle)
    rx = [x * c - y * s for x, y in orientation.corners_xy]
    ry = [x * s + y * c for x, y in orientation.corners_xy]
    x_lo, x_hi = -size[0] / 2.0 - min(rx), size[0] / 2.0 - max(rx)
    y_lo, y_hi = -size[1] / 2.0 - min(ry), size[1] / 2.0 - max(ry)
    if x_lo > x_hi + 1e-12 or y_lo > y_hi + 1e-12:
        return None
    return (x_lo, max(x_lo, x_hi)), (y_lo, max(y_lo, y_hi))


# Corners of the free range, as (u, v) fractions: packing from the corners leaves room.
_CORNERS = ((0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0))


def _sample(info: _Info, orientations: tuple[_Orientation, ...], region_pose: np.ndarray,
            size: tuple[float, float, float], rng: np.random.Generator, boxes: _FrameBoxes,
            exclude: str | None, label: str, alone: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """Local pose (object → region, (4, 4)) that fits and collides with nothing, with the
    world pose it gives (object → world, (4, 4)); None when no try fits.

    Tries, in order: the region centre displaced by the position noise (only for an object
    alone in its region, or seated), the four corners of the free range in each orientation, then
    uniform positions cycling through the orientations. Every try draws the same numbers
    from ``rng`` (yaw, two position noises, two uniforms), so the sequence is reproducible.
    """
    rand = info.obj.randomization
    sigma_pos = max(float(rand.position_noise_m), 0.0)
    sigma_yaw = math.radians(max(float(rand.rotation_noise_deg), 0.0))
    n_corner_tries = len(_CORNERS) * len(orientations)
    for attempt in range(MAX_TRIES):
        yaw = float(rng.normal(0.0, sigma_yaw)) if sigma_yaw > 0 else 0.0
        dx, dy = (rng.normal(0.0, sigma_pos, 2) if sigma_pos > 0 else (0.0, 0.0))
        u, v = rng.random(2).tolist()
        # Seated assets sit in the middle of their seat whoever else is there.
        k = attempt - 1 if alone or orientations[0].seated else attempt
        if k < 0:
            orientation = orientations[0]
        elif k < n_corner_tries:
            orientation = orientations[k // len(_CORNERS)]
            u, v = _CORNERS[k % len(_CORNERS)]
        else:
            orientation = orientations[k % len(orientations)]
        ranges = _footprint_range(orientation, yaw, size)
        if ranges is None:  # a tight fit: no room for the yaw noise
            yaw = 0.0
            ranges = _footprint_range(orientation, yaw, size)
        (x_lo, x_hi), (y_lo, y_hi) = ranges
        if k < 0:
            x = min(max((x_lo + x_hi) / 2.0 + dx, x_lo), x_hi)
            y = min(max((y_lo + y_hi) / 2.0 + dy, y_lo), y_hi)
        else:
            x, y = x_lo + u * (x_hi - x_lo), y_lo + v * (y_hi - y_lo)
        angle = orientation.yaw_rad + yaw
        c, s = math.cos(angle), math.sin(angle)
        local = np.eye(4)
        local[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ orientation.rotation
        local[:3, 3] = (x, y, 0.0 if orientation.seated else -float(orientation.lo[2]))
        world = region_pose @ local
        if not boxes.collides(info, world, exclude, label):
            return local, world
    return None


def _overfull_message(uid: str, info: _Info, label: str, size: tuple[float, float, float],
                      frame: int, boxes: _FrameBoxes) -> str:
    lo, hi = info.entry.extent_min_m, info.entry.extent_max_m
    own = f"{hi[0] - lo[0]:.2f} × {hi[1] - lo[1]:.2f} m"
    region_area = size[0] * size[1]
    sharing = [a for lab, a in zip(boxes.labels, boxes.areas) if lab == label]
    full = 100.0 * sum(sharing) / region_area if region_area > 0 else 100.0
    blockers = ", ".join(repr(u) for u, _ in boxes.blockers.most_common(3))
    return (f"object {uid!r} ({info.obj.class_name}, footprint {own}) finds no free spot on {label} at "
            f"frame {frame} after {MAX_TRIES} tries: the {size[0]:.2f} × {size[1]:.2f} m region already "
            f"holds {len(sharing)} object(s) covering {full:.0f}% of its area"
            + (f"; in the way: {blockers}" if blockers else ""))
