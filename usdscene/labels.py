"""Instance masks → per-object 2D labels: boxes, polygons, visibility. Pure (numpy + OpenCV).

Pixel convention (the one of :class:`usdscene.model.Intrinsics`, i.e. OpenCV's): pixel
centres sit at integer coordinates and pixel ``(x, y)`` covers ``[x - 0.5, x + 0.5] ×
[y - 0.5, y + 0.5]``; ``x`` is the column, ``y`` the row.

* A :class:`PixelBox` holds the *inclusive* pixel indices of the first and last covered
  column/row. Its OpenLABEL form (:meth:`PixelBox.center_size`) is ``[cx, cy, w, h]`` in the
  pixel-centre convention: it spans the covered pixels edge to edge, so ``w = x_max - x_min + 1``
  and ``cx = (x_min + x_max) / 2``. Exporters to formats whose pixel ``i`` covers
  ``[i, i + 1)`` (COCO, YOLO) add 0.5 (:meth:`PixelBox.xywh_corner`).
* Polygon vertices (:class:`Contour`) are pixel-centre coordinates of boundary pixels, as
  traced by ``cv2.findContours``; outer contours run around the object's outermost pixels,
  hole contours around the object's pixels that border a hole. With ``epsilon_px = 0`` they
  describe the mask exactly: :func:`rasterize_contours` gives back the same pixels.
* Simplification: ``cv2.approxPolyDP`` with ``epsilon_px`` (maximum distance in pixels of a
  dropped boundary pixel centre from the simplified polygon). The default
  :data:`DEFAULT_EPSILON_PX` = 0.75 px keeps every polygon within one pixel of the mask
  boundary; a re-rasterised polygon differs from the mask only in pixels that touch the boundary.

Visibility:

* *visible* = pixels of the object in the instance mask (occluders removed);
* *amodal* = pixels of the object's whole projection through the camera model, as if nothing
  occluded it, clipped to the image (:func:`rasterize_triangles` / :func:`amodal_projection`);
* ``visible_fraction = visible pixels / amodal pixels``, clipped to ``[0, 1]`` (the two
  rasterisations differ by a few boundary pixels, so the raw ratio can exceed 1 slightly);
* ``truncated`` = the unclipped projection leaves the image (or, without an amodal
  projection, the visible box touches the image border).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Collection, Iterable, Iterator, Mapping, Sequence

import cv2
import numpy as np

if TYPE_CHECKING:  # the projection module is pure too, but only needed for amodal labels
    from usdscene.model import Camera

log = logging.getLogger(__name__)

DEFAULT_EPSILON_PX = 0.75
# Projected triangle edges of distorting lenses are curves; triangles are split until their
# projected edges are at most this long (pixels), so the straight-edge raster stays within a
# fraction of a pixel of the curved one.
MAX_PROJECTED_EDGE_PX = 8.0
_MAX_SUBDIVISIONS = 5


# --------------------------------------------------------------------------------------------
# Data


@dataclass(frozen=True)
class PixelBox:
    """An axis-aligned box of whole pixels: inclusive column/row indices.

    Attributes:
        x_min, y_min: first covered column and row (pixels, may be negative for an unclipped
            projection).
        x_max, y_max: last covered column and row, inclusive (``>= x_min``, ``>= y_min``).
    """

    x_min: int
    y_min: int
    x_max: int
    y_max: int

    @property
    def width_px(self) -> int:
        return self.x_max - self.x_min + 1

    @property
    def height_px(self) -> int:
        return self.y_max - self.y_min + 1

    def center_size(self) -> tuple[float, float, float, float]:
        """OpenLABEL ``bbox`` value ``[cx, cy, w, h]`` (pixel centres at integers), pixels."""
        return ((self.x_min + self.x_max) / 2.0, (self.y_min + self.y_max) / 2.0,
                float(self.width_px), float(self.height_px))

    def xywh_corner(self) -> tuple[float, float, float, float]:
        """COCO ``[x, y, w, h]``: top-left corner where pixel ``i`` covers ``[i, i + 1)``."""
        return (float(self.x_min), float(self.y_min), float(self.width_px), float(self.height_px))

    @staticmethod
    def from_center_size(value: Sequence[float]) -> "PixelBox":
        """Inverse of :meth:`center_size` (values are rounded to whole pixels)."""
        cx, cy, w, h = (float(v) for v in value)
        x_min = int(round(cx - (w - 1.0) / 2.0))
        y_min = int(round(cy - (h - 1.0) / 2.0))
        return PixelBox(x_min, y_min, x_min + int(round(w)) - 1, y_min + int(round(h)) - 1)


@dataclass(frozen=True, eq=False)
class Contour:
    """One closed polygon of an object's visible region.

    Attributes:
        points_px: (N, 2) float64 vertices ``(x, y)`` in pixels (pixel centres at integers),
            N >= 1 (a single pixel gives one vertex, a one-pixel-wide line two).
        is_hole: True for the boundary of a hole inside an outer contour.
        parent: index (in the same :class:`ObjectLabel`'s ``contours``) of the outer contour
            enclosing this hole; -1 for outer contours.
    """

    points_px: np.ndarray
    is_hole: bool = False
    parent: int = -1

    def flat(self) -> list[float]:
        """``[x0, y0, x1, y1, ...]`` as plain floats (for JSON)."""
        return [float(v) for v in self.points_px.reshape(-1)]


@dataclass(frozen=True, eq=False)
class ObjectLabel:
    """Labels of one object in one image (one camera, one frame).

    Attributes:
        uid: OpenLABEL object uid.
        class_name: asset class (``""`` when unknown).
        mask_id: the object's id in the instance mask (uint16, > 0).
        box: tight box of the visible pixels; None when no pixel is visible.
        pixel_count: number of visible pixels.
        contours: outer contours and holes of the visible pixels (several outer contours when
            an occluder splits the object); empty when nothing is visible.
        amodal_box: box of the whole projection clipped to the image; None when unknown (no
            geometry given) or when the projection misses the image.
        amodal_pixel_count: pixels of the whole projection inside the image; None = unknown.
        truncated: the unclipped projection leaves the image.
        visible_fraction: ``pixel_count / amodal_pixel_count`` clipped to [0, 1]; None = unknown.
    """

    uid: str
    class_name: str
    mask_id: int
    box: PixelBox | None
    pixel_count: int
    contours: tuple[Contour, ...] = ()
    amodal_box: PixelBox | None = None
    amodal_pixel_count: int | None = None
    truncated: bool = False
    visible_fraction: float | None = None

    @property
    def visible(self) -> bool:
        return self.pixel_count > 0


@dataclass(frozen=True)
class ImageLabels:
    """All object labels of one image.

    Attributes:
        camera: camera (stream) name.
        frame: frame number.
        width_px, height_px: image size.
        objects: labels sorted by mask id.
    """

    camera: str
    frame: int
    width_px: int
    height_px: int
    objects: tuple[ObjectLabel, ...] = ()


@dataclass(frozen=True)
class Annotations:
    """Labels of a whole run.

    Attributes:
        images: one entry per (frame, camera) that was labelled, sorted by (frame, camera).
        epsilon_px: polygon simplification tolerance that was used (pixels).
        min_visible_fraction: labels below this visible fraction were dropped.
    """

    images: tuple[ImageLabels, ...] = ()
    epsilon_px: float = DEFAULT_EPSILON_PX
    min_visible_fraction: float = 0.0

    def frames(self) -> tuple[int, ...]:
        return tuple(sorted({image.frame for image in self.images}))

    def for_frame(self, frame: int) -> tuple[ImageLabels, ...]:
        return tuple(image for image in self.images if image.frame == frame)

    def __iter__(self) -> Iterator[ImageLabels]:
        return iter(self.images)


@dataclass(frozen=True, eq=False)
class AmodalProjection:
    """An object's whole projection into one image.

    Attributes:
        mask: (H, W) bool, True where the projection covers a pixel centre.
        truncated: the unclipped projection leaves the image.
    """

    mask: np.ndarray
    truncated: bool = False


# --------------------------------------------------------------------------------------------
# Mask → labels


def _boxes_of_ids(mask: np.ndarray, ids: np.ndarray) -> dict[int, PixelBox]:
    """Tight boxes of every id in ``ids`` present in ``mask`` in two passes over the image
    (per-column and per-row presence tables) instead of one full-image pass per object."""
    height, width = mask.shape
    top = int(mask.max()) + 1
    cols = np.zeros((top, width), dtype=bool)
    cols[mask, np.arange(width)[None, :]] = True
    rows = np.zeros((top, height), dtype=bool)
    rows[mask, np.arange(height)[:, None]] = True
    boxes = {}
    for i in ids.tolist():
        c, r = cols[i], rows[i]
        if not c.any():
            continue
        x0 = int(np.argmax(c))
        x1 = width - 1 - int(np.argmax(c[::-1]))
        y0 = int(np.argmax(r))
        y1 = height - 1 - int(np.argmax(r[::-1]))
        boxes[i] = PixelBox(x0, y0, x1, y1)
    return boxes


def box_of(mask: np.ndarray) -> PixelBox | None:
    """Tight box of the True pixels of a (H, W) bool mask; None when empty."""
    cols = np.flatnonzero(mask.any(axis=0))
    if cols.size == 0:
        return None
    rows = np.flatnonzero(mask.any(axis=1))
    return PixelBox(int(cols[0]), int(rows[0]), int(cols[-1]), int(rows[-1]))


def _box_and_count(mask: np.ndarray) -> tuple[PixelBox | None, int]:
    """Box and pixel count of a (H, W) bool mask in one full pass (rows) plus passes over
    the object's own rows only."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None, 0
    band = mask[rows[0]:rows[-1] + 1]
    cols = np.flatnonzero(band.any(axis=0))
    return (PixelBox(int(cols[0]), int(rows[0]), int(cols[-1]), int(rows[-1])),
            int(np.count_nonzero(band)))


def contours_of(region: np.ndarray, *, epsilon_px: float = DEFAULT_EPSILON_PX,
                offset_px: tuple[int, int] = (0, 0)) -> tuple[Contour, ...]:
    """Outer contours and holes of a binary region.

    Args:
        region: (H, W) bool or uint8 (non-zero = inside).
        epsilon_px: ``cv2.approxPolyDP`` tolerance in pixels; 0 keeps every corner of the
            pixel boundary (exact).
        offset_px: ``(dx, dy)`` added to every vertex (position of ``region`` in the image).

    Returns:
        Contours in ``cv2.findContours`` (RETR_CCOMP) order; holes point at their outer
        contour through ``parent``. 8-connected foreground, 4-connected holes.
    """
    padded = cv2.copyMakeBorder(region.astype(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    found, hierarchy = cv2.findContours(padded, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE,
                                        offset=(offset_px[0] - 1, offset_px[1] - 1))
    if hierarchy is None:
        return ()
    result = []
    for points, (_, _, _, parent) in zip(found, hierarchy[0]):
        if epsilon_px > 0 and len(points) > 3:
            points = cv2.approxPolyDP(points, float(epsilon_px), True)
        pts = points.reshape(-1, 2).astype(np.float64)
        pts.flags.writeable = False
        result.append(Contour(pts, is_hole=parent >= 0, parent=int(parent)))
    return tuple(result)


def label_image(mask: np.ndarray, ids: Mapping[int, str],
                amodal_masks: Mapping[str, np.ndarray | AmodalProjection] | None = None, *,
                classes: Mapping[str, str] | None = None,
                truncated: Collection[str] = (),
                camera: str = "", frame: int = 0,
                epsilon_px: float = DEFAULT_EPSILON_PX,
                min_visible_fraction: float = 0.0,
                min_pixel_count: int = 1) -> ImageLabels:
    """Labels of every object of one instance mask.

    Args:
        mask: (H, W) uint16 instance ids, 0 = background.
        ids: mask id → object uid. Ids in the mask but not here are ignored (logged).
        amodal_masks: uid → the object's whole projection, a (H, W) bool array or an
            :class:`AmodalProjection` (which also carries the truncation flag). Objects listed
            here but absent from the mask are fully occluded: they get a label without a
            visible box, with their amodal box and ``visible_fraction`` 0.
        classes: uid → class name.
        truncated: uids whose unclipped projection leaves the image (for plain-array amodal
            masks; :class:`AmodalProjection` carries its own flag).
        camera, frame: recorded in the result.
        epsilon_px: polygon simplification tolerance, pixels (0 = exact).
        min_visible_fraction: drop objects whose visible fraction is below this (objects
            without an amodal projection are kept).
        min_pixel_count: drop visible objects with fewer visible pixels (slivers). Fully
            occluded objects (0 visible pixels, amodal projection given) are kept unless
            ``min_visible_fraction`` > 0 drops them.

    Returns:
        ImageLabels with objects sorted by mask id.
    """
    if mask.ndim != 2:
        raise ValueError(f"instance mask must be (H, W), got shape {mask.shape}")
    height, width = mask.shape
    classes = classes or {}
    amodal_masks = amodal_masks or {}
    counts = np.bincount(mask.reshape(-1), minlength=1)
    present = np.flatnonzero(counts)
    present = present[present != 0]
    unknown = [int(i) for i in present if int(i) not in ids]
    if unknown:
        log.warning("%s frame %d: mask ids %s have no object; ignored", camera, frame, unknown)
    known = np.array([i for i in present.tolist() if i in ids], dtype=np.int64)
    boxes = _boxes_of_ids(mask, known) if known.size else {}

    labels = []
    for mask_id, uid in sorted(ids.items()):
        visible_box = boxes.get(mask_id)
        pixel_count = int(counts[mask_id]) if mask_id < counts.size else 0
        amodal = amodal_masks.get(uid)
        if visible_box is None and amodal is None:
            continue  # neither seen nor projected into this camera
        contours: tuple[Contour, ...] = ()
        if visible_box is not None:
            b = visible_box
            crop = mask[b.y_min:b.y_max + 1, b.x_min:b.x_max + 1] == mask_id
            contours = contours_of(crop, epsilon_px=epsilon_px, offset_px=(b.x_min, b.y_min))
        amodal_box = amodal_count = fraction = None
        is_truncated = uid in truncated
        if amodal is not None:
            amodal_mask = amodal.mask if isinstance(amodal, AmodalProjection) else amodal
            if amodal_mask.shape != mask.shape:
                raise ValueError(f"amodal mask of {uid!r} has shape {amodal_mask.shape}, "
                                 f"the instance mask {mask.shape}")
            if isinstance(amodal, AmodalProjection):
                is_truncated = is_truncated or amodal.truncated
            amodal_box, amodal_count = _box_and_count(amodal_mask)
            if amodal_count:
                fraction = min(1.0, pixel_count / amodal_count)
            else:
                # The projection misses every pixel centre (sub-pixel object) yet pixels may
                # be visible: call it fully visible rather than dividing by zero.
                fraction = 1.0 if pixel_count else 0.0
        elif visible_box is not None:
            is_truncated = is_truncated or (visible_box.x_min == 0 or visible_box.y_min == 0
                                            or visible_box.x_max == width - 1
                                            or visible_box.y_max == height - 1)
        if 0 < pixel_count < min_pixel_count:
            continue
        if fraction is not None and fraction < min_visible_fraction:
            continue
        labels.append(ObjectLabel(uid=uid, class_name=classes.get(uid, ""), mask_id=int(mask_id),
                                  box=visible_box, pixel_count=pixel_count, contours=contours,
                                  amodal_box=amodal_box, amodal_pixel_count=amodal_count,
                                  truncated=bool(is_truncated), visible_fraction=fraction))
    return ImageLabels(camera=camera, frame=int(frame), width_px=int(width), height_px=int(height),
                       objects=tuple(labels))


# --------------------------------------------------------------------------------------------
# Polygons → pixels (inverse of contours_of; used by tests and exporters)


def rasterize_contours(contours: Sequence[Contour], shape: tuple[int, int]) -> np.ndarray:
    """Pixels described by outer contours and holes, the inverse of :func:`contours_of`.

    Each outer contour is filled together with its boundary; each of its holes clears the
    pixels strictly inside the hole boundary (the boundary pixels belong to the object).
    Outer contours are drawn on separate layers and united, so an island inside a hole of
    another part survives.

    Args:
        contours: as returned by :func:`contours_of` (vertices rounded to whole pixels).
        shape: (H, W) of the result.

    Returns:
        (H, W) bool.
    """
    result = np.zeros(shape, dtype=bool)
    layer = np.zeros(shape, dtype=np.uint8)
    for index, outer in enumerate(contours):
        if outer.is_hole:
            continue
        layer[:] = 0
        pts = np.round(outer.points_px).astype(np.int32).reshape(-1, 1, 2)
        cv2.fillPoly(layer, [pts], 1)
        cv2.polylines(layer, [pts], True, 1)
        holes = [np.round(c.points_px).astype(np.int32).reshape(-1, 1, 2)
                 for c in contours if c.is_hole and c.parent == index]
        if holes:
            for hole in holes:
                cv2.fillPoly(layer, [hole], 0)
            cv2.polylines(layer, holes, True, 1)
        result |= layer.astype(bool)
    return result


def bridge_rings(rings: Sequence[np.ndarray]) -> np.ndarray:
    """Join several closed rings into one closed ring through zero-width bridges.

    Formats that allow one simple polygon per instance (YOLO segmentation) or per part (COCO
    polygons cannot express holes) get the parts and holes of an object as one ring: each next
    ring is entered from its vertex nearest to the ring built so far and left the same way.
    Filled with the even-odd rule, the result covers the parts and leaves the holes open,
    except for the bridges themselves (zero area).

    Args:
        rings: (Ni, 2) float vertex arrays.

    Returns:
        (M, 2) float64 vertices, M = sum(Ni) + 2 * (len(rings) - 1).
    """
    if not rings:
        return np.zeros((0, 2))
    merged = np.asarray(rings[0], dtype=np.float64).reshape(-1, 2)
    for ring in rings[1:]:
        ring = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
        d = ((merged[:, None, :] - ring[None, :, :]) ** 2).sum(axis=2)
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        entered = np.concatenate([ring[j:], ring[:j + 1]])  # closed walk around the ring
        merged = np.concatenate([merged[:i + 1], entered, merged[i:]])
    return merged


# --------------------------------------------------------------------------------------------
# Amodal projection


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


def rasterize_triangles(uv_px: np.ndarray, width_px: int, height_px: int,
                        valid: np.ndarray | None = None) -> AmodalProjection:
    """Fill projected triangles into an image-sized mask by pixel-centre sampling.

    A pixel belongs to the projection when its centre lies inside or on the edge of a
    triangle, the sampling rule of a renderer's one-sample-per-pixel id pass (OpenCV's
    ``fillConvexPoly`` instead rounds edges outwards, up to a pixel too wide).

    Args:
        uv_px: (T, 3, 2) float vertex pixel coordinates (pixel centres at integers).
        width_px, height_px: image size.
        valid: (T, 3) bool, False for vertices the lens cannot image; triangles with an
            invalid vertex are skipped and make the projection count as truncated.

    Returns:
        AmodalProjection: mask (H, W) bool, truncated = some vertex lies outside the image
        area ``[-0.5, W - 0.5] × [-0.5, H - 0.5]`` or was invalid.
    """
    uv = np.asarray(uv_px, dtype=np.float64).reshape(-1, 3, 2)
    mask = np.zeros((height_px, width_px), dtype=bool)
    truncated = False
    if valid is not None:
        ok = np.asarray(valid, dtype=bool).reshape(-1, 3).all(axis=1)
        truncated = bool((~ok).any())
        uv = uv[ok]
    finite = np.isfinite(uv).all(axis=(1, 2))
    truncated = truncated or bool((~finite).any())
    uv = uv[finite]
    if uv.size == 0:
        return AmodalProjection(mask, truncated)
    lo = uv.min(axis=1)
    hi = uv.max(axis=1)
    truncated = truncated or bool(((lo[:, 0] < -0.5) | (lo[:, 1] < -0.5)
                                   | (hi[:, 0] > width_px - 0.5) | (hi[:, 1] > height_px - 0.5)).any())
    # Candidate pixel centres of each triangle: its bounding box clipped to the image.
    x0 = np.clip(np.ceil(lo[:, 0]), 0, width_px).astype(np.int64)
    x1 = np.clip(np.floor(hi[:, 0]), -1, width_px - 1).astype(np.int64)
    y0 = np.clip(np.ceil(lo[:, 1]), 0, height_px).astype(np.int64)
    y1 = np.clip(np.floor(hi[:, 1]), -1, height_px - 1).astype(np.int64)
    bw = np.maximum(x1 - x0 + 1, 0)
    bh = np.maximum(y1 - y0 + 1, 0)
    a, b, c = uv[:, 0], uv[:, 1], uv[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    count = np.where(area2 != 0, bw * bh, 0)
    keep = np.flatnonzero(count)
    # Vectorised over triangles, in chunks that bound the candidate arrays (~4 M pixels).
    start = 0
    cumulative = np.cumsum(count[keep])
    while start < keep.size:
        base = cumulative[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(cumulative, base + _CANDIDATES_PER_CHUNK, side="right")))
        _fill_chunk(mask, keep[start:stop], count, x0, y0, bw, a, b, c, area2)
        start = stop
    return AmodalProjection(mask, truncated)


_CANDIDATES_PER_CHUNK = 1 << 22


def _fill_chunk(mask, tris, count, x0, y0, bw, a, b, c, area2) -> None:
    n = count[tris]
    owner = np.repeat(tris, n)
    local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    px = x0[owner] + local % bw[owner]
    py = y0[owner] + local // bw[owner]
    sign = np.sign(area2[owner])
    inside = np.ones(owner.size, dtype=bool)
    for p, q in ((a, b), (b, c), (c, a)):
        # Edge function of p→q at the pixel centre, oriented so the interior is >= 0.
        e = ((q[owner, 0] - p[owner, 0]) * (py - p[owner, 1])
             - (q[owner, 1] - p[owner, 1]) * (px - p[owner, 0])) * sign
        inside &= e >= 0
    mask[py[inside], px[inside]] = True


def _clip_triangles_near(tris_cam: np.ndarray, near_m: float) -> tuple[np.ndarray, bool]:
    """Clip (T, 3, 3) camera-frame triangles (OpenCV axes) to z >= near; returns the
    surviving triangles and whether any was cut."""
    z = tris_cam[:, :, 2]
    inside = z >= near_m
    all_in = inside.all(axis=1)
    crossing = inside.any(axis=1) & ~all_in
    pieces = [tris_cam[all_in]]
    for tri in tris_cam[crossing]:
        poly = _clip_polygon(tri, 2, near_m, True)
        for k in range(1, len(poly) - 1):  # fan triangulation of the convex clipped polygon
            pieces.append(np.stack([poly[0], poly[k], poly[k + 1]])[None])
    return np.concatenate(pieces) if pieces else np.zeros((0, 3, 3)), bool((~all_in).any())


def amodal_projection(camera: "Camera", triangles_world_m: np.ndarray, frame: int | None = None, *,
                      max_edge_px: float = MAX_PROJECTED_EDGE_PX) -> AmodalProjection:
    """Rasterise an object's world-space triangles through a camera model.

    Triangles are clipped at the camera's near plane (pinhole-like lenses) so that geometry
    behind the camera never folds into the image, projected with
    :func:`usdscene.projection.project_points` (every lens model, distortion included), split
    while a projected edge of a distorting lens is longer than ``max_edge_px``, and filled.

    Args:
        camera: the camera (intrinsics + pose at ``frame``).
        triangles_world_m: (T, 3, 3) float world coordinates in metres.
        frame: frame number for per-frame camera poses; None = the static pose.
        max_edge_px: subdivision threshold for distorting lenses, pixels.

    Returns:
        AmodalProjection of image size.
    """
    from usdscene.model import LensModel
    from usdscene.projection import project_points

    intr = camera.intrinsics
    tris = np.asarray(triangles_world_m, dtype=np.float64).reshape(-1, 3, 3)
    cut = False
    if intr.lens in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE):
        pose = camera.pose_at(frame) if frame is not None else camera.pose
        world_to_cam = pose.inverse()
        cam_pts = world_to_cam.transform_points(tris.reshape(-1, 3)).reshape(-1, 3, 3)
        cam_pts, cut = _clip_triangles_near(cam_pts, max(camera.clip_near_m, 1e-6))
        tris = pose.transform_points(cam_pts.reshape(-1, 3)).reshape(-1, 3, 3)
    curved = intr.lens not in (LensModel.PERSPECTIVE, LensModel.ORTHOGRAPHIC) or any(intr.distortion)

    def project(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        uv, ok = project_points(camera, t.reshape(-1, 3), frame)
        return np.asarray(uv, dtype=np.float64).reshape(-1, 3, 2), np.asarray(ok, bool).reshape(-1, 3)

    uv, ok = project(tris) if len(tris) else (np.zeros((0, 3, 2)), np.zeros((0, 3), bool))
    if curved and len(tris):
        done_uv, done_ok = [], []
        for _ in range(_MAX_SUBDIVISIONS):
            edges = np.linalg.norm(uv - np.roll(uv, -1, axis=1), axis=2).max(axis=1)
            split = ok.all(axis=1) & (edges > max_edge_px)
            done_uv.append(uv[~split])
            done_ok.append(ok[~split])
            if not split.any():
                break
            tris = _subdivide(tris[split])
            uv, ok = project(tris)
        else:
            done_uv.append(uv)
            done_ok.append(ok)
        uv, ok = np.concatenate(done_uv), np.concatenate(done_ok)
    result = rasterize_triangles(uv, intr.width_px, intr.height_px, ok)
    return AmodalProjection(result.mask, result.truncated or cut)


def _subdivide(tris: np.ndarray) -> np.ndarray:
    """Split (T, 3, 3) triangles at their edge midpoints → (4T, 3, 3)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    return np.concatenate([np.stack(t, axis=1) for t in
                           ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])


def label_images(items: Iterable[ImageLabels], *, epsilon_px: float = DEFAULT_EPSILON_PX,
                 min_visible_fraction: float = 0.0) -> Annotations:
    """Collect image labels into :class:`Annotations`, sorted by (frame, camera)."""
    images = sorted(items, key=lambda image: (image.frame, image.camera))
    return Annotations(images=tuple(images), epsilon_px=float(epsilon_px),
                       min_visible_fraction=float(min_visible_fraction))
