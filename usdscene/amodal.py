"""Amodal projections: an object's whole projection into a camera image, as if nothing
occluded it, from its world-space triangles. Pure (numpy + numba; no pxr, no bpy).

Rasterisation samples pixel centres (a pixel belongs to the projection when its centre lies
inside or on the edge of a projected triangle), the rule of a renderer's one-sample-per-pixel
id pass. It runs as one compiled loop over the triangles (numba) into a crop of the image the
size of the projection's box, so its cost is the covered pixels, not the image.

Exactness, per lens:

* perspective and orthographic: triangles are clipped at the near plane and projected; straight
  edges stay straight, so the raster is the exact full-mesh projection;
* distorting lenses (OpenCV pinhole with distortion, fisheye models): projected edges are
  curves; triangles are split until their projected edges are at most
  :data:`MAX_PROJECTED_EDGE_PX` long, which keeps the raster within a fraction of a pixel of
  the curved one;
* fisheye lenses with a field of view (``fov_deg``): the image is empty beyond the image circle.
  A vertex outside the field of view is moved along its azimuth onto the circle's cone, and
  triangles that cross the circle are split like curved ones, so an object cut by the circle
  keeps the part inside it (instead of losing every triangle with a vertex outside).

Objects whose bounding sphere lies outside a camera's field of view are culled before any
triangle is projected.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Mapping

import numpy as np

if TYPE_CHECKING:
    from usdscene.labels import PixelBox
    from usdscene.model import Camera, Intrinsics

# Projected triangle edges of distorting lenses are curves; triangles are split until their
# projected edges are at most this long (pixels), so the straight-edge raster stays within a
# fraction of a pixel of the curved one.
MAX_PROJECTED_EDGE_PX = 8.0
_MAX_SUBDIVISIONS = 5
# Vertices outside a fisheye's field of view are moved to just inside its cone (radians), so
# that the lens model still counts them as imaged.
_CONE_MARGIN_RAD = 1e-9


@dataclass(frozen=True, eq=False)
class AmodalProjection:
    """An object's whole projection into one image, stored as the crop of its box.

    Attributes:
        crop: (h, w) bool, True where the projection covers a pixel centre; (0, 0) when it
            covers none.
        origin_px: ``(x, y)`` image position of ``crop[0, 0]``.
        image_size_px: ``(width, height)`` of the image.
        truncated: the unclipped projection leaves the image (or the lens cannot image part
            of the object).
    """

    crop: np.ndarray
    origin_px: tuple[int, int]
    image_size_px: tuple[int, int]
    truncated: bool = False

    @classmethod
    def from_mask(cls, mask: np.ndarray, truncated: bool = False) -> AmodalProjection:
        """Wrap a (H, W) bool image-sized mask."""
        mask = np.asarray(mask, dtype=bool)
        height, width = mask.shape
        return cls(mask, (0, 0), (width, height), truncated)

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool image-sized mask (built on demand)."""
        width, height = self.image_size_px
        full = np.zeros((height, width), dtype=bool)
        x, y = self.origin_px
        h, w = self.crop.shape
        full[y:y + h, x:x + w] = self.crop
        return full

    @functools.cached_property
    def pixel_count(self) -> int:
        """Pixels of the projection inside the image."""
        return int(np.count_nonzero(self.crop))

    @functools.cached_property
    def box(self) -> PixelBox | None:
        """Tight box of the projection's pixels (image coordinates); None when it has none."""
        from usdscene.labels import PixelBox

        rows = np.flatnonzero(self.crop.any(axis=1))
        if rows.size == 0:
            return None
        cols = np.flatnonzero(self.crop.any(axis=0))
        x, y = self.origin_px
        return PixelBox(int(cols[0]) + x, int(rows[0]) + y, int(cols[-1]) + x, int(rows[-1]) + y)


def rasterize_triangles(uv_px: np.ndarray, width_px: int, height_px: int,
                        valid: np.ndarray | None = None) -> AmodalProjection:
    """Fill projected triangles by pixel-centre sampling (see the module docstring).

    Args:
        uv_px: (T, 3, 2) float vertex pixel coordinates (pixel centres at integers).
        width_px, height_px: image size.
        valid: (T, 3) bool, False for vertices the lens cannot image; triangles with an
            invalid vertex are skipped and make the projection count as truncated.

    Returns:
        AmodalProjection; truncated = some vertex lies outside the image area
        ``[-0.5, W - 0.5] × [-0.5, H - 0.5]`` or was invalid.
    """
    uv = np.ascontiguousarray(uv_px, dtype=np.float64).reshape(-1, 3, 2)
    imaged = (np.ones(len(uv), dtype=np.bool_) if valid is None
              else np.ascontiguousarray(valid, dtype=np.bool_).reshape(-1, 3))
    if valid is not None:
        imaged = imaged[:, 0] & imaged[:, 1] & imaged[:, 2]
    kernels = _kernels()
    x0, y0, x1, y1, truncated = kernels.crop_bounds(uv, imaged, width_px, height_px)
    if x1 < x0 or y1 < y0:
        return AmodalProjection(np.zeros((0, 0), dtype=bool), (0, 0), (width_px, height_px), bool(truncated))
    crop = np.zeros((y1 - y0 + 1, x1 - x0 + 1), dtype=np.bool_)
    kernels.fill(uv, imaged, x0, y0, crop)
    return AmodalProjection(crop, (int(x0), int(y0)), (width_px, height_px), bool(truncated))


@functools.cache
def _kernels():
    """The compiled triangle loops (compiled on first use, cached on disk by numba)."""
    import types

    import numba

    @numba.njit(cache=True, nogil=True)
    def crop_bounds(uv, imaged, width, height):
        """Pixel-centre box (x0, y0, x1, y1) covered by the imaged, finite triangles' boxes
        inside the image (empty: x1 < x0), and whether the projection is truncated."""
        x0, y0, x1, y1 = width, height, -1, -1
        truncated = False
        for t in range(uv.shape[0]):
            if not imaged[t]:
                truncated = True
                continue
            lo_x = min(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0])
            hi_x = max(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0])
            lo_y = min(uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1])
            hi_y = max(uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1])
            if not (math.isfinite(lo_x) and math.isfinite(hi_x) and math.isfinite(lo_y)
                    and math.isfinite(hi_y)):
                truncated = True
                continue
            if lo_x < -0.5 or lo_y < -0.5 or hi_x > width - 0.5 or hi_y > height - 0.5:
                truncated = True
            x0 = min(x0, max(0, int(math.ceil(lo_x))))
            y0 = min(y0, max(0, int(math.ceil(lo_y))))
            x1 = max(x1, min(width - 1, int(math.floor(hi_x))))
            y1 = max(y1, min(height - 1, int(math.floor(hi_y))))
        return x0, y0, x1, y1, truncated

    @numba.njit(cache=True, nogil=True)
    def fill(uv, imaged, x_origin, y_origin, crop):
        """Set the crop's pixels whose centre lies inside or on an imaged triangle."""
        height, width = crop.shape
        for t in range(uv.shape[0]):
            if not imaged[t]:
                continue
            ax, ay = uv[t, 0, 0], uv[t, 0, 1]
            bx, by = uv[t, 1, 0], uv[t, 1, 1]
            cx, cy = uv[t, 2, 0], uv[t, 2, 1]
            area2 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
            if not math.isfinite(area2) or area2 == 0.0:
                continue
            sign = 1.0 if area2 > 0.0 else -1.0
            px0 = max(int(math.ceil(min(ax, bx, cx))), x_origin)
            px1 = min(int(math.floor(max(ax, bx, cx))), x_origin + width - 1)
            py0 = max(int(math.ceil(min(ay, by, cy))), y_origin)
            py1 = min(int(math.floor(max(ay, by, cy))), y_origin + height - 1)
            for py in range(py0, py1 + 1):
                for px in range(px0, px1 + 1):
                    # Edge functions at the pixel centre, oriented so the interior is >= 0.
                    if ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) * sign < 0.0:
                        continue
                    if ((cx - bx) * (py - by) - (cy - by) * (px - bx)) * sign < 0.0:
                        continue
                    if ((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) * sign < 0.0:
                        continue
                    crop[py - y_origin, px - x_origin] = True

    @numba.njit(cache=True, nogil=True)
    def needs_split(uv, imaged, max_edge):
        """(T,) bool: imaged triangles of (T, 3, 2) uv with a projected edge longer than max_edge."""
        out = np.zeros(uv.shape[0], dtype=np.bool_)
        limit = max_edge * max_edge
        for t in range(uv.shape[0]):
            if not (imaged[t, 0] and imaged[t, 1] and imaged[t, 2]):
                continue
            for k in range(3):
                dx = uv[t, k, 0] - uv[t, (k + 1) % 3, 0]
                dy = uv[t, k, 1] - uv[t, (k + 1) % 3, 1]
                if dx * dx + dy * dy > limit:
                    out[t] = True
                    break
        return out

    return types.SimpleNamespace(crop_bounds=crop_bounds, fill=fill, needs_split=needs_split)


def amodal_projection(camera: Camera, triangles_world_m: np.ndarray, frame: int | None = None, *,
                      max_edge_px: float = MAX_PROJECTED_EDGE_PX) -> AmodalProjection:
    """Rasterise one object's world-space triangles through a camera model (see
    :func:`amodal_projections`).

    Args:
        camera: the camera (intrinsics + pose at ``frame``).
        triangles_world_m: (T, 3, 3) float world coordinates in metres.
        frame: frame number for per-frame camera poses; None = the static pose.
        max_edge_px: subdivision threshold for distorting lenses, pixels.

    Returns:
        AmodalProjection of the image size (empty when the object is out of view).
    """
    return amodal_projections(camera, {"": triangles_world_m}, frame, max_edge_px=max_edge_px)[""]


def amodal_projections(camera: Camera, triangles_world_m: Mapping[str, np.ndarray],
                       frame: int | None = None, *,
                       max_edge_px: float = MAX_PROJECTED_EDGE_PX) -> dict[str, AmodalProjection]:
    """Rasterise every object's world-space triangles through one camera, all objects in one
    vectorised pass (see the module docstring for what is exact on each lens model).

    Args:
        camera: the camera (intrinsics + pose at ``frame``).
        triangles_world_m: object uid → (T, 3, 3) float world coordinates in metres.
        frame: frame number for per-frame camera poses; None = the static pose.
        max_edge_px: subdivision threshold for distorting lenses, pixels.

    Returns:
        uid → AmodalProjection of the image size, for every uid given (empty when the object
        is out of view).
    """
    from usdscene.model import LensModel

    intr = camera.intrinsics
    size = (intr.width_px, intr.height_px)
    uids = list(triangles_world_m)
    empty = AmodalProjection(np.zeros((0, 0), dtype=bool), (0, 0), size, False)
    result = dict.fromkeys(uids, empty)
    # Each vertex is projected once (a closed mesh has about half as many vertices as
    # triangles, against three corners per triangle).
    meshes = [_indexed_mesh(triangles_world_m[uid]) for uid in uids]
    pose = camera.pose_at(frame) if frame is not None else camera.pose
    m = pose.as_array()
    # Cull whole objects by their bounding spheres before touching their triangles.
    visible = np.flatnonzero(_objects_in_view(intr, m, meshes))
    if not visible.size:
        return result
    indexed = [meshes[i] for i in visible]
    offsets = np.cumsum([0] + [len(mesh.points) for mesh in indexed])
    points = np.concatenate([mesh.points for mesh in indexed])
    faces = np.concatenate([mesh.faces + offset for mesh, offset in zip(indexed, offsets)])
    owner = np.repeat(visible, [len(mesh.faces) for mesh in indexed])
    # world → camera (OpenCV axes): R^T (p - t), written for row vectors.
    cam_points = (points - m[:3, 3]) @ m[:3, :3]
    cut = np.zeros(len(uids), dtype=bool)
    if intr.lens in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE):
        cam_points, faces, owner, clipped = _clip_near(cam_points, faces, owner, max(camera.clip_near_m, 1e-6))
        cut[clipped] = True
    cone = _fisheye_cone_rad(intr)
    curved = intr.lens not in (LensModel.PERSPECTIVE, LensModel.ORTHOGRAPHIC) or any(intr.distortion)

    def project(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(T, 3, 3) camera-frame triangles → uv (T, 3, 2), imaged (T, 3), inside the view (T, 3)."""
        uv, ok, inside = _project_points(intr, t.reshape(-1, 3), cone)
        return uv.reshape(-1, 3, 2), ok.reshape(-1, 3), inside.reshape(-1, 3)

    uv_p, ok_p, inside_p = _project_points(intr, cam_points, cone)
    uv, ok, inside = uv_p[faces], ok_p[faces], inside_p[faces]
    if curved:
        cam = None  # camera-frame triangles once subdividing (the first pass is indexed)
        done = []
        for _ in range(_MAX_SUBDIVISIONS):
            split = _kernels().needs_split(np.ascontiguousarray(uv), np.ascontiguousarray(ok), float(max_edge_px))
            if not split.any():
                done.append((uv, ok, inside, owner))
                break
            done.append((uv[~split], ok[~split], inside[~split], owner[~split]))
            cam = _subdivide(cam_points[faces[split]] if cam is None else cam[split])
            owner = np.tile(owner[split], 4)
            uv, ok, inside = project(cam)
        else:
            done.append((uv, ok, inside, owner))
        uv, ok, inside, owner = (np.concatenate(parts) for parts in zip(*done))
    if cone is not None:
        # Pieces entirely beyond the image circle are not imaged: drop them.
        outside = ~(inside[:, 0] & inside[:, 1] & inside[:, 2])
        cut[np.unique(owner[outside])] = True
        beyond = ~(inside[:, 0] | inside[:, 1] | inside[:, 2])
        uv, ok, owner = uv[~beyond], ok[~beyond], owner[~beyond]
    if len(owner) > 1 and (owner[1:] < owner[:-1]).any():  # subdivision appended pieces
        order = np.argsort(owner, kind="stable")
        uv, ok, owner = np.ascontiguousarray(uv[order]), ok[order], owner[order]
    bounds = np.searchsorted(owner, np.arange(len(uids) + 1))
    for index in visible:
        lo, hi = bounds[index], bounds[index + 1]
        if lo == hi:
            result[uids[index]] = replace(empty, truncated=bool(cut[index]))
            continue
        projection = rasterize_triangles(uv[lo:hi], intr.width_px, intr.height_px, ok[lo:hi])
        result[uids[index]] = replace(projection, truncated=projection.truncated or bool(cut[index]))
    return result


def _project_points(intrinsics: Intrinsics, points_cam: np.ndarray,
                    cone: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 3) camera-frame points → uv (N, 2), imaged (N,) bool, inside the field of view (N,)
    bool; points beyond a fisheye's cone are moved onto it first (:func:`_onto_cone`)."""
    from usdscene.projection import project_camera_points

    inside = np.ones(len(points_cam), dtype=bool)
    if cone is not None:
        points_cam, inside = _onto_cone(points_cam, cone)
    uv, ok = project_camera_points(intrinsics, points_cam)
    return np.asarray(uv, dtype=np.float64), np.asarray(ok, dtype=bool), inside


# (id of a triangle array) → (weak reference to it, its vertices (P, 3), faces (T, 3)); the
# triangle arrays of a stage are shared between the cameras of a frame and between frames.
@dataclass(frozen=True, eq=False)
class _IndexedMesh:
    """An object's triangles as unique vertices and faces, with its bounding sphere.

    Attributes:
        points: (P, 3) float64 unique vertices, world metres.
        faces: (T, 3) int64 vertex indices.
        centre: (3,) centre of the bounding box, world metres.
        radius: radius of the sphere around that box, metres.
    """

    points: np.ndarray
    faces: np.ndarray
    centre: np.ndarray
    radius: float


# id of a triangle array → (weak reference to it, its indexed mesh); the triangle arrays of a
# stage are shared between the cameras of a frame and between frames, so each is indexed once.
_INDEXED: dict[int, tuple[weakref.ref, _IndexedMesh]] = {}


def _indexed_mesh(triangles: np.ndarray) -> _IndexedMesh:
    """(T, 3, 3) triangles (the caller's array object) → its :class:`_IndexedMesh`, remembered
    for as long as that array object lives."""
    key = id(triangles)
    known = _INDEXED.get(key)
    if known is not None and known[0]() is triangles:
        return known[1]
    corners = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
    if len(corners):
        points, inverse = np.unique(corners, axis=0, return_inverse=True)
        lo, hi = points.min(axis=0), points.max(axis=0)
    else:
        points, inverse, lo, hi = corners, np.zeros(0, dtype=np.int64), np.zeros(3), np.zeros(3)
    mesh = _IndexedMesh(points, inverse.reshape(-1, 3).astype(np.int64), (lo + hi) / 2.0,
                        float(np.linalg.norm(hi - lo)) / 2.0)
    try:
        ref = weakref.ref(triangles, lambda _, key=key: _INDEXED.pop(key, None))
    except TypeError:  # not weak-referenceable: not remembered
        return mesh
    _INDEXED[key] = (ref, mesh)
    return mesh


def _clip_near(points_cam: np.ndarray, faces: np.ndarray, owner: np.ndarray,
               near_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Clip an indexed camera-frame mesh (OpenCV axes) to z >= near: triangles wholly in front
    are kept, those crossing the plane are cut (their pieces get new vertices), the rest go.

    Returns:
        ``(points (P', 3), faces (T', 3), owner (T',), owners that were cut)``.
    """
    in_front = points_cam[:, 2] >= near_m
    corner_in = in_front[faces]
    all_in = corner_in[:, 0] & corner_in[:, 1] & corner_in[:, 2]
    if all_in.all():
        return points_cam, faces, owner, np.zeros(0, dtype=np.int64)
    crossing = np.flatnonzero((corner_in[:, 0] | corner_in[:, 1] | corner_in[:, 2]) & ~all_in)
    pieces, piece_owner = [np.zeros((0, 3, 3))], [np.zeros(0, dtype=owner.dtype)]
    for index in crossing:
        poly = _clip_polygon(points_cam[faces[index]], 2, near_m, True)
        for k in range(1, len(poly) - 1):  # fan triangulation of the convex clipped polygon
            pieces.append(np.stack([poly[0], poly[k], poly[k + 1]])[None])
            piece_owner.append(owner[index:index + 1])
    new = np.concatenate(pieces)
    new_faces = len(points_cam) + np.arange(3 * len(new)).reshape(-1, 3)
    return (np.concatenate([points_cam, new.reshape(-1, 3)]),
            np.concatenate([faces[all_in], new_faces]), np.concatenate([owner[all_in], *piece_owner]),
            np.unique(owner[~all_in]))


def _fisheye_cone_rad(intrinsics: Intrinsics) -> float | None:
    """Half field of view of a fisheye lens with a declared ``fov_deg`` (radians), else None."""
    from usdscene.model import FISHEYE_LENSES

    if intrinsics.lens not in FISHEYE_LENSES or intrinsics.fov_deg is None:
        return None
    return math.radians(intrinsics.fov_deg) / 2.0


def _onto_cone(points_cam: np.ndarray, half_angle_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Move (N, 3) camera-frame points further than ``half_angle_rad`` from the optical axis
    onto the cone (same azimuth, unit distance; a lens only images directions).

    Returns:
        ``(points (N, 3), inside (N,) bool)``; inside = the point was within the cone.
    """
    x, y, z = points_cam[:, 0], points_cam[:, 1], points_cam[:, 2]
    rho = np.hypot(x, y)
    inside = np.arctan2(rho, z) <= half_angle_rad
    if inside.all():
        return points_cam, inside
    edge = half_angle_rad - _CONE_MARGIN_RAD
    safe = np.where(rho > 0, rho, 1.0)
    moved = np.stack([np.where(rho > 0, x / safe, 1.0) * math.sin(edge),
                      np.where(rho > 0, y / safe, 0.0) * math.sin(edge),
                      np.full_like(z, math.cos(edge))], axis=1)
    return np.where(inside[:, None], points_cam, moved), inside


@functools.lru_cache(maxsize=256)
def _view_half_angle_rad(intrinsics: Intrinsics) -> float:
    """Largest angle from the optical axis (radians) of any ray the image can show; π when
    unknown (orthographic, or a distortion that cannot be inverted at the border)."""
    from usdscene.model import LensModel
    from usdscene.projection import _border_pixels, pixel_rays

    if intrinsics.lens is LensModel.ORTHOGRAPHIC:
        return math.pi
    cone = _fisheye_cone_rad(intrinsics)
    if intrinsics.lens in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE):
        rays, valid = pixel_rays(intrinsics, _border_pixels(intrinsics.width_px, intrinsics.height_px))
        if not valid.all():
            return math.pi
        # 1° of margin for the straight border between sampled border points.
        return min(math.pi / 2, float(np.arccos(np.clip(rays[:, 2], -1, 1)).max()) + math.radians(1.0))
    return cone if cone is not None else math.pi


def _objects_in_view(intrinsics: Intrinsics, camera_to_world: np.ndarray,
                     meshes: list[_IndexedMesh]) -> np.ndarray:
    """(N,) bool per object: False when the object has no triangle or its bounding sphere lies
    wholly outside the camera's field of view (conservative: True when unsure).
    ``camera_to_world`` is the (4, 4) camera pose."""
    has_faces = np.array([len(mesh.faces) > 0 for mesh in meshes], dtype=bool)
    half_angle = _view_half_angle_rad(intrinsics)
    if half_angle >= math.pi or not meshes:
        return has_faces
    centres = np.array([mesh.centre for mesh in meshes]).reshape(-1, 3)
    radii = np.array([mesh.radius for mesh in meshes])
    centres = (centres - camera_to_world[:3, 3]) @ camera_to_world[:3, :3]
    distance = np.linalg.norm(centres, axis=1)
    off_axis = np.arctan2(np.hypot(centres[:, 0], centres[:, 1]), centres[:, 2])
    spread = np.arcsin(np.clip(radii / np.maximum(distance, 1e-300), 0.0, 1.0))
    return has_faces & ((distance <= radii) | (off_axis - spread <= half_angle))


def _subdivide(tris: np.ndarray) -> np.ndarray:
    """Split (T, 3, 3) triangles at their edge midpoints → (4T, 3, 3)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    return np.concatenate([np.stack(t, axis=1) for t in
                           ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])


def _clip_polygon(poly: np.ndarray, axis: int, bound: float, keep_greater: bool) -> np.ndarray:
    """Sutherland-Hodgman: clip a (N, D) polygon by the half-space coord[axis] >=/<= bound."""
    out = []
    n = len(poly)
    for k in range(n):
        a, b = poly[k], poly[(k + 1) % n]
        a_in = a[axis] >= bound if keep_greater else a[axis] <= bound
        b_in = b[axis] >= bound if keep_greater else b[axis] <= bound
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (bound - a[axis]) / (b[axis] - a[axis])
            out.append(a + t * (b - a))
    return np.asarray(out).reshape(-1, poly.shape[1])
