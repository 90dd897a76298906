"""People: walkers between entrances over the walk places, people standing at walk places, and
the walk cycle (the phase from the distance walked, the stride locked to the frame rate, foot
sliding; see :mod:`usdscene.generate.motion`)."""

from __future__ import annotations

import math
import re
from typing import Sequence

import numpy as np

from usdscene.scene.catalog import AssetEntry, Catalog
from usdscene.generate.movers import (FRONT_YAW, STRIDE_M, Ground, Track, TrackOptions, draw_mover, footprint_of,
                                      full_fail, place, problem)
from usdscene.generate.obstacles import floor_missing
from usdscene.generate.routes import (Area, Polyline, has_word, offset_sideways, place_graph, rounded,
                                      route_points, shortest_path, simplified, speed_profile, timed_distances)

PERSON_WORDS = ("person", "pedestrian", "human", "walker", "people")
WALK_VARIANT = re.compile(r"^walk_(\d+)$")
IDLE_VARIANTS = ("stand", "idle", "phone")
STRIDE_RANGE_M = (0.9, 1.8)
"""Strides a walker may take so that its phase advances a whole number of cycle poses per frame."""
PERSON_MARGIN_M = 0.05
"""Added around a person's footprint against others (swinging arms and legs)."""
WALK_TURN_RADIUS_M = 0.8
MIN_SHOWN_S = 2.0
"""Seconds of its route every walker is in the sequence for (at most half its route and half the sequence)."""
ROUTE_TRIES = 50
"""Candidates drawn on a walker's route before its route is drawn again (see :func:`walkers`)."""


def walk_variants(entry: AssetEntry) -> tuple[str, ...]:
    """The class's walk cycle ``walk_0`` .. ``walk_<n-1>`` in phase order (empty if none)."""
    found = {}
    for name in entry.variants.get("pose", ()):
        match = WALK_VARIANT.match(name)
        if match:
            found[int(match.group(1))] = name
    n = len(found)
    return tuple(found[k] for k in range(n)) if n and set(found) == set(range(n)) else ()


def person_classes(catalog: Catalog) -> tuple[str, ...]:
    """Classes that walk: a walk cycle, or a person word in the class name (sorted)."""
    return tuple(sorted(name for name in catalog.classes()
                        if catalog[name].kind != "environment"
                        and (walk_variants(catalog[name]) or has_word(name, PERSON_WORDS))))


def _check_capacity(areas: Sequence[Area], routes_m: Sequence[float], options: TrackOptions,
                    footprint_m2: float) -> None:
    """Fail at once when the walkers asked for cannot share the walk places: about ``people ·
    min(1, route time / sequence time)`` are on them at once (plus the standing people), and
    the walk places hold at most a third of their area in footprints."""
    area_m2 = sum(float(4.0 * np.prod(a.half)) for a in areas if a.role == "walk")
    capacity = int(area_m2 / 3.0 / max(footprint_m2, 1e-6))
    route_s = float(np.mean(routes_m)) / float(np.mean(options.speed_range_m_s))
    seconds = options.frames / float(options.fps)
    at_once = options.people * min(1.0, route_s / seconds) + options.standing
    if at_once > capacity:
        raise problem("--people", f"about {at_once:.0f} people would be on the walk places at once (a route "
                                  f"takes about {route_s:.0f} s, the sequence {seconds:g} s); their {area_m2:.0f} m² "
                                  f"hold about {capacity}: ask for fewer people or a longer sequence")


SUPPORT_STEP_M = 0.1
"""Spacing of the points of a route's centre line checked for a floor under them."""


def _off_floor(line: Polyline, obstacles) -> bool:
    """Whether a point of ``line`` (every :data:`SUPPORT_STEP_M`) has no floor under it."""
    pos, _ = line.at(np.arange(0.0, line.length + SUPPORT_STEP_M, SUPPORT_STEP_M))
    return bool(floor_missing(obstacles, pos[:, :2], pos[:, 2]).any())


def _check_support(areas: Sequence[Area], path: Sequence[int], points: np.ndarray, obstacles) -> None:
    """Refuse a route (``points`` (P, 3) through the places ``path``) whose centre line leaves
    the floor (an entrance box beside a walk place, past the slab's end: the walkers would hang
    in the air), naming its entrance and the spot."""
    line = Polyline(points)
    s = np.arange(0.0, line.length + SUPPORT_STEP_M, SUPPORT_STEP_M)
    pos, _ = line.at(s)
    missing = floor_missing(obstacles, pos[:, :2], pos[:, 2])
    if missing.any():
        x, y, _ = pos[int(np.argmax(missing))]
        first = float(s[int(np.argmax(missing))]) <= line.length / 2.0
        entrance = areas[path[0] if first else path[-1]].place
        raise problem(f"place {entrance!r}", f"walkers to and from this entrance would walk where there is no floor, "
                                             f"at ({x:.2f}, {y:.2f}) m (a route is lined up with the place beyond "
                                             "its entrance): put the entrance at the end of a walk place, on the floor")


TURN_INSET_M = 0.5
"""How far before the far end of its walk place a single door's route turns back (its walkers
turn on the spot up to :data:`WALK_TURN_RADIUS_M` before that, see :func:`~usdscene.generate.routes.rounded`)."""


def _far_end(area: Area, point: np.ndarray) -> np.ndarray:
    """The end of the area's long centre line farther from ``point`` (3,), :data:`TURN_INSET_M`
    inside it (at most its middle) → (3,)."""
    long_axis = int(np.argmax(area.half))
    local = np.zeros(2)
    side = -1.0 if float((point[:2] - area.centre[:2]) @ area.axes[:, long_axis]) > 0 else 1.0
    local[long_axis] = side * max(float(area.half[long_axis]) - TURN_INSET_M, 0.0)
    xy = area.centre[:2] + area.axes @ local
    return np.array([xy[0], xy[1], area.centre[2]])


def _there_and_back(areas: Sequence[Area], edges, gate: int) -> tuple[list[int], np.ndarray] | None:
    """A single door's route: in at ``gate``, along the walk places to the far end of the one
    whose far end lies farthest from the door, turn back there, and out the same way. Returns
    ``(places passed, points (P, 3))``, or None when no walk place is reached."""
    best = None
    for i, area in enumerate(areas):
        if area.role != "walk":
            continue
        there = shortest_path(areas, edges, gate, i, {"walk"})
        if there is None:
            continue
        points = route_points(areas, there)[:-1]  # up to the portal into the far place
        end = _far_end(area, points[-1])
        reach = float(np.linalg.norm(end[:2] - areas[gate].centre[:2]))
        if best is None or reach > best[0]:
            best = (reach, there, simplified(np.vstack([points, end[None]])))
    if best is None:
        return None
    _, there, points = best
    return there + there[::-1][1:], np.vstack([points, points[::-1][1:]])


def walkers(ground: Ground, classes: Sequence[str], accepted: list[Track]) -> list[Track]:
    """Walkers between entrances over the walk places, clear of ``accepted`` (see
    :mod:`usdscene.generate.motion`)."""
    areas, catalog, options, rng, obstacles = ground.areas, ground.catalog, ground.options, ground.rng, ground.obstacles
    if not options.people:
        return []
    F, fps = options.frames, float(options.fps)
    walk_roles = {"walk", "entrance"}
    edges = place_graph(areas, walk_roles)
    gates = [i for i in edges if areas[i].role == "entrance" and any(areas[j].role == "walk" for j in edges[i])]
    routes: list[tuple[list[int], np.ndarray]] = []  # (places passed, points (P, 3))
    for a in gates:
        for b in gates:
            if a != b:
                path = shortest_path(areas, edges, a, b, {"walk"})
                if path is not None:
                    routes.append((path, route_points(areas, path)))
    if not routes and len(gates) == 1:  # one door: walk in, turn at the far end of the walk space, walk out
        route = _there_and_back(areas, edges, gates[0])
        routes += [route] if route is not None else []
    if not routes:
        raise problem("setup places", "no route between two entrances over the walk places")
    if obstacles is not None:
        for path, points in routes:
            _check_support(areas, path, points, obstacles)
    sizes = [np.prod(2.0 * footprint_of(catalog[c], PERSON_MARGIN_M)[1]) for c in classes]
    _check_capacity(areas, [Polyline(points).length for _, points in routes], options, float(np.mean(sizes)))
    out: list[Track] = []
    low, high = options.speed_range_m_s
    for k in range(options.people):
        mover = draw_mover(catalog, classes, rng, PERSON_MARGIN_M)
        across = mover.footprint[1][0]  # facing -Y: the asset's x is across the path

        # The route (its direction) is drawn for a walker before its candidates, and again only
        # after ROUTE_TRIES of them failed: drawn with every candidate, a crowded way would
        # favour whichever direction overlaps the others least (all eight walkers of a platform
        # went one way).
        chosen: dict = {"tries": 0}

        def draw() -> Track | None:
            if chosen["tries"] % ROUTE_TRIES == 0:
                path, points = routes[int(rng.integers(len(routes)))]
                width = min(float(2 * areas[i].half.min()) for i in path if areas[i].role == "walk") \
                    if any(areas[i].role == "walk" for i in path) else 0.0
                chosen.update(path=path, points=points, room=max(0.0, width / 2.0 - float(across)))
            chosen["tries"] += 1
            path, points, room = chosen["path"], chosen["points"], chosen["room"]
            side = float(rng.uniform(-room, room)) if room > 0 else 0.0
            line = Polyline(rounded(offset_sideways(points, side), WALK_TURN_RADIUS_M))
            if obstacles is not None and _off_floor(line, obstacles):
                return None  # offset sideways past a slab's edge: drawn again
            speed = float(rng.uniform(low, high))
            duration_s = line.length / speed
            # Starts spread as in a steady flow, over [-duration, sequence) less the time every
            # walker is shown: those on their way at frame 0 are spread along their routes, not
            # bunched at the doors.
            shown_s = min(MIN_SHOWN_S, duration_s / 2.0, F / fps / 2.0)
            start_s = float(rng.uniform(shown_s - duration_s, F / fps - shown_s))
            s = timed_distances(speed_profile(line.length, speed, from_rest=False, to_rest=False, accel=1.0),
                                start_s=start_s, fps=fps, frames=F)
            present = np.isfinite(s) & (s <= line.length)
            if not present.any():
                return None
            pos, heading = line.at(np.nan_to_num(s, nan=0.0))
            return Track("walking", mover.class_name, present, pos, heading + FRONT_YAW, np.where(present, s, 0.0),
                         speed, route=tuple(areas[i].place for i in path), footprint=mover.footprint,
                         stride_m=locked_stride(speed, fps, len(walk_variants(mover.entry))))

        track, blocked = place(mover, draw, [*accepted, *out], obstacles)
        if track is None:
            raise full_fail("--people", len(out), options.people, "walkers", blocked)
        cycle = walk_variants(mover.entry)
        track.pose_variant = cycle[0] if cycle else None
        out.append(track)
    return out


def standing_people(ground: Ground, classes: Sequence[str], accepted: list[Track]) -> list[Track]:
    """People standing at random spots of the walk places for the whole sequence, clear of ``accepted``."""
    areas, catalog, options, rng, obstacles = ground.areas, ground.catalog, ground.options, ground.rng, ground.obstacles
    if not options.standing:
        return []
    F = options.frames
    walk = [a for a in areas if a.role == "walk"]
    out: list[Track] = []
    for k in range(options.standing):
        mover = draw_mover(catalog, classes, rng, PERSON_MARGIN_M)
        half = mover.footprint[1]

        def draw() -> Track:
            area = walk[int(rng.integers(len(walk)))]
            room = np.maximum(area.half - float(np.linalg.norm(half)), 0.0)
            local = rng.uniform(-room, room)
            xy = area.centre[:2] + area.axes @ local
            position = np.tile([xy[0], xy[1], area.centre[2]], (F, 1))
            yaw = np.full(F, float(rng.uniform(-math.pi, math.pi)))
            return Track("standing", mover.class_name, np.ones(F, dtype=bool), position, yaw, np.zeros(F), 0.0,
                         route=(area.place,), footprint=mover.footprint)

        track, blocked = place(mover, draw, [*accepted, *out], obstacles)
        if track is None:
            raise full_fail("--standing", len(out), options.standing, "standing people", blocked)
        idle = [v for v in mover.entry.variants.get("pose", ()) if v.startswith(IDLE_VARIANTS)]
        track.pose_variant = idle[int(rng.integers(len(idle)))] if idle else None
        out.append(track)
    return out


def locked_stride(speed_m_s: float, fps: float, cycle_length: int) -> float:
    """The stride (m) at which a walker's phase advances a whole number m of the cycle's poses
    per frame (``speed / fps = m · stride / n``), so the shown poses keep pace with the ground
    and no foot slides; the one nearest :data:`STRIDE_M` within :data:`STRIDE_RANGE_M`, else
    :data:`STRIDE_M` (a slow walker filmed fast: its feet slide, see :func:`foot_sliding`)."""
    if not cycle_length:
        return STRIDE_M
    step = speed_m_s / fps * cycle_length  # m · stride
    best = None
    for m in range(1, cycle_length):
        stride = step / m
        if STRIDE_RANGE_M[0] <= stride <= STRIDE_RANGE_M[1] and (best is None or abs(stride - STRIDE_M) < abs(best - STRIDE_M)):
            best = stride
    return STRIDE_M if best is None else best


def walk_phases(track: Track) -> np.ndarray:
    """(F,) walk-cycle phase in [0, 1) of a track (distance walked over its stride)."""
    return np.mod(track.walked / track.stride_m, 1.0)


def cycle_poses(track: Track, cycle_length: int) -> np.ndarray:
    """(F,) index k of the cycle pose shown at each frame, ``floor(phase · n)`` (a millionth of
    a pose of rounding allowance: a locked walker lands on whole poses)."""
    return np.mod(np.floor(track.walked / track.stride_m * cycle_length + 1e-6), cycle_length).astype(np.int64)


def foot_sliding(track: Track, cycle_length: int) -> float:
    """Foot sliding of a walker, metres per metre walked (see the module docstring); 1.0 for a
    class without a walk cycle (``cycle_length`` 0)."""
    idx = np.flatnonzero(track.present)
    if len(idx) < 2:
        return 0.0
    walked = np.diff(track.walked[idx])
    distance = float(np.abs(walked).sum())
    if distance == 0.0:
        return 0.0
    if not cycle_length:
        return 1.0
    k = cycle_poses(track, cycle_length)[idx]
    steps = np.mod(np.diff(k), cycle_length)
    return float(np.abs(walked - track.stride_m * steps / cycle_length).sum() / distance)
