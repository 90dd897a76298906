"""What a camera may be fixed to: the rule that splits a scene's geometry into mountable
structure (floors, walls, ceilings, posts, masts, buildings) and geometry that never carries a
camera (vegetation, vehicles, movable or soft things, and every object the document places).
Pure (numpy).

The rule, in order:

1. an environment mesh (or its nearest ancestor) with the custom attribute
   ``usdscene:mountable`` (bool) is what that attribute says;
2. otherwise a mesh whose prim path has a word of :data:`NEVER_MOUNTED_WORDS` (split at
   non-letters and at lower-to-upper case changes, so ``OakTree_2`` and ``tree_crown`` both
   name a tree; a word counts when it starts with one of them, so ``trees`` and ``foliage01``
   count and ``street`` does not) is not mountable;
3. every other environment mesh is mountable;
4. objects of the document (passengers, vehicles, bags) are never mountable: they move.

A mount must also lie outside every unmountable environment mesh (rays in all six axis
directions meet it: the point is enclosed, as inside a tree crown) and at least
:data:`KEEP_OUT_M` from it (no camera in the leaves of a hedge).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from usdscene.design.occluders import Occluders

# Word beginnings of environment parts that never carry a camera. "car" is left out on
# purpose: it would make a whole "car_park" environment unmountable; name a parked vehicle
# "vehicle" or mark it with usdscene:mountable = false.
NEVER_MOUNTED_WORDS = (
    "tree", "bush", "shrub", "hedge", "plant", "foliage", "leaf", "leaves", "vegetation", "grass", "crown",
    "vehicle", "truck", "lorry", "van", "bus", "sedan", "hatchback", "bicycle", "bike", "motorbike",
    "motorcycle", "scooter", "trolley", "awning", "umbrella", "tent", "flag", "banner", "curtain", "cloth",
    "fabric", "person", "people", "pedestrian", "passenger",
)
# Words of NEVER_MOUNTED_WORDS that must match whole (as a prefix they would hit "vanity",
# "business", "plantroom" is fine to hit, "bushing" is not a plant).
_WHOLE_WORDS = frozenset({"van", "bus", "bike", "tent", "flag", "crown"})
# Clearance of a mount from unmountable environment geometry, metres.
KEEP_OUT_M = 0.1
_AXES = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]])


def path_words(path: str) -> list[str]:
    """Lower-case words of a prim path: split at non-letters and at lower-to-upper changes."""
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", path)
    return [w.lower() for w in re.split(r"[^A-Za-z]+", spaced) if w]


def is_mountable(path: str, flag: bool | None) -> bool:
    """Whether an environment mesh may carry a camera (rules 1-3 of the module docstring)."""
    if flag is not None:
        return bool(flag)
    for word in path_words(path):
        for bad in NEVER_MOUNTED_WORDS:
            if word == bad or (bad not in _WHOLE_WORDS and word.startswith(bad)):
                return False
    return True


@dataclass(frozen=True)
class MountSurfaces:
    """The scene's triangles split by mountability.

    Attributes:
        mountable: (T,) bool per triangle of the scene's triangle array (environment first,
            then objects, as :func:`usdscene.design.camera_design.stage_triangles` orders them).
        unmountable: ray casting against the unmountable environment triangles alone.
        unmountable_paths: prim paths of the environment meshes judged unmountable.
    """

    mountable: np.ndarray
    unmountable: Occluders
    unmountable_paths: tuple[str, ...]

    def clear(self, points_m: np.ndarray, reach_m: float = 100.0) -> np.ndarray:
        """(N,) bool: each point is neither enclosed by unmountable geometry (hit in all six axis
        directions within ``reach_m``) nor within :data:`KEEP_OUT_M` of it along an axis."""
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        if not len(pts) or not self.unmountable.triangle_count:
            return np.ones(len(pts), dtype=bool)
        origins = np.repeat(pts, len(_AXES), axis=0)
        dist = self.unmountable.first_hit(origins, np.tile(_AXES, (len(pts), 1)), reach_m).reshape(len(pts), -1)
        enclosed = np.isfinite(dist).all(axis=1)
        return ~enclosed & (dist.min(axis=1) >= KEEP_OUT_M)


def mount_surfaces(environment: Sequence, object_triangle_count: int) -> MountSurfaces:
    """Mountability of every triangle of a scene.

    Args:
        environment: the environment's meshes in order (objects with ``path``,
            ``triangles_m`` (T_i, 3, 3) and ``mountable`` (bool or None), as
            :func:`usdscene.scene.stage_geometry.environment_meshes` returns).
        object_triangle_count: triangles of the document's objects that follow them.

    Returns:
        A :class:`MountSurfaces`.
    """
    flags, bad, paths = [], [], []
    for mesh in environment:
        ok = is_mountable(mesh.path, mesh.mountable)
        tris = np.asarray(mesh.triangles_m).reshape(-1, 3, 3)
        flags.append(np.full(len(tris), ok))
        if not ok and len(tris):
            bad.append(tris)
            paths.append(mesh.path)
    flags.append(np.zeros(object_triangle_count, dtype=bool))
    return MountSurfaces(np.concatenate(flags).astype(bool),
                         Occluders(np.concatenate(bad) if bad else np.zeros((0, 3, 3))), tuple(paths))
