"""Procedural mesh builders (pure numpy): the shapes every procedural asset is made of.

Every builder returns a :class:`MeshData` in metres with per-vertex normals, so smooth parts
(cushions, heads, bags) shade smoothly in any renderer without subdivision. Builders are
deterministic: the same arguments give bit-identical arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np


@dataclass(frozen=True)
class MeshData:
    """A polygon mesh.

    Attributes:
        points: (N, 3) float64 vertex positions in metres.
        normals: (N, 3) float64 unit vertex normals.
        face_counts: (F,) int32 vertices per face (3 or 4).
        face_indices: (sum(face_counts),) int32 vertex indices, counter-clockwise seen from
            outside (right-handed orientation).
    """

    points: np.ndarray
    normals: np.ndarray
    face_counts: np.ndarray
    face_indices: np.ndarray

    @property
    def triangle_count(self) -> int:
        """Triangles after fan triangulation of every face."""
        return int(np.sum(self.face_counts - 2))

    def transformed(self, matrix: np.ndarray) -> "MeshData":
        """This mesh moved by a (4, 4) column-vector transform (rotation + translation)."""
        m = np.asarray(matrix, dtype=np.float64)
        pts = self.points @ m[:3, :3].T + m[:3, 3]
        nrm = self.normals @ np.linalg.inv(m[:3, :3])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
        return MeshData(pts, nrm, self.face_counts, self.face_indices)

    def translated(self, offset_m: Sequence[float]) -> "MeshData":
        """The same mesh moved by ``offset_m`` (metres)."""
        return MeshData(self.points + np.asarray(offset_m, dtype=np.float64), self.normals,
                        self.face_counts, self.face_indices)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min (3,), max (3,)) of the points in metres."""
        return self.points.min(axis=0), self.points.max(axis=0)


def merge(meshes: Iterable[MeshData]) -> MeshData:
    """One mesh holding all ``meshes`` (indices offset)."""
    meshes = list(meshes)
    offsets = np.cumsum([0] + [len(m.points) for m in meshes[:-1]])
    return MeshData(
        points=np.concatenate([m.points for m in meshes]),
        normals=np.concatenate([m.normals for m in meshes]),
        face_counts=np.concatenate([m.face_counts for m in meshes]).astype(np.int32),
        face_indices=np.concatenate([m.face_indices + o for m, o in zip(meshes, offsets)]).astype(np.int32),
    )


def _grid_faces(rows: int, cols: int, *, wrap_cols: bool = False, flip: bool = False) -> np.ndarray:
    """Quad indices of a (rows, cols) vertex grid stored row-major → (Q, 4) int32."""
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(cols if wrap_cols else cols - 1), indexing="ij")
    r, c = r.ravel(), c.ravel()
    c1 = (c + 1) % cols
    quads = np.stack([r * cols + c, r * cols + c1, (r + 1) * cols + c1, (r + 1) * cols + c], axis=1)
    if flip:
        quads = quads[:, ::-1]
    return quads.astype(np.int32)


def _quads(points: np.ndarray, normals: np.ndarray, quads: np.ndarray) -> MeshData:
    return MeshData(points.astype(np.float64), normals.astype(np.float64),
                    np.full(len(quads), 4, dtype=np.int32), quads.reshape(-1).astype(np.int32))


def _band(half: float, radius: float, segments: int) -> np.ndarray:
    """Coordinates along one axis of a rounded box: flat middle plus ``segments`` samples in
    each rounded band, so the projected arcs get evenly spaced vertices."""
    inner = half - radius
    if radius <= 0 or segments <= 0:
        return np.array([-half, half])
    angles = np.linspace(0.0, np.pi / 2, segments + 1)[1:]
    outer = inner + radius * np.sin(angles)
    return np.concatenate([-outer[::-1], [-inner, inner] if inner > 1e-9 else [0.0], outer])


def rounded_box(size_m: Sequence[float], radius_m: float, segments: int = 2) -> MeshData:
    """A box with rounded edges and corners, centred on the origin.

    Args:
        size_m: (x, y, z) full size in metres.
        radius_m: edge radius (clamped to half the smallest size).
        segments: vertices per quarter arc (0 = sharp box).
    """
    half = np.asarray(size_m, dtype=np.float64) / 2.0
    r = float(min(radius_m, half.min() * 0.999))
    inner = half - r
    coords = [_band(h, r, segments) for h in half]
    parts = []
    for axis in range(3):
        u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1.0, 1.0):
            uu, vv = np.meshgrid(coords[u_axis], coords[v_axis], indexing="ij")
            q = np.zeros(uu.shape + (3,))
            q[..., axis] = sign * half[axis]
            q[..., u_axis] = uu
            q[..., v_axis] = vv
            q = q.reshape(-1, 3)
            clipped = np.clip(q, -inner, inner)
            d = q - clipped
            length = np.linalg.norm(d, axis=1, keepdims=True)
            direction = np.where(length > 1e-12, d / np.maximum(length, 1e-12), 0.0)
            pts = np.where(length > 1e-12, clipped + r * direction, q)
            nrm = np.where(length > 1e-12, direction, 0.0)
            flat = np.zeros(3)
            flat[axis] = sign
            nrm = np.where(length > 1e-12, nrm, flat)
            # (u, v) grid quads face -axis; flip them on the + side.
            quads = _grid_faces(len(coords[u_axis]), len(coords[v_axis]), flip=sign > 0)
            parts.append(_quads(pts, nrm, quads))
    return merge(parts)


def box(size_m: Sequence[float]) -> MeshData:
    """A sharp box centred on the origin (flat normals)."""
    return rounded_box(size_m, 0.0, 0)


def ellipsoid(radii_m: Sequence[float], rings: int = 8, sectors: int = 12) -> MeshData:
    """An ellipsoid centred on the origin (poles on ±Z)."""
    rx, ry, rz = (float(v) for v in radii_m)
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    pts = unit * [rx, ry, rz]
    nrm = unit / [rx, ry, rz]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    quads = _grid_faces(rings + 1, sectors, wrap_cols=True, flip=True)
    return _quads(pts, nrm, quads)


def _frame_along(direction: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose third column is ``direction`` (unit)."""
    z = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def capsule(start_m: Sequence[float], end_m: Sequence[float], radius_start_m: float,
            radius_end_m: float | None = None, rings: int = 4, sectors: int = 12) -> MeshData:
    """A (tapered) capsule: two hemispheres joined by a cone, from ``start_m`` to ``end_m``.

    Used for limbs; ``rings`` vertex rings per hemisphere.
    """
    r0 = float(radius_start_m)
    r1 = float(r0 if radius_end_m is None else radius_end_m)
    a = np.asarray(start_m, dtype=np.float64)
    b = np.asarray(end_m, dtype=np.float64)
    length = float(np.linalg.norm(b - a))
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    profile = []  # (radius, z, normal_r, normal_z) from the bottom pole to the top pole
    for k in range(rings + 1):
        ang = -np.pi / 2 + (np.pi / 2) * k / rings
        profile.append((r0 * np.cos(ang), r0 * np.sin(ang), np.cos(ang), np.sin(ang)))
    for k in range(rings + 1):
        ang = (np.pi / 2) * k / rings
        profile.append((r1 * np.cos(ang), length + r1 * np.sin(ang), np.cos(ang), np.sin(ang)))
    prof = np.asarray(profile)
    rad, zz, nr, nz = (prof[:, i][:, None] for i in range(4))
    cos, sin = np.cos(phi)[None, :], np.sin(phi)[None, :]
    pts = np.stack([rad * cos, rad * sin, np.broadcast_to(zz, (len(prof), sectors))], axis=-1)
    nrm = np.stack([nr * cos, nr * sin, np.broadcast_to(nz, (len(prof), sectors))], axis=-1)
    quads = _grid_faces(len(prof), sectors, wrap_cols=True)
    local = _quads(pts.reshape(-1, 3), nrm.reshape(-1, 3), quads)
    m = np.eye(4)
    m[:3, :3] = _frame_along(b - a if length > 1e-9 else np.array([0.0, 0.0, 1.0]))
    m[:3, 3] = a
    return local.transformed(m)


def lathe(profile_rz_m: Sequence[Sequence[float]], sectors: int = 16, *, smooth: bool = True) -> MeshData:
    """A surface of revolution around +Z from a (radius, z) polyline (bottom to top).

    A profile point with radius 0 closes the surface at that end.
    """
    prof = np.asarray(profile_rz_m, dtype=np.float64)
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    cos, sin = np.cos(phi)[None, :], np.sin(phi)[None, :]
    r, z = prof[:, 0:1], prof[:, 1:2]
    pts = np.stack([r * cos, r * sin, np.broadcast_to(z, (len(prof), sectors))], axis=-1)
    # Profile normals from neighbouring segments (2D normal of the (r, z) polyline).
    tangent = np.gradient(prof, axis=0) if len(prof) > 2 else np.diff(prof, axis=0).repeat(2, axis=0)
    n2 = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    n2 /= np.maximum(np.linalg.norm(n2, axis=1, keepdims=True), 1e-12)
    nr, nz = n2[:, 0:1], n2[:, 1:2]
    nrm = np.stack([nr * cos, nr * sin, np.broadcast_to(nz, (len(prof), sectors))], axis=-1)
    quads = _grid_faces(len(prof), sectors, wrap_cols=True)
    return _quads(pts.reshape(-1, 3), nrm.reshape(-1, 3), quads)


def cylinder(radius_m: float, height_m: float, sectors: int = 16, *, caps: bool = True) -> MeshData:
    """A cylinder along +Z from z = 0 to ``height_m`` with flat caps."""
    side = lathe([(radius_m, 0.0), (radius_m, height_m)], sectors)
    side = MeshData(side.points, np.concatenate([side.points[:, :2] / radius_m,
                                                 np.zeros((len(side.points), 1))], axis=1),
                    side.face_counts, side.face_indices)
    if not caps:
        return side
    return merge([side, disk(radius_m, sectors, z_m=0.0, up=False), disk(radius_m, sectors, z_m=height_m, up=True)])


def disk(radius_m: float, sectors: int = 16, *, z_m: float = 0.0, up: bool = True) -> MeshData:
    """A flat disk (triangle fan around a centre vertex) at height ``z_m`` facing ±Z."""
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    pts = np.concatenate([[[0.0, 0.0, z_m]], np.stack([radius_m * np.cos(phi), radius_m * np.sin(phi),
                                                       np.full(sectors, z_m)], axis=1)])
    nrm = np.tile([0.0, 0.0, 1.0 if up else -1.0], (sectors + 1, 1))
    k = np.arange(sectors)
    tris = np.stack([np.zeros(sectors, dtype=int), 1 + k, 1 + (k + 1) % sectors], axis=1)
    if not up:
        tris = tris[:, ::-1]
    return MeshData(pts, nrm, np.full(sectors, 3, dtype=np.int32), tris.reshape(-1).astype(np.int32))


def sweep(path_m: Sequence[Sequence[float]], radius_m: float, sides: int = 8) -> MeshData:
    """A tube of circular section along a polyline (open ends), e.g. handles and straps."""
    path = np.asarray(path_m, dtype=np.float64)
    tangents = np.gradient(path, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    # Parallel transport of the section frame avoids twisting along the path.
    normal = np.cross(tangents[0], [0.0, 0.0, 1.0] if abs(tangents[0][2]) < 0.9 else [1.0, 0.0, 0.0])
    normal /= np.linalg.norm(normal)
    frames = []
    for t in tangents:
        normal = normal - t * np.dot(normal, t)
        normal /= np.linalg.norm(normal)
        frames.append((normal, np.cross(t, normal)))
    phi = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    pts, nrm = [], []
    for p, (n, b) in zip(path, frames):
        ring = np.cos(phi)[:, None] * n + np.sin(phi)[:, None] * b
        nrm.append(ring)
        pts.append(p + radius_m * ring)
    quads = _grid_faces(len(path), sides, wrap_cols=True)
    return _quads(np.concatenate(pts), np.concatenate(nrm), quads)


def arc_points(radius_m: float, start_deg: float, end_deg: float, count: int,
               plane: str = "xz", centre_m: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """(count, 3) points on a circular arc in the ``xz`` or ``yz`` or ``xy`` plane."""
    ang = np.radians(np.linspace(start_deg, end_deg, count))
    a, b = radius_m * np.cos(ang), radius_m * np.sin(ang)
    zero = np.zeros(count)
    axes = {"xz": (a, zero, b), "yz": (zero, a, b), "xy": (a, b, zero)}[plane]
    return np.stack(axes, axis=1) + np.asarray(centre_m, dtype=np.float64)


def quad_strip(rows: np.ndarray, *, closed: bool = False) -> MeshData:
    """A surface through a (R, C, 3) grid of points (rows along the first axis); normals from
    the grid's cross products (facing the side where the quads are counter-clockwise)."""
    grid = np.asarray(rows, dtype=np.float64)
    r, c = grid.shape[:2]
    du = np.gradient(grid, axis=0)
    dv = np.gradient(grid, axis=1)
    nrm = np.cross(dv, du).reshape(-1, 3)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    quads = _grid_faces(r, c, wrap_cols=closed)
    return _quads(grid.reshape(-1, 3), nrm, quads)


def rotation_z(angle_deg: float) -> np.ndarray:
    """(4, 4) rotation about Z by ``angle_deg`` degrees (counter-clockwise seen from +Z)."""
    a = np.radians(angle_deg)
    m = np.eye(4)
    m[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    return m


def rotation_y(angle_deg: float) -> np.ndarray:
    """(4, 4) rotation about Y by ``angle_deg`` degrees (counter-clockwise seen from +Y)."""
    a = np.radians(angle_deg)
    m = np.eye(4)
    m[[0, 0, 2, 2], [0, 2, 0, 2]] = [np.cos(a), np.sin(a), -np.sin(a), np.cos(a)]
    return m


def rotation_x(angle_deg: float) -> np.ndarray:
    """(4, 4) rotation about X by ``angle_deg`` degrees (counter-clockwise seen from +X)."""
    a = np.radians(angle_deg)
    m = np.eye(4)
    m[[1, 1, 2, 2], [1, 2, 1, 2]] = [np.cos(a), -np.sin(a), np.sin(a), np.cos(a)]
    return m


def translation(offset_m: Sequence[float]) -> np.ndarray:
    """(4, 4) translation by ``offset_m`` (metres)."""
    m = np.eye(4)
    m[:3, 3] = offset_m
    return m
