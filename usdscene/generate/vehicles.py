"""Vehicles: arriving along the lanes into a free bay nose first, or leaving one (backing out,
a pause to shift, driving off to an entrance); every vehicle uses its own bay."""

from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from usdscene.scene.catalog import AssetEntry, Catalog
from usdscene.generate.movers import FRONT_YAW, Ground, Track, TrackOptions, draw_mover, full_fail, place, problem
from usdscene.generate.routes import (Polyline, has_word, on_centreline, place_graph, rounded, route_points,
                                      shortest_path, simplified, speed_profile, timed_distances)

log = logging.getLogger(__name__)

VEHICLE_WORDS = ("vehicle", "car", "van", "truck", "bus")
VEHICLE_MARGIN_M = 0.05
VEHICLE_SPEED_RANGE_M_S = (2.5, 4.5)
"""Cruise speeds of vehicles in a car park (9-16 km/h)."""
VEHICLE_DECEL_M_S2 = 1.5
REVERSE_SPEED_M_S = 1.0
REVERSE_RUN_M = 3.0
"""How far a leaving vehicle backs along the lane past the bay's lane spot."""
SHIFT_PAUSE_S = 1.0
"""A leaving vehicle's stop between backing out and driving off (shifting into drive), seconds."""
VEHICLE_TURN_RADIUS_M = 3.0
"""Turning radius of a vehicle's origin (the middle of its footprint) in metres, where the
places leave room for it (a car park's bay ends 3.4 m from the lane's centre line)."""
SIDEWAYS_RATIO = 1.5
"""A vehicle class longer across (x) than this times along (y) is warned about (see the module doc)."""


def vehicle_classes(catalog: Catalog) -> tuple[str, ...]:
    """Sorted non-environment catalog classes whose name has a vehicle word (:data:`VEHICLE_WORDS`, plurals
    too)."""
    return tuple(sorted(name for name in catalog.classes()
                        if catalog[name].kind != "environment" and has_word(name, VEHICLE_WORDS)))


def _warn_sideways(name: str, entry: AssetEntry) -> None:
    """Warn when a vehicle class looks turned: longer across its front (x) than along it (y)."""
    size = np.asarray(entry.extent_max_m) - np.asarray(entry.extent_min_m)
    if size[0] > SIDEWAYS_RATIO * size[1]:
        log.warning("vehicle class %r is %.1f m across and %.1f m long (front towards -Y, forward_axis %s): it "
                    "drives sideways; if its front faces +X or -X, add it again with usdscene assets add "
                    "--forward-axis", name, size[0], size[1], entry.forward_axis)


def vehicles(ground: Ground, classes: Sequence[str], accepted: list[Track]) -> list[Track]:
    """Vehicles arriving into or leaving a bay each, clear of ``accepted`` (see :mod:`usdscene.generate.motion`)."""
    areas, catalog, options, rng, obstacles = ground.areas, ground.catalog, ground.options, ground.rng, ground.obstacles
    if not options.vehicles:
        return []
    for name in classes:
        _warn_sideways(name, catalog[name])
    edges = place_graph(areas, {"lane", "bay", "entrance"})
    bays = [i for i in edges if areas[i].role == "bay" and any(areas[j].role == "lane" for j in edges[i])]
    gates = [i for i in edges if areas[i].role == "entrance" and any(areas[j].role == "lane" for j in edges[i])]
    reachable = {}
    for bay in bays:
        paths = [p for p in (shortest_path(areas, edges, g, bay, {"lane"}) for g in gates) if p is not None]
        if paths:
            reachable[bay] = paths
    if len(reachable) < options.vehicles:
        raise problem("--vehicles", f"{options.vehicles} vehicles need as many bays reachable from an entrance "
                                    f"along the lanes; the setup has {len(reachable)}")
    free = sorted(reachable)
    out: list[Track] = []
    for k in range(options.vehicles):
        mover = draw_mover(catalog, classes, rng, VEHICLE_MARGIN_M)
        bay = None

        def draw() -> Track | None:
            nonlocal bay
            bay = free[int(rng.integers(len(free)))]
            path = reachable[bay][int(rng.integers(len(reachable[bay])))]
            speed = float(rng.uniform(*VEHICLE_SPEED_RANGE_M_S))
            if rng.random() < 0.5:
                track = _arriving(areas, path, speed, options, rng)
            else:
                track = _leaving(areas, path, speed, options, rng)
            if track is not None:
                track.class_name = mover.class_name
                track.footprint = mover.footprint
            return track

        track, blocked = place(mover, draw, [*accepted, *out], obstacles)
        if track is None:
            raise full_fail("--vehicles", len(out), options.vehicles, "vehicles", blocked)
        out.append(track)
        free.remove(bay)
    return out


def _arriving(areas, path, speed, options: TrackOptions, rng) -> Track | None:
    F, fps = options.frames, float(options.fps)
    line = Polyline(rounded(route_points(areas, path), VEHICLE_TURN_RADIUS_M))
    duration_s = line.length / speed + speed / VEHICLE_DECEL_M_S2
    start_s = float(rng.uniform(-duration_s / 2.0, max(F / fps - duration_s, 0.0)))
    s = timed_distances(speed_profile(line.length, speed, from_rest=False, to_rest=True, accel=VEHICLE_DECEL_M_S2),
                        start_s=start_s, fps=fps, frames=F)
    present = np.isfinite(s)  # parked after arriving: stays
    s = np.minimum(np.nan_to_num(s, nan=0.0), line.length)
    pos, heading = line.at(s)
    return Track("arriving", "", present, pos, heading + FRONT_YAW, np.zeros(F), speed,
                 route=tuple(areas[i].place for i in path))


def _leaving(areas, path, speed, options: TrackOptions, rng) -> Track | None:
    """Parked nose-in at frame 0, backs out past the bay's lane spot, then drives out."""
    F, fps = options.frames, float(options.fps)
    out_path = path[::-1]  # bay, lane ..., entrance
    bay, spot = areas[out_path[0]], areas[out_path[1]]
    ahead = route_points(areas, out_path[1:])
    direction = ahead[1, :2] - ahead[0, :2]
    direction /= max(float(np.linalg.norm(direction)), 1e-12)
    back = spot.centre.copy()
    back[:2] -= REVERSE_RUN_M * direction
    reverse = Polyline(rounded(np.array([bay.centre, on_centreline(spot, bay.centre), back]),
                               VEHICLE_TURN_RADIUS_M))
    forward = Polyline(rounded(simplified(np.vstack([back[None], ahead[1:]])), VEHICLE_TURN_RADIUS_M))
    depart_s = float(rng.uniform(0.0, max(F / fps * 0.8, 0.0)))
    backing = speed_profile(reverse.length, REVERSE_SPEED_M_S, from_rest=True, to_rest=True, accel=VEHICLE_DECEL_M_S2)
    s1 = timed_distances(backing, start_s=depart_s, fps=fps, frames=F)
    reversing_s = backing[1][-1]
    t1 = depart_s + reversing_s + SHIFT_PAUSE_S
    s2 = timed_distances(speed_profile(forward.length, speed, from_rest=True, to_rest=False, accel=VEHICLE_DECEL_M_S2),
                         start_s=t1, fps=fps, frames=F)
    pos1, head1 = reverse.at(np.minimum(np.nan_to_num(s1, nan=0.0), reverse.length))
    pos2, head2 = forward.at(np.nan_to_num(s2, nan=0.0))
    moving_on = np.isfinite(s2)
    pos = np.where(moving_on[:, None], pos2, pos1)
    # Backing out the nose points against the motion; the first reversing heading at rest.
    heading = np.where(moving_on, head2, head1 + math.pi)
    present = ~(moving_on & (s2 > forward.length))
    return Track("leaving", "", present, pos, heading + FRONT_YAW, np.zeros(F), speed,
                 route=tuple(areas[i].place for i in out_path))
