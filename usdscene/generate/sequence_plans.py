"""Plans of the sequence generators: per frame, the combinations it holds.

One function per strategy of :mod:`usdscene.generate.sequences`: ``single-class``
(:func:`plan_single_class`), ``balanced`` and ``appearance`` (:func:`plan_balanced`) and the
naive ablation ``random`` (:func:`plan_random`). A plan is a list of frames, each a list of
:class:`usdscene.generate.combinations.Combination`; draws come from the generator passed in.
"""

from __future__ import annotations

import collections
import logging
from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

import numpy as np

from usdscene.generate.combinations import Combination, Region

log = logging.getLogger(__name__)

def plan_single_class(combinations: Sequence[Combination], conflicts: Mapping[Region, frozenset[Region]],
                      blocked: Iterable[Region] = ()) -> list[list[Combination]]:
    """One frame per (class, relation), holding every fitting place (sorted); places whose
    regions overlap (:func:`region_conflicts`) go to a further frame of the same group.
    ``blocked`` regions (those of the setup's fixed objects) are left out."""
    blocked = set(blocked)
    groups: dict[tuple[str, str], list[Combination]] = collections.defaultdict(list)
    for combo in sorted(combinations):
        if combo.region not in blocked:
            groups[(combo.class_name, combo.relation)].append(combo)
    frames = []
    for key in sorted(groups):
        pending = groups[key]
        while pending:
            used: set[Region] = set()
            frame, later = [], []
            for combo in pending:
                if combo.region in used:
                    later.append(combo)
                else:
                    frame.append(combo)
                    used |= conflicts.get(combo.region, {combo.region})
            frames.append(frame)
            pending = later
    return frames


@dataclass(frozen=True)
class FrameSlots:
    """The frames a plan fills (:func:`plan_balanced`, :func:`plan_random`).

    Attributes:
        count: sequence length, frames.
        objects_per_frame: instance-frames (draws) per frame.
        taken: per frame, regions already used (fixed objects, passengers); not changed.
    """

    count: int
    objects_per_frame: int
    taken: Sequence[set[Region]]


def plan_balanced(combinations: Sequence[Combination], classes: Sequence[str], slots: FrameSlots,
                  conflicts: Mapping[Region, frozenset[Region]],
                  rng: np.random.Generator) -> list[list[Combination]]:
    """Share ``n_frames × objects_per_frame`` instance-frames equally among the classes.

    Args:
        combinations: the fitting combinations (:func:`fitting_combinations`).
        classes: classes to balance (each has at least one combination).
        slots: the frames: how many, instance-frames per frame, regions already used per frame
            (fixed objects).
        conflicts: region → overlapping regions (:func:`region_conflicts`); one object
            among them per frame.
        rng: generator (draw order: class shares, per-class orders and extras, the shuffle).

    Returns:
        Per frame, its combinations. A class that cannot get a free region in any frame with
        room loses that instance (logged; the report shows the counts).
    """
    n_frames, objects_per_frame, taken = slots.count, slots.objects_per_frame, slots.taken
    by_class: dict[str, list[Combination]] = collections.defaultdict(list)
    for combo in sorted(combinations):
        by_class[combo.class_name].append(combo)
    total = n_frames * objects_per_frame
    base, extra = divmod(total, len(classes))
    lucky = set(int(i) for i in rng.permutation(len(classes))[:extra])
    instances: list[Combination] = []
    firsts: set[int] = set()  # positions of each class's first pass over its combinations
    for index, class_name in enumerate(classes):
        want = base + (1 if index in lucky else 0)
        own = by_class[class_name]
        order = [own[int(i)] for i in rng.permutation(len(own))]
        chosen = order[:want]
        firsts.update(range(len(instances), len(instances) + len(chosen)))
        relations = sorted({c.relation for c in own})
        by_relation = {r: [c for c in own if c.relation == r] for r in relations}
        for _ in range(want - len(chosen)):
            pool = by_relation[relations[int(rng.integers(len(relations)))]]
            chosen.append(pool[int(rng.integers(len(pool)))])
        instances.extend(chosen)
    # Random order, but coverage first, and within it classes with the fewest combinations
    # first: they have the fewest regions to choose from once frames fill up.
    shuffled = [int(i) for i in rng.permutation(len(instances))]
    shuffled.sort(key=lambda i: (i not in firsts, len(by_class[instances[i].class_name])))
    instances = [instances[i] for i in shuffled]

    frames: list[list[Combination]] = [[] for _ in range(n_frames)]
    used = [set(t) for t in taken]
    cursor = 0
    dropped: collections.Counter = collections.Counter()
    for combo in instances:
        frame = _free_frame(combo.region, frames, used, objects_per_frame, cursor)
        if frame is None:
            # Its own region is busy wherever there is room: any other region of the class.
            for alt in (by_class[combo.class_name][int(i)] for i in rng.permutation(len(by_class[combo.class_name]))):
                frame = _free_frame(alt.region, frames, used, objects_per_frame, cursor)
                if frame is not None:
                    combo = alt
                    break
        if frame is None:
            dropped[combo.class_name] += 1
            continue
        frames[frame].append(combo)
        used[frame] |= conflicts.get(combo.region, {combo.region})
        cursor = (frame + 1) % n_frames
    for class_name, count in sorted(dropped.items()):
        log.warning("no frame had a free region for %d %s instance(s); fewer objects per frame "
                    "(or more frames) keep the classes balanced", count, class_name)
    return frames


def plan_random(combinations: Sequence[Combination], classes: Sequence[str], slots: FrameSlots,
                conflicts: Mapping[Region, frozenset[Region]],
                rng: np.random.Generator) -> list[list[Combination]]:
    """The naive generator: uniform random classes and places, no balancing.

    Per frame, ``objects_per_frame`` draws: a class, uniformly; a place, uniformly among the
    places with a free region that holds the class; a relation, uniformly among the class's
    free regions at that place. A class with no free region left in the frame loses that
    instance (the frame holds fewer objects). Class counts are whatever the draws give, and
    nothing makes every combination occur: this is what :func:`plan_balanced` is measured
    against.

    Args:
        combinations: the fitting combinations (:func:`fitting_combinations`).
        classes: classes to draw from (each has at least one combination).
        slots: the frames: how many, draws per frame, regions already used per frame (fixed
            objects, passengers).
        conflicts: region → overlapping regions (:func:`region_conflicts`).
        rng: generator (draw order per frame and draw: class, place, relation).

    Returns:
        Per frame, its combinations.
    """
    n_frames, objects_per_frame, taken = slots.count, slots.objects_per_frame, slots.taken
    by_class: dict[str, list[Combination]] = collections.defaultdict(list)
    for combo in sorted(combinations):
        by_class[combo.class_name].append(combo)
    frames: list[list[Combination]] = []
    for frame in range(n_frames):
        used = set(taken[frame])
        row: list[Combination] = []
        for _ in range(objects_per_frame):
            class_name = classes[int(rng.integers(len(classes)))]
            free = [c for c in by_class[class_name] if c.region not in used]
            if not free:
                continue
            places = sorted({c.place for c in free})
            place = places[int(rng.integers(len(places)))]
            here = [c for c in free if c.place == place]
            combo = here[int(rng.integers(len(here)))]
            row.append(combo)
            used |= conflicts.get(combo.region, {combo.region})
        frames.append(row)
    return frames


def _free_frame(region: Region, frames: list[list[Combination]], used: list[set[Region]],
                capacity: int, start: int) -> int | None:
    """First frame from ``start`` (cyclic) with room and ``region`` free."""
    n = len(frames)
    for k in range(n):
        f = (start + k) % n
        if len(frames[f]) < capacity and region not in used[f]:
            return f
    return None
