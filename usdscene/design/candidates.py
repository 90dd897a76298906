"""Candidate cameras of a plan: mount positions on the ceiling and the walls found by casting
rays in the environment, aimed at clusters of targets, times every lens. Pure.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from usdscene.document.model import Camera, Pose
from usdscene.design.lenses import Lens, lens_intrinsics
from usdscene.design.occluders import Occluders
from usdscene.design.targets import Target

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Mount:
    """A place a camera can be fixed.

    Attributes:
        position_m: (3,) camera centre, metres (a little off the surface).
        surface: ``ceiling`` or ``wall``.
        normal: (3,) unit normal of the surface, pointing into the room.
    """

    position_m: tuple[float, float, float]
    surface: str
    normal: tuple[float, float, float]


def candidate_mounts(occluders: Occluders, region_min_m: Sequence[float], region_max_m: Sequence[float], *,
                     spacing_m: float = 0.8, offset_m: float = 0.05, walls: bool = True) -> list[Mount]:
    """Ceiling and wall positions of the environment inside an axis-aligned region.

    A grid of probe points at the region's mid-height (``spacing_m`` apart in X and Y) casts
    rays up (ceiling) and, with ``walls``, sideways in ±X and ±Y at 80 % of the ceiling height
    (walls). A probe counts only when a ray down also hits something (it is inside the
    environment, not above an open floor). Mounts sit ``offset_m`` off the surface hit.

    Args:
        occluders: the environment (and objects) to cast against.
        region_min_m, region_max_m: (3,) corners of the space to look in, metres.
        spacing_m: grid spacing.
        offset_m: distance of the camera centre from its surface.
        walls: add wall mounts.

    Returns:
        Mounts, deduplicated to a ``spacing_m / 2`` grid, in a deterministic order.
    """
    lo, hi = np.asarray(region_min_m, float), np.asarray(region_max_m, float)
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

    def add(p: np.ndarray, surface: str, normal: Sequence[float]) -> None:
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


def candidate_cameras(mounts: Sequence[Mount], targets: Sequence[Target], lenses: Sequence[Lens], *,
                      aims: int = 4, cluster_m: float = 1.6, max_range_m: float = 8.0) -> list[Camera]:
    """Cameras at every mount, aimed along the surface normal and at the ``aims`` nearest target
    clusters (within ``max_range_m``), with every lens.

    Camera names are ``cand_<mount>_<aim>_<lens>``; ``custom`` records the lens name, mount
    surface and aim, which the plan writes back into the document.

    Returns:
        Cameras in mount, aim, lens order.
    """
    clusters = target_clusters(targets, cluster_m)
    cameras = []
    for m_index, mount in enumerate(mounts):
        p = np.asarray(mount.position_m)
        normal = np.asarray(mount.normal)
        # A wall camera along its normal looks at the opposite wall; tilt it down 35°.
        base = normal if mount.surface == "ceiling" else normal * math.cos(math.radians(35)) + \
            np.array([0.0, 0.0, -math.sin(math.radians(35))])
        directions = [base]
        if len(clusters):
            d = np.linalg.norm(clusters - p, axis=1)
            order = [i for i in np.argsort(d, kind="stable") if 0.3 < d[i] <= max_range_m]
            for i in order[:aims]:
                v = (clusters[i] - p) / d[i]
                if float(v @ normal) > 0.05:  # not into the surface the camera hangs on
                    directions.append(v)
        for a_index, forward in enumerate(directions):
            rotation = look_rotation(forward)
            for lens in lenses:
                cameras.append(Camera(
                    name=f"cand_{m_index:04d}_{a_index}_{lens.name}",
                    intrinsics=lens_intrinsics(lens),
                    pose=Pose.from_rotation_translation(rotation, p),
                    model_name=lens.name,
                    custom={"lens": lens.name, "mount": mount.surface, "aim": "normal" if a_index == 0 else "target"}))
    return cameras
