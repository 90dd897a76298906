"""Amodal projections: an object's whole projection into a camera image, as if nothing
occluded it, from its world-space triangles. Pure (numpy + numba; no pxr, no bpy).

Rasterisation samples pixel centres (a pixel belongs to the projection when its centre lies
inside or on the edge of a projected triangle), the rule of a renderer's one-sample-per-pixel
id pass. It runs as one compiled loop over the triangles (numba) into a crop of the image the
size of the projection's box, so its cost is the covered pixels, not the image.

Exactness, per lens:

* perspective and orthographic: triangles are clipped at the near plane and projected; straight
  edges stay straight, so the raster is the exact full-mesh projection;
* pinhole models the renderer draws through a perspective render and a remap (OpenCV pinhole
  with distortion, non-square pixels): filled through that render's lens (straight edges,
  exact) and sampled as the instance mask is, each output pixel taking the render pixel the
  mask's nearest-neighbour remap takes (:func:`_through_render`), so a visible pixel is
  always an amodal one;
* distorting lenses (fisheye models): projected edges are curves; triangles are split until their projected edges are at most
  :data:`MAX_PROJECTED_EDGE_PX` long, which keeps the raster within a fraction of a pixel of
  the curved one;
* fisheye lenses with a field of view (``fov_deg``): the image is empty beyond the image circle.
  The lens model still maps directions beyond the circle's cone, so triangles are projected
  whole and the fill stops at the circle (exact there); only vertices the model cannot map at
  all (behind an OpenCV fisheye) are moved along their azimuth onto the cone, and the
  triangles they belong to are split until their projected edges are at most
  :data:`MAX_CUT_EDGE_PX` long. On the cabin's 39 fisheyes every box lies within 1 px of that
  of a 16 times finer split (``benchmarks/amodal_precision.py``).

Objects whose bounding sphere lies outside a camera's field of view are culled before any
triangle is projected; closed meshes are filled from the faces of one facing only (exact, see
:func:`amodal_projections`). All objects of a camera are projected together and filled in one
compiled pass (:mod:`usdscene.labels.amodal_kernels`), each into a crop trimmed to its pixels.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

import numpy as np

from usdscene.labels.pixel_box import PixelBox

if TYPE_CHECKING:
    from usdscene.document.model import Camera, Intrinsics

# Revision of the rasterisation rules; kept labels computed under another revision are
# computed anew (:class:`usdscene.dataset.annotation.ImageLabeller`). Raise it whenever a change can
# move a projection's pixels.
RASTER_REVISION = 6

# Projected triangle edges of distorting lenses are curves; triangles are split until their
# projected edges are at most this long (pixels), so the straight-edge raster stays within a
# fraction of a pixel of the curved one.
MAX_PROJECTED_EDGE_PX = 8.0
# Vertices a fisheye model cannot map (behind an OpenCV fisheye) are moved onto the cone of
# its field of view, which smears their triangles along the image circle; triangles with such
# a vertex are split further, until their projected edges are at most this long (pixels).
MAX_CUT_EDGE_PX = 1.0
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
        rows = np.flatnonzero(self.crop.any(axis=1))
        if rows.size == 0:
            return None
        cols = np.flatnonzero(self.crop.any(axis=0))
        x, y = self.origin_px
        return PixelBox(int(cols[0]) + x, int(rows[0]) + y, int(cols[-1]) + x, int(rows[-1]) + y)


# The crop of a projection that covers no pixel centre (read-only: shared).
_EMPTY_CROP = np.zeros((0, 0), dtype=bool)
_EMPTY_CROP.flags.writeable = False


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
    uv = np.ascontiguousarray(uv_px, dtype=np.float64).reshape(-1, 2)
    imaged = (np.ones(len(uv), dtype=np.bool_) if valid is None
              else np.ascontiguousarray(valid, dtype=np.bool_).reshape(-1))
    faces = np.arange(len(uv), dtype=np.int64).reshape(-1, 3)
    owner = np.zeros(len(faces), dtype=np.int64)
    return _rasterize_objects(uv, imaged, np.ones(len(uv), dtype=np.bool_), np.zeros(len(uv), dtype=np.bool_),
                              faces, owner, 1, width_px, height_px, np.zeros(1, dtype=bool), _NO_CIRCLE)[0]


def _rasterize_objects(uv: np.ndarray, imaged: np.ndarray, inside: np.ndarray, clamped: np.ndarray,
                       faces: np.ndarray, owner: np.ndarray, n_objects: int, width_px: int, height_px: int,
                       cut: np.ndarray, circle: np.ndarray) -> list[AmodalProjection]:
    """Rasterise the faces of ``n_objects`` objects in one compiled pass (arguments as in
    :func:`usdscene.labels.amodal_kernels.rasterize_objects`; ``cut`` (N,) bool: objects already
    known to be truncated, e.g. by the near plane).

    Returns:
        One AmodalProjection per object index, its crop trimmed to the covered pixels; it is
        truncated when ``cut`` says so, when a vertex leaves the image or the lens, or when a
        face leaves a fisheye's cone.
    """
    from usdscene.labels.amodal_kernels import rasterize_objects

    crops, offsets, origin, tight, counts, truncated, cone_cut = rasterize_objects(
        uv, imaged, inside, clamped, faces, owner, n_objects, width_px, height_px, circle)
    size = (width_px, height_px)
    is_truncated = (truncated | cone_cut | cut).tolist()
    projections = []
    # Python ints from lists: per-element numpy scalars would cost more than the rest here.
    for o, (x0, y0, w, h), (x_min, y_min, x_max, y_max), count, start in zip(
            range(n_objects), origin.tolist(), tight.tolist(), counts.tolist(), offsets.tolist()):
        if not count:
            projection = AmodalProjection(_EMPTY_CROP, (0, 0), size, is_truncated[o])
            projection.__dict__.update(pixel_count=0, box=None)
        else:
            crop = crops[start:start + w * h].reshape(h, w)[y_min - y0:y_max - y0 + 1, x_min - x0:x_max - x0 + 1]
            projection = AmodalProjection(crop, (x_min, y_min), size, is_truncated[o])
            # Known from the fill: spare the cached properties their pass over the crop.
            projection.__dict__.update(pixel_count=count, box=PixelBox(x_min, y_min, x_max, y_max))
        projections.append(projection)
    return projections


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

    Closed meshes (after merging equal vertices, every edge run along as often in one
    direction as in the other: the faces' boundaries cancel, see :func:`_is_closed`) are
    filled from the faces of one facing only when the camera lies outside the object's
    bounding sphere (and beyond the near plane): the surface's winding number is 0 at the
    camera and far along every ray, so a ray that meets the surface crosses it as often
    through faces of one facing as through faces of the other (a surface that touches or
    passes through itself included), and either facing alone covers the pixels the whole
    mesh covers, with half the triangles. Open meshes use every face.

    Args:
        camera: the camera (intrinsics + pose at ``frame``).
        triangles_world_m: object uid → (T, 3, 3) float world coordinates in metres.
        frame: frame number for per-frame camera poses; None = the static pose.
        max_edge_px: subdivision threshold for distorting lenses, pixels.

    Returns:
        uid → AmodalProjection of the image size, for every uid given (empty when the object
        is out of view).
    """
    from usdscene.labels.amodal_kernels import faces_to_fill, to_camera, used_vertices
    from usdscene.labels.projection import native_renderable
    from usdscene.lens import lens_for

    intr = camera.intrinsics
    if lens_for(intr).pinhole and not native_renderable(intr):
        return _through_render(camera, triangles_world_m, frame)
    size = (intr.width_px, intr.height_px)
    uids = list(triangles_world_m)
    empty = AmodalProjection(np.zeros((0, 0), dtype=bool), (0, 0), size, False)
    result = dict.fromkeys(uids, empty)
    # Each vertex is projected once (a closed mesh has about half as many vertices as
    # triangles, against three corners per triangle).
    meshes = [_indexed_mesh(triangles_world_m[uid]) for uid in uids]
    pose = camera.pose_at(frame) if frame is not None else camera.pose
    m = pose.as_array()
    near_m = max(camera.clip_near_m, 1e-6)
    # Cull whole objects by their bounding spheres before touching their triangles.
    in_view, camera_clear = _objects_in_view(intr, m, meshes, near_m)
    visible = np.flatnonzero(in_view)
    if not visible.size:
        return result
    indexed = [meshes[i] for i in visible]
    offsets = np.cumsum([0] + [len(mesh.points) for mesh in indexed])
    points = np.concatenate([mesh.points for mesh in indexed])
    faces = np.concatenate([mesh.faces + offset for mesh, offset in zip(indexed, offsets)])
    # Objects by their position among the visible ones.
    owner = np.repeat(np.arange(len(visible)), [len(mesh.faces) for mesh in indexed])
    # world → camera (OpenCV axes): R^T (p - t).
    cam_points = to_camera(points, np.ascontiguousarray(m, dtype=np.float64))
    near_cut = np.zeros(len(visible), dtype=bool)
    lens = lens_for(intr)
    if lens.pinhole:
        cam_points, faces, owner, clipped = _clip_near(cam_points, faces, owner, near_m)
        near_cut[clipped] = True
    single_facing = (np.array([mesh.closed for mesh in indexed], dtype=bool) & camera_clear[visible]
                     & ~near_cut & (not lens.orthographic))
    if single_facing.any():
        faces, owner = faces_to_fill(cam_points, faces, owner, single_facing)
        # About half the vertices of a closed mesh belong to faces turned away only.
        cam_points, faces = used_vertices(cam_points, faces)
    uv, ok, inside, clamped = _project_points(intr, cam_points)
    if not lens.straight or any(intr.distortion):
        uv, ok, inside, clamped, faces, owner = _split_curved(intr, cam_points, uv, ok, inside, clamped, faces,
                                                              owner, float(max_edge_px))
    projections = _rasterize_objects(uv, ok, inside, clamped, faces, owner, len(visible), intr.width_px,
                                     intr.height_px, near_cut, _image_circle(intr))
    for index, projection in zip(visible, projections):
        result[uids[index]] = projection
    return result


def _through_render(camera: Camera, triangles_world_m: Mapping[str, np.ndarray],
                    frame: int | None) -> dict[str, AmodalProjection]:
    """Amodal projections of a pinhole camera the renderer draws through a straight perspective
    render and a nearest-neighbour remap (:func:`usdscene.labels.projection.undistorted_render_intrinsics`,
    the instance mask's own path): the objects are filled through the render's lens (straight
    edges, exact) and each output pixel takes the render pixel its mask takes.

    Sampled at the output's own pixel centres instead, a sub-pixel-thin limb or a far person
    could cover render pixels the mask shows but no output pixel centre (an empty amodal box
    for a person 1-5 px visible), as the mask samples the render's pixel centres, up to half a
    render pixel away from the rays of the output's.
    """
    from dataclasses import replace

    render = _render_intrinsics(camera.intrinsics)
    sources = amodal_projections(replace(camera, intrinsics=render), triangles_world_m, frame)
    samples = _render_samples(camera.intrinsics)
    size = (camera.intrinsics.width_px, camera.intrinsics.height_px)
    out = {}
    for uid, source in sources.items():
        out[uid] = _sampled(source, samples, size)
    return out


def _sampled(source: AmodalProjection, samples: _RenderSamples, size: tuple[int, int]) -> AmodalProjection:
    """The output image's projection from the render's ``source``: each output pixel of the
    window that can sample the source's crop takes the render pixel its mask takes."""
    if source.box is None:
        return AmodalProjection(_EMPTY_CROP, (0, 0), size, source.truncated)
    x0, y0 = source.origin_px
    h, w = source.crop.shape
    # The output window: every output pixel sampling a render column / row of the crop.
    u0, u1 = int(samples.col_lo[x0:x0 + w].min()), int(samples.col_hi[x0:x0 + w].max())
    v0, v1 = int(samples.row_lo[y0:y0 + h].min()), int(samples.row_hi[y0:y0 + h].max())
    if u1 < u0 or v1 < v0:  # nothing of the crop is sampled: it lies beyond the output image
        return AmodalProjection(_EMPTY_CROP, (0, 0), size, True)
    rows = samples.rows[v0:v1 + 1, u0:u1 + 1] - y0
    cols = samples.cols[v0:v1 + 1, u0:u1 + 1] - x0
    taken = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    window = np.zeros(rows.shape, dtype=bool)
    window[taken] = source.crop[rows[taken], cols[taken]]
    # Truncated: the render's own word, or covered render pixels no output pixel samples
    # (beyond the output image).
    seen = np.zeros_like(source.crop)
    seen[rows[window], cols[window]] = True
    truncated = source.truncated or bool((source.crop & ~seen).any())
    kept_rows, kept_cols = np.flatnonzero(window.any(axis=1)), np.flatnonzero(window.any(axis=0))
    if not kept_rows.size:
        return AmodalProjection(_EMPTY_CROP, (0, 0), size, truncated)
    crop = window[kept_rows[0]:kept_rows[-1] + 1, kept_cols[0]:kept_cols[-1] + 1]
    return AmodalProjection(crop, (u0 + int(kept_cols[0]), v0 + int(kept_rows[0])), size, truncated)


@dataclass(frozen=True, eq=False)
class _RenderSamples:
    """Which render pixel each output pixel's mask takes, and the inverse as ranges.

    Attributes:
        rows, cols: (H, W) int32 render row and column of each output pixel (-1: none).
        row_lo, row_hi: (render height,) first and last output row sampling each render row
            (lo > hi when none); ``col_lo``, ``col_hi`` (render width,) the same for columns.
    """

    rows: np.ndarray
    cols: np.ndarray
    row_lo: np.ndarray
    row_hi: np.ndarray
    col_lo: np.ndarray
    col_hi: np.ndarray


@functools.lru_cache(maxsize=64)
def _render_intrinsics(intrinsics: Intrinsics) -> Intrinsics:
    """The native lens the renderer draws ``intrinsics`` through (cached)."""
    from usdscene.labels.projection import undistorted_render_intrinsics

    return undistorted_render_intrinsics(intrinsics)


# About 10 bytes per output pixel each (a 1920x1080 camera: 20 MB).
@functools.lru_cache(maxsize=16)
def _render_samples(intrinsics: Intrinsics) -> _RenderSamples:
    """The render pixel each output pixel's mask takes: ``cv2.remap`` ``INTER_NEAREST``'s
    rounding of :func:`usdscene.labels.projection.remap_grids` (half to even, as ``cvRound``);
    -1 where it takes none (no ray, or outside the render)."""
    from usdscene.labels.projection import remap_grids

    render = _render_intrinsics(intrinsics)
    map_x, map_y = remap_grids(intrinsics, render)
    cols = np.rint(map_x).astype(np.int32)
    rows = np.rint(map_y).astype(np.int32)
    outside = (cols < 0) | (cols >= render.width_px) | (rows < 0) | (rows >= render.height_px)
    cols[outside], rows[outside] = -1, -1
    v, u = np.mgrid[0:intrinsics.height_px, 0:intrinsics.width_px].astype(np.int32)
    ok = ~outside
    ranges = []
    for index, position, count in ((rows, v, render.height_px), (cols, u, render.width_px)):
        lo, hi = np.full(count, np.iinfo(np.int32).max, dtype=np.int32), np.full(count, -1, dtype=np.int32)
        np.minimum.at(lo, index[ok], position[ok])
        np.maximum.at(hi, index[ok], position[ok])
        ranges += [lo, hi]
    for array in (rows, cols, *ranges):
        array.flags.writeable = False
    return _RenderSamples(rows, cols, *ranges)


def _split_curved(intrinsics: Intrinsics, points_cam: np.ndarray, uv: np.ndarray, imaged: np.ndarray,
                  inside: np.ndarray, clamped: np.ndarray, faces: np.ndarray, owner: np.ndarray,
                  max_edge_px: float) -> tuple[np.ndarray, ...]:
    """Split the faces of a distorting lens whose projected edges are longer than
    ``max_edge_px`` (or :data:`MAX_CUT_EDGE_PX` for faces partly clamped onto a fisheye's
    cone) at their edge midpoints, up to :data:`_MAX_SUBDIVISIONS` times.

    Args:
        intrinsics: the lens.
        points_cam: (P, 3) camera-frame vertices; ``uv`` (P, 2), ``imaged``, ``inside`` and
            ``clamped`` (P,) their projection (:func:`_project_points`); ``faces`` (T, 3) and
            ``owner`` (T,) the faces to draw.

    Returns:
        ``(uv, imaged, inside, clamped, faces, owner)`` with the split faces replaced by their
        pieces (the pieces' vertices appended after the given ones).
    """
    from usdscene.labels.amodal_kernels import edge_midpoints, needs_split, partition_faces, split_faces

    split = needs_split(uv, imaged, clamped, faces, max_edge_px, MAX_CUT_EDGE_PX)
    if not split.any():
        return uv, imaged, inside, clamped, faces, owner
    # Pieces are vertex index triples into a pool that grows by each level's edge midpoints:
    # a corner or a midpoint is projected once, not again in every piece that shares it. The
    # pool's arrays grow by doubling, not by a copy per level.
    count = len(points_cam)
    pool = [points_cam, uv, imaged, inside, clamped]
    kept, kept_owner, pieces, piece_owner = partition_faces(faces, owner, split)
    face_parts, owner_parts = [kept], [kept_owner]
    for level in range(_MAX_SUBDIVISIONS):
        midpoints, edge = edge_midpoints(pool[0][:count], pieces)
        pieces, piece_owner = split_faces(pieces, piece_owner, edge, count)
        end = count + len(midpoints)
        if end > len(pool[0]):
            grown = []
            for array in pool:
                bigger = np.empty((max(2 * end, 1024),) + array.shape[1:], dtype=array.dtype)
                bigger[:count] = array[:count]
                grown.append(bigger)
            pool = grown
        for array, new in zip(pool, (midpoints, *_project_points(intrinsics, midpoints))):
            array[count:end] = new
        count = end
        if level == _MAX_SUBDIVISIONS - 1:  # the last level keeps every piece, long or not
            face_parts.append(pieces)
            owner_parts.append(piece_owner)
            break
        again = needs_split(pool[1][:count], pool[2][:count], pool[4][:count], pieces, max_edge_px,
                            MAX_CUT_EDGE_PX)
        kept, kept_owner, pieces, piece_owner = partition_faces(pieces, piece_owner, again)
        face_parts.append(kept)
        owner_parts.append(kept_owner)
        if not len(pieces):
            break
    _, uv, imaged, inside, clamped = (array[:count] for array in pool)
    return uv, imaged, inside, clamped, np.concatenate(face_parts), np.concatenate(owner_parts)


def _project_points(intrinsics: Intrinsics, points_cam: np.ndarray) -> tuple[np.ndarray, ...]:
    """Project (N, 3) camera-frame points for rasterising.

    A fisheye with a field of view images nothing beyond its image circle, but its lens model
    still maps the directions beyond the circle's cone (the rasteriser cuts the image at the
    circle): points there are projected by the model without its field-of-view limit, and
    only those the model cannot map at all (behind an OpenCV fisheye, where its radius stops
    growing) are moved onto the cone (:func:`_onto_cone`).

    Returns:
        ``(uv (N, 2) float64, imaged (N,), inside (N,), clamped (N,))``, bool arrays: the lens
        images the point; it lies within the field-of-view cone; it was moved onto the cone.
    """
    from usdscene.labels.projection import project_camera_points, project_camera_points_with_angle

    cone = _fisheye_cone_rad(intrinsics)
    if cone is None:
        none = np.zeros(len(points_cam), dtype=bool)
        uv, ok = project_camera_points(intrinsics, points_cam)
        return np.asarray(uv, dtype=np.float64), np.asarray(ok, dtype=bool), ~none, none
    # The model without the limit puts every point where the limited one does, and the angles
    # it computes on the way tell which points lie inside the cone.
    uv, ok, theta = project_camera_points_with_angle(_without_fov(intrinsics), points_cam)
    inside = theta <= cone
    if inside.all() and not ok.all():  # the limited lens's own word (an OpenCV fisheye beyond 180°)
        uv, ok = project_camera_points(intrinsics, points_cam)
    clamped = ~ok & ~inside
    if clamped.any():
        uv[clamped], ok[clamped] = project_camera_points(intrinsics, _onto_cone(points_cam[clamped], cone))
    return uv, ok, inside, clamped


@functools.lru_cache(maxsize=256)
def _without_fov(intrinsics: Intrinsics) -> Intrinsics:
    """The same lens without its field-of-view limit."""
    from dataclasses import replace

    return replace(intrinsics, fov_deg=None)


# The circle argument of the rasteriser for images without an image circle.
_NO_CIRCLE = np.zeros(5)


@functools.lru_cache(maxsize=256)
def _image_circle(intrinsics: Intrinsics) -> np.ndarray:
    """``(cx, cy, fx, fy, r)`` of a fisheye's image circle, r in units of the focal lengths
    (the image radius of a ray on the field-of-view cone); :data:`_NO_CIRCLE` for other
    lenses. The fisheye models are radial, so the circle is that ellipse in pixels."""
    from usdscene.labels.projection import project_camera_points

    cone = _fisheye_cone_rad(intrinsics)
    if cone is None:
        return _NO_CIRCLE
    uv, ok = project_camera_points(_without_fov(intrinsics), np.array([[math.sin(cone), 0.0, math.cos(cone)]]))
    radius = (float(uv[0, 0]) - intrinsics.cx_px) / intrinsics.fx_px
    if not ok[0] or not radius > 0.0:
        return _NO_CIRCLE
    return np.array([intrinsics.cx_px, intrinsics.cy_px, intrinsics.fx_px, intrinsics.fy_px, radius])


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
        closed: every edge of a non-degenerate face is shared by exactly two faces that
            run along it in opposite directions (a closed, consistently wound surface).
    """

    points: np.ndarray
    faces: np.ndarray
    centre: np.ndarray
    radius: float
    closed: bool


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
    faces = inverse.reshape(-1, 3).astype(np.int64)
    mesh = _IndexedMesh(points, faces, (lo + hi) / 2.0, float(np.linalg.norm(hi - lo)) / 2.0,
                        _is_closed(faces, len(points)))
    try:
        ref = weakref.ref(triangles, lambda _, key=key: _INDEXED.pop(key, None))
    except TypeError:  # not weak-referenceable: not remembered
        return mesh
    _INDEXED[key] = (ref, mesh)
    return mesh


def _is_closed(faces: np.ndarray, n_points: int) -> bool:
    """Whether (T, 3) faces over ``n_points`` vertices form closed, consistently wound
    surfaces: faces with a repeated vertex (no area) aside, every edge is run along as often
    in one direction as in the other, so the faces' boundaries cancel.

    That is what makes one facing cover the whole projection (see :func:`amodal_projections`);
    a surface may touch itself: the baked people's posed bodies have distinct vertices at
    equal positions, which merging equal vertices turns into faces without area and edges run
    along twice in the same direction (and twice in the other).
    """
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    if not len(faces):
        return False
    start, end = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    return bool(np.array_equal(np.sort(start * n_points + end), np.sort(end * n_points + start)))


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
    from usdscene.document.model import FISHEYE_LENSES

    if intrinsics.lens not in FISHEYE_LENSES or intrinsics.fov_deg is None:
        return None
    return math.radians(intrinsics.fov_deg) / 2.0


def _onto_cone(points_cam: np.ndarray, half_angle_rad: float) -> np.ndarray:
    """(N, 3) camera-frame points moved onto the cone of ``half_angle_rad`` around the optical
    axis (same azimuth, unit distance; a lens only images directions) → (N, 3)."""
    x, y = points_cam[:, 0], points_cam[:, 1]
    rho = np.hypot(x, y)
    edge = half_angle_rad - _CONE_MARGIN_RAD
    safe = np.where(rho > 0, rho, 1.0)
    return np.stack([np.where(rho > 0, x / safe, 1.0) * math.sin(edge),
                     np.where(rho > 0, y / safe, 0.0) * math.sin(edge),
                     np.full(len(points_cam), math.cos(edge))], axis=1)


@functools.lru_cache(maxsize=256)
def _view_half_angle_rad(intrinsics: Intrinsics) -> float:
    """Largest angle from the optical axis (radians) of any ray the image can show; π when
    unknown (orthographic, or a distortion that cannot be inverted at the border)."""
    from usdscene.labels.projection import _border_pixels, pixel_rays
    from usdscene.lens import lens_for

    lens = lens_for(intrinsics)
    if lens.orthographic:
        return math.pi
    cone = _fisheye_cone_rad(intrinsics)
    if lens.pinhole:
        rays, valid = pixel_rays(intrinsics, _border_pixels(intrinsics.width_px, intrinsics.height_px))
        if not valid.all():
            return math.pi
        # 1° of margin for the straight border between sampled border points.
        return min(math.pi / 2, float(np.arccos(np.clip(rays[:, 2], -1, 1)).max()) + math.radians(1.0))
    return cone if cone is not None else math.pi


def _objects_in_view(intrinsics: Intrinsics, camera_to_world: np.ndarray, meshes: list[_IndexedMesh],
                     near_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Where each object's bounding sphere lies with respect to the camera.

    Args:
        intrinsics: the lens.
        camera_to_world: (4, 4) camera pose.
        meshes: N objects.
        near_m: near clipping distance, metres.

    Returns:
        ``(in_view, clear)``, (N,) bool each: ``in_view`` False when the object has no
        triangle or its sphere lies wholly outside the field of view (conservative: True when
        unsure); ``clear`` True when the camera lies outside the sphere by more than
        ``near_m``.
    """
    has_faces = np.array([len(mesh.faces) > 0 for mesh in meshes], dtype=bool)
    if not meshes:
        return has_faces, has_faces
    centres = np.array([mesh.centre for mesh in meshes]).reshape(-1, 3)
    radii = np.array([mesh.radius for mesh in meshes])
    centres = (centres - camera_to_world[:3, 3]) @ camera_to_world[:3, :3]
    distance = np.linalg.norm(centres, axis=1)
    clear = distance > radii + near_m
    half_angle = _view_half_angle_rad(intrinsics)
    if half_angle >= math.pi:
        return has_faces, clear
    off_axis = np.arctan2(np.hypot(centres[:, 0], centres[:, 1]), centres[:, 2])
    spread = np.arcsin(np.clip(radii / np.maximum(distance, 1e-300), 0.0, 1.0))
    return has_faces & ((distance <= radii) | (off_axis - spread <= half_angle)), clear


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
