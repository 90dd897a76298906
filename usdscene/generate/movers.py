"""A mover and the one step every kind of mover shares: its track over the sequence
(:class:`Track`), the options of a moving sequence (:class:`TrackOptions`), its footprint, and
placing it: draw a class and its look, then draw candidate tracks until one keeps clear of the
environment's obstacles and of every mover already placed (:func:`place`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from usdscene.scene.catalog import AssetEntry, Catalog
from usdscene.errors import DocumentError
from usdscene.generate.obstacles import STEP_HEIGHT_M, Obstacles

STRIDE_M = 1.4
"""Length of one walk cycle (two steps) in metres: an adult at 1.3 m/s and 110 steps/min."""
MAX_TRIES = 200
FRONT_YAW = math.pi / 2.0
"""Yaw (rad) added to a heading so that an asset's front (-Y, the catalog's contract) points along it."""


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
        moving: (F,) bool, the frames where a walker shows its walk cycle; at the others it shows
            ``still_pose`` (a crowd's person standing in a queue); None: every frame walks.
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
    moving: np.ndarray | None = None
    still_pose: str | None = None


def footprint_of(entry: AssetEntry, margin: float) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(entry.extent_min_m[:2], float), np.asarray(entry.extent_max_m[:2], float)
    return (lo + hi) / 2.0, (hi - lo) / 2.0 + margin


def mover_height(entry: AssetEntry) -> float:
    """Top of a class above its origin (m), the tallest of its variants."""
    tops = [entry.extent_max_m[2]] + [hi[2] for by in entry.variant_extents.values() for _, hi in by.values()]
    return float(max(tops))


def draw_look(entry: AssetEntry, rng: np.random.Generator) -> tuple[str | None, AssetEntry]:
    """One appearance of the class (None when it has none) and the entry with that variant's
    extent: a van's footprint is longer than the class's default sedan's."""
    looks = entry.appearances
    look = looks[int(rng.integers(len(looks)))] if looks else None
    return look, entry.for_variants({"appearance": look}) if look else entry


def hits_obstacle(track: Track, obstacles: Obstacles | None, height_m: float, margin_m: float) -> bool:
    """Whether the track's footprint (less the ``margin_m`` kept from other movers: swinging arms
    brush a seat back, they do not walk through a pillar) meets an obstacle at a frame where it
    is present."""
    if obstacles is None:
        return False
    idx = np.flatnonzero(track.present)
    centre, axes, half = _rects(track)
    return bool(obstacles.blocked(centre[idx], axes[idx], half - margin_m, track.position[idx, 2], height_m).any())


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


def collides(track: Track, accepted: Sequence[Track]) -> bool:
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


def problem(where: str, message: str) -> DocumentError:
    return DocumentError(message, where=where)


def full_fail(flag: str, placed: int, wanted: int, what: str, blocked: int = 0) -> DocumentError:
    if blocked == MAX_TRIES:
        return problem(flag, f"only {placed} of {wanted} {what} fit: every one of {MAX_TRIES} routes drawn for "
                             f"the next one meets an obstacle of the environment (geometry from {STEP_HEIGHT_M:g} m "
                             "above the ground to the mover's height); the places lead through walls or pillars")
    return problem(flag, f"only {placed} of {wanted} {what} fit without overlapping another mover or an obstacle "
                         f"at some frame ({MAX_TRIES} tries for the next one); the space holds no more at once: "
                         "ask for fewer, a longer sequence or more space")


@dataclass(frozen=True)
class Ground:
    """What the movers of one sequence are placed on, the same for every kind of mover: the
    ground ``areas`` (:func:`usdscene.generate.routes.ground_areas`), the ``catalog``, the
    ``options``, the one generator ``rng`` (every kind draws from it in turn) and the
    environment's ``obstacles`` (None: none)."""

    areas: Sequence
    catalog: Catalog
    options: TrackOptions
    rng: np.random.Generator
    obstacles: Obstacles | None


@dataclass(frozen=True)
class Mover:
    """A mover drawn before its track: its class and catalog entry, its appearance (None when
    the class has none), its footprint ``(offset (2,), half (2,))`` in metres (of the
    appearance's extent, ``margin_m`` added around it) and its height above its origin (m)."""

    class_name: str
    entry: AssetEntry
    appearance: str | None
    footprint: tuple[np.ndarray, np.ndarray]
    height_m: float
    margin_m: float


def draw_mover(catalog: Catalog, classes: Sequence[str], rng: np.random.Generator, margin_m: float) -> Mover:
    """Draw a class of ``classes`` and one of its appearances (:func:`draw_look`)."""
    name = classes[int(rng.integers(len(classes)))]
    entry = catalog[name]
    look, sized = draw_look(entry, rng)
    return Mover(name, entry, look, footprint_of(sized, margin_m), mover_height(entry), margin_m)


def place(mover: Mover, draw: Callable[[], Track | None], others: Sequence[Track],
          obstacles: Obstacles | None) -> tuple[Track | None, int]:
    """Place a mover until it fits: call ``draw`` (a candidate track of ``mover``, or None when
    a draw gives none) up to :data:`MAX_TRIES` times and take the first candidate that meets no
    obstacle (:func:`hits_obstacle`) and overlaps none of ``others`` at any frame
    (:func:`collides`); it gets the mover's appearance.

    Returns:
        ``(track, blocked)``: the track placed, or None when none fitted, and how many
        candidates met an obstacle (:func:`full_fail` says why when none fitted).
    """
    blocked = 0
    for _ in range(MAX_TRIES):
        track = draw()
        if track is None:
            continue
        if hits_obstacle(track, obstacles, mover.height_m, mover.margin_m):
            blocked += 1
            continue
        if not collides(track, others):
            track.appearance = mover.appearance
            return track, blocked
    return None, blocked
