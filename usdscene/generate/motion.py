"""Things that move: walkers and vehicles over time, as per-frame poses of a sequence document.

``usdscene generate tracks`` (:func:`generate_tracks`) reads a setup scene and writes a document
whose people and vehicles move continuously from frame to frame, each one object (one uid, one
track) for the whole sequence. It knows no particular environment; it reads the places of the
environment (and those the setup declares as cuboids) by the words of their name or kind:

* **walk places** (``walkway``, ``footpath``, ``sidewalk``, ``pavement``, ``aisle``,
  ``platform``, ``corridor``, ``concourse``, ``crossing``): the walkable ground; two walk places
  connect where their ``is_on`` boxes touch (within :data:`TOUCH_TOLERANCE_M`);
* **entrances** (``entrance``, ``exit``, ``door``, ``gate``, ``stairs``): where walkers and
  vehicles come in and go out; an entrance serves walkers when it touches a walk place and
  vehicles when it touches a lane;
* **lanes** (``lane``, ``road``, ``driveway``, ``ramp``) and **bays** (``bay``, ``parking``,
  ``stall``): where vehicles drive and park.

Routes run through the chain of touching places found by the shortest path between their
centres; the points a route passes are the portals between consecutive places (the point of
one box nearest the other), corners rounded into circular arcs (turning circles). The route
stays on the support surface of its places (z interpolated between them): movers stay on the
ground and upright (rotation about world Z only).

Walkers enter at one entrance, walk to another at a constant speed drawn from
``speed_range_m_s`` (0.8-1.8 m/s), offset sideways within the narrowest place of their route,
and leave. Standing people stand at random spots of the walk places for the whole sequence.
Vehicles either arrive (enter at a vehicle entrance at cruise speed, drive along the lanes into
a free bay nose first and stop there, braking at :data:`VEHICLE_DECEL_M_S2`) or leave (parked
at frame 0, reverse out of the bay into the lane, stop for :data:`SHIFT_PAUSE_S`, then drive
to an entrance); every vehicle
uses its own bay. No two movers overlap at any frame: each is its asset's footprint rectangle
(plus :data:`PERSON_MARGIN_M` around people) and a candidate route that would touch an earlier
one at some frame is drawn again (new times, speed, entrances, offset), up to
:data:`MAX_TRIES` times; then the space holds no more and the generator says so.

**Obstacles.** The places say where movers may go, not what stands there: a pillar at a
footpath's edge, a wall beside an entrance. The environment's visible surfaces are recorded as
occupied cubes of :data:`OBSTACLE_CELL_M` (:class:`Obstacles`, from :func:`environment_obstacles`),
and a drawn route whose footprint meets geometry from :data:`STEP_HEIGHT_M` above its ground up
to the mover's height (kerbs and paint are stepped over, a roof above is not in the way) at a
frame where it is present is drawn again like an overlapping one; so walkers keep to the walk
places minus the obstacles' footprints. When every draw meets an obstacle the error says so.

**Walk cycle.** The phase of a walker is the distance walked over its stride,
``phase = (s / stride) mod 1``. A person class whose ``pose`` variant set has ``walk_0`` ..
``walk_<n-1>`` (a cycle of n phases) shows variant ``walk_k``, ``k = floor(phase · n)``, at each
frame: written per frame as text object data ``walk_pose_variant`` with the num
``walk_phase``. Held poses make the planted foot slide: **foot sliding** is, per frame,
``|Δs - stride · Δk / n|`` (distance walked minus what the shown poses advance), summed and
divided by the distance walked (the report's ``foot_sliding_m_per_m``). The stride is therefore
chosen per walker (:func:`locked_stride`): within 0.9-1.8 m, the one at which the phase
advances a whole number of poses per frame, and sliding is zero; at 5 fps with 8 poses every
speed of 0.8-1.8 m/s locks, at 10 fps only walkers from 1.125 m/s do (the others keep 1.4 m and
slide about as far as they walk). A class without a walk cycle slides its whole distance (1.0). Composition selects one ``pose`` variant per object: the per-frame variant is in
the document and the annotations, and a renderer that switches variants per frame follows it.

**Facing.** Every mover faces -Y, the catalog's contract: the shipped library is modelled so,
and ``usdscene assets add --forward-axis`` turns an imported asset whose front faces another
way to face it (recording ``forward_axis``). A walker's or vehicle's yaw is its heading plus a
quarter turn (:data:`FRONT_YAW`), so the asset's -Y points where it goes. An entry without a
recorded ``forward_axis`` was added saying its front already faces -Y, and is taken at its word;
no guess from the mesh is made (a long axis tells no front from back). A vehicle class longer
across (x) than along (y) by more than :data:`SIDEWAYS_RATIO` would drive sideways: the
generator warns and names ``--forward-axis``.

Every moving object gets per frame ``pose_matrix4x4`` (the time-sampled transform of the
stage) and the vec ``ground_position_m`` ``[x, y, z]``: where it stands on the ground (the
asset's origin, metres), which the multi-view export turns into ground-grid cells.
"""

from __future__ import annotations

import dataclasses
import heapq
import logging
import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.scene.catalog import AssetEntry, Catalog, scene_catalog
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import MAX_FPS, FrameInterval, Pose, SceneObject, SceneSpec, canonical_json

log = logging.getLogger(__name__)

STRATEGY = "tracks"
"""The ``usdscene generate`` strategy name of this module."""
WALK_WORDS = ("walkway", "footpath", "sidewalk", "pavement", "aisle", "platform", "corridor",
              "concourse", "crossing")
ENTRANCE_WORDS = ("entrance", "exit", "door", "gate", "stairs")
LANE_WORDS = ("lane", "road", "driveway", "ramp")
BAY_WORDS = ("bay", "parking", "stall")
PERSON_WORDS = ("person", "pedestrian", "human", "walker", "people")
VEHICLE_WORDS = ("vehicle", "car", "van", "truck", "bus")
WALK_VARIANT = re.compile(r"^walk_(\d+)$")
IDLE_VARIANTS = ("stand", "idle", "phone")

TOUCH_TOLERANCE_M = 0.35
"""Two place boxes closer than this (metres) connect (a kerb line between two regions)."""
STRIDE_M = 1.4
"""Length of one walk cycle (two steps) in metres: an adult at 1.3 m/s and 110 steps/min."""
STRIDE_RANGE_M = (0.9, 1.8)
"""Strides a walker may take so that its phase advances a whole number of cycle poses per frame."""
PERSON_MARGIN_M = 0.05
"""Added around a person's footprint against others (swinging arms and legs)."""
VEHICLE_MARGIN_M = 0.05
VEHICLE_SPEED_RANGE_M_S = (2.5, 4.5)
"""Cruise speeds of vehicles in a car park (9-16 km/h)."""
VEHICLE_DECEL_M_S2 = 1.5
REVERSE_SPEED_M_S = 1.0
REVERSE_RUN_M = 3.0
"""How far a leaving vehicle backs along the lane past the bay's lane spot."""
SHIFT_PAUSE_S = 1.0
"""A leaving vehicle's stop between backing out and driving off (shifting into drive), seconds."""
WALK_TURN_RADIUS_M = 0.8
VEHICLE_TURN_RADIUS_M = 3.0
"""Turning radius of a vehicle's origin (the middle of its footprint) in metres, where the
places leave room for it (a car park's bay ends 3.4 m from the lane's centre line)."""
ARC_STEP_DEG = 5.0
"""Angle between the points of a rounded corner."""
OBSTACLE_CELL_M = 0.1
"""Edge of the cubes in which the environment's surfaces are recorded as obstacles (metres);
an obstacle is found to within about one of them."""
STEP_HEIGHT_M = 0.3
"""Geometry up to this height above a mover's ground is stepped or driven over (kerbs, paint)."""
MAX_OBSTACLE_CELLS = 30_000_000
"""Most cubes of an obstacle grid; a larger environment gets coarser cubes."""
MAX_TRIES = 200
FRONT_YAW = math.pi / 2.0
"""Yaw (rad) added to a heading so that an asset's front (-Y, the catalog's contract) points along it."""
SIDEWAYS_RATIO = 1.5
"""A vehicle class longer across (x) than this times along (y) is warned about (see the module doc)."""
MAX_PEOPLE = 10000
MAX_VEHICLES = 10000


@dataclass(frozen=True)
class TrackOptions:
    """What ``usdscene generate tracks`` generates.

    Attributes:
        frames: sequence length in frames (frames 0 .. frames-1).
        fps: frame rate, frames per second (written to ``metadata.usdscene.fps``).
        people: walkers (each one track entering and leaving at entrances).
        vehicles: vehicles (arriving into a bay or leaving one).
        standing: people standing at walk places for the whole sequence.
        seed: seed of the generator and of the document.
        person_classes: classes drawn for people; empty = the catalog's person classes (a
            ``walk_*`` pose variant, or a person word in the class name).
        vehicle_classes: classes drawn for vehicles; empty = the catalog's vehicle classes.
        speed_range_m_s: walker speeds, uniform in [low, high] metres per second.
    """

    frames: int
    fps: float
    people: int = 0
    vehicles: int = 0
    standing: int = 0
    seed: int = 0
    person_classes: tuple[str, ...] = ()
    vehicle_classes: tuple[str, ...] = ()
    speed_range_m_s: tuple[float, float] = (0.8, 1.8)


@dataclass(frozen=True)
class Area:
    """The ground box of a place: ``centre`` (3,) on its support surface, ``axes`` (2, 2) its
    x and y directions in the world ground plane as columns, ``half`` (2,) half sizes (m)."""

    place: str
    role: str
    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray


@dataclass
class Track:
    """One mover over the sequence (arrays over the frames 0 .. F-1).

    Attributes:
        kind: ``walking``, ``standing``, ``arriving`` or ``leaving``.
        class_name: asset class.
        present: (F,) bool.
        position: (F, 3) ground position (asset origin) in world metres.
        yaw: (F,) asset rotation about world Z, radians.
        walked: (F,) distance walked along the route, metres (walkers; 0 otherwise).
        speed_m_s: cruise speed.
        route: places passed, in order.
    """

    kind: str
    class_name: str
    present: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    walked: np.ndarray
    speed_m_s: float
    route: tuple[str, ...] = ()
    appearance: str | None = None
    pose_variant: str | None = None
    stride_m: float = STRIDE_M
    footprint: tuple[np.ndarray, np.ndarray] = field(default=None)  # (offset (2,), half (2,))


@dataclass(frozen=True)
class GeneratedTracks:
    """A generated moving sequence: the scene and its report (see :func:`tracks_report`)."""

    scene: SceneSpec
    tracks: tuple[Track, ...]
    report: Mapping


# --------------------------------------------------------------------------------------------
# Places


def _has_word(text: str, words: Sequence[str]) -> bool:
    for token in re.split(r"[^a-z0-9]+", text.lower()):
        if token in words or (token.endswith("s") and token[:-1] in words):
            return True
    return False


def _role(name: str, kind: str) -> str | None:
    for role, words in (("entrance", ENTRANCE_WORDS), ("walk", WALK_WORDS), ("lane", LANE_WORDS),
                        ("bay", BAY_WORDS)):
        if _has_word(name, words) or _has_word(kind, words):
            return role
    return None


def ground_areas(catalog: Catalog, scene: SceneSpec) -> list[Area]:
    """The walk places, entrances, lanes and bays of the scene's environment (with the places
    the scene declares), in place-name order; each from its ``is_on`` region (else its first)."""
    if scene.environment is None or scene.environment not in catalog:
        return []
    places = scene_catalog(catalog, scene).places(scene.environment)
    found = []
    for name in sorted(places):
        place = places[name]
        role = _role(name, place.kind)
        if role is None or not place.regions:
            continue
        region = place.regions.get("is_on") or next(iter(place.regions.values()))
        m = region.pose.as_array()
        axes = m[:2, :2].copy()
        axes /= np.linalg.norm(axes, axis=0, keepdims=True)
        found.append(Area(name, role, m[:3, 3].copy(), axes,
                          np.array(region.size_m[:2], dtype=np.float64) / 2.0))
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


def _touch(a: Area, b: Area, tolerance: float = TOUCH_TOLERANCE_M) -> bool:
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
    local = (_on_centreline(towards, area.centre)[:2] - area.centre[:2]) @ area.axes
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


def _graph(areas: Sequence[Area], roles: set[str]) -> dict[int, list[int]]:
    nodes = [i for i, a in enumerate(areas) if a.role in roles]
    edges: dict[int, list[int]] = {i: [] for i in nodes}
    for x, i in enumerate(nodes):
        for j in nodes[x + 1:]:
            if _touch(areas[i], areas[j]) and _in_front(areas[i], areas[j]) and _in_front(areas[j], areas[i]):
                edges[i].append(j)
                edges[j].append(i)
    return edges


def _shortest(areas: Sequence[Area], edges: Mapping[int, list[int]], start: int, goal: int,
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


def _on_centreline(area: Area, point: np.ndarray) -> np.ndarray:
    """``point`` (3,) moved onto the long centre line of the area's box (its height kept)."""
    long_axis = int(np.argmax(area.half))
    local = (point[:2] - area.centre[:2]) @ area.axes
    local[1 - long_axis] = 0.0
    local[long_axis] = np.clip(local[long_axis], -area.half[long_axis], area.half[long_axis])
    xy = area.centre[:2] + area.axes @ local
    return np.array([xy[0], xy[1], area.centre[2]])


def _route_points(areas: Sequence[Area], path: Sequence[int]) -> np.ndarray:
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
        points += [portals[k], _on_centreline(areas[i], portals[k]), _on_centreline(areas[i], portals[k + 1])]
    points += [portals[-1], final]
    return _simplified(np.asarray(points, dtype=np.float64))


def _simplified(pts: np.ndarray) -> np.ndarray:
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


def _rounded(points: np.ndarray, radius_m: float) -> np.ndarray:
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


def _offset(points: np.ndarray, distance: float) -> np.ndarray:
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


class _Polyline:
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


# --------------------------------------------------------------------------------------------
# Classes


def _walk_variants(entry: AssetEntry) -> tuple[str, ...]:
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
                        and (_walk_variants(catalog[name]) or _has_word(name, PERSON_WORDS))))


def vehicle_classes(catalog: Catalog) -> tuple[str, ...]:
    """Sorted non-environment catalog classes whose name has a vehicle word (:data:`VEHICLE_WORDS`, plurals
    too)."""
    return tuple(sorted(name for name in catalog.classes()
                        if catalog[name].kind != "environment" and _has_word(name, VEHICLE_WORDS)))


def _warn_sideways(name: str, entry: AssetEntry) -> None:
    """Warn when a vehicle class looks turned: longer across its front (x) than along it (y)."""
    size = np.asarray(entry.extent_max_m) - np.asarray(entry.extent_min_m)
    if size[0] > SIDEWAYS_RATIO * size[1]:
        log.warning("vehicle class %r is %.1f m across and %.1f m long (front towards -Y, forward_axis %s): it "
                    "drives sideways; if its front faces +X or -X, add it again with usdscene assets add "
                    "--forward-axis", name, size[0], size[1], entry.forward_axis)


def _footprint(entry: AssetEntry, margin: float) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(entry.extent_min_m[:2], float), np.asarray(entry.extent_max_m[:2], float)
    return (lo + hi) / 2.0, (hi - lo) / 2.0 + margin


# --------------------------------------------------------------------------------------------
# Obstacles of the environment


@dataclass(frozen=True)
class Obstacles:
    """The environment's surfaces as occupied cubes of ``cell_m``: cube (i, j, k) spans
    ``origin + cell_m · (i, j, k)`` to that plus ``cell_m``. ``below`` (NX, NY, NZ + 1) int32
    counts, per column, the occupied cubes under each level (a running sum over z), so whether a
    height band of a column holds geometry is one subtraction."""

    origin: np.ndarray
    cell_m: float
    below: np.ndarray

    @classmethod
    def from_triangles(cls, triangles: np.ndarray, cell_m: float = OBSTACLE_CELL_M) -> "Obstacles":
        """From (T, 3, 3) world triangles in metres (see :func:`environment_obstacles`); the
        cubes double in size until there are at most :data:`MAX_OBSTACLE_CELLS`."""
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        if not len(tri):
            return cls(np.zeros(3), cell_m, np.zeros((1, 1, 2), dtype=np.int32))
        lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
        while np.prod(np.floor(hi / cell_m) - np.floor(lo / cell_m) + 1) > MAX_OBSTACLE_CELLS:
            cell_m *= 2.0
        origin = np.floor(lo / cell_m) * cell_m
        shape = np.floor((hi - origin) / cell_m).astype(np.int64) + 1
        solid = np.zeros(int(np.prod(shape)), dtype=bool)
        corner, scale = origin.astype(np.float32), np.float32(1.0 / cell_m)
        for points in _surface_points(tri, cell_m):
            idx = np.clip(((points - corner) * scale).astype(np.int32), 0, (shape - 1).astype(np.int32))
            solid[(idx[:, 0].astype(np.int64) * shape[1] + idx[:, 1]) * shape[2] + idx[:, 2]] = True
        solid = solid.reshape(tuple(shape))
        below = np.zeros((shape[0], shape[1], shape[2] + 1), dtype=np.int32)
        np.cumsum(solid, axis=2, out=below[:, :, 1:])
        return cls(origin, float(cell_m), below)

    def blocked(self, centre: np.ndarray, axes: np.ndarray, half: np.ndarray, ground_z: np.ndarray,
                height_m: float) -> np.ndarray:
        """(N,) whether each footprint rectangle meets geometry from :data:`STEP_HEIGHT_M` to
        ``height_m`` above its ground.

        Args:
            centre: (N, 2) rectangle centres; axes: (N, 2, 2) their x and y directions as
                columns; half: (2,) half sizes (m); ground_z: (N,) ground heights (m).

        The rectangle, shrunk by half a cube (a surface marks the whole cube it lies in), is
        tested at points a cube apart (every cube inside it holds one); poses repeated to the
        millimetre and milliradian (a parked car) are tested once.
        """
        centre, axes = np.asarray(centre, dtype=np.float64), np.asarray(axes, dtype=np.float64)
        ground_z = np.asarray(ground_z, dtype=np.float64)
        key = np.round(np.concatenate([centre, axes[:, :, 0], ground_z[:, None]], axis=1) * 1000.0)
        _, first, back = np.unique(key, axis=0, return_index=True, return_inverse=True)
        centre, axes, ground_z = centre[first], axes[first], ground_z[first]
        inner = np.maximum(np.asarray(half, dtype=np.float64) - self.cell_m / 2.0, 0.0)
        n = np.ceil(2.0 * inner / self.cell_m).astype(np.int64) + 1
        gx, gy = np.meshgrid(np.linspace(-inner[0], inner[0], n[0]), np.linspace(-inner[1], inner[1], n[1]),
                             indexing="ij")
        gx, gy = gx.ravel()[None, :, None], gy.ravel()[None, :, None]  # (1, K, 1)
        world = centre[:, None, :] + gx * axes[:, None, :, 0] + gy * axes[:, None, :, 1]  # (N, K, 2)
        cell = np.floor((world - self.origin[:2]) / self.cell_m).astype(np.int64)
        nx, ny, levels = self.below.shape
        inside = (cell[..., 0] >= 0) & (cell[..., 0] < nx) & (cell[..., 1] >= 0) & (cell[..., 1] < ny)
        column = np.where(inside, cell[..., 0] * ny + cell[..., 1], 0)  # (N, K)
        z = ground_z - self.origin[2]
        k0 = np.clip(np.floor((z + STEP_HEIGHT_M) / self.cell_m), 0, levels - 1).astype(np.int64)[:, None]
        k1 = np.clip(np.ceil((z + height_m) / self.cell_m), 0, levels - 1).astype(np.int64)[:, None]
        flat = self.below.reshape(-1)
        count = flat[column * levels + k1] - flat[column * levels + k0]
        return np.any(inside & (count > 0), axis=1)[np.ravel(back)]


def _surface_points(triangles: np.ndarray, spacing: float, most: int = 2_000_000):
    """Points on the (T, 3, 3) triangles at most ``spacing`` apart along each edge, as float32
    arrays (M, 3) (triangles of one subdivision count together, at most about ``most`` points
    an array). With ``spacing`` one cube, every cube a surface crosses gets a point but those it
    only grazes at a corner (a cube beside them does)."""
    edges = np.stack([triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 1],
                      triangles[:, 0] - triangles[:, 2]], axis=1)
    counts = np.maximum(np.ceil(np.linalg.norm(edges, axis=2).max(axis=1) / spacing), 1).astype(np.int64)
    for m in np.unique(counts):
        i, j = np.meshgrid(np.arange(m + 1), np.arange(m + 1), indexing="ij")
        keep = (i + j) <= m
        u = (i[keep] / m).astype(np.float32)[None, :, None]
        v = (j[keep] / m).astype(np.float32)[None, :, None]
        group = triangles[counts == m].astype(np.float32)
        step = max(1, most // int(keep.sum()))
        for k in range(0, len(group), step):
            t = group[k:k + step]
            corner = t[:, None, 0]
            yield (corner + u * (t[:, None, 1] - corner) + v * (t[:, None, 2] - corner)).reshape(-1, 3)


def environment_obstacles(setup: SceneSpec, catalog: Catalog) -> Obstacles:
    """The obstacles of the setup's environment: the environment alone (no objects, lights or
    declared places) composed into a temporary stage, its visible meshes (place boxes are guides,
    not geometry) recorded by :meth:`Obstacles.from_triangles`."""
    import tempfile

    from usdscene.scene.compose import compose_stage
    from usdscene.scene.stage_geometry import environment_triangles

    bare = replace(setup, objects=(), relations=(), places=(), lights=(), frame_end=setup.frame_start)
    with tempfile.TemporaryDirectory(prefix="usdscene-obstacles-") as folder:
        compose_stage(bare, catalog, folder)
        triangles = environment_triangles(Path(folder) / "scene.usda")
    return Obstacles.from_triangles(triangles)


def _mover_height(entry: AssetEntry) -> float:
    """Top of a class above its origin (m), the tallest of its variants."""
    tops = [entry.extent_max_m[2]] + [hi[2] for by in entry.variant_extents.values() for _, hi in by.values()]
    return float(max(tops))


def _hits_obstacle(track: Track, obstacles: Obstacles | None, height_m: float, margin_m: float) -> bool:
    """Whether the track's footprint (less the ``margin_m`` kept from other movers: swinging arms
    brush a seat back, they do not walk through a pillar) meets an obstacle at a frame where it
    is present."""
    if obstacles is None:
        return False
    idx = np.flatnonzero(track.present)
    centre, axes, half = _rects(track)
    return bool(obstacles.blocked(centre[idx], axes[idx], half - margin_m, track.position[idx, 2], height_m).any())


# --------------------------------------------------------------------------------------------
# Overlap of movers


def _rects(track: Track) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame: centre (F, 2), axes (F, 2, 2) as columns, and half sizes (2,)."""
    offset, half = track.footprint
    c, s = np.cos(track.yaw), np.sin(track.yaw)
    axes = np.stack([np.stack([c, s], axis=1), np.stack([-s, c], axis=1)], axis=2)
    centre = track.position[:, :2] + np.einsum("fij,j->fi", axes, offset)
    return centre, axes, half


def overlapping_frames(a: Track, b: Track) -> np.ndarray:
    """Frames (indices) where the footprints of two tracks, both present, overlap."""
    both = np.flatnonzero(a.present & b.present)
    if not len(both):
        return both
    ca, aa, ha = (x[both] if x.ndim > 1 else x for x in _rects(a))
    cb, ab, hb = (x[both] if x.ndim > 1 else x for x in _rects(b))
    reach = np.linalg.norm(ha) + np.linalg.norm(hb)
    d = cb - ca
    near = np.einsum("fi,fi->f", d, d) < reach * reach
    separated = ~near
    for axes in (aa, ab):
        for k in range(2):
            n = axes[:, :, k]
            ra = np.abs(np.einsum("fi,fij->fj", n, aa)) @ ha
            rb = np.abs(np.einsum("fi,fij->fj", n, ab)) @ hb
            separated |= np.abs(np.einsum("fi,fi->f", d, n)) >= ra + rb
    return both[~separated]


def _collides(track: Track, accepted: Sequence[Track]) -> bool:
    """Whether ``track`` overlaps any accepted one at some frame. The accepted tracks' centres
    are compared at once first (a bounding-circle test over every frame); only those that come
    near get the exact rectangle test."""
    if not accepted:
        return False
    reach_new = float(np.linalg.norm(track.footprint[1]) + np.linalg.norm(track.footprint[0]))
    positions = np.stack([t.position[:, :2] for t in accepted])  # (K, F, 2)
    present = np.stack([t.present for t in accepted]) & track.present  # (K, F)
    reach = np.array([np.linalg.norm(t.footprint[1]) + np.linalg.norm(t.footprint[0]) for t in accepted]) + reach_new
    gap = np.einsum("kfi,kfi->kf", positions - track.position[None, :, :2], positions - track.position[None, :, :2])
    near = np.any(present & (gap < (reach * reach)[:, None]), axis=1)
    return any(len(overlapping_frames(track, accepted[k])) for k in np.flatnonzero(near))


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
        raise _problem("--people", f"about {at_once:.0f} people would be on the walk places at once (a route "
                                   f"takes about {route_s:.0f} s, the sequence {seconds:g} s); their {area_m2:.0f} m² "
                                   f"hold about {capacity}: ask for fewer people or a longer sequence")


# --------------------------------------------------------------------------------------------
# Motion profiles


def _profile(length: float, v_max: float, *, from_rest: bool, to_rest: bool,
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


def _timing(length: float, v_max: float, *, from_rest: bool, to_rest: bool, accel: float,
            start_s: float, fps: float, frames: int) -> np.ndarray:
    """Distance along a route (F,) at frames 0..F-1 for a mover that starts at time
    ``start_s`` (seconds) and moves as :func:`_profile` says. NaN before the start; ``length``
    and beyond after the end."""
    grid, t = _profile(length, v_max, from_rest=from_rest, to_rest=to_rest, accel=accel)
    t = start_s + t
    times = np.arange(frames) / fps
    s = np.interp(times, t, grid)
    s[times < t[0]] = np.nan
    s[times > t[-1]] = length + 1.0  # gone (past the end)
    return s


# --------------------------------------------------------------------------------------------
# Generation


def _problem(where: str, message: str) -> DocumentError:
    return DocumentError(message, where=where)


def _check(setup: SceneSpec, catalog: Catalog, options: TrackOptions, areas: Sequence[Area]):
    problems = ProblemCollector()
    if options.frames < 1:
        problems.add("--frames", f"frame count must be at least 1, got {options.frames}")
    if not (isinstance(options.fps, (int, float)) and 0.0 < options.fps <= MAX_FPS):
        problems.add("--fps", f"frame rate {options.fps!r} fps is not in (0, {MAX_FPS:g}]")
    for name, value, most in (("--people", options.people, MAX_PEOPLE), ("--vehicles", options.vehicles, MAX_VEHICLES),
                              ("--standing", options.standing, MAX_PEOPLE)):
        if not 0 <= value <= most:
            problems.add(name, f"expected a count in [0, {most}], got {value}")
    low, high = options.speed_range_m_s
    if not 0.0 < low <= high:
        problems.add("--speed", f"walking speeds must satisfy 0 < low <= high, got {low}..{high}")
    if setup.environment is None or setup.environment not in catalog:
        problems.add("metadata.usdscene.environment",
                     f"the setup needs an environment of the catalog, got {setup.environment!r}")
    problems.raise_if_any(DocumentError)
    people_classes = options.person_classes or person_classes(catalog)
    car_classes = options.vehicle_classes or vehicle_classes(catalog)
    for flag, names in (("--person-classes", options.person_classes), ("--vehicle-classes", options.vehicle_classes)):
        for name in names:
            if name not in catalog:
                problems.add(flag, f"unknown class {name!r}")
    walk = [a for a in areas if a.role == "walk"]
    lanes = [a for a in areas if a.role == "lane"]
    bays = [a for a in areas if a.role == "bay"]
    entrances = [a for a in areas if a.role == "entrance"]
    where = f"setup environment {setup.environment!r}"
    if options.people + options.standing:
        if not people_classes:
            problems.add("--person-classes", "the catalog has no person class (a class with walk_* pose "
                                             "variants or a person word in its name); name one")
        if not walk:
            problems.add(where, "no walkable space: no place whose name or kind says "
                                f"{', '.join(WALK_WORDS)}; declare one (a place object with an is_on cuboid)")
    if options.people:
        if walk and not any(any(_touch(e, w) for w in walk) for e in entrances):
            problems.add(where, "no entrance for walkers: no place named or kinded "
                                f"{', '.join(ENTRANCE_WORDS)} touches a walk place; declare one")
    if options.vehicles:
        if not car_classes:
            problems.add("--vehicle-classes", "the catalog has no vehicle class; name one")
        if not lanes or not bays:
            problems.add(where, f"vehicles need lanes ({', '.join(LANE_WORDS)}) and bays "
                                f"({', '.join(BAY_WORDS)}); found {len(lanes)} lanes and {len(bays)} bays")
        elif not any(any(_touch(e, lane) for lane in lanes) for e in entrances):
            problems.add(where, "no entrance for vehicles: no entrance place touches a lane; declare one")
        elif options.vehicles > len(bays):
            problems.add("--vehicles", f"{options.vehicles} vehicles need as many bays; the setup has "
                                       f"{len(bays)}")
    problems.raise_if_any(DocumentError)
    return people_classes, car_classes


def generate_tracks(setup: SceneSpec, catalog: Catalog, options: TrackOptions, *,
                    setup_sha256: str = "", obstacles: Obstacles | None = None) -> GeneratedTracks:
    """The moving sequence of ``setup`` (see the module docstring).

    Args:
        setup: the setup scene (environment, cameras, lights, fixed objects).
        catalog: asset catalog with the environment and the mover classes.
        options: counts, length, rate, seed.
        setup_sha256: recorded in the report.
        obstacles: the environment's obstacles; default :func:`environment_obstacles` of the
            setup (composes its environment: needs usd-core).

    Returns:
        The scene (setup + one object per track, frames 0 .. frames-1, ``fps``) and its report.

    Raises:
        DocumentError: bad options, a setup without walk places, entrances, lanes or bays for
            what is asked, or more movers than the space holds (naming the option).
    """
    areas = ground_areas(catalog, setup)
    people_classes, car_classes = _check(setup, catalog, options, areas)
    if obstacles is None and options.people + options.standing + options.vehicles:
        obstacles = environment_obstacles(setup, catalog)
    rng = np.random.default_rng(options.seed)
    tracks: list[Track] = []
    tracks += _vehicles(areas, catalog, car_classes, options, rng, tracks, obstacles)
    tracks += _standing(areas, catalog, people_classes, options, rng, tracks, obstacles)
    tracks += _walkers(areas, catalog, people_classes, options, rng, tracks, obstacles)
    scene = _scene(setup, catalog, tracks, options)
    report = tracks_report(scene, tracks, catalog, options, setup_sha256=setup_sha256)
    return GeneratedTracks(scene=scene, tracks=tuple(tracks), report=report)


def _draw_look(entry: AssetEntry, rng: np.random.Generator) -> tuple[str | None, AssetEntry]:
    """One appearance of the class (None when it has none) and the entry with that variant's
    extent: a van's footprint is longer than the class's default sedan's."""
    looks = entry.appearances
    look = looks[int(rng.integers(len(looks)))] if looks else None
    return look, entry.for_variants({"appearance": look}) if look else entry


def _full_fail(flag: str, placed: int, wanted: int, what: str, blocked: int = 0) -> DocumentError:
    if blocked == MAX_TRIES:
        return _problem(flag, f"only {placed} of {wanted} {what} fit: every one of {MAX_TRIES} routes drawn for "
                              f"the next one meets an obstacle of the environment (geometry from {STEP_HEIGHT_M:g} m "
                              "above the ground to the mover's height); the places lead through walls or pillars")
    return _problem(flag, f"only {placed} of {wanted} {what} fit without overlapping another mover or an obstacle "
                          f"at some frame ({MAX_TRIES} tries for the next one); the space holds no more at once: "
                          "ask for fewer, a longer sequence or more space")


def _walkers(areas, catalog, classes, options: TrackOptions, rng, accepted: list[Track],
             obstacles: Obstacles | None) -> list[Track]:
    if not options.people:
        return []
    F, fps = options.frames, float(options.fps)
    walk_roles = {"walk", "entrance"}
    edges = _graph(areas, walk_roles)
    walk = [i for i, a in enumerate(areas) if a.role == "walk"]
    gates = [i for i in edges if areas[i].role == "entrance" and any(areas[j].role == "walk" for j in edges[i])]
    routes: list[list[int]] = []
    for a in gates:
        for b in gates:
            if a != b:
                path = _shortest(areas, edges, a, b, {"walk"})
                if path is not None:
                    routes.append(path)
    if not routes:
        if len(gates) == 1:  # one door: walk in, turn at the far end of the walk space, walk out
            far = max(walk, key=lambda i: float(np.linalg.norm(areas[i].centre[:2] - areas[gates[0]].centre[:2])))
            there = _shortest(areas, edges, gates[0], far, {"walk"})
            if there is not None:
                routes.append(there + there[::-1][1:])
    if not routes:
        raise _problem("setup places", "no route between two entrances over the walk places")
    sizes = [np.prod(2.0 * _footprint(catalog[c], PERSON_MARGIN_M)[1]) for c in classes]
    _check_capacity(areas, [_Polyline(_route_points(areas, r)).length for r in routes], options, float(np.mean(sizes)))
    out: list[Track] = []
    low, high = options.speed_range_m_s
    for k in range(options.people):
        cls = classes[int(rng.integers(len(classes)))]
        entry = catalog[cls]
        look, sized = _draw_look(entry, rng)
        offset, half = _footprint(sized, PERSON_MARGIN_M)
        across = half[0]  # facing -Y: the asset's x is across the path
        height, blocked = _mover_height(entry), 0
        for _ in range(MAX_TRIES):
            path = routes[int(rng.integers(len(routes)))]
            width = min(float(2 * areas[i].half.min()) for i in path if areas[i].role == "walk") \
                if any(areas[i].role == "walk" for i in path) else 0.0
            room = max(0.0, width / 2.0 - float(across))
            side = float(rng.uniform(-room, room)) if room > 0 else 0.0
            line = _Polyline(_rounded(_offset(_route_points(areas, path), side), WALK_TURN_RADIUS_M))
            speed = float(rng.uniform(low, high))
            duration_s = line.length / speed
            start_s = float(rng.uniform(-duration_s / 2.0, max(F / fps - duration_s / 2.0, 0.0)))
            s = _timing(line.length, speed, from_rest=False, to_rest=False, accel=1.0, start_s=start_s,
                        fps=fps, frames=F)
            present = np.isfinite(s) & (s <= line.length)
            if not present.any():
                continue
            pos, heading = line.at(np.nan_to_num(s, nan=0.0))
            track = Track("walking", cls, present, pos, heading + FRONT_YAW, np.where(present, s, 0.0), speed,
                          route=tuple(areas[i].place for i in path), footprint=(offset, half),
                          stride_m=locked_stride(speed, fps, len(_walk_variants(entry))))
            if _hits_obstacle(track, obstacles, height, PERSON_MARGIN_M):
                blocked += 1
                continue
            if not _collides(track, [*accepted, *out]):
                track.appearance = look
                cycle = _walk_variants(entry)
                track.pose_variant = cycle[0] if cycle else None
                out.append(track)
                break
        else:
            raise _full_fail("--people", len(out), options.people, "walkers", blocked)
    return out


def _standing(areas, catalog, classes, options: TrackOptions, rng, accepted: list[Track],
              obstacles: Obstacles | None) -> list[Track]:
    if not options.standing:
        return []
    F = options.frames
    walk = [a for a in areas if a.role == "walk"]
    out: list[Track] = []
    for k in range(options.standing):
        cls = classes[int(rng.integers(len(classes)))]
        entry = catalog[cls]
        look, sized = _draw_look(entry, rng)
        offset, half = _footprint(sized, PERSON_MARGIN_M)
        height, blocked = _mover_height(entry), 0
        for _ in range(MAX_TRIES):
            area = walk[int(rng.integers(len(walk)))]
            room = np.maximum(area.half - float(np.linalg.norm(half)), 0.0)
            local = rng.uniform(-room, room)
            xy = area.centre[:2] + area.axes @ local
            position = np.tile([xy[0], xy[1], area.centre[2]], (F, 1))
            yaw = np.full(F, float(rng.uniform(-math.pi, math.pi)))
            track = Track("standing", cls, np.ones(F, dtype=bool), position, yaw, np.zeros(F), 0.0,
                          route=(area.place,), footprint=(offset, half))
            if _hits_obstacle(track, obstacles, height, PERSON_MARGIN_M):
                blocked += 1
                continue
            if not _collides(track, [*accepted, *out]):
                track.appearance = look
                idle = [v for v in entry.variants.get("pose", ()) if v.startswith(IDLE_VARIANTS)]
                track.pose_variant = idle[int(rng.integers(len(idle)))] if idle else None
                out.append(track)
                break
        else:
            raise _full_fail("--standing", len(out), options.standing, "standing people", blocked)
    return out


def _vehicles(areas, catalog, classes, options: TrackOptions, rng, accepted: list[Track],
              obstacles: Obstacles | None) -> list[Track]:
    if not options.vehicles:
        return []
    for name in classes:
        _warn_sideways(name, catalog[name])
    edges = _graph(areas, {"lane", "bay", "entrance"})
    bays = [i for i in edges if areas[i].role == "bay" and any(areas[j].role == "lane" for j in edges[i])]
    gates = [i for i in edges if areas[i].role == "entrance" and any(areas[j].role == "lane" for j in edges[i])]
    reachable = {}
    for bay in bays:
        paths = [p for p in (_shortest(areas, edges, g, bay, {"lane"}) for g in gates) if p is not None]
        if paths:
            reachable[bay] = paths
    if len(reachable) < options.vehicles:
        raise _problem("--vehicles", f"{options.vehicles} vehicles need as many bays reachable from an entrance "
                                     f"along the lanes; the setup has {len(reachable)}")
    free = sorted(reachable)
    out: list[Track] = []
    for k in range(options.vehicles):
        cls = classes[int(rng.integers(len(classes)))]
        entry = catalog[cls]
        look, sized = _draw_look(entry, rng)
        offset, half = _footprint(sized, VEHICLE_MARGIN_M)
        height, blocked = _mover_height(entry), 0
        for _ in range(MAX_TRIES):
            bay = free[int(rng.integers(len(free)))]
            path = reachable[bay][int(rng.integers(len(reachable[bay])))]
            speed = float(rng.uniform(*VEHICLE_SPEED_RANGE_M_S))
            if rng.random() < 0.5:
                track = _arriving(areas, path, speed, options, rng)
            else:
                track = _leaving(areas, path, speed, options, rng)
            if track is None:
                continue
            track.class_name = cls
            track.footprint = (offset, half)
            if _hits_obstacle(track, obstacles, height, VEHICLE_MARGIN_M):
                blocked += 1
                continue
            if not _collides(track, [*accepted, *out]):
                track.appearance = look
                out.append(track)
                free.remove(bay)
                break
        else:
            raise _full_fail("--vehicles", len(out), options.vehicles, "vehicles", blocked)
    return out


def _arriving(areas, path, speed, options: TrackOptions, rng) -> Track | None:
    F, fps = options.frames, float(options.fps)
    line = _Polyline(_rounded(_route_points(areas, path), VEHICLE_TURN_RADIUS_M))
    duration_s = line.length / speed + speed / VEHICLE_DECEL_M_S2
    start_s = float(rng.uniform(-duration_s / 2.0, max(F / fps - duration_s, 0.0)))
    s = _timing(line.length, speed, from_rest=False, to_rest=True, accel=VEHICLE_DECEL_M_S2, start_s=start_s,
                fps=fps, frames=F)
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
    ahead = _route_points(areas, out_path[1:])
    direction = ahead[1, :2] - ahead[0, :2]
    direction /= max(float(np.linalg.norm(direction)), 1e-12)
    back = spot.centre.copy()
    back[:2] -= REVERSE_RUN_M * direction
    reverse = _Polyline(_rounded(np.array([bay.centre, _on_centreline(spot, bay.centre), back]),
                                      VEHICLE_TURN_RADIUS_M))
    forward = _Polyline(_rounded(_simplified(np.vstack([back[None], ahead[1:]])), VEHICLE_TURN_RADIUS_M))
    depart_s = float(rng.uniform(0.0, max(F / fps * 0.8, 0.0)))
    s1 = _timing(reverse.length, REVERSE_SPEED_M_S, from_rest=True, to_rest=True, accel=VEHICLE_DECEL_M_S2,
                 start_s=depart_s, fps=fps, frames=F)
    reversing_s = _profile(reverse.length, REVERSE_SPEED_M_S, from_rest=True, to_rest=True,
                           accel=VEHICLE_DECEL_M_S2)[1][-1]
    t1 = depart_s + reversing_s + SHIFT_PAUSE_S
    s2 = _timing(forward.length, speed, from_rest=True, to_rest=False, accel=VEHICLE_DECEL_M_S2, start_s=t1,
                 fps=fps, frames=F)
    pos1, head1 = reverse.at(np.minimum(np.nan_to_num(s1, nan=0.0), reverse.length))
    pos2, head2 = forward.at(np.nan_to_num(s2, nan=0.0))
    moving_on = np.isfinite(s2)
    pos = np.where(moving_on[:, None], pos2, pos1)
    # Backing out the nose points against the motion; the first reversing heading at rest.
    heading = np.where(moving_on, head2, head1 + math.pi)
    present = ~(moving_on & (s2 > forward.length))
    return Track("leaving", "", present, pos, heading + FRONT_YAW, np.zeros(F), speed,
                 route=tuple(areas[i].place for i in out_path))


# --------------------------------------------------------------------------------------------
# The document


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


def _yaw_pose(position: np.ndarray, yaw: float) -> Pose:
    c, s = math.cos(yaw), math.sin(yaw)
    return Pose((c, -s, 0.0, float(position[0]), s, c, 0.0, float(position[1]),
                 0.0, 0.0, 1.0, float(position[2]), 0.0, 0.0, 0.0, 1.0))


def _runs(present: np.ndarray) -> tuple[FrameInterval, ...]:
    idx = np.flatnonzero(present)
    if not len(idx):
        return ()
    cuts = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[cuts + 1]])
    ends = np.concatenate([idx[cuts], [idx[-1]]])
    return tuple(FrameInterval(int(a), int(b)) for a, b in zip(starts, ends))


def _next_uid(setup: SceneSpec) -> int:
    used = [int(u) for u in (*(e.uid for e in setup.lights), *(e.uid for e in setup.places),
                             *(e.uid for e in setup.objects)) if str(u).isdigit()]
    return max(used, default=-1) + 1


def _scene(setup: SceneSpec, catalog: Catalog, tracks: Sequence[Track], options: TrackOptions) -> SceneSpec:
    first = _next_uid(setup)
    counters: dict[str, int] = {}
    objects = []
    for k, track in enumerate(tracks):
        n = counters.get(track.kind, 0)
        counters[track.kind] = n + 1
        entry = catalog[track.class_name]
        cycle = _walk_variants(entry) if track.kind == "walking" else ()
        idx = np.flatnonzero(track.present)
        poses = tuple((int(f), _yaw_pose(track.position[f], float(track.yaw[f]))) for f in idx)
        phases = walk_phases(track)
        shown = cycle_poses(track, len(cycle)) if cycle else None
        frame_extra = []
        for f in idx:
            data: dict = {"vec": [{"name": "ground_position_m",
                                   "val": [float(v) for v in track.position[f]]}]}
            if cycle:
                data["num"] = [{"name": "walk_phase", "val": float(phases[f])}]
                data["text"] = [{"name": "walk_pose_variant", "val": cycle[int(shown[f])]}]
            frame_extra.append((int(f), canonical_json({"object_data": data})))
        intervals = [{"frame_start": iv.frame_start, "frame_end": iv.frame_end} for iv in _runs(track.present)]
        pointers = {"ground_position_m": {"type": "vec", "frame_intervals": intervals}}
        if cycle:
            pointers["walk_phase"] = {"type": "num", "frame_intervals": intervals}
            pointers["walk_pose_variant"] = {"type": "text", "frame_intervals": intervals}
        texts = [{"name": "motion", "val": track.kind}, {"name": "route", "val": " ".join(track.route)}]
        nums = [{"name": "speed_m_s", "val": float(track.speed_m_s)}]
        if track.kind == "walking":
            nums.append({"name": "stride_m", "val": float(track.stride_m)})
        for item in texts:
            pointers[item["name"]] = {"type": "text", "frame_intervals": []}
        for item in nums:
            pointers[item["name"]] = {"type": "num", "frame_intervals": []}
        extra = canonical_json({"object_data": {"text": texts, "num": nums}, "object_data_pointers": pointers})
        objects.append(SceneObject(
            uid=str(first + k), name=f"{track.kind}_{n:03d}", class_name=track.class_name,
            frame_intervals=_runs(track.present), frame_poses=poses, appearance=track.appearance,
            pose_variant=track.pose_variant, extra=extra, frame_extra=tuple(frame_extra)))
    return replace(setup, frame_start=0, frame_end=options.frames - 1, fps=float(options.fps), seed=options.seed,
                   objects=(*setup.objects, *objects))


# --------------------------------------------------------------------------------------------
# Report


def _stats(values: Sequence[float]) -> dict:
    if not len(values):
        return {"count": 0}
    v = np.asarray(values, dtype=np.float64)
    return {"count": int(len(v)), "min": float(v.min()), "mean": round(float(v.mean()), 3), "max": float(v.max())}


def tracks_report(scene: SceneSpec, tracks: Sequence[Track], catalog: Catalog, options: TrackOptions, *,
                  setup_sha256: str = "") -> dict:
    """Track lengths, people per frame, per camera the tracks in view and for how long.

    A track is *in view* of a camera in a frame when the centre of its asset's box projects
    inside the image through the camera's lens (occlusion is not considered: the rendered
    labels say what is visible).
    """
    from usdscene.labels.projection import project_points

    F, fps = options.frames, float(options.fps)
    people = np.zeros(F, dtype=np.int64)
    lengths: dict[str, list[int]] = {}
    sliding = []
    for track in tracks:
        lengths.setdefault(track.kind, []).append(int(track.present.sum()))
        if track.kind in ("walking", "standing"):
            people += track.present
        if track.kind == "walking":
            sliding.append(foot_sliding(track, len(_walk_variants(catalog[track.class_name]))))
    uid_of = {id(t): o.uid for t, o in zip(tracks, scene.objects[len(scene.objects) - len(tracks):])}
    cameras = {}
    for cam in scene.cameras:
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        seen_frames = []
        by_kind: dict[str, int] = {}
        for track in tracks:
            entry = catalog[track.class_name]
            centre = (np.asarray(entry.extent_min_m) + np.asarray(entry.extent_max_m)) / 2.0
            c, s = np.cos(track.yaw), np.sin(track.yaw)
            world = track.position + np.stack([c * centre[0] - s * centre[1], s * centre[0] + c * centre[1],
                                               np.full(F, centre[2])], axis=1)
            uv, valid = project_points(cam, world)
            inside = valid & track.present & (uv[:, 0] >= -0.5) & (uv[:, 0] < w - 0.5) \
                & (uv[:, 1] >= -0.5) & (uv[:, 1] < h - 0.5)
            n = int(inside.sum())
            if n:
                seen_frames.append(n)
                by_kind[track.kind] = by_kind.get(track.kind, 0) + 1
        cameras[cam.name] = {"tracks_in_view": len(seen_frames), "by_motion": dict(sorted(by_kind.items())),
                             "frames_in_view": _stats(seen_frames),
                             "seconds_in_view": _stats([n / fps for n in seen_frames])}
    return {
        "strategy": "tracks",
        "frames": F, "fps": fps, "seconds": F / fps,
        "tracks": len(tracks),
        "track_frames": {kind: _stats(v) for kind, v in sorted(lengths.items())},
        "people_per_frame": _stats(people.tolist()),
        "foot_sliding_m_per_m": _stats(sliding),
        "stride_m": STRIDE_M,
        "cameras": cameras,
        "uids": {track.kind: sorted((uid_of[id(t)] for t in tracks if t.kind == track.kind), key=int)
                 for track in tracks},
        "generator": {"people": options.people, "standing": options.standing, "vehicles": options.vehicles,
                      "seed": options.seed, "speed_range_m_s": list(options.speed_range_m_s),
                      "setup_sha256": setup_sha256},
    }


def generate_tracks_document(setup_path: str | os.PathLike, out_path: str | os.PathLike,
                             options: TrackOptions) -> GeneratedTracks:
    """Read a setup document, generate its moving sequence, check that it composes, write
    ``DOC`` and ``DOC.report.json`` (atomically; nothing is written when anything fails).

    Raises:
        DocumentError: bad setup or options (see :func:`generate_tracks`).
        AssetError: bad asset catalog.
    """
    from usdscene.bulk import paused_collection
    from usdscene.generate.sequences import read_setup, write_generated

    setup_path, out_path = Path(setup_path), Path(out_path)
    with paused_collection():
        setup, catalog, provenance = read_setup(setup_path, out_path)
        generated = generate_tracks(setup, catalog, options, setup_sha256=provenance.source_sha256)
        report = write_generated(generated.scene, generated.report, out_path, catalog, provenance)
    return dataclasses.replace(generated, report=report)
