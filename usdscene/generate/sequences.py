"""Dataset programs: sequence documents generated from one camera setup.

A *setup* scene (environment, cameras, lights, render settings, asset paths, ROI rules and any
fixed objects) becomes a *sequence* scene: the generator adds dynamic objects, their placement
relations to the environment's places, frame intervals and the frame range. Nothing here knows
a particular environment: it works from the catalog's places (their support regions) and each
class's supported relations and extent.

Strategies (:data:`STRATEGIES`):

* ``single-class``: one frame per (class, relation) that fits somewhere; the frame holds that
  class at every place whose region for that relation holds it ("backpacks on all the seats").
  Every fitting (class, relation, place) *combination* occurs exactly once.
* ``balanced``: ``frames × objects_per_frame`` instance-frames shared out so that every class
  has the same number of instance-frames (within 1); each class first takes every combination
  it fits, in random order, then random extra ones (relation first, uniform, then place), so
  every fitting combination occurs at least once when the frame count allows
  (:func:`usdscene.generate.combinations.frames_for_coverage`); the report lists those that do
  not.
* ``appearance``: like ``balanced``, with a random appearance variant and a random colour per
  object, and each object used for at most :data:`APPEARANCE_LIFETIME_FRAMES` frames.
* ``random``: the naive generator, the ablation of ``balanced``
  (:func:`usdscene.generate.sequence_plans.plan_random`): each instance a uniformly random class
  at a uniformly random free place where it fits; no equal counts, no coverage.

The modules beside this one hold the parts: :mod:`usdscene.generate.combinations` (what fits
where), :mod:`usdscene.generate.sequence_plans` (the per-frame plan of each strategy),
:mod:`usdscene.generate.laps` (seated passengers' laps) and :mod:`usdscene.generate.balance` (the
balance report).

Capacity: a support region (one relation of one place) holds at most one generated object per
frame, and only objects that :func:`usdscene.scene.placement.fits_region` accepts; regions of fixed
objects of the setup and of seated passengers are taken first. Then every generated document is
checked by running the placement exactly as composition will (same draws, see
:func:`check_composes`), so a generated document always composes.

Objects are reused across frames (a pool per class, the k-th instance of a class in a frame is
its k-th object), which keeps a 500-frame document at a few hundred USD prims; each relation
holds for one frame. The chosen appearance variant and colour of every object are written into
the document (explicit object data), so every label traces back to its variant and colour, and
the generator's seed and options to the report.

Passengers (``occupancy``): per frame, before the objects, that fraction of the places whose
``is_on`` region seats a passenger-kind class gets one. Each seated passenger draws its
``pose`` variant per frame (among the poses whose lap holds the object planned on it, if any);
passengers of one class and pose share a pool whose objects draw random appearance variants.
Seated passengers are supports: every support place their class declares (the ``lap``, per
pose: :func:`lap_regions`) is a *lap place* ``<seat>/lap`` that ``balanced`` and
``appearance`` fill like any region while somebody sits there; the document relates the object
``is_on`` the passenger object.
"""

from __future__ import annotations

import collections
import hashlib
import logging
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from usdscene.generate.balance import balance_report
from usdscene.generate.combinations import (Combination, Region, fitting_combinations, frames_for_coverage,
                                           most_combinations, region_conflicts, selected_places)
from usdscene.generate.laps import (PASSENGER_RELATION, Lap, lap_combinations, lap_place_name, passenger_seats,
                                   with_lap_places)
from usdscene.generate.sequence_plans import FrameSlots, plan_balanced, plan_random, plan_single_class
from usdscene.scene.catalog import COMBINED_SETS, Catalog, PlaceRegion
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import PLACEMENT_RELATIONS, FrameInterval, PlaceRef, Randomization, Relation, SceneObject, SceneSpec
from usdscene.scene.placement import fits_region
from usdscene.document.stage_schema import VARIANT_SET_APPEARANCE

log = logging.getLogger(__name__)

STRATEGIES = ("single-class", "balanced", "appearance", "random")
APPEARANCE_LIFETIME_FRAMES = 5
"""An ``appearance`` object keeps its look for at most this many frames (fresh looks often,
without a USD prim per instance-frame)."""
COLOR_DECIMALS = 4
# Second entropy word of the generator that draws world and sensor ranges (seeded with the
# generator seed and this), apart from the one that draws objects.
DOMAIN_STREAM = 28


@dataclass(frozen=True)
class GenerateOptions:
    """What to generate.

    Attributes:
        strategy: one of :data:`STRATEGIES`.
        frames: sequence length for ``balanced``/``appearance``; None = what full coverage
            needs (:func:`frames_for_coverage`). ``single-class`` decides its own length.
        seed: seed of the generator and of the document (composition draws from it too).
        classes: object classes to place; empty = every ``object``-kind class of the catalog.
        place_patterns: shell-style patterns (``seat_*``) of the places to use; empty = all.
        occupancy: fraction (0..1) of the passenger seats taken per frame.
        objects_per_frame: generated objects per frame (``balanced``/``appearance``); None = the
            class count, or what coverage within ``frames`` needs when ``frames`` is given.
        position_noise_m: position noise (standard deviation, metres) of generated objects.
        rotation_noise_deg: yaw noise (standard deviation, degrees) of generated objects.
        split: training split rule written into the document (``metadata.usdscene.split``,
            :mod:`usdscene.document.splits` syntax); "" keeps the setup's own rule, if any.
        split_seed: seed of a ``fractions`` split rule.
    """

    strategy: str
    frames: int | None = None
    seed: int = 0
    classes: tuple[str, ...] = ()
    place_patterns: tuple[str, ...] = ()
    occupancy: float = 0.0
    objects_per_frame: int | None = None
    position_noise_m: float = 0.03
    rotation_noise_deg: float = 20.0
    split: str = ""
    split_seed: int = 0


@dataclass(frozen=True)
class GeneratedSequence:
    """A generated sequence.

    Attributes:
        scene: the setup plus the generated objects, places, relations and frame range.
        report: the balance report (see :func:`balance_report`) plus ``generator`` (strategy,
            seed, options) and ``coverage`` (fitting combinations, the uncovered ones, the
            frame count that covers all).
    """

    scene: SceneSpec
    report: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# The generator


def generate_sequence(setup: SceneSpec, catalog: Catalog, options: GenerateOptions, *,
                      setup_sha256: str = "") -> GeneratedSequence:
    """Generate a sequence scene from a setup scene.

    Args:
        setup: the setup (environment, cameras, lights, render settings, fixed objects).
        catalog: asset catalog with the environment and the classes.
        options: strategy and knobs.
        setup_sha256: digest of the setup document, recorded in the report.

    Returns:
        The sequence and its report.

    Raises:
        DocumentError: bad options (unknown strategy, class or pattern, occupancy outside
            [0, 1]), a setup without environment.
    """
    from usdscene.scene.catalog import scene_catalog

    catalog = scene_catalog(catalog, setup)  # places the setup declares itself
    classes, combos, passenger_classes = _check_options(setup, catalog, options)
    rng = np.random.default_rng(options.seed)
    n_places_regions = {c.region for c in combos}
    all_regions = sorted((name, relation) for name, place in catalog.places(setup.environment).items()
                         for relation in place.regions)
    conflicts = region_conflicts(catalog, setup.environment, all_regions)
    fixed_taken = [(region, when) for fixed_region, when in _fixed_regions(setup)
                   for region in conflicts.get(fixed_region, {fixed_region})]

    laps = lap_regions(catalog, setup.environment, passenger_classes, options)
    if laps:
        conflicts = region_conflicts(with_lap_places(catalog, setup.environment, laps), setup.environment,
                                     all_regions + sorted(laps))
    if options.strategy == "single-class":
        plan = plan_single_class(combos, conflicts, (region for region, _ in fixed_taken))
        n_frames = len(plan)
        per_frame = max((len(p) for p in plan), default=0)
        busy = [{r for c in combos_ for r in conflicts.get(c.region, {c.region})} | _taken_at(fixed_taken, f)
                for f, combos_ in enumerate(plan)]
        seated = _draw_seats(busy, setup, catalog, passenger_classes, options, conflicts, rng)
        lap_combos: tuple[Combination, ...] = ()
    else:
        lap_combos = lap_combinations(catalog, classes, laps)
        combos = tuple(sorted(combos + lap_combos))
        per_frame = options.objects_per_frame
        if per_frame is None:
            per_frame = len(classes) if options.frames is None else math.ceil(
                len(classes) * most_combinations(combos, classes) / options.frames)
        per_frame = max(1, min(per_frame, len(n_places_regions)))
        n_frames = options.frames or frames_for_coverage(combos, classes, per_frame)
        seated = _draw_seats([_taken_at(fixed_taken, f) for f in range(n_frames)], setup, catalog,
                             passenger_classes, options, conflicts, rng)
        seat_laps = _laps_by_seat(laps)
        taken = [_taken_at(fixed_taken, f) | _seated_taken(row, laps, seat_laps, conflicts)
                 for f, row in enumerate(seated)]
        plan_strategy = plan_random if options.strategy == "random" else plan_balanced
        plan = plan_strategy(combos, classes, FrameSlots(n_frames, per_frame, taken), conflicts, rng)

    slots = _pool_indices(plan, options.strategy)
    looks = _draw_looks(plan, slots, catalog, setup.environment, options, rng)
    seats = _dress_passengers(seated, plan, catalog, laps, rng)
    scene = _sequence_scene(setup, plan, slots, looks, seats, options)
    drawn = None
    if (scene.world is not None and scene.world.randomize) or any(
            c.sensor is not None and c.sensor.randomize for c in scene.cameras):
        from usdscene.document.imaging import randomize_scene

        # A generator of its own: the objects drawn above stay what they were without ranges.
        scene, drawn = randomize_scene(scene, np.random.default_rng([int(options.seed), DOMAIN_STREAM]))
    report = _sequence_report(scene, catalog, options, plan, combos, classes, (per_frame, n_frames), setup_sha256)
    if drawn is not None:
        report["domain_randomization"] = drawn
    return GeneratedSequence(scene=scene, report=report)


def _sequence_report(scene: SceneSpec, catalog: Catalog, options: GenerateOptions, plan, combos, classes,
                     sizes: tuple[int, int], setup_sha256: str) -> dict:
    """The generated sequence's report: its balance, the generator's options and what the plan
    covers of the combinations (``sizes``: objects per frame and frames)."""
    per_frame, n_frames = sizes
    covered = {c for frame in plan for c in frame}
    uncovered = sorted(set(combos) - covered)
    report = balance_report(scene, catalog)
    report["generator"] = {
        "strategy": options.strategy, "seed": int(options.seed), "setup_sha256": setup_sha256,
        "classes": list(classes), "place_patterns": list(options.place_patterns),
        "occupancy": float(options.occupancy), "objects_per_frame": int(per_frame),
        "frames": int(n_frames), "position_noise_m": float(options.position_noise_m),
        "rotation_noise_deg": float(options.rotation_noise_deg),
        "split": scene.split_rule, "split_seed": int(scene.split_seed)}
    report["coverage"] = {
        "combinations": len(combos), "covered": len(covered), "uncovered_count": len(uncovered),
        "uncovered": [[c.class_name, c.relation, c.place] for c in uncovered],
        "frames_for_full_coverage": (n_frames if options.strategy == "single-class"
                                     else frames_for_coverage(combos, classes, per_frame)),
        "classes_fitting_nowhere": sorted(set(options.classes or catalog.classes("object")) - set(classes)),
    }
    single = _without_variants(catalog, classes, options)
    if single:  # only then: reports of documents without such classes stay as they were
        report["coverage"]["classes_without_variants"] = single
    return report


def _without_variants(catalog: Catalog, classes: Sequence[str], options: GenerateOptions) -> list[str]:
    """Classes ``appearance`` cannot vary (one appearance variant or none), warned about: a USD
    file's variant sets on child prims are not lifted (see :mod:`usdscene.assetgen.asset_import`)."""
    if options.strategy != "appearance":
        return []
    single = [c for c in classes if len(catalog[c].appearances) < 2]
    for name in single:
        log.warning("class %r has %d appearance variant(s); the appearance strategy cannot vary it",
                    name, len(catalog[name].appearances))
    return single


def _check_options(setup: SceneSpec, catalog: Catalog, options: GenerateOptions):
    problems = ProblemCollector()
    if options.strategy not in STRATEGIES:
        problems.add("strategy", f"unknown strategy {options.strategy!r}; expected one of {', '.join(STRATEGIES)}")
    if setup.environment is None:
        problems.add("metadata.usdscene.environment", "the setup document names no environment; "
                                                      "the generator places objects at its places")
    elif setup.environment not in catalog:
        problems.add("metadata.usdscene.environment", f"environment {setup.environment!r} is not in the "
                                                      f"asset catalog (known: {', '.join(catalog.classes('environment'))})")
    if options.frames is not None and options.frames < 1:
        problems.add("--frames", f"frame count must be at least 1, got {options.frames}")
    if options.frames is not None and options.strategy == "single-class":
        problems.add("--frames", "single-class decides its length (one frame per class and relation); "
                                 "leave --frames out")
    if options.objects_per_frame is not None and options.objects_per_frame < 1:
        problems.add("--objects-per-frame", f"must be at least 1, got {options.objects_per_frame}")
    if not 0.0 <= options.occupancy <= 1.0:
        problems.add("--occupancy", f"occupancy must be a fraction in [0, 1], got {options.occupancy}")
    if options.seed < 0:
        problems.add("--seed", f"seed must be non-negative, got {options.seed}")
    if options.split:
        from usdscene.document.splits import parse_split

        try:
            parse_split(options.split)
        except DocumentError as exc:
            problems.extend(exc.problems)
    if options.split_seed < 0:
        problems.add("--split-seed", f"seed must be non-negative, got {options.split_seed}")
    known = catalog.classes("object")
    for name in options.classes:
        if name not in catalog or catalog[name].kind != "object":
            problems.add("--classes", f"unknown object class {name!r} (known: {', '.join(known)})")
    problems.raise_if_any(DocumentError)
    places = selected_places(catalog, setup.environment, options.place_patterns)
    if options.place_patterns and not places:
        problems.add("--places", f"no place of {setup.environment!r} matches "
                                 f"{', '.join(repr(p) for p in options.place_patterns)}")
    wanted = tuple(sorted(dict.fromkeys(options.classes))) or known
    combos = fitting_combinations(catalog, setup.environment, wanted, options.place_patterns)
    classes = tuple(c for c in wanted if any(k.class_name == c for k in combos))
    if not classes:
        problems.add("--classes", f"none of the classes {', '.join(wanted) or '(none)'} fits any selected "
                                  f"place of {setup.environment!r}")
    for name in sorted(set(wanted) - set(classes)):
        log.warning("class %r fits no selected place of %r; it is left out", name, setup.environment)
    problems.raise_if_any(DocumentError)
    return classes, combos, catalog.classes("passenger")


def _fixed_regions(setup: SceneSpec) -> list[tuple[Region, tuple[FrameInterval, ...]]]:
    """Regions the setup's own objects use, with when (empty intervals = always)."""
    places = setup.place_by_uid()
    objects = setup.object_by_uid()
    out = []
    for rel in setup.relations:
        if rel.type in PLACEMENT_RELATIONS and rel.object_uid in places and rel.subject_uid in objects:
            intervals = rel.frame_intervals or objects[rel.subject_uid].frame_intervals
            out.append(((places[rel.object_uid].name, rel.type), tuple(intervals)))
    return out


def _taken_at(fixed: Sequence[tuple[Region, tuple[FrameInterval, ...]]], frame: int) -> set[Region]:
    return {region for region, intervals in fixed if not intervals or any(frame in iv for iv in intervals)}


def _random_color(rng: np.random.Generator) -> tuple[float, float, float]:
    return tuple(round(float(v), COLOR_DECIMALS) for v in rng.random(3))  # type: ignore[return-value]


def _variants_fitting_everywhere(plan: list[list[Combination]], slots: list[list[int]], catalog: Catalog,
                                 environment: str) -> dict[tuple[str, int], tuple[str, ...]]:
    """(class, pool index) → the appearance variants that fit every place region that pool
    object visits, for classes whose variants differ in size (``variant_extents``). The
    default variant fits them all (the plan is made with it), so it is the fallback."""
    places = catalog.places(environment)
    sizes: dict[tuple[str, int], set] = collections.defaultdict(set)
    for frame, combos in enumerate(plan):
        for combo, slot in zip(combos, slots[frame]):
            # Lap places move with the passenger's pose; the placement checks those.
            if catalog[combo.class_name].variant_extents and "/" not in combo.place:
                sizes[(combo.class_name, slot)].add(tuple(places[combo.place].regions[combo.relation].size_m))
    out = {}
    for key, needed in sizes.items():
        entry = catalog[key[0]]
        out[key] = tuple(v for v in entry.appearances
                         if all(fits_region(entry.for_variants({VARIANT_SET_APPEARANCE: v}), size) for size in needed)
                         ) or (entry.default_appearance,)
    return out


def _draw_looks(plan: list[list[Combination]], slots: list[list[int]], catalog: Catalog, environment: str,
                options: GenerateOptions, rng: np.random.Generator) -> list[list[tuple[str | None, tuple[float, float, float] | None]]]:
    """Per frame and instance: (appearance variant, colour). ``appearance`` draws one per
    object of the pool (``slots``, see :func:`_pool_indices`) among the variants that fit every
    region the object visits, the others use the class default. A class that cannot be
    recoloured gets no colour (a colour is drawn all the same, so later draws stay put)."""
    drawn: dict[tuple[str, int], tuple] = {}
    fitting_variants = (_variants_fitting_everywhere(plan, slots, catalog, environment)
                        if options.strategy == "appearance" else {})
    out = []
    for frame, combos in enumerate(plan):
        row = []
        for combo, slot in zip(combos, slots[frame]):
            entry = catalog[combo.class_name]
            variants = entry.appearances
            if options.strategy != "appearance":
                row.append((entry.default_appearance, None))
                continue
            key = (combo.class_name, slot)
            if key not in drawn:
                fitting = fitting_variants.get(key, variants)
                variant = fitting[int(rng.integers(len(fitting)))] if fitting else None
                color = _random_color(rng)  # drawn for every class, so later draws do not move
                drawn[key] = (variant, color if entry.recolourable else None)
            row.append(drawn[key])
        out.append(row)
    return out


def _pool_indices(plan: list[list[Combination]], strategy: str) -> list[list[int]]:
    """Per frame and instance: the index of its object in the class's pool.

    The k-th instance of a class in a frame is object k of the pool; ``appearance`` moves on
    to fresh objects every :data:`APPEARANCE_LIFETIME_FRAMES` frames.
    """
    lifetime = APPEARANCE_LIFETIME_FRAMES if strategy == "appearance" else None
    width: collections.Counter = collections.Counter()  # class → pool objects per frame block
    for combos in plan:
        for name, count in collections.Counter(c.class_name for c in combos).items():
            width[name] = max(width[name], count)
    out = []
    for frame, combos in enumerate(plan):
        seen: collections.Counter = collections.Counter()
        block = frame // lifetime if lifetime else 0
        row = []
        for combo in combos:
            row.append(block * width[combo.class_name] + seen[combo.class_name])
            seen[combo.class_name] += 1
        out.append(row)
    return out


def lap_regions(catalog: Catalog, environment: str, passenger_classes: Sequence[str],
                options: GenerateOptions) -> dict[Region, Lap]:
    """The support regions seated passengers offer, per seat: ``(seat_03A/lap, is_on)`` → :class:`Lap`.

    A passenger class offers the ``is_on`` places its catalog entry declares (per pose
    variant, :meth:`usdscene.scene.catalog.AssetEntry.places_for`); seated on a seat's ``is_on``
    region, without noise, its asset frame is that region's frame. Empty when ``occupancy`` is 0.
    """
    if options.occupancy <= 0.0:
        return {}
    out: dict[Region, Lap] = {}
    places = catalog.places(environment)
    for class_name in passenger_classes:
        entry = catalog[class_name]
        if not entry.declares_support(PASSENGER_RELATION):
            continue
        # Combined sets (pose+appearance) give exact laps at placement; plans use the one set.
        variant_set = next(iter(sorted(n for n in entry.variant_places if COMBINED_SETS not in n)), "")
        variants = entry.variants.get(variant_set, ()) if variant_set else ("",)
        for seat in passenger_seats(catalog, environment, class_name, options.place_patterns):
            seat_pose = places[seat].regions[PASSENGER_RELATION].pose
            by_place: dict[str, dict[str, PlaceRegion]] = collections.defaultdict(dict)
            for variant in variants:
                found = entry.support_region(PASSENGER_RELATION, {variant_set: variant} if variant_set else None)
                if found is not None:
                    name, region = found
                    by_place[name][variant] = PlaceRegion(region.relation, seat_pose.compose(region.pose),
                                                          region.size_m)
            for name, by_variant in sorted(by_place.items()):
                # One passenger class per seat offers laps (the first by name): a lap place
                # name must say whose lap it is.
                out.setdefault((lap_place_name(seat, name), PASSENGER_RELATION),
                               Lap(class_name, name, dict(by_variant), variant_set))
    return out


def _draw_seats(busy: Sequence[set[Region]], setup: SceneSpec, catalog: Catalog,
                passenger_classes: Sequence[str], options: GenerateOptions,
                conflicts: Mapping[Region, frozenset[Region]],
                rng: np.random.Generator) -> list[list[tuple[str, str]]]:
    """Per frame: (passenger class, seat place) of each passenger.

    ``occupancy`` of the seats, among those ``busy`` (per frame: regions already used) leaves
    free, in random seats, each with a random passenger class that fits it.
    """
    if options.occupancy <= 0.0 or not passenger_classes:
        return [[] for _ in busy]
    seats_by_class = {c: set(passenger_seats(catalog, setup.environment, c, options.place_patterns))
                      for c in passenger_classes}
    all_seats = sorted(set().union(*seats_by_class.values()))
    wanted = int(round(options.occupancy * len(all_seats)))
    out = []
    for taken in busy:
        free = [s for s in all_seats if (s, PASSENGER_RELATION) not in taken]
        chosen = [free[int(i)] for i in rng.permutation(len(free))]
        # Seats whose regions overlap take one passenger.
        free, taken_now = [], set()
        for seat in chosen:
            if (seat, PASSENGER_RELATION) not in taken_now:
                free.append(seat)
                taken_now |= conflicts.get((seat, PASSENGER_RELATION), {(seat, PASSENGER_RELATION)})
        row = []
        for seat in free[:wanted]:
            fitting = [c for c in passenger_classes if seat in seats_by_class[c]]
            row.append((fitting[int(rng.integers(len(fitting)))], seat))
        out.append(row)
    return out


def _laps_by_seat(laps: Mapping[Region, Lap]) -> dict[str, list[tuple[Region, Lap]]]:
    """Seat → its lap regions (sorted): those whose place name starts with ``<seat>/``
    (:func:`lap_place_name`). Built once, so the per-frame steps look a seat's laps up instead
    of scanning every lap for every passenger."""
    out: dict[str, list[tuple[Region, Lap]]] = collections.defaultdict(list)
    for region, lap in sorted(laps.items()):
        name = region[0]
        # Every "/" may end the seat's name (a seat name could hold one itself).
        for cut in (i for i, ch in enumerate(name) if ch == "/"):
            out[name[:cut]].append((region, lap))
    return dict(out)


def _seated_taken(row: Sequence[tuple[str, str]], laps: Mapping[Region, Lap],
                  seat_laps: Mapping[str, Sequence[tuple[Region, Lap]]],
                  conflicts: Mapping[Region, frozenset[Region]]) -> set[Region]:
    """Regions a frame's passengers take: their seats and what overlaps them, except their own
    laps; and the laps of every seat without a passenger offering one. ``seat_laps`` is
    :func:`_laps_by_seat` of ``laps``."""
    offered = {region for cls, seat in row for region, lap in seat_laps.get(seat, ())
               if lap.passenger_class == cls}
    taken = set(laps) - offered
    for _, seat in row:
        taken |= set(conflicts.get((seat, PASSENGER_RELATION), {(seat, PASSENGER_RELATION)})) - offered
    return taken


def _dress_passengers(seated: Sequence[Sequence[tuple[str, str]]], plan: list[list[Combination]],
                      catalog: Catalog, laps: Mapping[Region, Lap],
                      rng: np.random.Generator) -> list[list[tuple[str, str | None, int, str, str | None]]]:
    """Per frame: (passenger class, pose variant, pool index, seat place, appearance) of each
    passenger.

    Each passenger draws its pose (uniform) among the class's pose variants, or, when the plan
    puts an object on its lap, among the poses whose lap holds that object. Passengers of one
    class and pose share a pool: the k-th such passenger of a frame is pool object k, which
    draws its appearance variant when first used. Classes without a pose variant set keep the
    asset's default (pose None).
    """
    from usdscene.document.stage_schema import VARIANT_SET_POSE

    looks: dict[tuple[str, str | None, int], str | None] = {}
    seat_laps = _laps_by_seat(laps)
    out = []
    for frame, row in enumerate(seated):
        on_lap = {c.place: catalog[c.class_name] for c in plan[frame] if (c.place, c.relation) in laps}
        dealt: collections.Counter = collections.Counter()
        dressed = []
        for class_name, seat in row:
            entry = catalog[class_name]
            poses = entry.variants.get(VARIANT_SET_POSE, ())
            for (place, _), lap in seat_laps.get(seat, ()):
                if place in on_lap and lap.passenger_class == class_name:
                    poses = tuple(p for p in poses if p in lap.by_variant
                                  and fits_region(on_lap[place], lap.by_variant[p].size_m, upright_only=True))
            pose = poses[int(rng.integers(len(poses)))] if poses else None
            slot = dealt[(class_name, pose)]
            dealt[(class_name, pose)] += 1
            if (class_name, pose, slot) not in looks:
                variants = entry.appearances
                looks[(class_name, pose, slot)] = variants[int(rng.integers(len(variants)))] if variants else None
            dressed.append((class_name, pose, slot, seat, looks[(class_name, pose, slot)]))
        out.append(dressed)
    return out


def _sequence_scene(setup: SceneSpec, plan: list[list[Combination]], slots: list[list[int]], looks, seats,
                    options: GenerateOptions) -> SceneSpec:
    """The setup plus pooled objects, their per-frame relations and the frame range."""
    int_uids = [int(u) for u in (*(o.uid for o in setup.objects), *(p.uid for p in setup.places),
                                 *(lt.uid for lt in setup.lights)) if u.isdigit()]
    next_uid = iter(range(max(int_uids, default=-1) + 1, 1 << 62))
    rel_uids = [int(r.uid) for r in setup.relations if r.uid.isdigit()]
    next_rel = iter(range(max(rel_uids, default=-1) + 1, 1 << 62))
    place_uid = {p.name: p.uid for p in setup.places}
    new_places: list[PlaceRef] = []

    def place_ref(name: str) -> str:
        if name not in place_uid:
            place_uid[name] = str(next(next_uid))
            new_places.append(PlaceRef(place_uid[name], name))
        return place_uid[name]

    noise = Randomization(position_noise_m=float(options.position_noise_m),
                          rotation_noise_deg=float(options.rotation_noise_deg))
    # (class, pose, pool index) → frames, look; then relations per frame. Objects have pose
    # "", passengers their pose variant and a pool index below zero.
    uses: dict[tuple[str, str, int], list[int]] = collections.defaultdict(list)
    look_of: dict[tuple[str, str, int], tuple] = {}
    per_frame: list[list[tuple[tuple[str, str, int], str, str | tuple[str, str, int]]]] = []
    for frame, combos in enumerate(plan):
        row: list = []
        sitter: dict[str, tuple[str, str, int]] = {}
        for class_name, pose, slot, seat, appearance in seats[frame]:
            key = (class_name, pose or "", -1 - slot)
            uses[key].append(frame)
            look_of[key] = (appearance, None)
            sitter[seat] = key
            row.append((key, PASSENGER_RELATION, seat))
        for combo, slot, look in zip(combos, slots[frame], looks[frame]):
            key = (combo.class_name, "", slot)
            uses[key].append(frame)
            look_of[key] = look
            seat = combo.place.split("/", 1)[0]
            # On a lap: related to the passenger sitting there.
            row.append((key, combo.relation, sitter[seat] if "/" in combo.place else combo.place))
        per_frame.append(row)
    uid_of: dict[tuple[str, str, int], str] = {}
    objects = list(setup.objects)
    for key in sorted(uses, key=lambda k: (k[0], k[2] < 0, k[1], abs(k[2]))):
        class_name, pose, slot = key
        uid = str(next(next_uid))
        uid_of[key] = uid
        appearance, color = look_of[key]
        if slot >= 0:
            label = f"{class_name}_{slot:04d}"
        else:
            label = f"{class_name}_{pose + '_' if pose else ''}seated_{-1 - slot:03d}"
        objects.append(SceneObject(
            uid=uid, name=label, class_name=class_name,
            frame_intervals=_intervals(uses[key]), appearance=appearance, pose_variant=pose or None,
            color_rgb=color, randomization=noise if slot >= 0 else Randomization()))
    relations = list(setup.relations)
    for frame, row in enumerate(per_frame):
        for key, relation, target in row:
            relations.append(Relation(uid=str(next(next_rel)), type=relation, subject_uid=uid_of[key],
                                      object_uid=uid_of[target] if isinstance(target, tuple) else place_ref(target),
                                      frame_intervals=(FrameInterval(frame, frame),)))
    n_frames = max(len(plan), 1)
    split = dict(split_rule=options.split, split_seed=int(options.split_seed)) if options.split else {}
    return replace(setup, **split, frame_start=0, frame_end=n_frames - 1, objects=tuple(objects),
                   places=tuple(setup.places) + tuple(new_places), relations=tuple(relations),
                   seed=int(options.seed),
                   description=(setup.description + " " if setup.description else "")
                   + f"Generated by usdscene generate {options.strategy} (seed {options.seed}).")


def _intervals(frames: Iterable[int]) -> tuple[FrameInterval, ...]:
    runs: list[list[int]] = []
    for f in sorted(set(frames)):
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return tuple(FrameInterval(a, b) for a, b in runs)


# --------------------------------------------------------------------------------------------
# Checks and the written document


def check_composes(scene: SceneSpec, catalog: Catalog) -> None:
    """Run the placement of ``scene`` with the draws composition will make.

    Raises:
        CompositionError: what composing the scene would raise.
    """
    from usdscene.scene.compose import draw_looks  # the composer's own first draws (no pxr at import)
    from usdscene.scene.placement import place_objects

    rng = np.random.default_rng(scene.seed)
    looks = draw_looks(scene, catalog, rng)
    place_objects(scene, catalog, rng, appearances={uid: look[0] for uid, look in looks.items()})


def report_path(document: str | os.PathLike) -> Path:
    """``DOC.report.json`` next to the document."""
    path = Path(document)
    return path.with_name(path.name + ".report.json")


def generate_document(setup_path: str | os.PathLike, out_path: str | os.PathLike,
                      options: GenerateOptions) -> GeneratedSequence:
    """Read a setup document, generate, check that it composes, write ``DOC`` and
    ``DOC.report.json``.

    Asset paths of the setup are rewritten relative to the output document's folder.

    Raises:
        DocumentError: bad setup document or options.
        AssetError: bad asset catalog.
        CompositionError: the generated document would not compose (a defect of the generator).
    """
    from usdscene.bulk import paused_collection

    with paused_collection():  # the document is millions of live containers (see usdscene.bulk)
        return _generate_document(Path(setup_path), Path(out_path), options)


def _generate_document(setup_path: Path, out_path: Path, options: GenerateOptions) -> GeneratedSequence:
    setup, catalog, provenance = read_setup(setup_path, out_path)
    generated = generate_sequence(setup, catalog, options, setup_sha256=provenance.source_sha256)
    return replace(generated, report=write_generated(generated.scene, generated.report, out_path, catalog,
                                                     provenance))


def read_setup(setup_path: Path, out_path: Path):
    """A setup document and its asset catalog, with the paths the setup names (asset folders,
    a world's HDRI) made relative to the folder of the document to be written at ``out_path``.

    Returns:
        ``(setup SceneSpec, Catalog, provenance of the setup file)``.

    Raises:
        DocumentError: bad setup document. AssetError: bad asset catalog.
    """
    from usdscene.converters.openlabel import load_with_provenance, read_loaded
    from usdscene.scene.catalog import load_catalog

    document, provenance = load_with_provenance(setup_path)
    setup = read_loaded(document, provenance)
    base = Path(setup_path).resolve().parent
    catalog = load_catalog(setup.asset_paths, base_dir=base)
    out_dir = Path(out_path).resolve().parent
    moved = tuple(os.path.relpath(p if os.path.isabs(p) else base / p, out_dir).replace(os.sep, "/")
                  for p in setup.asset_paths)
    setup = replace(setup, asset_paths=moved)
    if setup.world is not None and setup.world.hdri and not os.path.isabs(setup.world.hdri):
        # relative to the document, like asset_paths
        setup = replace(setup, world=replace(setup.world, hdri=os.path.relpath(
            base / setup.world.hdri, out_dir).replace(os.sep, "/")))
    return setup, catalog, provenance


def write_generated(scene: SceneSpec, report: dict, out_path: Path, catalog, provenance) -> dict:
    """Check that a generated scene composes as it will be read back, then write it to
    ``out_path`` and its report (completed with the document's name and sha256) to
    :func:`report_path` atomically; returns the written report.

    Raises:
        CompositionError: the document would not compose (a defect of the generator); nothing
            is written.
    """
    from usdscene.converters.openlabel import read_loaded, write_document, write_openlabel
    from usdscene.files import remove_stale_temporaries, write_json_atomic

    written = write_openlabel(scene)
    # What composition will read: the written document, read back.
    check_composes(read_loaded(written, provenance), catalog)
    # A killed earlier run's half-written document or report (their temporary files).
    remove_stale_temporaries(Path(out_path).parent, recursive=False, name=Path(out_path).name + ".")
    write_document(out_path, written)
    report = dict(report)
    report["document"] = Path(out_path).name
    report["document_sha256"] = hashlib.sha256(Path(out_path).read_bytes()).hexdigest()
    write_json_atomic(report_path(out_path), report)
    return report
