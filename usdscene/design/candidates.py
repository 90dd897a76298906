"""Candidate cameras of a plan: mount positions found by casting rays in the environment
(ceilings and walls of rooms; poles and façades in the open air), mounts the environment marks
(``mount_*`` nodes) or the user gives, aimed at clusters of targets, times every lens. Only
mountable structure carries a mount (:mod:`usdscene.design.mount_surfaces`). Pure.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import MutableMapping, Sequence

import numpy as np

from usdscene.document.model import Camera, Pose
from usdscene.design.lenses import Lens, lens_intrinsics
from usdscene.design.mount_surfaces import MountSurfaces
from usdscene.design.occluders import Occluders
from usdscene.design.targets import Target

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Mount:
    """A place a camera can be fixed.

    Attributes:
        position_m: (3,) camera centre, metres (a little off the surface).
        surface: ``ceiling`` or ``wall`` (rooms), ``pole`` or ``facade`` (open air), ``node``
            (an environment's ``mount_*`` node) or ``user`` (``--mounts FILE``).
        normal: (3,) unit normal of the surface, pointing away from it (a node's facing);
            (0, 0, 0) where the mount may look any way (poles, user mounts).
        aims: (3,) unit directions the camera may take; empty = the surface normal (if any)
            and the nearest target clusters.
        name: the node's or user's name of the mount ("" for found mounts).
    """

    position_m: tuple[float, float, float]
    surface: str
    normal: tuple[float, float, float]
    aims: tuple[tuple[float, float, float], ...] = ()
    name: str = ""


@dataclass(frozen=True)
class RoomGrid:
    """How :func:`candidate_mounts` probes a room.

    Attributes:
        spacing_m: grid spacing, metres.
        offset_m: distance of the camera centre from its surface, metres.
        walls: add wall mounts.
    """

    spacing_m: float = 0.8
    offset_m: float = 0.05
    walls: bool = True


@dataclass(frozen=True)
class PoleGrid:
    """How :func:`open_air_mounts` stands poles and finds façades.

    Attributes:
        heights_m: camera heights above the ground, metres.
        spacing_m: pole grid spacing, metres.
        ground_band_m: how far above the region's lowest point the ground may lie, metres.
        facade_reach_m: how far from a pole a façade is looked for, metres.
        offset_m: distance of a façade camera from its wall, metres.
    """

    heights_m: tuple[float, ...] = (4.0, 6.0)
    spacing_m: float = 4.0
    ground_band_m: float = 1.0
    facade_reach_m: float = 12.0
    offset_m: float = 0.05


@dataclass(frozen=True)
class Aiming:
    """How :func:`candidate_cameras` aims a mount's cameras.

    Attributes:
        aims: how many of the nearest target clusters a mount aims at.
        cluster_m: target cluster cell, metres.
        max_range_m: farthest cluster aimed at from a ceiling or wall mount, metres.
        open_air_range_m: farthest cluster aimed at from any other mount, metres.
    """

    aims: int = 4
    cluster_m: float = 1.6
    max_range_m: float = 8.0
    open_air_range_m: float = 20.0


def candidate_mounts(occluders: Occluders, region_m: tuple[Sequence[float], Sequence[float]], *,
                     grid: RoomGrid = RoomGrid(), surfaces: MountSurfaces | None = None,
                     structure: Occluders | None = None,
                     left_out: MutableMapping[str, int] | None = None) -> list[Mount]:
    """Ceiling and wall positions of the environment inside an axis-aligned region.

    A grid of probe points at the region's mid-height (``grid.spacing_m`` apart in X and Y) casts
    rays up (ceiling) and, with ``grid.walls``, sideways in ±X and ±Y at 80 % of the ceiling height
    (walls). A probe counts only when a ray down also hits something (it is inside the
    environment, not above an open floor). Mounts sit ``grid.offset_m`` off the surface hit.

    Args:
        occluders: the environment (and objects) to cast against.
        region_m: ((3,), (3,)) min and max corners of the space to look in, metres.
        grid: the probe grid (:class:`RoomGrid`).
        surfaces: when given, a mount must be clear of unmountable geometry
            (:meth:`MountSurfaces.clear`).
        structure: when given, the rays are cast against it instead of ``occluders``: the
            mountable triangles alone, so that a passenger's head or a tree crown is neither a
            ceiling nor a wall, and the ray goes on to the structure behind it.
        left_out: when given, counts of what was not made a mount, by reason (added to).

    Returns:
        Mounts, deduplicated to a ``grid.spacing_m / 2`` grid, in a deterministic order.
    """
    spacing_m, offset_m, walls = grid.spacing_m, grid.offset_m, grid.walls
    lo, hi = np.asarray(region_m[0], float), np.asarray(region_m[1], float)
    if structure is not None:
        occluders = structure
    xs = np.arange(lo[0] + spacing_m / 2, hi[0], spacing_m)
    ys = np.arange(lo[1] + spacing_m / 2, hi[1], spacing_m)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    z_mid = lo[2] + 0.5 * (hi[2] - lo[2])
    probes = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, z_mid)], axis=1)
    span = float(np.linalg.norm(hi - lo))
    down = occluders.first_hit(probes, np.tile([0.0, 0.0, -1.0], (len(probes), 1)), span)
    up = occluders.first_hit(probes, np.tile([0.0, 0.0, 1.0], (len(probes), 1)), span)
    inside = np.isfinite(down) & np.isfinite(up)
    mounts: list[Mount] = []
    keys: set[tuple[int, int, int]] = set()
    _count(left_out, "room probes with no ceiling above or no floor below (open air)", int((~inside).sum()))

    def add(p: np.ndarray, surface: str, normal: Sequence[float]) -> None:
        if surfaces is not None and not surfaces.clear(p)[0]:
            _count(left_out, f"{surface} positions inside or within 10 cm of unmountable geometry", 1)
            return
        key = tuple(int(round(v / (spacing_m / 2))) for v in p)
        if key not in keys and np.all(p >= lo - 1e-9) and np.all(p <= hi + 1e-9):
            keys.add(key)  # type: ignore[arg-type]
            mounts.append(Mount(tuple(float(v) for v in p), surface, tuple(float(v) for v in normal)))  # type: ignore[arg-type]

    for p, d in zip(probes[inside], up[inside]):
        add(p + np.array([0.0, 0.0, d - offset_m]), "ceiling", (0.0, 0.0, -1.0))
    if walls and inside.any():
        ceiling = probes[inside, 2] + up[inside]
        wall_probes = probes[inside].copy()
        wall_probes[:, 2] = lo[2] + 0.8 * (ceiling - lo[2])
        for direction in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)):
            dirs = np.tile(direction, (len(wall_probes), 1))
            dist = occluders.first_hit(wall_probes, dirs, span)
            # Only the outermost probe of each line sees the wall directly, the others hit it
            # too but land on the same dedup key.
            for p, d in zip(wall_probes, dist):
                if np.isfinite(d) and d > offset_m:
                    add(p + np.asarray(direction) * (d - offset_m), "wall", tuple(-v for v in direction))
    return mounts


def open_air_mounts(occluders: Occluders, triangles_m: np.ndarray, surfaces: MountSurfaces,
                    region_m: tuple[Sequence[float], Sequence[float]], *, grid: PoleGrid = PoleGrid(),
                    left_out: MutableMapping[str, int] | None = None) -> list[Mount]:
    """Poles and façade mounts of the open air.

    A grid of rays (``grid.spacing_m`` apart in X and Y) comes straight down from above the region.
    Where the first surface it meets is *open ground* (mountable, facing up within 25°, and no
    more than ``ground_band_m`` above the lowest point of the region: the walkable or drivable
    level, not a roof or a tree crown), a pole stands, with a camera at each of ``heights_m``
    above the ground. From each pole camera, rays in ±X and ±Y meet the nearest wall within
    ``facade_reach_m``: where that wall is mountable and upright (within 20° of vertical), a
    façade mount at that height faces away from it. Mounts within the keep-out boxes of
    ``surfaces`` are dropped.

    Args:
        occluders: the whole scene.
        triangles_m: (T, 3, 3) the same triangles (for surface normals).
        surfaces: mountability of those triangles.
        region_m: ((3,), (3,)) min and max corners of the space to look in, metres.
        grid: the poles' grid, heights and façade reach (:class:`PoleGrid`).
        left_out: when given, counts of pole positions (grid rays) and pole cameras not made
            mounts, by reason (added to), e.g. ground higher than ``ground_band_m`` above the
            lowest point.

    Returns:
        Pole mounts, then façade mounts, deduplicated to a ``grid.spacing_m / 4`` grid, deterministic.
    """
    heights_m, spacing_m, ground_band_m = grid.heights_m, grid.spacing_m, grid.ground_band_m
    facade_reach_m, offset_m = grid.facade_reach_m, grid.offset_m
    lo, hi = np.asarray(region_m[0], float), np.asarray(region_m[1], float)
    tris = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3, 3)
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    xs = np.arange(lo[0] + spacing_m / 2, hi[0], spacing_m)
    ys = np.arange(lo[1] + spacing_m / 2, hi[1], spacing_m)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    top = hi[2] + 1.0
    starts = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, top)], axis=1)
    dist, hit = occluders.first_hit_triangle(starts, np.tile([0.0, 0.0, -1.0], (len(starts), 1)), top - lo[2] + 1.0)
    ground = np.isfinite(dist) & (hit >= 0)
    _count(left_out, "pole positions over nothing", int((~ground).sum()))
    first = hit.clip(0)
    unmountable = ground & ~surfaces.mountable[first]
    _count(left_out, "pole positions whose first surface below is unmountable (a tree, a vehicle, ...)",
           int(unmountable.sum()))
    tilted = ground & ~unmountable & (np.abs(normals[first, 2]) < math.cos(math.radians(25)))
    _count(left_out, "pole positions over ground steeper than 25 degrees", int(tilted.sum()))
    ground &= ~unmountable & ~tilted
    high = ground & ((top - np.where(np.isfinite(dist), dist, 0.0)) > lo[2] + ground_band_m)
    _count(left_out, f"pole positions over ground more than {ground_band_m:g} m above the scene's lowest point "
                     f"(z = {lo[2]:.2f} m: a roof, a deck above lower steps)", int(high.sum()))
    ground &= ~high
    poles: list[Mount] = []
    facades: list[Mount] = []
    keys: set[tuple] = set()
    cell = spacing_m / 4
    for start, d in zip(starts[ground], dist[ground]):
        foot = start - np.array([0.0, 0.0, d])
        for h in heights_m:
            p = foot + np.array([0.0, 0.0, float(h)])
            if not surfaces.clear(p)[0]:
                _count(left_out, "pole cameras inside or within 10 cm of unmountable geometry", 1)
            elif ("pole", *np.round(p / cell).astype(int)) not in keys:
                keys.add(("pole", *np.round(p / cell).astype(int)))
                poles.append(Mount(tuple(float(v) for v in p), "pole", (0.0, 0.0, 0.0)))  # type: ignore[arg-type]
            for direction in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)):
                reach, tri = occluders.first_hit_triangle(p[None], np.asarray([direction]), facade_reach_m)
                t = int(tri[0])
                if not np.isfinite(reach[0]) or t < 0 or reach[0] <= offset_m or not surfaces.mountable[t] \
                        or abs(normals[t, 2]) > math.sin(math.radians(20)):
                    continue
                q = p + np.asarray(direction) * (reach[0] - offset_m)
                key = ("facade", *np.round(q / cell).astype(int))
                if key in keys or not surfaces.clear(q)[0]:
                    continue
                keys.add(key)
                facades.append(Mount(tuple(float(v) for v in q), "facade",  # type: ignore[arg-type]
                                     tuple(-v for v in direction)))  # type: ignore[arg-type]
    return poles + facades


def _count(left_out: MutableMapping[str, int] | None, reason: str, n: int) -> None:
    """Add ``n`` to ``left_out[reason]`` (nothing when there is no counter or ``n`` is 0)."""
    if left_out is not None and n:
        left_out[reason] = left_out.get(reason, 0) + n


def look_rotation(forward: Sequence[float]) -> np.ndarray:
    """Camera → world rotation (OpenCV axes: x right, y down, z forward) looking along
    ``forward`` with the image's up towards world +Z (straight down: image up = world +Y).

    Returns:
        (3, 3) float64.
    """
    z = np.asarray(forward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0]) if z[2] < 0 else np.array([-1.0, 0.0, 0.0])
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def target_clusters(targets: Sequence[Target], cell_m: float) -> np.ndarray:
    """Centroids of targets grouped on an XY grid of ``cell_m`` cells (deterministic).

    Returns:
        (K, 3) float64 centroids in metres, sorted by cell.
    """
    centres = np.array([t.centre_m for t in targets]).reshape(-1, 3)
    cells = np.floor(centres[:, :2] / cell_m).astype(np.int64)
    groups: dict[tuple[int, int], list[int]] = {}
    for i, c in enumerate(map(tuple, cells)):
        groups.setdefault(c, []).append(i)
    return np.array([centres[groups[k]].mean(axis=0) for k in sorted(groups)]).reshape(-1, 3)


# Surfaces of rooms (aims within the room's reach) and of the open air (longer reach).
_ROOM_SURFACES = ("ceiling", "wall")


def candidate_cameras(mounts: Sequence[Mount], targets: Sequence[Target], lenses: Sequence[Lens], *,
                      aiming: Aiming = Aiming()) -> list[Camera]:
    """Cameras at every mount, with every lens, aimed along the mount's own ``aims`` when it has
    some, else along the surface normal (ceilings, nodes; walls and façades tilted 35° down)
    and at the ``aiming.aims`` nearest target clusters (within ``aiming.max_range_m`` of a
    ceiling or wall mount, ``aiming.open_air_range_m`` of any other) that lie in front of the surface.

    Camera names are ``cand_<mount>_<aim>_<lens>``; ``custom`` records the lens name, mount
    surface and aim, which the plan writes back into the document.

    Returns:
        Cameras in mount, aim, lens order.
    """
    aims, cluster_m = aiming.aims, aiming.cluster_m
    max_range_m, open_air_range_m = aiming.max_range_m, aiming.open_air_range_m
    clusters = target_clusters(targets, cluster_m)
    cameras = []
    for m_index, mount in enumerate(mounts):
        p = np.asarray(mount.position_m)
        normal = np.asarray(mount.normal)
        directions: list[tuple[np.ndarray, str]] = []
        if mount.aims:
            directions = [(np.asarray(a, dtype=np.float64), "given") for a in mount.aims]
        else:
            if mount.surface in ("ceiling", "node"):
                directions.append((normal, "normal"))
            elif np.linalg.norm(normal) > 0:
                # A wall camera along its normal looks at the opposite wall; tilt it down 35°.
                directions.append((normal * math.cos(math.radians(35)) +
                                   np.array([0.0, 0.0, -math.sin(math.radians(35))]), "normal"))
            reach = max_range_m if mount.surface in _ROOM_SURFACES else open_air_range_m
            if len(clusters):
                d = np.linalg.norm(clusters - p, axis=1)
                order = [i for i in np.argsort(d, kind="stable") if 0.3 < d[i] <= reach]
                for i in order[:aims]:
                    v = (clusters[i] - p) / d[i]
                    # Not into the surface the camera hangs on (poles have none).
                    if not np.linalg.norm(normal) or float(v @ normal) > 0.05:
                        directions.append((v, "target"))
        for a_index, (forward, aim) in enumerate(directions):
            rotation = look_rotation(forward)
            for lens in lenses:
                custom = {"lens": lens.name, "mount": mount.surface, "aim": aim}
                if mount.name:
                    custom["mount_name"] = mount.name
                cameras.append(Camera(
                    name=f"cand_{m_index:04d}_{a_index}_{lens.name}",
                    intrinsics=lens_intrinsics(lens),
                    pose=Pose.from_rotation_translation(rotation, p),
                    model_name=lens.name,
                    custom=custom))
    return cameras
