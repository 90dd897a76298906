"""Ray casting against a scene's world triangles: Embree through ``embreex`` when it is
installed, trimesh's own ray-triangle test otherwise. Pure (no pxr, no bpy).
"""

from __future__ import annotations

import logging

import numpy as np


log = logging.getLogger(__name__)


# A ray stops this short of its target point (the marker radius of verification renders).
RAY_MARGIN_M = 0.02


class Occluders:
    """The scene's triangles as a ray-casting structure (built once, queried many times).

    Embree (``embreex``) when it imports, else trimesh's pure ray-triangle intersector.

    Args:
        triangles_m: (T, 3, 3) world triangle vertices, metres.
    """

    def __init__(self, triangles_m: np.ndarray) -> None:
        tris = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3, 3)
        self.triangle_count = len(tris)
        self.bounds_m = (tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)) if len(tris) else \
            (np.zeros(3), np.zeros(3))
        vertices = tris.reshape(-1, 3)
        faces = np.arange(len(vertices)).reshape(-1, 3)
        self._embree = None
        self._trimesh = None
        if not len(tris):
            return
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
        except ImportError:
            import trimesh

            log.info("embreex not installed: pure-Python ray casting (slower)")
            self._trimesh = trimesh.ray.ray_triangle.RayMeshIntersector(
                trimesh.Trimesh(vertices=vertices, faces=faces, process=False))
            return
        # Embree is single precision: rays start near the origin of their own geometry, so
        # shift everything by the scene's centre.
        self._offset = (self.bounds_m[0] + self.bounds_m[1]) / 2
        scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene=scene, vertices=(vertices - self._offset).astype(np.float32),
                     indices=faces.astype(np.int32))
        self._embree = scene

    @property
    def backend(self) -> str:
        """``embree`` or ``trimesh``."""
        return "embree" if self._embree is not None else "trimesh"

    def blocked(self, origins_m: np.ndarray, points_m: np.ndarray, margin_m: float = RAY_MARGIN_M) -> np.ndarray:
        """Whether a triangle lies on the segment from each origin to its point.

        Args:
            origins_m: (N, 3) or (3,) ray origins, metres.
            points_m: (N, 3) end points, metres.
            margin_m: the segment stops this short of the point.

        Returns:
            (N,) bool.
        """
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        origins = np.broadcast_to(np.asarray(origins_m, dtype=np.float64), pts.shape)
        if len(pts) == 0 or (self._embree is None and self._trimesh is None):
            return np.zeros(len(pts), dtype=bool)
        delta = pts - origins
        dist = np.linalg.norm(delta, axis=1)
        dirs = delta / np.where(dist > 0, dist, 1.0)[:, None]
        far = np.maximum(dist - margin_m, 0.0)
        if self._embree is not None:
            hits = self._embree.run((origins - self._offset).astype(np.float32), dirs.astype(np.float32),
                                    dists=far.astype(np.float32), query="OCCLUDED")
            return (np.asarray(hits) != -1) & (far > 0)
        index_tri, index_ray, locations = self._trimesh.intersects_id(
            origins, dirs, multiple_hits=True, return_locations=True)
        out = np.zeros(len(pts), dtype=bool)
        if len(index_ray):
            t = np.einsum("ij,ij->i", locations - origins[index_ray], dirs[index_ray])
            close = (t > 1e-9) & (t < far[index_ray])
            out[np.unique(index_ray[close])] = True
        return out

    def first_hit(self, origins_m: np.ndarray, directions: np.ndarray, max_m: float = 1e3) -> np.ndarray:
        """Distance along each ray to the first triangle; ``inf`` where none within ``max_m``.

        Args:
            origins_m: (N, 3) ray origins, metres.
            directions: (N, 3) unit directions.

        Returns:
            (N,) float64 metres.
        """
        return self.first_hit_triangle(origins_m, directions, max_m)[0]

    def first_hit_triangle(self, origins_m: np.ndarray, directions: np.ndarray,
                           max_m: float = 1e3) -> tuple[np.ndarray, np.ndarray]:
        """Distance along each ray to the first triangle, and that triangle's index.

        Args:
            origins_m: (N, 3) ray origins, metres.
            directions: (N, 3) unit directions.

        Returns:
            (N,) float64 metres (``inf`` where no triangle within ``max_m``) and (N,) int64
            triangle indices into the constructor's array (-1 where none).
        """
        origins = np.asarray(origins_m, dtype=np.float64).reshape(-1, 3)
        dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(origins), np.inf)
        index = np.full(len(origins), -1, dtype=np.int64)
        if self._embree is not None:
            result = self._embree.run((origins - self._offset).astype(np.float32), dirs.astype(np.float32),
                                      dists=np.full(len(origins), max_m, np.float32), output=1)
            hit = np.asarray(result["geomID"]) != -1
            out[hit] = np.asarray(result["tfar"], dtype=np.float64)[hit]
            index[hit] = np.asarray(result["primID"], dtype=np.int64)[hit]
            return out, index
        if self._trimesh is None:
            return out, index
        index_tri, index_ray, locations = self._trimesh.intersects_id(origins, dirs, multiple_hits=False,
                                                                      return_locations=True)
        if len(index_ray):
            d = np.linalg.norm(locations - origins[index_ray], axis=1)
            near = d <= max_m
            out[index_ray[near]] = d[near]
            index[index_ray[near]] = np.asarray(index_tri)[near]
        return out, index
