"""What fits where: the (class, relation, place) combinations a sequence generator draws from.

A *region* is one support region of the environment (a place and one of its relations); a
*combination* puts one class into one region. :func:`fitting_combinations` lists those whose
region holds the class (:func:`usdscene.scene.placement.fits_region`), and
:func:`region_conflicts` which regions overlap, so that they take one object between them per
frame. The design of the generators is in :mod:`usdscene.generate.sequences`.
"""

from __future__ import annotations

import collections
import fnmatch
import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from usdscene.scene.catalog import Catalog, place_items
from usdscene.scene.placement import fits_region

OPEN_HEIGHT_M = 3.0
"""Height (metres) a region of unlimited clearance counts with when regions are compared."""

REGION_TOUCH_M = 1e-3
"""Regions that overlap by less than this (neighbours sharing a face) do not conflict."""

Region = tuple[str, str]
"""(place name, relation): one support region of the environment."""


@dataclass(frozen=True, order=True)
class Combination:
    """One class at one configuration and place: ``backpack is_below seat_03A``."""

    class_name: str
    relation: str
    place: str

    @property
    def region(self) -> Region:
        """The region of this combination: (place name, relation)."""
        return (self.place, self.relation)


def fitting_combinations(catalog: Catalog, environment: str, classes: Sequence[str],
                         place_patterns: Sequence[str] = ()) -> tuple[Combination, ...]:
    """Every (class, relation, place) whose region holds one object of the class.

    Args:
        catalog: asset catalog (class extents and relations, the environment's places).
        environment: environment class.
        classes: classes to consider.
        place_patterns: shell-style place name patterns; empty = every place.

    Returns:
        Sorted combinations.
    """
    out = []
    fits: dict[tuple, bool] = {}  # places of one kind share region sizes
    for name, place in selected_places(catalog, environment, place_patterns):
        for relation, region in sorted(place.regions.items()):
            for class_name in classes:
                entry = catalog[class_name]
                key = (class_name, tuple(region.size_m))
                if key not in fits:
                    fits[key] = fits_region(entry, region.size_m)
                if relation in entry.relations and fits[key]:
                    out.append(Combination(class_name, relation, name))
    return tuple(sorted(out))


def region_conflicts(catalog: Catalog, environment: str,
                     regions: Iterable[Region]) -> dict[Region, frozenset[Region]]:
    """Regions whose boxes overlap (each region conflicts with itself).

    An object stays inside its region's box (footprint inside, height within the clearance),
    so objects in regions that do not overlap never collide; regions that do overlap (the
    legroom in front of one seat and the floor below the next) take one object between them
    per frame. Unlimited heights count as :data:`OPEN_HEIGHT_M`.

    Returns:
        region → the regions it overlaps, itself included.
    """
    from usdscene.scene.placement import boxes_overlap

    places = catalog.places(environment)
    regions = sorted(set(regions))
    centres, axes, halves = [], [], []
    for name, relation in regions:
        region = places[name].regions[relation]
        pose = region.pose.as_array()
        height = min(float(region.size_m[2]), OPEN_HEIGHT_M)
        centres.append(pose[:3, :3] @ np.array([0.0, 0.0, height / 2.0]) + pose[:3, 3])
        axes.append(pose[:3, :3])
        halves.append(np.array([region.size_m[0] / 2.0, region.size_m[1] / 2.0, height / 2.0]))
    centres_a, axes_a, halves_a = np.asarray(centres), np.asarray(axes), np.asarray(halves)
    out = {}
    for i, region in enumerate(regions):
        hits = boxes_overlap((centres_a[i], axes_a[i], halves_a[i]), (centres_a, axes_a, halves_a),
                             tolerance_m=REGION_TOUCH_M)
        out[region] = frozenset({regions[j] for j in np.flatnonzero(hits)} | {region})
    return out


def frames_for_coverage(combinations: Iterable[Combination], classes: Sequence[str],
                        objects_per_frame: int) -> int:
    """Frames that ``balanced`` needs for every combination to occur once: the class with the
    most combinations needs that many instance-frames, and so does every other class."""
    most = most_combinations(list(combinations), classes)
    return max(1, math.ceil(len(classes) * most / max(objects_per_frame, 1)))


def most_combinations(combos: Sequence[Combination], classes: Sequence[str]) -> int:
    """The largest number of combinations any of ``classes`` has (1 when ``classes`` is empty)."""
    per_class = collections.Counter(c.class_name for c in combos)
    return max((per_class[c] for c in classes), default=1)


def selected_places(catalog: Catalog, environment: str, patterns: Sequence[str]):
    """(name, place) of the places of ``environment`` matching any shell-style pattern of
    ``patterns`` (every place when empty), in :func:`usdscene.scene.catalog.place_items` order."""
    return [(name, place) for name, place in place_items(catalog.places(environment))
            if not patterns or any(fnmatch.fnmatchcase(name, p) for p in patterns)]
