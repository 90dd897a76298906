"""A crowd simulated by a pedestrian-dynamics engine: ``usdscene generate tracks --motion crowd``.

The route generator (:mod:`usdscene.generate.motion`) draws each walker on a fixed route and
redraws it until it touches nobody, so two walkers never pass each other. Here the people are
agents of JuPedSim's collision-free speed model (the optional extra ``usdscene[crowd]``,
imported only when a crowd is generated), walking over the walkable area of
:func:`usdscene.generate.crowd_area.crowd_layout`; the engine keeps them apart and lets them
pass, slow down in dense places and line up.

**Who and when** (:class:`CrowdOptions`): ``people`` are inside at frame 0 (spread over the
walkable area) and the crowd keeps that many: each who leaves is replaced by an arrival at an
entrance; ``density_p_m2`` asks for that many per square metre of walkable area instead;
``arrivals_per_min`` adds arrivals at every entrance (a Poisson process; an entrance's own
``arrivals_per_min`` number wins). The simulation starts :data:`WARM_UP_S` (or, with arrivals
only, the time to cross the area) before frame 0, so people are already inside at frame 0.

**What they do.** Each arriving person draws an exit among the other entrances (all of them
equally likely; the same one when there is only one), then, with each stage place's ``share``
(or the option's), a waypoint to pass, and a queue to join or a waiting spot to stand at:

* a **queue** releases its head every ``60 / service_per_min`` seconds (``pop`` of the engine's
  queue stage); the people in it stand in line;
* a **waiting spot** (one person each) holds its person for a time drawn uniformly from
  ``wait_s``, then lets go (the engine's waiting set, switched off for that person);
* **groups** (``group_share`` of the arrivals, of 2-4 people drawn uniformly) enter together
  and keep together by a rule on top of the engine (:func:`group_speed_factor`): each step, a
  member ``d`` metres ahead of the group's centre along its heading walks at ``1 - d / 2 m`` of
  the group's speed (the slowest member's), one behind at up to 1.3 times it; so the members
  stay within :data:`GROUP_SPREAD_M` of their centre (most within 2.5 m);
* **conversations**: ``conversations`` circles of 2-3 people stand on the walk places for the
  whole sequence, facing the circle's centre (agents of a waiting set that never releases them);
* **seated** people sit on the benches (the seated class, e.g. the shipped ``passenger``, in its
  ``upright`` pose) for the whole sequence; the bench is an obstacle the others walk around.

**Bodies.** The engine's positions at the frame instants become one track per person: the
ground position (with the support height of the walk place under it, ``ground_position_m``),
the facing from the velocity smoothed over :data:`SMOOTHING_S` (held while still), the walk
cycle's phase from the distance walked (stride locked to the person's mean speed as in the route
generator), and the ``standing`` pose while slower than :data:`STILL_M_S`.
Same setup, options and seed: the same bytes (the engine is deterministic; every draw comes from
one seeded ``numpy.random.Generator``).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.document.model import SceneSpec
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import MAX_FPS
from usdscene.generate.crowd_area import PERSON_RADIUS_M, SEAT_SPACING_M, CrowdLayout, StagePlace, crowd_layout
from usdscene.generate.motion import MAX_PEOPLE, GeneratedTracks, _scene, tracks_report
from usdscene.generate.movers import FRONT_YAW, Track, TrackOptions, draw_look
from usdscene.generate.obstacles import Obstacles, environment_obstacles
from usdscene.generate.walkers import locked_stride, person_classes, walk_variants
from usdscene.scene.catalog import Catalog

log = logging.getLogger(__name__)

INSTALL_HINT = "pip install 'usdscene[crowd]'"
"""How to get the crowd engine (JuPedSim, LGPL-3.0, the ``crowd`` extra)."""
ENGINE_STEP_S = 0.1
"""Longest engine time step (s): the collision-free speed model fails in a hall with pillars at 0.2 s."""
WARM_UP_S = 5.0
"""Engine time before frame 0 when people are placed inside at the start (they settle)."""
MAX_WARM_UP_S = 180.0
STILL_M_S = 0.2
"""Slower than this (smoothed), a person shows its standing pose and keeps its facing."""
SMOOTHING_S = 0.6
"""Window of the moving average of positions whose derivative gives the facing."""
GROUP_LEAD_M = 2.0
"""A group member this far ahead of the group's centre (along its heading) stops for the others."""
GROUP_SLOWEST = 0.05
GROUP_FAST = 1.3
GROUP_SPREAD_M = 5.0
"""Every member of a group stays within this distance of the group's centre (tested on the car
park's 2.4 m footpaths, where half of the groups keep within :data:`GROUP_TYPICAL_SPREAD_M`)."""
GROUP_TYPICAL_SPREAD_M = 2.5
MAX_DENSITY_P_M2 = 2.0
"""The most people per square metre of walkable area that a crowd is placed at."""
MAX_FLOW_P_M_S = 1.3
"""The most people per metre of entrance width per second who can come in (a door's capacity)."""
MIN_GAP_M = 0.1
"""Free space between two people where a person is placed or arrives."""
ARRIVAL_ROUNDS = 1
"""Batches of candidate spots an arrival tries at its door per engine step."""
CONVERSATION_RADIUS_M = 0.55
SEATED_POSE = "upright"
STANDING_POSES = ("standing", "idle", "stand")


@dataclass(frozen=True)
class CrowdOptions:
    """What ``usdscene generate tracks --motion crowd`` generates (see the module docstring).

    Attributes:
        frames, fps, seed, person_classes, speed_range_m_s: as :class:`TrackOptions`.
        people: people inside at frame 0, kept (each who leaves is replaced).
        density_p_m2: people per square metre of walkable area instead of ``people`` (0: unused).
        arrivals_per_min: arrivals per minute at every entrance (places may say their own).
        queue_share: fraction of the people who join a queue (places may say their own ``share``).
        service_per_min: people a queue releases per minute.
        wait_share: fraction who stand at a waiting spot; wait_s: (low, high) waiting time, s.
        via_share: fraction who pass a waypoint.
        group_share: fraction of the arrivals who come in groups of 2-4.
        conversations: standing circles of 2-3 people; seated: people sitting on the benches.
        seated_classes: classes of the seated people (default: the catalog's passenger classes).
    """

    frames: int
    fps: float
    seed: int = 0
    people: int = 0
    density_p_m2: float = 0.0
    arrivals_per_min: float = 0.0
    queue_share: float = 0.0
    service_per_min: float = 6.0
    wait_share: float = 0.0
    wait_s: tuple[float, float] = (10.0, 60.0)
    via_share: float = 0.0
    group_share: float = 0.0
    conversations: int = 0
    seated: int = 0
    person_classes: tuple[str, ...] = ()
    seated_classes: tuple[str, ...] = ()
    speed_range_m_s: tuple[float, float] = (0.8, 1.6)


@dataclass
class CrowdRun:
    """The engine's people at the frame instants.

    Attributes:
        xy: (N, F, 2) positions in world metres (NaN where absent).
        kind: (N,) ``walking``, ``standing`` or ``seated``; group: (N,) group index or -1;
        speed_m_s: (N,) desired speeds.
        queue_counts: place → (F,) people in line at each frame; released: place → count.
        waited: (waits,) seconds each finished wait lasted; waits_started: waits begun.
        place: (N,) the stage place of a standing or seated person ("" otherwise).
        facing_xy: (N, 2) where a standing person faces (its circle's centre), NaN otherwise.
    """

    xy: np.ndarray
    kind: np.ndarray
    group: np.ndarray
    speed_m_s: np.ndarray
    queue_counts: dict = field(default_factory=dict)
    released: dict = field(default_factory=dict)
    waited: list = field(default_factory=list)
    waits_started: int = 0
    place: list = field(default_factory=list)
    facing_xy: np.ndarray | None = None
    routes: list = field(default_factory=list)


def _jupedsim():
    try:
        import jupedsim
    except ImportError:
        raise DocumentError(f"the crowd model needs the pedestrian engine JuPedSim, which is not installed: "
                            f"{INSTALL_HINT}", where="--motion crowd") from None
    return jupedsim


def _rate(stage: StagePlace, key: str, default: float) -> float:
    return float(stage.numbers.get(key, default))


def _spawn_region(layout: CrowdLayout, entrance: StagePlace):
    """Where arrivals at ``entrance`` appear: its box on the walkable area, a radius in."""
    from usdscene.generate.crowd_area import _box

    return _box(entrance.area).intersection(layout.walkable).buffer(-PERSON_RADIUS_M - 0.02)


def _exit_polygon(layout: CrowdLayout, entrance: StagePlace):
    """The entrance's box on the walkable area, as one convex polygon (the engine's exit)."""
    import shapely

    from usdscene.generate.crowd_area import _box

    piece = _box(entrance.area).intersection(layout.walkable)
    parts = sorted(getattr(piece, "geoms", [piece]), key=lambda p: -p.area)
    # The engine takes convex exits only: the hull of the entrance's piece (inside its box).
    return shapely.Polygon(parts[0].convex_hull.exterior) if parts and not parts[0].is_empty else None


def _component_of(layout: CrowdLayout, point) -> int:
    import shapely

    parts = list(getattr(layout.walkable, "geoms", [layout.walkable]))
    for k, p in enumerate(parts):
        if p.buffer(1e-6).contains(shapely.Point(point)) or p.distance(shapely.Point(point)) < 1e-3:
            return k
    return -1


def check_crowd(layout: CrowdLayout, options: CrowdOptions, where: str) -> dict:
    """Refuse what the walkable area cannot do: an entrance it does not connect to another
    exit, a queue or waiting place no entrance reaches, a density or arrival rate it cannot
    hold (saying the most it holds). Returns the per-entrance spawn regions and exit polygons.
    """
    import shapely

    problems = ProblemCollector()
    entrances = [s for s in layout.stages if s.role == "entrance"]
    spawn, exits = {}, {}
    for e in entrances:
        region, polygon = _spawn_region(layout, e), _exit_polygon(layout, e)
        if polygon is not None and not region.is_empty:
            spawn[e.place], exits[e.place] = region, polygon
    if not spawn:
        problems.add(where, "no entrance for the crowd: no place named or kinded entrance, exit, door or stairs "
                            "lies on the walkable area (the walk places minus the obstacles); declare one")
        problems.raise_if_any(DocumentError)
    comp = {name: _component_of(layout, shapely.Point(region.representative_point())) for name, region in spawn.items()}
    # The engine walks one connected piece: the one with the most entrances (then the largest).
    pieces = list(getattr(layout.walkable, "geoms", [layout.walkable]))
    main = max(set(comp.values()), key=lambda k: (sum(1 for j in comp.values() if j == k), pieces[k].area))
    for name, k in sorted(comp.items()):
        if k != main:
            problems.add(f"place {name!r}", "the walkable area (the walk places minus the obstacles) does not "
                                             "connect this entrance to the other entrances and exits")
    for stage in layout.stages:
        if stage.role in ("queue", "wait", "waypoint"):
            if not len(stage.points):
                problems.add(f"place {stage.place!r}", f"this {stage.role} place has no spot on the walkable area "
                                                        "(it lies off the walk places or inside an obstacle)")
                continue
            if _component_of(layout, stage.points[0]) != main:
                problems.add(f"place {stage.place!r}", f"no entrance reaches this {stage.role} place over the "
                                                        "walkable area (the walk places minus the obstacles)")
    area_m2 = float(pieces[main].area)
    most = int(math.floor(MAX_DENSITY_P_M2 * area_m2))
    wanted = int(round(options.density_p_m2 * area_m2)) if options.density_p_m2 else options.people
    if wanted + 3 * options.conversations > most:
        flag = "--density" if options.density_p_m2 else "--people"
        problems.add(flag, f"{wanted + 3 * options.conversations} people do not fit the {area_m2:.0f} m² walkable "
                           f"area; it holds at most {most} ({MAX_DENSITY_P_M2:g} per m²)")
    for e in entrances:
        rate = _rate(e, "arrivals_per_min", options.arrivals_per_min)
        width = 2.0 * float(e.area.half.max())
        cap = MAX_FLOW_P_M_S * width * 60.0
        if rate > cap:
            problems.add(f"place {e.place!r}", f"{rate:g} arrivals per minute do not fit through this {width:.1f} m "
                                                f"entrance; it admits at most {cap:.0f} per minute")
    problems.raise_if_any(DocumentError)
    return {"spawn": spawn, "exits": exits, "area": pieces[main]}


class _Engine:
    """One JuPedSim simulation of the layout, its stages and the bookkeeping of behaviours."""

    def __init__(self, layout: CrowdLayout, options: CrowdOptions, regions: Mapping, rng: np.random.Generator,
                 dt: float) -> None:
        jps = _jupedsim()
        self.jps, self.layout, self.options, self.rng, self.dt = jps, layout, options, rng, dt
        self.area = regions["area"]
        self.sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=self.area, dt=dt)
        self.entrances = sorted(regions["spawn"])
        self.spawn = regions["spawn"]
        self.exit_stage = {name: self.sim.add_exit_stage(regions["exits"][name]) for name in self.entrances}
        self.queues = {s.place: (s, self.sim.add_queue_stage([tuple(p) for p in s.points]))
                       for s in layout.of_role("queue") if len(s.points)}
        self.spots = [(s, k, self.sim.add_waiting_set_stage([tuple(p)])) for s in layout.of_role("wait")
                      for k, p in enumerate(s.points)]
        self.waypoints = {s.place: (s, self.sim.add_waypoint_stage(tuple(s.points[0]), float(max(0.5, s.area.half.min()))))
                          for s in layout.of_role("waypoint") if len(s.points)}
        self.journeys: dict[tuple[int, ...], int] = {}
        self.agent_person: dict[int, int] = {}
        self.person_agent: dict[int, int] = {}
        self.spot_of: dict[int, int] = {}  # spot index -> person
        self.spot_until: dict[int, float] = {}
        self.spot_since: dict[int, float] = {}
        self.next_pop = {name: None for name in self.queues}
        self.released = {name: 0 for name in self.queues}
        self.waited: list[float] = []
        self.waits_started = 0
        self.speeds: list[float] = []
        self.kinds: list[str] = []
        self.groups: list[int] = []
        self.places: list[str] = []
        self.facing: list[tuple[float, float]] = []
        self.routes: list[str] = []
        self.group_members: dict[int, list[int]] = {}
        self.walking = 0  # walking people in the simulation now, less those leaving
        self.leaving: list[int] = []
        self.time_s = 0.0

    # -- journeys -----------------------------------------------------------------------------

    def _journey(self, stages: Sequence[int]) -> int:
        key = tuple(stages)
        if key not in self.journeys:
            journey = self.jps.JourneyDescription(list(key))
            for a, b in zip(key, key[1:]):
                journey.set_transition_for_stage(a, self.jps.Transition.create_fixed_transition(b))
            self.journeys[key] = self.sim.add_journey(journey)
        return self.journeys[key]

    def _share(self, stage: StagePlace, default: float) -> float:
        return _rate(stage, "share", default)

    def _plan(self, entrance: str | None) -> tuple[list[int], str, int | None]:
        """A person's stages (ids), its route text and its waiting spot (or None)."""
        rng, o = self.rng, self.options
        others = [e for e in self.entrances if e != entrance] or self.entrances
        exit_name = others[int(rng.integers(len(others)))]
        stages, route = [], [entrance or "inside"]
        for name, (stage, sid) in sorted(self.waypoints.items()):
            if rng.random() < self._share(stage, o.via_share):
                stages.append(sid)
                route.append(name)
        spot = None
        draw = rng.random()
        queue_total = sum(self._share(s, o.queue_share) for s, _ in self.queues.values())
        if self.queues and draw < queue_total:
            acc = 0.0
            for name, (stage, sid) in sorted(self.queues.items()):
                acc += self._share(stage, o.queue_share)
                if draw < acc:
                    stages.append(sid)
                    route.append(name)
                    break
        elif self.spots:
            shares = {s.place: self._share(s, o.wait_share) for s, _, _ in self.spots}
            if rng.random() < min(1.0, sum(shares.values()) / max(len(shares), 1)):
                free = [i for i in range(len(self.spots)) if i not in self.spot_of]
                if free:
                    spot = free[int(rng.integers(len(free)))]
                    stages.append(self.spots[spot][2])
                    route.append(self.spots[spot][0].place)
        stages.append(self.exit_stage[exit_name])
        route.append(exit_name)
        return stages, " ".join(route), spot

    # -- agents -------------------------------------------------------------------------------

    def _free(self, xy: np.ndarray) -> bool:
        near = self.sim.agents_in_range(tuple(xy), 2 * PERSON_RADIUS_M + MIN_GAP_M)
        return not any(True for _ in near)

    def _add(self, xy, stages: Sequence[int], kind: str, speed: float, group: int = -1, place: str = "",
             facing=(math.nan, math.nan), route: str = "") -> int:
        person = len(self.kinds)
        params = self.jps.CollisionFreeSpeedModelAgentParameters(
            position=(float(xy[0]), float(xy[1])), v0=speed, radius=PERSON_RADIUS_M,
            journey_id=self._journey(stages), stage_id=stages[0])
        try:
            agent = self.sim.add_agent(params)
        except RuntimeError as exc:
            log.warning("engine refused an agent: %s", exc)
            raise DocumentError(f"the crowd engine could not place a person at ({xy[0]:.2f}, {xy[1]:.2f}) m at "
                                f"{self.time_s:.1f} s", where=f"place {self.layout.place_at(np.asarray(xy))!r}") from None
        self.agent_person[agent], self.person_agent[person] = person, agent
        self.kinds.append(kind)
        self.speeds.append(speed)
        self.groups.append(group)
        self.places.append(place)
        self.facing.append(facing)
        self.routes.append(route)
        self.walking += kind == "walking"
        return person

    def _speed(self) -> float:
        return float(self.rng.uniform(*self.options.speed_range_m_s))

    def _random_points(self, region, count: int, rounds: int = 50) -> list[np.ndarray]:
        """Up to ``count`` points of ``region`` a person's width from every agent and each other
        (``rounds`` batches of candidates drawn)."""
        import shapely

        if region.is_empty or count <= 0:
            return []
        x0, y0, x1, y1 = region.bounds
        out: list[np.ndarray] = []
        tries = 0
        while len(out) < count and tries < rounds:
            tries += 1
            cand = self.rng.uniform((x0, y0), (x1, y1), size=(max(64, 4 * (count - len(out))), 2))
            cand = cand[shapely.contains_xy(region, cand[:, 0], cand[:, 1])]
            for p in cand:
                if len(out) >= count:
                    break
                if out and np.min(np.linalg.norm(np.asarray(out) - p, axis=1)) < 2 * PERSON_RADIUS_M + MIN_GAP_M:
                    continue
                if self._free(p):
                    out.append(p)
        return out

    def place_inside(self, count: int) -> None:
        """``count`` people spread over the walkable area, each on its way (its own plan)."""
        inner = self.area.buffer(-PERSON_RADIUS_M - 0.02)
        for p in self._random_points(inner, count):
            stages, route, spot = self._plan(None)
            person = self._add(p, stages, "walking", self._speed(), route=route)
            if spot is not None:
                self.spot_of[spot] = person

    def arrive(self, entrance: str) -> bool:
        """One arrival (or a group) at ``entrance``; False when the door is full this step."""
        o, rng = self.options, self.rng
        stage = next(s for s in self.layout.of_role("entrance") if s.place == entrance)
        size = 1
        if rng.random() < _rate(stage, "group_share", o.group_share):
            size = int(rng.integers(2, 5))
        # A crowded door is tried with one batch of candidates per step (the arrival waits outside).
        points = self._random_points(self.spawn[entrance], size, rounds=ARRIVAL_ROUNDS)
        if len(points) < size:
            return False
        stages, route, spot = self._plan(entrance)
        if size > 1:
            spot = None  # a group walks on together
            stages = [s for s in stages if s not in {x[2] for x in self.spots}]
        speed = min(self._speed() for _ in range(size))
        group = len(self.group_members) if size > 1 else -1
        members = []
        for p in points:
            members.append(self._add(p, stages, "walking", speed, group=group, route=route))
        if size > 1:
            self.group_members[group] = members
        if spot is not None:
            self.spot_of[spot] = members[0]
        return True

    def converse(self, count: int) -> None:
        """``count`` standing circles of 2-3 people on the walk places, kept for the whole run."""
        inner = self.area.buffer(-(CONVERSATION_RADIUS_M + PERSON_RADIUS_M + 0.1))
        for centre in self._random_points(inner, count):
            n = int(self.rng.integers(2, 4))
            turn = float(self.rng.uniform(0, 2 * math.pi))
            spots = [centre + CONVERSATION_RADIUS_M * np.array([math.cos(turn + 2 * math.pi * k / n),
                                                                 math.sin(turn + 2 * math.pi * k / n)]) for k in range(n)]
            if not all(self._free(p) for p in spots):
                continue
            sid = self.sim.add_waiting_set_stage([tuple(p) for p in spots])
            place = self.layout.place_at(centre)
            for p in spots:
                self._add(p, [sid], "standing", 1.0, place=place, facing=(float(centre[0]), float(centre[1])),
                          route=place)

    # -- stepping -----------------------------------------------------------------------------

    def step(self) -> None:
        jps = self.jps
        t = self.time_s
        for name, (stage, sid) in self.queues.items():
            queue = self.sim.get_stage(sid)
            waiting = queue.count_enqueued()
            if waiting and self.next_pop[name] is None:
                self.next_pop[name] = t + 60.0 / _rate(stage, "service_per_min", self.options.service_per_min)
            if waiting and t >= self.next_pop[name]:
                queue.pop(1)
                self.released[name] += 1
                self.next_pop[name] = None
        for spot, person in list(self.spot_of.items()):
            stage_place, _, sid = self.spots[spot]
            agent = self.person_agent.get(person)
            stage = self.sim.get_stage(sid)
            if agent is None:
                del self.spot_of[spot]
                stage.state = jps.WaitingSetState.ACTIVE
                continue
            if spot in self.spot_until:
                if self.sim.agent(agent).stage_id != sid:  # walked on
                    self.waited.append(t - self.spot_since.pop(spot))
                    del self.spot_until[spot], self.spot_of[spot]
                    stage.state = jps.WaitingSetState.ACTIVE
                elif t >= self.spot_until[spot]:
                    stage.state = jps.WaitingSetState.INACTIVE
            elif stage.count_waiting():
                low = _rate(stage_place, "wait_min_s", self.options.wait_s[0])
                high = _rate(stage_place, "wait_max_s", self.options.wait_s[1])
                self.spot_since[spot] = t
                self.waits_started += 1
                self.spot_until[spot] = t + float(self.rng.uniform(low, max(low, high)))
        for members in self.group_members.values():
            alive = [self.person_agent[m] for m in members if m in self.person_agent]
            if len(alive) < 2:
                continue
            agents = [self.sim.agent(a) for a in alive]
            pos = np.array([a.position for a in agents])
            centre = pos.mean(axis=0)
            heading = np.array([a.orientation for a in agents]).mean(axis=0)
            norm = float(np.linalg.norm(heading))
            if norm < 1e-6:
                continue
            ahead = (pos - centre) @ (heading / norm)
            base = self.speeds[members[0]]
            for agent, lead in zip(agents, ahead):
                agent.model.v0 = base * group_speed_factor(float(lead))
        try:
            self.sim.iterate()
        except RuntimeError as exc:
            log.debug("engine step failed: %s", exc)
            raise DocumentError(f"the crowd engine stopped at {t:.1f} s: a person near there left the walkable area "
                                "or was pushed into an obstacle; widen the walk places or ask for fewer people",
                                where=f"place {self._worst_place()!r}") from None
        self.time_s += self.dt
        # The engine reports the agents that reached their exit in this step; they leave the
        # agent list at the start of the next one (so their mapping goes then).
        for agent in self.leaving:
            person = self.agent_person.pop(agent)
            del self.person_agent[person]
        self.leaving = list(self.sim.removed_agents())
        self.walking -= len(self.leaving)

    def _worst_place(self) -> str:
        """The place of the person nearest to (or furthest beyond) the walkable area's edge."""
        import shapely

        agents = list(self.sim.agents())
        if not agents:
            return ""
        xy = np.array([a.position for a in agents])
        depth = shapely.distance(self.area.boundary, shapely.points(xy))
        depth = np.where(shapely.contains_xy(self.area, xy[:, 0], xy[:, 1]), depth, -depth)
        return self.layout.place_at(xy[int(np.argmin(depth))])

    def positions(self) -> dict[int, tuple[float, float]]:
        return {self.agent_person[a.id]: a.position for a in self.sim.agents()}


def group_speed_factor(lead_m: float) -> float:
    """The group rule: a member ``lead_m`` metres ahead of its group's centre along the group's
    heading (negative: behind) walks at this fraction of the group's speed: ``1 - lead / 2 m``,
    at least :data:`GROUP_SLOWEST` and at most :data:`GROUP_FAST`."""
    return min(GROUP_FAST, max(GROUP_SLOWEST, 1.0 - lead_m / GROUP_LEAD_M))


def simulate(layout: CrowdLayout, options: CrowdOptions, regions: Mapping) -> CrowdRun:
    """Run the crowd over the sequence (see the module docstring); positions at the frames."""
    rng = np.random.default_rng(options.seed)
    fps = float(options.fps)
    steps = max(1, int(math.ceil((1.0 / fps) / ENGINE_STEP_S - 1e-9)))
    dt = 1.0 / fps / steps
    engine = _Engine(layout, options, regions, rng, dt)
    kept = int(round(options.density_p_m2 * regions["area"].area)) if options.density_p_m2 else options.people
    entrances = engine.entrances
    rates = {e.place: _rate(e, "arrivals_per_min", options.arrivals_per_min) for e in layout.of_role("entrance")
             if e.place in engine.spawn}
    if kept:
        warm = WARM_UP_S
    else:
        x0, y0, x1, y1 = regions["area"].bounds
        warm = min(MAX_WARM_UP_S, math.hypot(x1 - x0, y1 - y0) / float(np.mean(options.speed_range_m_s)))
    warm_steps = int(math.ceil(warm / dt))
    engine.time_s = -warm_steps * dt
    engine.converse(options.conversations)
    engine.place_inside(kept)
    next_arrival = {name: (engine.time_s + float(rng.exponential(60.0 / r)) if r > 0 else math.inf)
                    for name, r in sorted(rates.items())}
    frames = options.frames
    records: list[dict[int, tuple[float, float]]] = []
    queue_counts = {name: np.zeros(frames, dtype=np.int64) for name in engine.queues}
    total = warm_steps + frames * steps
    for k in range(total + 1):
        if k >= warm_steps and (k - warm_steps) % steps == 0:
            f = (k - warm_steps) // steps
            if f >= frames:
                break
            records.append(engine.positions())
            for name, (_, sid) in engine.queues.items():
                queue_counts[name][f] = engine.sim.get_stage(sid).count_enqueued()
        t = engine.time_s
        for name in sorted(next_arrival):
            while next_arrival[name] <= t:
                if not engine.arrive(name):
                    break  # the door is full: the arrival waits outside for the next step
                next_arrival[name] += float(rng.exponential(60.0 / rates[name]))
        while engine.walking < kept:  # each who left is replaced by an arrival at an entrance
            if not engine.arrive(entrances[int(rng.integers(len(entrances)))]):
                break
        engine.step()
    n = len(engine.kinds)
    xy = np.full((n, frames, 2), np.nan)
    for f, rec in enumerate(records):
        for person, p in rec.items():
            xy[person, f] = p
    return CrowdRun(xy=xy, kind=np.array(engine.kinds, dtype=object), group=np.array(engine.groups),
                    speed_m_s=np.array(engine.speeds), queue_counts=queue_counts, released=engine.released,
                    waited=engine.waited, waits_started=engine.waits_started, place=engine.places,
                    facing_xy=np.array(engine.facing, dtype=np.float64), routes=engine.routes)


# --------------------------------------------------------------------------------------------
# Bodies


def _smoothed(xy: np.ndarray, window: int) -> np.ndarray:
    """(F, 2) positions averaged over ``window`` frames centred on each (NaN frames left out)."""
    if window <= 1:
        return xy
    ok = np.isfinite(xy[:, 0])
    filled = np.where(ok[:, None], xy, 0.0)
    kernel = np.ones(window)
    s = np.stack([np.convolve(filled[:, k], kernel, mode="same") for k in range(2)], axis=1)
    c = np.convolve(ok.astype(float), kernel, mode="same")
    return np.where(ok[:, None], s / np.maximum(c, 1.0)[:, None], np.nan)


def person_tracks(run: CrowdRun, layout: CrowdLayout, catalog: Catalog, classes: Sequence[str],
                  options: CrowdOptions, rng: np.random.Generator) -> list[Track]:
    """One :class:`Track` per person of the run (bodies: facing, phase, ground height)."""
    fps = float(options.fps)
    window = max(1, int(round(SMOOTHING_S * fps)) | 1)
    tracks = []
    for p in range(len(run.kind)):
        xy = run.xy[p]
        present = np.isfinite(xy[:, 0])
        if not present.any():
            continue
        cls = classes[int(rng.integers(len(classes)))]
        entry = catalog[cls]
        look, _ = draw_look(entry, rng)
        filled = np.where(present[:, None], xy, xy[present][0])
        z = layout.support_z(filled)
        z = np.where(np.isfinite(z), z, 0.0)
        position = np.concatenate([filled, z[:, None]], axis=1)
        smooth = _smoothed(np.where(present[:, None], xy, np.nan), window)
        # the gradient before zeroing the absent frames: a frame beside an absence is then still,
        # not a jump to the world origin (which turned a person arriving or leaving for one frame)
        vel = np.nan_to_num(np.gradient(smooth, axis=0)) * fps
        speed = np.linalg.norm(vel, axis=1)
        moving = present & (speed >= STILL_M_S)
        yaw = np.full(len(xy), np.nan)
        if run.kind[p] == "standing" and np.all(np.isfinite(run.facing_xy[p])):
            d = run.facing_xy[p] - filled
            yaw = np.arctan2(d[:, 1], d[:, 0]) + FRONT_YAW
        else:
            yaw[moving] = np.arctan2(vel[moving, 1], vel[moving, 0]) + FRONT_YAW
            idx = np.flatnonzero(np.isfinite(yaw))
            if len(idx):  # held while still: the last facing (before the first move: the first)
                last = np.maximum.accumulate(np.where(np.isfinite(yaw), np.arange(len(yaw)), -1))
                yaw = np.where(last >= 0, yaw[np.maximum(last, 0)], yaw[idx[0]])
            else:
                yaw[:] = FRONT_YAW
        step = np.concatenate([[0.0], np.linalg.norm(np.diff(filled, axis=0), axis=1)])
        step = np.where(present & np.concatenate([[False], present[:-1]]), step, 0.0)
        walked = np.cumsum(step)
        mean_speed = float(step[moving].sum() / max(moving.sum(), 1) * fps) if moving.any() else 0.0
        cycle = walk_variants(entry)
        still = next((v for v in STANDING_POSES if v in entry.variants.get("pose", ())), None)
        walking = run.kind[p] == "walking"
        track = Track("walking" if walking else "standing", cls, present, position,
                      np.mod(yaw + math.pi, 2 * math.pi) - math.pi, walked, float(run.speed_m_s[p]),
                      route=tuple(run.routes[p].split()), appearance=look,
                      pose_variant=(cycle[0] if cycle and walking else still),
                      stride_m=locked_stride(max(mean_speed, 0.5), fps, len(cycle)),
                      moving=moving, still_pose=still)
        tracks.append(track)
    return tracks


def seated_tracks(layout: CrowdLayout, catalog: Catalog, classes: Sequence[str], count: int, options: CrowdOptions,
                  rng: np.random.Generator) -> list[Track]:
    """``count`` people sitting on the benches' spots (drawn without repeats) for the whole run,
    facing the bench's -Y (its front, the catalog's contract)."""
    spots = [(s, k) for s in layout.of_role("seat") for k in range(len(s.points))]
    if count > len(spots):
        raise DocumentError(f"{count} seated people need as many bench spots; the benches have {len(spots)} "
                            f"({SEAT_SPACING_M:g} m apart)", where="--seated")
    order = rng.permutation(len(spots))[:count]
    out = []
    F = options.frames
    for i in sorted(order.tolist()):
        stage, k = spots[i]
        cls = classes[int(rng.integers(len(classes)))]
        look, _ = draw_look(catalog[cls], rng)
        xy = stage.points[k]
        position = np.tile([xy[0], xy[1], stage.area.centre[2]], (F, 1))
        yaw = math.atan2(stage.area.axes[1, 0], stage.area.axes[0, 0])
        track = Track("seated", cls, np.ones(F, bool), position, np.full(F, yaw), np.zeros(F), 0.0,
                      route=(stage.place,), appearance=look, pose_variant=SEATED_POSE
                      if SEATED_POSE in catalog[cls].variants.get("pose", ()) else None)
        out.append(track)
    return out


def seated_classes(catalog: Catalog) -> tuple[str, ...]:
    """Catalog classes of kind ``passenger`` (seated people), sorted."""
    return catalog.classes("passenger")


def _check_options(setup: SceneSpec, catalog: Catalog, options: CrowdOptions) -> tuple[tuple[str, ...], tuple[str, ...]]:
    problems = ProblemCollector()
    if options.frames < 1:
        problems.add("--frames", f"frame count must be at least 1, got {options.frames}")
    if not (isinstance(options.fps, (int, float)) and 0.0 < options.fps <= MAX_FPS):
        problems.add("--fps", f"frame rate {options.fps!r} fps is not in (0, {MAX_FPS:g}]")
    if not 0 <= options.people <= MAX_PEOPLE:
        problems.add("--people", f"expected a count in [0, {MAX_PEOPLE}], got {options.people}")
    for flag, value in (("--queue-share", options.queue_share), ("--wait-share", options.wait_share),
                        ("--via-share", options.via_share), ("--group-share", options.group_share)):
        if not 0.0 <= value <= 1.0:
            problems.add(flag, f"expected a fraction in [0, 1], got {value}")
    if options.service_per_min <= 0:
        problems.add("--service", f"a queue must release people: expected a rate > 0 per minute, got "
                                  f"{options.service_per_min}")
    low, high = options.wait_s
    if not 0.0 <= low <= high:
        problems.add("--wait", f"waiting times must satisfy 0 <= low <= high, got {low}..{high}")
    low, high = options.speed_range_m_s
    if not 0.0 < low <= high:
        problems.add("--speed", f"walking speeds must satisfy 0 < low <= high, got {low}..{high}")
    if options.density_p_m2 < 0 or options.arrivals_per_min < 0:
        problems.add("--density" if options.density_p_m2 < 0 else "--arrivals", "expected a value >= 0")
    if setup.environment is None or setup.environment not in catalog:
        problems.add("metadata.usdscene.environment",
                     f"the setup needs an environment of the catalog, got {setup.environment!r}")
    problems.raise_if_any(DocumentError)
    people = options.person_classes or person_classes(catalog)
    sitting = options.seated_classes or seated_classes(catalog)
    for flag, names in (("--person-classes", options.person_classes), ("--seated-classes", options.seated_classes)):
        for name in names:
            if name not in catalog:
                problems.add(flag, f"unknown class {name!r}")
    if not people:
        problems.add("--person-classes", "the catalog has no person class (a class with walk_* pose variants or a "
                                         "person word in its name); name one")
    if options.seated and not sitting:
        problems.add("--seated-classes", "the catalog has no seated class (kind passenger); name one")
    problems.raise_if_any(DocumentError)
    return people, sitting


def generate_crowd(setup: SceneSpec, catalog: Catalog, options: CrowdOptions, *, setup_sha256: str = "",
                   obstacles: Obstacles | None = None) -> GeneratedTracks:
    """The crowd sequence of ``setup`` (see the module docstring).

    Args:
        obstacles: the environment's obstacles; default :func:`environment_obstacles` (composes
            the bare environment: needs usd-core).

    Raises:
        DocumentError: bad options, the engine missing (saying how to install it), a walkable
            area that does not connect the entrances, a queue nobody reaches, more people than
            the area or the doors hold (saying the most), a failure of the engine (naming the
            place and the time).
    """
    people_classes, sitting = _check_options(setup, catalog, options)
    _jupedsim()
    if obstacles is None:
        obstacles = environment_obstacles(setup, catalog)
    layout = crowd_layout(setup, catalog, obstacles)
    regions = check_crowd(layout, options, f"setup environment {setup.environment!r}")
    run = simulate(layout, options, regions)
    rng = np.random.default_rng([options.seed, 1])
    tracks = person_tracks(run, layout, catalog, people_classes, options, rng)
    seated = int(options.seated) + sum(int(s.numbers.get("seated", 0)) for s in layout.of_role("seat"))
    if seated and not sitting:  # the setup's benches ask for them (options.seated was checked above)
        raise DocumentError(f"the setup's seats ask for {seated} seated people, but the catalog has no seated "
                            f"class (kind passenger); name one", where="--seated-classes")
    if seated:
        tracks += seated_tracks(layout, catalog, sitting, seated, options, rng)
    scene = _scene(setup, catalog, tracks, TrackOptions(frames=options.frames, fps=options.fps, seed=options.seed))
    route_options = TrackOptions(frames=options.frames, fps=options.fps, people=len(tracks), seed=options.seed)
    report = tracks_report(scene, tracks, catalog, route_options, setup_sha256=setup_sha256)
    report["strategy"] = "tracks"
    report["motion"] = "crowd"
    report["crowd"] = {
        "walkable_area_m2": round(float(layout.walkable.area), 2),
        "people_at_frame_0": int(np.isfinite(run.xy[:, 0, 0]).sum()) if run.xy.size else 0,
        "queues": {name: {"most_in_line": int(c.max()) if len(c) else 0, "released": int(run.released[name])}
                   for name, c in sorted(run.queue_counts.items())},
        "waits": {"started": run.waits_started, "finished": len(run.waited),
                  "mean_s": round(float(np.mean(run.waited)), 2) if run.waited else 0.0},
        "groups": int(len(set(int(g) for g in run.group if g >= 0))),
        "standing": int(sum(1 for k in run.kind if k == "standing")),
        "seated": seated,
    }
    report["generator"] = {**{k: (list(v) if isinstance(v, tuple) else v)
                              for k, v in dataclasses.asdict(options).items()}, "setup_sha256": setup_sha256}
    return GeneratedTracks(scene=scene, tracks=tuple(tracks), report=report)


def generate_crowd_document(setup_path: str | os.PathLike, out_path: str | os.PathLike,
                            options: CrowdOptions) -> GeneratedTracks:
    """Read a setup, generate its crowd, check that it composes, write ``DOC`` and
    ``DOC.report.json`` atomically (nothing is written when anything fails)."""
    from usdscene.bulk import paused_collection
    from usdscene.generate.sequences import read_setup, write_generated

    setup_path, out_path = Path(setup_path), Path(out_path)
    _jupedsim()
    with paused_collection():
        setup, catalog, provenance = read_setup(setup_path, out_path)
        generated = generate_crowd(setup, catalog, options, setup_sha256=provenance.source_sha256)
        report = write_generated(generated.scene, generated.report, out_path, catalog, provenance)
    return dataclasses.replace(generated, report=report)
