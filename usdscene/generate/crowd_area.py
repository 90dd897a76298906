"""Where a crowd may walk and what it does there: the walkable area and the crowd's stages.

:func:`crowd_layout` reads a setup's places by the words of their names or kinds
(:data:`QUEUE_WORDS`, :data:`WAIT_WORDS`, :data:`SEAT_WORDS`, :data:`WAYPOINT_WORDS`, and the
walk places and entrances of :mod:`usdscene.generate.motion`) and returns a
:class:`CrowdLayout`: the walkable area as polygons with holes (the walk places and entrances,
minus the environment's obstacles grown by a person's radius), and the places that become the
pedestrian engine's stages. It needs no engine (shapely only): :mod:`usdscene.generate.crowd`
drives JuPedSim with it.

Each stage place may carry its behaviour in the setup document, as ``num`` object data of its
place object (a place object with the place's name; an ``is_on`` cuboid declares the place when
the environment lacks it): ``arrivals_per_min`` and ``group_share`` on an entrance,
``service_per_min`` on a queue place, ``wait_min_s`` and ``wait_max_s`` on a waiting place,
``share`` (the fraction of people who visit it) on any queue, waiting place or waypoint,
``seated`` on a bench, ``conversations`` on a walk place. The command line's options give the
values of the places that do not say.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from usdscene.document.model import SceneSpec
from usdscene.errors import DocumentError
from usdscene.generate.obstacles import STEP_HEIGHT_M, Obstacles, floor_missing
from usdscene.generate.routes import ENTRANCE_WORDS, WALK_WORDS, Area, place_areas, touch
from usdscene.scene.catalog import Catalog

QUEUE_WORDS = ("queue", "gate", "counter", "kiosk", "ticket")
"""A place whose name or kind says one of these is a queue: people line up along it and are
served one at a time at its head."""
WAIT_WORDS = ("waiting", "wait", "platform_edge", "board")
"""A place whose name or kind says one of these is a waiting place: people stand at a spot of
it for a drawn time (``platform_edge`` as a phrase: ``platform`` alone is a walk place)."""
SEAT_WORDS = ("bench", "seat", "seating")
"""Benches: people sit on them in the seated pose for the whole sequence."""
WAYPOINT_WORDS = ("waypoint", "via")
"""Waypoints: people pass through them on the way to their exit."""
CROWD_ENTRANCE_WORDS = tuple(w for w in ENTRANCE_WORDS if w != "gate")
"""Entrances of a crowd: the route generator's words except ``gate``, which is a queue here
(ticket gates are passed one at a time)."""
PERSON_RADIUS_M = 0.2
"""Radius of a person's disc in the engine (JuPedSim's default; shoulders 0.4 m across)."""
QUEUE_SPACING_M = 0.6
"""Distance between the places of a queue."""
WAIT_SPACING_M = 0.9
"""Distance between the spots of a waiting place."""
SEAT_SPACING_M = 0.6
"""Distance between seated people on a bench."""
PERSON_HEIGHT_M = 1.8
"""Geometry up to this height above a walk place (from :data:`STEP_HEIGHT_M`) is an obstacle."""
SIMPLIFY_M = 0.03
"""Tolerance (m) of the walkable area's outline simplification."""
MIN_PIECE_M2 = 0.5
"""Pieces of walkable area smaller than this (between a pillar and a wall) are dropped."""


@dataclass(frozen=True)
class StagePlace:
    """A place that becomes an engine stage.

    Attributes:
        place: place name; role: ``queue``, ``wait``, ``seat``, ``waypoint``, ``entrance``.
        area: its ground box (see :class:`usdscene.generate.routes.Area`).
        numbers: the ``num`` object data of its place object in the setup (behaviour values).
        points: (P, 2) its positions in world metres: a queue's places from head to back, a
            waiting place's or bench's spots, a waypoint's centre; entrances: none.
    """

    place: str
    role: str
    area: Area
    numbers: Mapping[str, float] = field(default_factory=dict)
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass(frozen=True)
class CrowdLayout:
    """The walkable area and the stage places of a setup.

    Attributes:
        walkable: shapely (Multi)Polygon, world metres in the ground plane: where a person's
            centre may be (walk places and entrances minus obstacles grown by
            :data:`PERSON_RADIUS_M`).
        obstacles: shapely geometry of the obstacles' footprints (not grown).
        ground: the walk places and entrances (their boxes give the support height).
        stages: the stage places, in place-name order.
        walk_numbers: place name → ``num`` object data of walk places (``conversations``).
    """

    walkable: object
    obstacles: object
    ground: tuple[Area, ...]
    stages: tuple[StagePlace, ...]
    walk_numbers: Mapping[str, Mapping[str, float]]

    def of_role(self, role: str) -> list[StagePlace]:
        return [s for s in self.stages if s.role == role]

    def support_z(self, xy: np.ndarray) -> np.ndarray:
        """(N,) height (m) of the support surface under points (N, 2): the highest walk place
        or entrance whose box holds the point (1 cm tolerance); NaN where none does."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        z = np.full(len(xy), np.nan)
        for a in self.ground:
            local = np.abs((xy - a.centre[:2]) @ a.axes)
            inside = np.all(local <= a.half + 0.01, axis=1)
            z = np.where(inside & ~(z >= a.centre[2]), a.centre[2], z)
        return z

    def place_at(self, xy: np.ndarray) -> str:
        """The name of the walk place, entrance or stage place nearest a point (2,)."""
        best, name = math.inf, ""
        for a in (*self.ground, *(s.area for s in self.stages)):
            local = np.abs((np.asarray(xy[:2]) - a.centre[:2]) @ a.axes)
            d = float(np.linalg.norm(np.maximum(local - a.half, 0.0)))
            if d < best:
                best, name = d, a.place
        return name


def _phrase(text: str, words: Sequence[str]) -> bool:
    """Whether ``text`` says one of ``words`` (a word, its plural, or a ``_`` phrase of words)."""
    tokens = [t for t in re.split(r"[^a-z0-9]+", text.lower()) if t]
    joined = "_" + "_".join(tokens) + "_"
    for word in words:
        if "_" in word:
            if "_" + word + "_" in joined:
                return True
        elif word in tokens or word + "s" in tokens:
            return True
    return False


def crowd_role(name: str, kind: str) -> str | None:
    """The crowd role of a place from its name or kind: ``queue``, ``wait``, ``seat``,
    ``waypoint``, ``entrance``, ``walk`` or None. Stage words win over walk words (a
    ``platform_edge`` is a waiting place on the platform)."""
    for role, words in (("seat", SEAT_WORDS), ("queue", QUEUE_WORDS), ("wait", WAIT_WORDS),
                        ("waypoint", WAYPOINT_WORDS), ("entrance", CROWD_ENTRANCE_WORDS), ("walk", WALK_WORDS)):
        if _phrase(name, words) or _phrase(kind, words):
            return role
    return None


def place_numbers(setup: SceneSpec) -> dict[str, dict[str, float]]:
    """Place name → the ``num`` object data of its place object in the setup."""
    out: dict[str, dict[str, float]] = {}
    for ref in setup.places:
        if not ref.extra:
            continue
        data = json.loads(ref.extra).get("object_data", {})
        nums = {str(n.get("name")): n.get("val") for n in data.get("num", ())}
        for name, val in nums.items():
            if not isinstance(val, (int, float)) or isinstance(val, bool) or not math.isfinite(val) or val < 0:
                raise DocumentError(f"expected a number >= 0, got {val!r}", where=f"place {ref.name!r} num {name!r}")
        out[ref.name] = {k: float(v) for k, v in nums.items()}
    return out


def _areas(catalog: Catalog, setup: SceneSpec) -> list[tuple[Area, str]]:
    """Every place with a crowd role, as (ground box with the role, kind), in name order."""
    return place_areas(catalog, setup, crowd_role)


def _box(area: Area, grow: float = 0.0):
    import shapely

    signs = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64)
    return shapely.Polygon(area.centre[:2] + (signs * (area.half + grow)) @ area.axes.T)


def obstacle_footprints(obstacles: Obstacles | None, ground: Sequence[Area], height_m: float = PERSON_HEIGHT_M):
    """What is not walkable on the walk places, as a shapely geometry: the union of the columns
    of ``obstacles.cell_m`` whose geometry lies between :data:`STEP_HEIGHT_M` and ``height_m``
    above the place's support surface (obstacles) or that have no floor at it
    (:func:`floor_missing`), within each place's box grown by a cell."""
    import shapely

    if obstacles is None:
        return shapely.Polygon()
    cell = obstacles.cell_m
    pieces = []
    for a in ground:
        lo, hi = (np.array(_box(a, cell).bounds[:2]), np.array(_box(a, cell).bounds[2:]))
        i0 = np.floor((lo - obstacles.origin[:2]) / cell).astype(int)
        i1 = np.ceil((hi - obstacles.origin[:2]) / cell).astype(int)
        gx, gy = np.meshgrid(np.arange(i0[0], i1[0]), np.arange(i0[1], i1[1]), indexing="ij")
        centres = obstacles.origin[:2] + (np.stack([gx, gy], axis=-1) + 0.5) * cell  # (NX, NY, 2)
        flat = centres.reshape(-1, 2)
        if not len(flat):
            continue
        axes = np.broadcast_to(np.eye(2), (len(flat), 2, 2))
        hit = obstacles.blocked(flat, axes, np.zeros(2), np.full(len(flat), a.centre[2]), height_m)
        hit |= floor_missing(obstacles, flat, a.centre[2])
        hit = hit.reshape(gx.shape)
        # Runs of blocked cells along x in each row become one rectangle each (fewer polygons).
        for j in range(hit.shape[1]):
            col = np.concatenate([[False], hit[:, j], [False]])
            starts = np.flatnonzero(~col[:-1] & col[1:])
            ends = np.flatnonzero(col[:-1] & ~col[1:])
            y0 = obstacles.origin[1] + (i0[1] + j) * cell
            for s, e in zip(starts, ends):
                x0 = obstacles.origin[0] + (i0[0] + s) * cell
                pieces.append(shapely.box(x0, y0, x0 + (e - s) * cell, y0 + cell))
    return shapely.union_all(pieces) if pieces else shapely.Polygon()


def crowd_layout(setup: SceneSpec, catalog: Catalog, obstacles: Obstacles | None) -> CrowdLayout:
    """The walkable area and stage places of ``setup`` (see the module docstring).

    Raises:
        DocumentError: no walk place, no entrance touching the walkable area, a bad place number.
    """
    import shapely

    numbers = place_numbers(setup)
    found = _areas(catalog, setup)
    walk = [a for a, _ in found if a.role == "walk"]
    # Entrances serve the crowd where they touch a walk place (a vehicle gate on a lane does not).
    ground = tuple(a for a, _ in found if a.role == "walk" or (a.role == "entrance" and any(touch(a, w) for w in walk)))
    where = f"setup environment {setup.environment!r}"
    if not any(a.role == "walk" for a in ground):
        raise DocumentError("no walkable space: no place whose name or kind says "
                            f"{', '.join(WALK_WORDS)}; declare one (a place object with an is_on cuboid)", where=where)
    floor = shapely.union_all([_box(a) for a in ground])
    blocked = obstacle_footprints(obstacles, ground)
    walkable = floor.difference(blocked.buffer(PERSON_RADIUS_M, join_style="mitre"))
    parts = [p for p in getattr(walkable, "geoms", [walkable]) if p.area >= MIN_PIECE_M2]
    walkable = shapely.MultiPolygon(parts) if len(parts) > 1 else (parts[0] if parts else shapely.Polygon())
    # The cubes' staircase outlines simplified (a thousand edges slow every engine step
    # several times); by at most SIMPLIFY_M, within the 5 cm a person's disc may graze.
    walkable = shapely.set_precision(walkable.simplify(SIMPLIFY_M), 1e-4)
    stages = []
    for area, _ in found:
        if area.role == "walk" or (area.role == "entrance" and not any(area is g for g in ground)):
            continue
        stages.append(StagePlace(area.place, area.role, area, numbers.get(area.place, {}),
                                 _stage_points(area, walkable, [a for a, _ in found if a.role == "entrance"])))
    walk_numbers = {a.place: numbers.get(a.place, {}) for a in ground if a.role == "walk"}
    return CrowdLayout(walkable, blocked, ground, tuple(stages), walk_numbers)


def _stage_points(area: Area, walkable, entrances: Sequence[Area]) -> np.ndarray:
    """The positions of a stage place (see :class:`StagePlace`); queue and waiting positions
    only where a person's centre may stand (inside ``walkable``, its radius from the edge)."""
    import shapely

    long_axis = int(np.argmax(area.half))
    if area.role == "entrance":
        return np.zeros((0, 2))
    if area.role == "waypoint":
        return area.centre[None, :2].copy()
    if area.role in ("queue", "seat"):
        spacing = QUEUE_SPACING_M if area.role == "queue" else SEAT_SPACING_M
        n = max(1, int(math.floor(2.0 * area.half[long_axis] / spacing)))
        t = (np.arange(n) - (n - 1) / 2.0) * spacing
        local = np.zeros((n, 2))
        local[:, long_axis] = t
        points = area.centre[:2] + local @ area.axes.T
        if area.role == "queue" and entrances:
            # The head is the end farther from the nearest entrance: people join at the back.
            nearest = min(entrances, key=lambda e: float(np.linalg.norm(e.centre[:2] - area.centre[:2])))
            if np.linalg.norm(points[0] - nearest.centre[:2]) < np.linalg.norm(points[-1] - nearest.centre[:2]):
                points = points[::-1]
    else:  # wait: a grid of spots
        n = np.maximum(1, np.floor(2.0 * area.half / WAIT_SPACING_M)).astype(int)
        u = (np.arange(n[0]) - (n[0] - 1) / 2.0) * WAIT_SPACING_M
        v = (np.arange(n[1]) - (n[1] - 1) / 2.0) * WAIT_SPACING_M
        gu, gv = np.meshgrid(u, v, indexing="ij")
        points = area.centre[:2] + np.stack([gu.ravel(), gv.ravel()], axis=1) @ area.axes.T
    if area.role == "seat":
        return points
    inner = walkable.buffer(-PERSON_RADIUS_M)
    keep = shapely.contains_xy(inner, points[:, 0], points[:, 1]) if not inner.is_empty else np.zeros(len(points), bool)
    return points[keep]
