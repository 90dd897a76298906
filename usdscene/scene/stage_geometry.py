"""World-space triangles of the composed stage's objects, per frame (for amodal labels).

Reads ``/World/Objects/<class>_<uid>`` prims (see :mod:`usdscene.document.stage_schema`): every
``UsdGeom.Mesh`` below an object (instance proxies included, ``guide``/``proxy`` purposes and
invisible meshes skipped) is triangulated (fan triangulation of each polygon; the ordering
does not matter for a filled silhouette) and transformed with
``ComputeLocalToWorldTransform(time)``. Objects invisible at a frame are left out.

Triangulated local points are computed once per mesh (again per frame only for meshes whose
points are time-sampled), and world triangles are cached per object and per unique set of mesh
transforms, so a static object costs one matrix comparison per frame and a moving object one
matrix product.
"""

from __future__ import annotations

import logging
import os
from collections import OrderedDict
from dataclasses import dataclass
from typing import Collection

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdscene.document import stage_schema
from usdscene.errors import CompositionError

log = logging.getLogger(__name__)

_CACHE_PER_OBJECT = 8  # unique transform sets kept per object (moving objects evict oldest)


@dataclass(frozen=True)
class _MeshInfo:
    path: str
    triangles_local: np.ndarray | None  # (T, 3, 3) float64; None = points are time-sampled
    indices: np.ndarray                 # (T, 3) int vertex indices


def triangulate(face_vertex_counts: np.ndarray, face_vertex_indices: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons → (T, 3) vertex indices; faces with < 3 vertices are dropped.

    Args:
        face_vertex_counts: (F,) int vertices per face.
        face_vertex_indices: (sum(counts),) int point indices, face after face.
    """
    counts = np.asarray(face_vertex_counts, dtype=np.int64).reshape(-1)
    indices = np.asarray(face_vertex_indices, dtype=np.int64).reshape(-1)
    if counts.size == 0 or counts.sum() != indices.size:
        return np.zeros((0, 3), dtype=np.int64)
    starts = np.cumsum(counts) - counts
    tri_per_face = np.maximum(counts - 2, 0)
    face = np.repeat(np.arange(counts.size), tri_per_face)
    k = np.arange(int(tri_per_face.sum())) - np.repeat(np.cumsum(tri_per_face) - tri_per_face, tri_per_face)
    first = starts[face]
    return np.stack([indices[first], indices[first + k + 1], indices[first + k + 2]], axis=1)


def _uid_of(prim: Usd.Prim) -> str | None:
    uid = prim.GetCustomDataByKey(stage_schema.CUSTOM_UID)
    if uid is None:
        attr = prim.GetAttribute(stage_schema.ATTR_USER_UID)
        uid = attr.Get() if attr and attr.HasValue() else None
    return None if uid is None else str(uid)


class StageGeometry:
    """Triangles of the stage's objects, frame after frame.

    Example:
        >>> geometry = StageGeometry("out/stage/scene.usda")
        >>> triangles = geometry.triangles(frame=12)   # {uid: (T, 3, 3) float64 metres}
    """

    def __init__(self, stage: Usd.Stage | str | os.PathLike) -> None:
        if isinstance(stage, Usd.Stage):
            self.stage = stage
        else:
            self.stage = Usd.Stage.Open(str(stage))
            if self.stage is None:
                raise CompositionError(f"cannot open USD stage {str(stage)!r}", where=str(stage))
        self._objects: dict[str, tuple[Usd.Prim, list[_MeshInfo]]] = {}
        self._cache: dict[str, OrderedDict[bytes, np.ndarray]] = {}
        root = self.stage.GetPrimAtPath(stage_schema.OBJECTS)
        if not root:
            return
        for prim in root.GetChildren():
            uid = _uid_of(prim)
            if uid is None:
                log.warning("%s has no %s; skipped", prim.GetPath(), stage_schema.CUSTOM_UID)
                continue
            self._objects[uid] = (prim, self._meshes(prim))

    @property
    def uids(self) -> tuple[str, ...]:
        """uids of the objects read from the stage."""
        return tuple(self._objects)

    @staticmethod
    def _meshes(prim: Usd.Prim) -> list[_MeshInfo]:
        meshes = []
        for child in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()):
            if not child.IsA(UsdGeom.Mesh):
                continue
            mesh = UsdGeom.Mesh(child)
            counts = mesh.GetFaceVertexCountsAttr().Get()
            indices = mesh.GetFaceVertexIndicesAttr().Get()
            if counts is None or indices is None:
                continue
            tri_indices = triangulate(np.asarray(counts), np.asarray(indices))
            points_attr = mesh.GetPointsAttr()
            static = points_attr.GetNumTimeSamples() == 0
            local = None
            if static:
                points = points_attr.Get()
                if points is None:
                    continue
                pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
                if tri_indices.size and tri_indices.max() >= len(pts):
                    log.warning("%s: face index beyond its %d points; skipped", child.GetPath(), len(pts))
                    continue
                local = pts[tri_indices]
            meshes.append(_MeshInfo(str(child.GetPath()), local, tri_indices))
        return meshes

    def triangles(self, frame: int, uids: Collection[str] | None = None) -> dict[str, np.ndarray]:
        """World-space triangles of the objects visible at ``frame``.

        Args:
            frame: frame number (= USD time code).
            uids: restrict to these objects; None = all.

        Returns:
            uid → (T, 3, 3) float64 triangle vertices in world metres (read-only arrays,
            shared with the cache). Invisible objects and objects without meshes are absent.
        """
        time = Usd.TimeCode(frame)
        xforms = UsdGeom.XformCache(time)
        result = {}
        for uid, prim, meshes in self._visible_objects(time, uids):
            parts, key_parts, dynamic = [], [], False
            visible_meshes = []
            for info in meshes:
                mesh_prim = self.stage.GetPrimAtPath(info.path)
                imageable = UsdGeom.Imageable(mesh_prim)
                if imageable.ComputeVisibility(time) == UsdGeom.Tokens.invisible:
                    continue
                if imageable.ComputePurpose() in (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy):
                    continue
                matrix = np.asarray(xforms.GetLocalToWorldTransform(mesh_prim), dtype=np.float64)
                visible_meshes.append((info, matrix))
                key_parts.append(info.path.encode() + matrix.tobytes())
                dynamic |= info.triangles_local is None
            if not visible_meshes:
                continue
            key = b"|".join(key_parts)
            cache = self._cache.setdefault(uid, OrderedDict())
            if not dynamic and key in cache:
                cache.move_to_end(key)
                result[uid] = cache[key]
                continue
            for info, matrix in visible_meshes:
                local = info.triangles_local
                if local is None:
                    pts = np.asarray(UsdGeom.Mesh(self.stage.GetPrimAtPath(info.path)).GetPointsAttr().Get(time),
                                     dtype=np.float64).reshape(-1, 3)
                    local = pts[info.indices]
                # USD matrices act on row vectors: p_world = p_local · M.
                parts.append(local @ matrix[:3, :3] + matrix[3, :3])
            world = np.concatenate(parts) if parts else np.zeros((0, 3, 3))
            world.flags.writeable = False
            if not dynamic:
                cache[key] = world
                while len(cache) > _CACHE_PER_OBJECT:
                    cache.popitem(last=False)
            result[uid] = world
        return result


    def _visible_objects(self, time, uids: Collection[str] | None):
        """``(uid, prim, meshes)`` of the objects (of ``uids``; None = all) visible at ``time``."""
        for uid, (prim, meshes) in self._objects.items():
            if uids is not None and uid not in uids:
                continue
            if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
                continue
            yield uid, prim, meshes

    def transforms(self, frame: int, uids: Collection[str] | None = None) -> dict[str, np.ndarray]:
        """Local → world matrices of the objects' prims visible at ``frame`` (their pose; for
        the yaw of their 3D boxes, :mod:`usdscene.labels.cuboids`).

        Returns:
            uid → (4, 4) float64 USD matrix (row vectors: ``p_world = p_local · M``).
        """
        time = Usd.TimeCode(frame)
        xforms = UsdGeom.XformCache(time)
        result = {}
        for uid, prim, _ in self._visible_objects(time, uids):
            result[uid] = np.asarray(xforms.GetLocalToWorldTransform(prim), dtype=np.float64)
        return result

    def keypoints(self, frame: int, uids: Collection[str] | None = None) -> dict[str, np.ndarray]:
        """World-space keypoints of the visible objects that carry them (people:
        ``stage_schema.ATTR_KEYPOINTS`` on the object's prim, from its selected variants).

        Returns:
            uid → (17, 3) float64 world metres, COCO-17 order.
        """
        time = Usd.TimeCode(frame)
        xforms = UsdGeom.XformCache(time)
        result = {}
        for uid, prim, _ in self._visible_objects(time, uids):
            attr = prim.GetAttribute(stage_schema.ATTR_KEYPOINTS)
            if not attr or not attr.HasValue():
                # A pose changing per frame: the keypoints of the pose child shown at this frame.
                shown = [child for child in prim.GetChildren()
                         if child.HasAttribute(stage_schema.ATTR_USER_POSE)
                         and UsdGeom.Imageable(child).ComputeVisibility(time) != UsdGeom.Tokens.invisible]
                attr = shown[0].GetAttribute(stage_schema.ATTR_KEYPOINTS) if len(shown) == 1 else None
                if not attr or not attr.HasValue():
                    continue
                prim = shown[0]
            local = np.asarray(attr.Get(time), dtype=np.float64).reshape(-1, 3)
            matrix = np.asarray(xforms.GetLocalToWorldTransform(prim), dtype=np.float64)
            result[uid] = local @ matrix[:3, :3] + matrix[3, :3]  # USD: row vectors
        return result


def object_triangles(stage: Usd.Stage | str | os.PathLike, frame: int) -> dict[str, np.ndarray]:
    """One-shot form of :meth:`StageGeometry.triangles` (no cache kept between calls)."""
    return StageGeometry(stage).triangles(frame)


# Custom attribute an environment author sets on a mesh (or an ancestor) to say whether a
# camera may be fixed to it (see docs/camera-design.md, "What a camera may be fixed to").
ATTR_MOUNTABLE = "usdscene:mountable"
# Prefixes of the environment nodes that mark a camera mount (``mount.pole_3`` in a DCC tool;
# USD prim names cannot hold a dot, so exporters write ``mount_pole_3``).
MOUNT_NODE_PREFIXES = ("mount.", "mount_")


@dataclass(frozen=True)
class EnvironmentMesh:
    """One mesh of the environment asset in world space.

    Attributes:
        path: its prim path.
        triangles_m: (T, 3, 3) float64 world triangle vertices, metres.
        mountable: the ``usdscene:mountable`` attribute of the mesh or its nearest ancestor
            that has one; None when none says.
    """

    path: str
    triangles_m: np.ndarray
    mountable: bool | None = None


def _open(stage: Usd.Stage | str | os.PathLike) -> Usd.Stage:
    if isinstance(stage, Usd.Stage):
        return stage
    opened = Usd.Stage.Open(str(stage))
    if opened is None:
        raise CompositionError(f"cannot open USD stage {str(stage)!r}", where=str(stage))
    return opened


def _mountable_flag(prim: Usd.Prim) -> bool | None:
    while prim and prim.GetPath() != Sdf.Path.absoluteRootPath:
        attr = prim.GetAttribute(ATTR_MOUNTABLE)
        if attr and attr.HasAuthoredValue():
            return bool(attr.Get())
        prim = prim.GetParent()
    return None


def environment_meshes(stage: Usd.Stage | str | os.PathLike, frame: int = 0) -> list[EnvironmentMesh]:
    """The meshes under ``/World/Environment`` (the environment asset) at ``frame``, in
    traversal order; ``guide``/``proxy`` purposes (place regions), ``render`` purpose (the
    backdrop: ground and buildings to the horizon, drawn, never an obstacle or a mount) and
    invisible meshes are skipped.
    """
    stage = _open(stage)
    root = stage.GetPrimAtPath(stage_schema.ENVIRONMENT)
    if not root:
        return []
    time = Usd.TimeCode(frame)
    xforms = UsdGeom.XformCache(time)
    meshes = []
    for info in StageGeometry._meshes(root):
        prim = stage.GetPrimAtPath(info.path)
        imageable = UsdGeom.Imageable(prim)
        if imageable.ComputeVisibility(time) == UsdGeom.Tokens.invisible:
            continue
        if imageable.ComputePurpose() in (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy, UsdGeom.Tokens.render):
            continue
        local = info.triangles_local
        if local is None:
            pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(time), dtype=np.float64).reshape(-1, 3)
            local = pts[info.indices]
        matrix = np.asarray(xforms.GetLocalToWorldTransform(prim), dtype=np.float64)
        meshes.append(EnvironmentMesh(info.path, local @ matrix[:3, :3] + matrix[3, :3], _mountable_flag(prim)))
    return meshes


def environment_triangles(stage: Usd.Stage | str | os.PathLike, frame: int = 0) -> np.ndarray:
    """World triangles of everything under ``/World/Environment`` (the environment asset) at
    ``frame``; ``guide``/``proxy``/``render`` purposes (place regions, the backdrop) and
    invisible meshes are skipped.

    Returns:
        (T, 3, 3) float64 triangle vertices in world metres.
    """
    parts = [m.triangles_m for m in environment_meshes(stage, frame)]
    return np.concatenate(parts) if parts else np.zeros((0, 3, 3))


def mount_nodes(stage: Usd.Stage | str | os.PathLike, frame: int = 0) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Camera mounts the environment marks: prims under ``/World/Environment`` whose name
    starts with ``mount.`` or ``mount_``.

    Returns:
        (name, (3,) world position in metres, (3,) unit direction of the node's -Z axis, the
        way a USD camera looks), in traversal order.
    """
    stage = _open(stage)
    root = stage.GetPrimAtPath(stage_schema.ENVIRONMENT)
    if not root:
        return []
    xforms = UsdGeom.XformCache(Usd.TimeCode(frame))
    nodes = []
    for prim in Usd.PrimRange(root, Usd.TraverseInstanceProxies()):
        name = prim.GetName()
        if not name.lower().startswith(MOUNT_NODE_PREFIXES) or not prim.IsA(UsdGeom.Xformable):
            continue
        matrix = np.asarray(xforms.GetLocalToWorldTransform(prim), dtype=np.float64)
        forward = -matrix[2, :3]
        norm = float(np.linalg.norm(forward))
        nodes.append((name, matrix[3, :3].copy(), forward / norm if norm > 0 else np.array([0.0, 0.0, -1.0])))
    return nodes
