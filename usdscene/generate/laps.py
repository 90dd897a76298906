"""Seated passengers as supports: the seats that seat a passenger class and the laps they offer.

A seated passenger's declared support place (its ``lap``, per pose variant) becomes a *lap
place* ``<seat>/lap`` that the generators of :mod:`usdscene.generate.sequences` fill like any
region while somebody sits there.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from usdscene.generate.combinations import OPEN_HEIGHT_M, Combination, Region, selected_places
from usdscene.document.model import Pose
from usdscene.scene.catalog import Catalog, Place, PlaceRegion
from usdscene.scene.placement import fits_region

PASSENGER_RELATION = "is_on"
"""The relation that seats a passenger on a place, and that puts an object on a lap."""

SEAT_HEIGHT_TOLERANCE_M = 0.05
"""How much shorter than a seated asset's legs a seat may be."""


def passenger_seats(catalog: Catalog, environment: str, class_name: str,
                    place_patterns: Sequence[str] = ()) -> tuple[str, ...]:
    """Places whose ``is_on`` region seats a passenger-kind class: the region holds it and its
    support is high enough above the floor (world z = 0) for the legs, which reach
    ``-extent_min_m[2]`` below the origin (an aisle floor does not seat anybody)."""
    entry = catalog[class_name]
    legs_m = max(-entry.extent_min_m[2], 0.0)
    out = []
    for name, place in selected_places(catalog, environment, place_patterns):
        region = place.regions.get(PASSENGER_RELATION)
        if (region is not None and PASSENGER_RELATION in entry.relations and fits_region(entry, region.size_m)
                and float(region.pose.translation_m[2]) >= legs_m - SEAT_HEIGHT_TOLERANCE_M):
            out.append(name)
    return tuple(out)


@dataclass(frozen=True)
class Lap:
    """A support place a seated passenger offers (its ``lap``), on one seat.

    Attributes:
        passenger_class: the passenger class offering it.
        place: the passenger asset's place name (``lap``).
        by_variant: variant of the passenger's pose variant set → the region in world
            coordinates when seated on this seat; variants without one are left out.
        variant_set: the variant set that decides it (``pose``); "" when it does not vary.
    """

    passenger_class: str
    place: str
    by_variant: Mapping[str, PlaceRegion]
    variant_set: str = ""


def lap_place_name(seat: str, place: str) -> str:
    """Name of a passenger's support place on a seat in plans and reports: ``seat_03A/lap``."""
    return f"{seat}/{place}"


def lap_combinations(catalog: Catalog, classes: Sequence[str], laps: Mapping[Region, Lap]) -> tuple[Combination, ...]:
    """(class, ``is_on``, ``seat/lap``) for every class that fits the lap of at least one pose
    (:func:`usdscene.scene.placement.fits_region`, as for places); the passenger then takes a pose
    whose lap holds it (:func:`_dress_passengers`)."""
    out = []
    for (place, relation), lap in sorted(laps.items()):
        for class_name in classes:
            entry = catalog[class_name]
            if relation in entry.relations and any(fits_region(entry, r.size_m, upright_only=True)
                                                     for r in lap.by_variant.values()):
                out.append(Combination(class_name, relation, place))
    return tuple(out)


def with_lap_places(catalog: Catalog, environment: str, laps: Mapping[Region, Lap]) -> Catalog:
    """``catalog`` whose environment also has one place per lap, its region the box around the
    lap of every pose (for :func:`usdscene.generate.combinations.region_conflicts`: whatever pose
    is drawn, a lap object stays inside it)."""
    entry = catalog[environment]
    places = dict(entry.places)
    for (name, relation), lap in laps.items():
        regions = list(lap.by_variant.values())
        base = regions[0].pose.as_array()
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for region in regions:
            local = np.linalg.inv(base) @ region.pose.as_array()
            half = np.array([region.size_m[0] / 2.0, region.size_m[1] / 2.0, 0.0])
            for corner in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                for z in (0.0, min(float(region.size_m[2]), OPEN_HEIGHT_M)):
                    point = local[:3, :3] @ np.array([corner[0] * half[0], corner[1] * half[1], z]) + local[:3, 3]
                    lo, hi = np.minimum(lo, point), np.maximum(hi, point)
        centre = base.copy()
        centre[:3, 3] = base[:3, :3] @ np.array([(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, lo[2]]) + base[:3, 3]
        places[name] = Place(name, "lap", {relation: PlaceRegion(relation, Pose.from_matrix(centre),
                                                                 tuple(float(v) for v in hi - lo))})
    entries = dict(catalog.entries)
    entries[environment] = dataclasses.replace(entry, places=places)
    return dataclasses.replace(catalog, entries=entries)
