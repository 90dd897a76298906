"""Routes over the ground: the places of an environment read by the words of their names (walk
places, entrances, lanes, bays, :func:`ground_areas`), the graph of touching places and the
shortest chain through it, the route polyline through a chain (portals, centre lines, corners
rounded into turning circles, a sideways offset), and the distance a mover has come along a
route at each frame (:func:`timed_distances`).

The movers of :mod:`usdscene.generate.motion` (walkers, vehicles) and any other crowd model
draw their routes from here."""

from __future__ import annotations

import heapq
import math
import re
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from usdscene.scene.catalog import Catalog, scene_catalog
from usdscene.document.model import SceneSpec

WALK_WORDS = ("walkway", "footpath", "sidewalk", "pavement", "aisle", "platform", "corridor",
              "concourse", "crossing")
ENTRANCE_WORDS = ("entrance", "exit", "door", "gate", "stairs")
LANE_WORDS = ("lane", "road", "driveway", "ramp")
BAY_WORDS = ("bay", "parking", "stall")
TOUCH_TOLERANCE_M = 0.35
"""Two place boxes closer than this (metres) connect (a kerb line between two regions)."""
ARC_STEP_DEG = 5.0
"""Angle between the points of a rounded corner."""


@dataclass(frozen=True)
class Area:
    """The ground box of a place: ``centre`` (3,) on its support surface, ``axes`` (2, 2) its
    x and y directions in the world ground plane as columns, ``half`` (2,) half sizes (m)."""

    place: str
    role: str
    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray


def has_word(text: str, words: Sequence[str]) -> bool:
    for token in re.split(r"[^a-z0-9]+", text.lower()):
        if token in words or (token.endswith("s") and token[:-1] in words):
            return True
    return False


def _role(name: str, kind: str) -> str | None:
    for role, words in (("entrance", ENTRANCE_WORDS), ("walk", WALK_WORDS), ("lane", LANE_WORDS),
                        ("bay", BAY_WORDS)):
        if has_word(name, words) or has_word(kind, words):
            return role
    return None


def place_areas(catalog: Catalog, scene: SceneSpec, role_of) -> list[tuple[Area, str]]:
    """``(area, place kind)`` of every place of the scene's environment (with the places the
    scene declares) to which ``role_of(name, kind)`` gives a role (None: left out), in
    place-name order; each from its ``is_on`` region (else its first)."""
    if scene.environment is None or scene.environment not in catalog:
        return []
    places = scene_catalog(catalog, scene).places(scene.environment)
    found = []
    for name in sorted(places):
        place = places[name]
        role = role_of(name, place.kind)
        if role is None or not place.regions:
            continue
        region = place.regions.get("is_on") or next(iter(place.regions.values()))
        m = region.pose.as_array()
        axes = m[:2, :2].copy()
        axes /= np.linalg.norm(axes, axis=0, keepdims=True)
        found.append((Area(name, role, m[:3, 3].copy(), axes,
                           np.array(region.size_m[:2], dtype=np.float64) / 2.0), place.kind))
    return found


def ground_areas(catalog: Catalog, scene: SceneSpec) -> list[Area]:
    """The walk places, entrances, lanes and bays of the scene's environment (with the places
    the scene declares), in place-name order; each from its ``is_on`` region (else its first)."""
    found = [area for area, _ in place_areas(catalog, scene, _role)]
    # A walk place inside another adds nothing but narrower detours (a car park's walkway spots
    # inside its footpath); lanes and bays are kept, each is a destination.
    return [a for a in found if a.role != "walk"
            or not any(b is not a and b.role == "walk" and _inside(a, b) for b in found)]


def _inside(a: Area, b: Area) -> bool:
    """Whether a's ground box lies in b's (1 cm tolerance) and is smaller."""
    local = np.abs((_corners(a) - b.centre[:2]) @ b.axes)
    return bool(np.all(local <= b.half + 0.01)) and float(np.prod(a.half)) < float(np.prod(b.half))


def _corners(area: Area, grow: float = 0.0) -> np.ndarray:
    h = area.half + grow
    signs = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64)
    return area.centre[:2] + (signs * h) @ area.axes.T


def touch(a: Area, b: Area, tolerance: float = TOUCH_TOLERANCE_M) -> bool:
    """Separating-axis test of the two ground boxes, each grown by half the tolerance."""
    ca, cb = _corners(a, tolerance / 2), _corners(b, tolerance / 2)
    for axis in (*a.axes.T, *b.axes.T):
        pa, pb = ca @ axis, cb @ axis
        if pa.max() < pb.min() or pb.max() < pa.min():
            return False
    return True


def _nearest_in(area: Area, point: np.ndarray) -> np.ndarray:
    """The point of the area's ground box nearest ``point`` (2,) → (2,)."""
    local = (point - area.centre[:2]) @ area.axes
    local = np.clip(local, -area.half, area.half)
    return area.centre[:2] + area.axes @ local


def _portal(a: Area, b: Area, start: np.ndarray | None = None) -> np.ndarray:
    """A point (3,) where the route passes from a to b: the point of a nearest b's nearest point
    to ``start`` (2,) (default a's centre), at the mean height of the two."""
    p = _nearest_in(a, _nearest_in(b, a.centre[:2] if start is None else start))
    return np.array([p[0], p[1], (a.centre[2] + b.centre[2]) / 2.0])


def _end_point(area: Area, towards: Area) -> np.ndarray:
    """Where a route starts or ends in a place (3,): its centre, except in an entrance, where it
    is moved across the entrance (never along the way in) to line up with the centre line of the
    place beyond: a 6 m vehicle gate serving two lanes is entered in line with each lane."""
    if area.role != "entrance":
        return area.centre
    way_in = int(np.argmax(np.abs((towards.centre[:2] - area.centre[:2]) @ area.axes)))
    local = (on_centreline(towards, area.centre)[:2] - area.centre[:2]) @ area.axes
    local[way_in] = 0.0
    xy = area.centre[:2] + area.axes @ np.clip(local, -area.half, area.half)
    return np.array([xy[0], xy[1], area.centre[2]])


def _in_front(bay: Area, other: Area) -> bool:
    """A bay connects only to the places in front of it: whose centre lies within the bay's
    width (across its long axis); a lane spot beside the next bay does not lead into it."""
    if bay.role != "bay":
        return True
    across = 1 - int(np.argmax(bay.half))
    local = (other.centre[:2] - bay.centre[:2]) @ bay.axes
    return abs(float(local[across])) <= float(bay.half[across])


def place_graph(areas: Sequence[Area], roles: set[str]) -> dict[int, list[int]]:
    nodes = [i for i, a in enumerate(areas) if a.role in roles]
    edges: dict[int, list[int]] = {i: [] for i in nodes}
    for x, i in enumerate(nodes):
        for j in nodes[x + 1:]:
            if touch(areas[i], areas[j]) and _in_front(areas[i], areas[j]) and _in_front(areas[j], areas[i]):
                edges[i].append(j)
                edges[j].append(i)
    return edges


def shortest_path(areas: Sequence[Area], edges: Mapping[int, list[int]], start: int, goal: int,
                  through: set[str]) -> list[int] | None:
    """Dijkstra over place centres; only places of a role in ``through`` are passed through."""
    dist = {start: 0.0}
    prev: dict[int, int] = {}
    heap = [(0.0, start)]
    while heap:
        d, i = heapq.heappop(heap)
        if i == goal:
            path = [goal]
            while path[-1] != start:
                path.append(prev[path[-1]])
            return path[::-1]
        if d > dist[i] or (i != start and areas[i].role not in through):
            continue
        for j in edges[i]:
            nd = d + float(np.linalg.norm(areas[i].centre[:2] - areas[j].centre[:2]))
            if nd < dist.get(j, math.inf):
                dist[j], prev[j] = nd, i
                heapq.heappush(heap, (nd, j))
    return None


def on_centreline(area: Area, point: np.ndarray) -> np.ndarray:
    """``point`` (3,) moved onto the long centre line of the area's box (its height kept)."""
    long_axis = int(np.argmax(area.half))
    local = (point[:2] - area.centre[:2]) @ area.axes
    local[1 - long_axis] = 0.0
    local[long_axis] = np.clip(local[long_axis], -area.half[long_axis], area.half[long_axis])
    xy = area.centre[:2] + area.axes @ local
    return np.array([xy[0], xy[1], area.centre[2]])


def route_points(areas: Sequence[Area], path: Sequence[int]) -> np.ndarray:
    """(P, 3) points of a route through places: the start (:func:`_end_point`), then per place
    passed the portal in, its centre line from there to the portal out, the portal out; the end.
    Collinear and repeated points are merged."""
    first = _end_point(areas[path[0]], areas[path[1]])
    final = _end_point(areas[path[-1]], areas[path[-2]])
    portals = [_portal(areas[i], areas[j]) for i, j in zip(path, path[1:])]
    portals[0] = _portal(areas[path[0]], areas[path[1]], first[:2])
    portals[-1] = _portal(areas[path[-2]], areas[path[-1]], final[:2]) if len(path) > 2 else portals[-1]
    points = [first]
    for k, i in enumerate(path[1:-1]):
        points += [portals[k], on_centreline(areas[i], portals[k]), on_centreline(areas[i], portals[k + 1])]
    points += [portals[-1], final]
    return simplified(np.asarray(points, dtype=np.float64))


def simplified(pts: np.ndarray) -> np.ndarray:
    out = [pts[0]]
    for p in pts[1:]:
        if np.linalg.norm(p[:2] - out[-1][:2]) > 1e-6:
            out.append(p)
    k = 1
    while k < len(out) - 1:  # drop inner points on the straight line of their neighbours
        a, b, c = out[k - 1][:2], out[k][:2], out[k + 1][:2]
        u, v = b - a, c - b
        if abs(u[0] * v[1] - u[1] * v[0]) < 1e-9 * (np.linalg.norm(u) * np.linalg.norm(v) + 1e-12) and u @ v > 0:
            del out[k]
        else:
            k += 1
    return np.asarray(out)


def rounded(points: np.ndarray, radius_m: float) -> np.ndarray:
    """(P, 3) → (Q, 3): every inner corner replaced by a circular arc of ``radius_m`` tangent to
    both of its edges (a turning circle, points every :data:`ARC_STEP_DEG`), heights interpolated
    along it. The arc starts at most ``radius_m`` before the corner (a turn sharper than a
    quarter, up to turning back on the spot, gets a tighter arc), and where an edge is too
    short for that (the whole of a first or last edge, half of an inner one, which the next
    corner shares) it is tightened to fit."""
    if len(points) < 3:
        return points
    out = [points[0]]
    last = len(points) - 2
    for k in range(1, last + 1):
        a, b, c = points[k - 1], points[k], points[k + 1]
        len_in, len_out = float(np.linalg.norm(b[:2] - a[:2])), float(np.linalg.norm(c[:2] - b[:2]))
        d_in, d_out = (b[:2] - a[:2]) / len_in, (c[:2] - b[:2]) / len_out
        turn = math.atan2(d_in[0] * d_out[1] - d_in[1] * d_out[0], float(d_in @ d_out))  # signed, radians
        if abs(turn) < 1e-9:
            out.append(b)
            continue
        half_tan = math.tan(abs(turn) / 2.0)
        tangent = min(radius_m * min(half_tan, 1.0), len_in if k == 1 else len_in / 2.0,
                      len_out if k == last else len_out / 2.0)
        radius = tangent / half_tan
        enter, leave = b - tangent * (b - a) / len_in, b + tangent * (c - b) / len_out
        centre = enter[:2] + radius * math.copysign(1.0, turn) * np.array([-d_in[1], d_in[0]])
        start = math.atan2(enter[1] - centre[1], enter[0] - centre[0])
        t = np.linspace(0.0, 1.0, max(int(math.ceil(math.degrees(abs(turn)) / ARC_STEP_DEG)), 1) + 1)
        angle = start + turn * t
        out += list(np.stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle),
                              enter[2] + (leave[2] - enter[2]) * t], axis=1))
    out.append(points[-1])
    return np.asarray(out)


def offset_sideways(points: np.ndarray, distance: float) -> np.ndarray:
    """Shift a polyline sideways (to the left of its direction) by ``distance`` metres."""
    if distance == 0.0 or len(points) < 2:
        return points
    d = np.diff(points[:, :2], axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    tangent = np.vstack([d[:1], d[:-1] + d[1:], d[-1:]])
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    out = points.copy()
    out[:, :2] += distance * normal
    return out


class Polyline:
    """Arc-length parametrised polyline: position (3,) and heading at a distance s."""

    def __init__(self, points: np.ndarray) -> None:
        # Repeated points (an arc ending where its edge does) would make zero-length segments
        # without a heading.
        keep = np.concatenate([[True], np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1) > 1e-9])
        if keep.sum() < 2:
            keep[-1] = True
        points = points[keep]
        self.points = points
        seg = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
        self.s = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.s[-1])

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((N, 3) positions, (N,) headings in radians) at distances ``s`` (N,)."""
        s = np.clip(s, 0.0, self.length)
        pos = np.stack([np.interp(s, self.s, self.points[:, k]) for k in range(3)], axis=1)
        seg = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.points) - 2)
        d = self.points[seg + 1, :2] - self.points[seg, :2]
        return pos, np.arctan2(d[:, 1], d[:, 0])


def speed_profile(length: float, v_max: float, *, from_rest: bool, to_rest: bool,
                  accel: float) -> tuple[np.ndarray, np.ndarray]:
    """Distances along a route (M,) every 2 cm and the seconds (M,) at which a mover reaches
    them: cruise ``v_max``, accelerating from rest / braking to rest at ``accel`` m/s² when asked."""
    grid = np.linspace(0.0, length, max(int(length / 0.02), 2) + 1)
    v = np.full_like(grid, v_max)
    if to_rest:
        v = np.minimum(v, np.sqrt(2.0 * accel * (length - grid)))
    if from_rest:
        v = np.minimum(v, np.sqrt(2.0 * accel * grid))
    v = np.maximum(v, 0.05 * v_max)  # the ends: no division by zero
    dt = np.diff(grid) / ((v[:-1] + v[1:]) / 2.0)
    return grid, np.concatenate([[0.0], np.cumsum(dt)])


def timed_distances(profile: tuple[np.ndarray, np.ndarray], *, start_s: float, fps: float,
                    frames: int) -> np.ndarray:
    """Distance along a route (F,) at frames 0..F-1 for a mover that starts at time
    ``start_s`` (seconds) and moves as ``profile`` (:func:`speed_profile` of the route) says.
    NaN before the start; the route's length and beyond after the end."""
    grid, t = profile
    length = grid[-1]  # linspace ends exactly on the length
    t = start_s + t
    times = np.arange(frames) / fps
    s = np.interp(times, t, grid)
    s[times < t[0]] = np.nan
    s[times > t[-1]] = length + 1.0  # gone (past the end)
    return s
