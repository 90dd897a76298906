"""Obstacles of an environment: its visible surfaces recorded as occupied cubes
(:class:`Obstacles`, from :func:`environment_obstacles`), and whether a mover's footprint meets
geometry between a step's height above its ground and its own height; whether a point has a
floor under it (:func:`floor_missing`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from usdscene.scene.catalog import Catalog
from usdscene.document.model import SceneSpec

OBSTACLE_CELL_M = 0.1
"""Edge of the cubes in which the environment's surfaces are recorded as obstacles (metres);
an obstacle is found to within about one of them."""
STEP_HEIGHT_M = 0.3
"""Geometry up to this height above a mover's ground is stepped or driven over (kerbs, paint)."""
FLOOR_BAND_M = (0.35, 0.1)
"""A walk place has a floor under a point when a surface lies from this far below its support
height to this far above it (metres); where none does, the point is no more walkable than an obstacle."""
MAX_OBSTACLE_CELLS = 30_000_000
"""Most cubes of an obstacle grid; a larger environment gets coarser cubes."""


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


def floor_missing(obstacles: Obstacles, xy: np.ndarray, z_m) -> np.ndarray:
    """(N,) whether no surface of the environment lies within :data:`FLOOR_BAND_M` of the support
    height ``z_m`` (a float or (N,)) under each point (N, 2): a stairwell, the end of a slab,
    outside the model. Obstacles without any geometry (an empty grid: nothing known about the
    ground) miss no floor."""
    if not obstacles.below[..., -1].any():
        return np.zeros(len(xy), dtype=bool)
    cell = obstacles.cell_m
    nx, ny, levels = obstacles.below.shape
    idx = np.floor((np.asarray(xy, dtype=np.float64) - obstacles.origin[:2]) / cell).astype(np.int64)
    inside = (idx[:, 0] >= 0) & (idx[:, 0] < nx) & (idx[:, 1] >= 0) & (idx[:, 1] < ny)
    column = np.where(inside, idx[:, 0] * ny + idx[:, 1], 0)
    low, high = FLOOR_BAND_M
    z = np.broadcast_to(np.asarray(z_m, dtype=np.float64), (len(column),))
    k0 = np.clip(np.floor((z - low - obstacles.origin[2]) / cell), 0, levels - 1).astype(np.int64)
    k1 = np.clip(np.ceil((z + high - obstacles.origin[2]) / cell), 0, levels - 1).astype(np.int64)
    flat = obstacles.below.reshape(-1)
    return ~inside | (flat[column * levels + k1] - flat[column * levels + k0] == 0)
