"""Things that move: walkers and vehicles over time, as per-frame poses of a sequence document.

``usdscene generate tracks`` (:func:`generate_tracks`) reads a setup scene and writes a document
whose people and vehicles move continuously from frame to frame, each one object (one uid, one
track) for the whole sequence. It knows no particular environment; it reads the places of the
environment (and those the setup declares as cuboids) by the words of their name or kind:

* **walk places** (``walkway``, ``footpath``, ``sidewalk``, ``pavement``, ``aisle``,
  ``platform``, ``corridor``, ``concourse``, ``crossing``): the walkable ground; two walk places
  connect where their ``is_on`` boxes touch (within :data:`~usdscene.generate.routes.TOUCH_TOLERANCE_M`);
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
a free bay nose first and stop there, braking at :data:`~usdscene.generate.vehicles.VEHICLE_DECEL_M_S2`) or leave (parked
at frame 0, reverse out of the bay into the lane, stop for :data:`~usdscene.generate.vehicles.SHIFT_PAUSE_S`, then drive
to an entrance); every vehicle
uses its own bay. No two movers overlap at any frame: each is its asset's footprint rectangle
(plus :data:`~usdscene.generate.walkers.PERSON_MARGIN_M` around people) and a candidate route that would touch an earlier
one at some frame is drawn again (new times, speed, entrances, offset), up to
:data:`~usdscene.generate.movers.MAX_TRIES` times; then the space holds no more and the generator says so.

**Obstacles.** The places say where movers may go, not what stands there: a pillar at a
footpath's edge, a wall beside an entrance. The environment's visible surfaces are recorded as
occupied cubes of :data:`~usdscene.generate.obstacles.OBSTACLE_CELL_M` (:class:`Obstacles`, from :func:`environment_obstacles`),
and a drawn route whose footprint meets geometry from :data:`~usdscene.generate.obstacles.STEP_HEIGHT_M` above its ground up
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
chosen per walker (:func:`~usdscene.generate.walkers.locked_stride`): within 0.9-1.8 m, the one at which the phase
advances a whole number of poses per frame, and sliding is zero; at 5 fps with 8 poses every
speed of 0.8-1.8 m/s locks, at 10 fps only walkers from 1.125 m/s do (the others keep 1.4 m and
slide about as far as they walk). A class without a walk cycle slides its whole distance (1.0). Composition selects one ``pose`` variant per object: the per-frame variant is in
the document and the annotations, and a renderer that switches variants per frame follows it.

**Facing.** Every mover faces -Y, the catalog's contract: the shipped library is modelled so,
and ``usdscene assets add --forward-axis`` turns an imported asset whose front faces another
way to face it (recording ``forward_axis``). A walker's or vehicle's yaw is its heading plus a
quarter turn (:data:`~usdscene.generate.movers.FRONT_YAW`), so the asset's -Y points where it goes. An entry without a
recorded ``forward_axis`` was added saying its front already faces -Y, and is taken at its word;
no guess from the mesh is made (a long axis tells no front from back). A vehicle class longer
across (x) than along (y) by more than :data:`~usdscene.generate.vehicles.SIDEWAYS_RATIO` would drive sideways: the
generator warns and names ``--forward-axis``.

Every moving object gets per frame ``pose_matrix4x4`` (the time-sampled transform of the
stage) and the vec ``ground_position_m`` ``[x, y, z]``: where it stands on the ground (the
asset's origin, metres), which the multi-view export turns into ground-grid cells.

**Where the parts live.** This module reads the options, checks the setup, runs the movers and
writes the document and its report; the parts have a module each:
:mod:`usdscene.generate.routes` (places, their graph, route polylines and timing),
:mod:`usdscene.generate.obstacles`, :mod:`usdscene.generate.movers` (a track, a footprint, and
:func:`~usdscene.generate.movers.place`, the "draw until it fits" step every mover shares),
:mod:`usdscene.generate.walkers` (walkers, standing people, the walk cycle) and
:mod:`usdscene.generate.vehicles`. Another kind of mover (a crowd model) is one more module
beside them that draws its routes from ``routes`` and places its movers with ``place``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.scene.catalog import Catalog
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import MAX_FPS, FrameInterval, Pose, SceneObject, SceneSpec, canonical_json
from usdscene.generate.movers import STRIDE_M, Ground, Track, TrackOptions
from usdscene.generate.obstacles import Obstacles, environment_obstacles
from usdscene.generate.routes import BAY_WORDS, ENTRANCE_WORDS, LANE_WORDS, WALK_WORDS, Area, ground_areas, touch
from usdscene.generate.vehicles import vehicle_classes, vehicles
from usdscene.generate.walkers import (cycle_poses, foot_sliding, person_classes, standing_people, walk_phases,
                                       walk_variants, walkers)

STRATEGY = "tracks"
"""The ``usdscene generate`` strategy name of this module."""
MAX_PEOPLE = 10000
MAX_VEHICLES = 10000


@dataclass(frozen=True)
class GeneratedTracks:
    """A generated moving sequence: the scene and its report (see :func:`tracks_report`)."""

    scene: SceneSpec
    tracks: tuple[Track, ...]
    report: Mapping


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
        if walk and not any(any(touch(e, w) for w in walk) for e in entrances):
            problems.add(where, "no entrance for walkers: no place named or kinded "
                                f"{', '.join(ENTRANCE_WORDS)} touches a walk place; declare one")
    if options.vehicles:
        if not car_classes:
            problems.add("--vehicle-classes", "the catalog has no vehicle class; name one")
        if not lanes or not bays:
            problems.add(where, f"vehicles need lanes ({', '.join(LANE_WORDS)}) and bays "
                                f"({', '.join(BAY_WORDS)}); found {len(lanes)} lanes and {len(bays)} bays")
        elif not any(any(touch(e, lane) for lane in lanes) for e in entrances):
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
    ground = Ground(areas, catalog, options, rng, obstacles)
    tracks += vehicles(ground, car_classes, tracks)
    tracks += standing_people(ground, people_classes, tracks)
    tracks += walkers(ground, people_classes, tracks)
    scene = _scene(setup, catalog, tracks, options)
    report = tracks_report(scene, tracks, catalog, options, setup_sha256=setup_sha256)
    return GeneratedTracks(scene=scene, tracks=tuple(tracks), report=report)


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


def frame_data_text(position_m: np.ndarray, phase: float | None, pose_json: str | None) -> str:
    """A mover's per-frame object data as :func:`canonical_json` writes it (byte for byte: sorted
    keys, no spaces, floats as ``repr``): ``ground_position_m`` (3,), and for a walker its
    ``walk_phase`` and ``walk_pose_variant`` (``pose_json``: the variant as a JSON string).
    Formatted directly: a crowd of 500 over 3,000 frames writes 1.5 million of them."""
    x, y, z = (float(v) for v in position_m)
    vec = f'"vec":[{{"name":"ground_position_m","val":[{x!r},{y!r},{z!r}]}}]'
    if phase is None:
        return f'{{"object_data":{{{vec}}}}}'
    return (f'{{"object_data":{{"num":[{{"name":"walk_phase","val":{phase!r}}}],'
            f'"text":[{{"name":"walk_pose_variant","val":{pose_json}}}],{vec}}}}}')


def _scene(setup: SceneSpec, catalog: Catalog, tracks: Sequence[Track], options: TrackOptions) -> SceneSpec:
    first = _next_uid(setup)
    counters: dict[str, int] = {}
    objects = []
    for k, track in enumerate(tracks):
        n = counters.get(track.kind, 0)
        counters[track.kind] = n + 1
        entry = catalog[track.class_name]
        cycle = walk_variants(entry) if track.kind == "walking" else ()
        idx = np.flatnonzero(track.present)
        poses = tuple((int(f), _yaw_pose(track.position[f], float(track.yaw[f]))) for f in idx)
        phases = walk_phases(track)
        shown = cycle_poses(track, len(cycle)) if cycle else None
        frame_extra = []
        texts = {}  # pose variant → its JSON string
        for f in idx:
            pose = None
            if cycle:
                still = track.moving is not None and not track.moving[f] and track.still_pose is not None
                pose = track.still_pose if still else cycle[int(shown[f])]
                if pose not in texts:
                    texts[pose] = json.dumps(pose, ensure_ascii=False)
            frame_extra.append((int(f), frame_data_text(track.position[f], float(phases[f]) if cycle else None,
                                                        texts.get(pose))))
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
            sliding.append(foot_sliding(track, len(walk_variants(catalog[track.class_name]))))
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
