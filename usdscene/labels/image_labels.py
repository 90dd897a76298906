"""Instance masks → per-object 2D labels: boxes, polygons, visibility. Pure (numpy + OpenCV).

Pixel convention (the one of :class:`usdscene.document.model.Intrinsics`, i.e. OpenCV's): pixel
centres sit at integer coordinates and pixel ``(x, y)`` covers ``[x - 0.5, x + 0.5] ×
[y - 0.5, y + 0.5]``; ``x`` is the column, ``y`` the row.

* A :class:`PixelBox` holds the *inclusive* pixel indices of the first and last covered
  column/row. Its OpenLABEL form (:meth:`PixelBox.center_size`) is ``[cx, cy, w, h]`` in the
  pixel-centre convention: it spans the covered pixels edge to edge, so ``w = x_max - x_min + 1``
  and ``cx = (x_min + x_max) / 2``. Exporters to formats whose pixel ``i`` covers
  ``[i, i + 1)`` (COCO, YOLO) add 0.5 (:meth:`PixelBox.xywh_corner`).
* Polygon vertices (:class:`Contour`) lie on the pixel outline of the visible region: on pixel
  corners, at half-integer coordinates (:mod:`usdscene.labels.pixel_outline`). Filled by pixel
  centres, the rule of COCO tools (pycocotools) and of :func:`rasterize_contours`, they give
  back exactly the mask's pixels. Each 8-connected part has one outer contour; holes are
  4-connected, as ``cv2.findContours`` has them.
* Simplification: Douglas-Peucker (``cv2.approxPolyDP``) with ``epsilon_px``, the largest
  distance in pixels of the simplified polygon from the outline. Every pixel centre lies at
  least half a pixel from the outline, so below half a pixel the simplified polygon still
  fills to exactly the mask: the default :data:`DEFAULT_EPSILON_PX` = 0.49 px. ``0`` keeps
  every corner of the outline; larger values trade pixels at the boundary for fewer vertices.

Visibility:

* *visible* = pixels of the object in the instance mask (occluders removed);
* *amodal* = pixels of the object's whole projection through the camera model, as if nothing
  occluded it, clipped to the image (:mod:`usdscene.labels.amodal`);
* ``visible_fraction = |visible ∩ amodal| / |amodal|`` in pixels. The render's boundaries
  differ from the exact projection by a fraction of a pixel (Cycles jitters its one id sample
  inside the pixel filter; remapped lenses take the nearest rendered pixel), so some visible
  pixels lie just outside the projection: counting them would cancel real occlusion;
* ``truncated`` = the unclipped projection leaves the image (or, without an amodal
  projection, the visible box touches the image border).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from typing import Collection, Iterable, Iterator, Mapping, Sequence

import numpy as np

from usdscene.labels.amodal import AmodalProjection
from usdscene.labels.pixel_box import PixelBox
from usdscene.labels.pixel_outline import fill_rings, outline_rings, simplify_ring

log = logging.getLogger(__name__)

DEFAULT_EPSILON_PX = 0.49
# Revision of the labels' own rules (polygon form, visible fraction); kept labels computed under
# another revision are computed anew (:class:`usdscene.dataset.annotation.ImageLabeller`).
LABELS_REVISION = 2


# --------------------------------------------------------------------------------------------
# Data


@dataclass(frozen=True, eq=False)
class Contour:
    """One closed polygon of an object's visible region.

    Attributes:
        points_px: (N, 2) float64 vertices ``(x, y)`` in pixels (pixel centres at integers):
            corners of the pixel outline, at half-integers, N >= 4 (a single pixel is its
            square).
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
        visible_fraction: visible pixels inside the amodal projection / ``amodal_pixel_count``,
            in [0, 1]; None = unknown.
        keypoints: people only: the 17 COCO keypoints as ``(x, y, v)`` rows (pixels, flags of
            :mod:`usdscene.labels.keypoints`); None for objects without keypoints.
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
    keypoints: tuple[tuple[float, float, int], ...] | None = None

    @property
    def visible(self) -> bool:
        """Whether at least one pixel of the object is visible."""
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
        """The frames that have images, ascending."""
        return tuple(sorted({image.frame for image in self.images}))

    def for_frame(self, frame: int) -> tuple[ImageLabels, ...]:
        """The images of ``frame`` (one per camera), in stored order."""
        return tuple(image for image in self.images if image.frame == frame)

    def __iter__(self) -> Iterator[ImageLabels]:
        return iter(self.images)


# --------------------------------------------------------------------------------------------
# Mask → labels


def _ids_of_mask(mask: np.ndarray) -> tuple[np.ndarray, dict[int, PixelBox]]:
    """Pixel count of every id of an integer mask and the tight box of every id present but 0
    (the background), in one compiled pass over the image instead of one full-image pass per
    object.

    Returns:
        ``(counts (max id + 1,) int64, mask id → PixelBox)``.
    """
    count = int(mask.max()) + 1 if mask.size else 1
    counts, lo_x, lo_y, hi_x, hi_y = _id_bounds_kernel()(np.ascontiguousarray(mask), count)
    return counts, {i: PixelBox(int(lo_x[i]), int(lo_y[i]), int(hi_x[i]), int(hi_y[i]))
                    for i in np.flatnonzero(counts).tolist() if i}


@functools.cache
def _id_bounds_kernel():
    """Compiled (numba, cached on disk): per id of a (H, W) integer mask, its pixel count and
    the first and last column and row holding it (``hi_x = -1`` for absent ids)."""
    from usdscene.compiled import njit

    @njit(nogil=True)
    def id_bounds(mask, count):
        height, width = mask.shape
        counts = np.zeros(count, dtype=np.int64)
        lo_x = np.full(count, width, dtype=np.int64)
        lo_y = np.full(count, height, dtype=np.int64)
        hi_x = np.full(count, -1, dtype=np.int64)
        hi_y = np.full(count, -1, dtype=np.int64)
        for y in range(height):
            for x in range(width):
                i = mask[y, x]
                counts[i] += 1
                if x < lo_x[i]:
                    lo_x[i] = x
                if x > hi_x[i]:
                    hi_x[i] = x
                if y < lo_y[i]:
                    lo_y[i] = y
                hi_y[i] = y
        return counts, lo_x, lo_y, hi_x, hi_y

    return id_bounds


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


def _pixels_inside(mask: np.ndarray, mask_id: int, visible_box: PixelBox | None, crop: np.ndarray,
                   origin_px: tuple[int, int]) -> int:
    """Pixels of ``mask_id`` in ``mask`` that ``crop`` (a bool region whose ``[0, 0]`` lies at
    image position ``origin_px``) covers, counted over the overlap of the two boxes only."""
    if visible_box is None:
        return 0
    ox, oy = origin_px
    x0, y0 = max(visible_box.x_min, ox), max(visible_box.y_min, oy)
    x1 = min(visible_box.x_max + 1, ox + crop.shape[1])
    y1 = min(visible_box.y_max + 1, oy + crop.shape[0])
    if x1 <= x0 or y1 <= y0:
        return 0
    return int(np.count_nonzero((mask[y0:y1, x0:x1] == mask_id) & crop[y0 - oy:y1 - oy, x0 - ox:x1 - ox]))


def contours_of(region: np.ndarray, *, epsilon_px: float = DEFAULT_EPSILON_PX,
                offset_px: tuple[int, int] = (0, 0)) -> tuple[Contour, ...]:
    """Outer contours and holes of a binary region, on its pixel outline.

    Args:
        region: (H, W) bool or uint8 (non-zero = inside).
        epsilon_px: simplification tolerance in pixels (see the module docstring); 0 keeps
            every corner of the outline.
        offset_px: ``(dx, dy)`` added to every vertex (position of ``region`` in the image).

    Returns:
        Each 8-connected part's outer contour followed by its holes (4-connected), parts in
        the order of their top-left pixel; holes point at their outer contour through
        ``parent``.
    """
    result = []
    for points, is_hole, parent in outline_rings(region, offset_px):
        pts = simplify_ring(points, epsilon_px)
        pts.flags.writeable = False
        result.append(Contour(pts, is_hole=is_hole, parent=parent))
    return tuple(result)


def label_image(mask: np.ndarray, ids: Mapping[int, str],
                amodal_masks: Mapping[str, np.ndarray | AmodalProjection] | None = None, *,
                classes: Mapping[str, str] | None = None,
                truncated: Collection[str] = (),
                camera: str = "", frame: int = 0,
                epsilon_px: float = DEFAULT_EPSILON_PX,
                min_visible_fraction: float = 0.0,
                min_pixel_count: int = 1,
                keypoints: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> ImageLabels:
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
        keypoints: uid → ``(uv (K, 2), valid (K,))``, the object's keypoints projected into
            this image (:func:`usdscene.labels.projection.project_points`); flagged against
            the mask (:func:`usdscene.labels.keypoints.keypoint_visibility`).

    Returns:
        ImageLabels with objects sorted by mask id.
    """
    if mask.ndim != 2:
        raise ValueError(f"instance mask must be (H, W), got shape {mask.shape}")
    height, width = mask.shape
    classes = classes or {}
    amodal_masks = amodal_masks or {}
    counts, boxes = _ids_of_mask(mask)
    present = np.flatnonzero(counts)
    present = present[present != 0]
    unknown = [int(i) for i in present if int(i) not in ids]
    if unknown:
        log.warning("%s frame %d: mask ids %s have no object; ignored", camera, frame, unknown)

    # Every person's keypoints flagged in one call (a call per person cost more than the test).
    flagged_of = {}
    people = [(uid, mask_id) for mask_id, uid in ids.items() if keypoints and uid in keypoints]
    if people:
        from usdscene.labels.keypoints import keypoint_visibility

        uv = [np.asarray(keypoints[uid][0], dtype=np.float64).reshape(-1, 2) for uid, _ in people]
        valid = np.concatenate([np.asarray(keypoints[uid][1], dtype=bool).reshape(-1) for uid, _ in people])
        owner = np.repeat([int(mask_id) for _, mask_id in people], [len(points) for points in uv])
        rows = keypoint_visibility(np.concatenate(uv), valid, mask, owner).tolist()
        starts = np.cumsum([0] + [len(points) for points in uv]).tolist()
        flagged_of = {mask_id: rows[a:b] for (_, mask_id), a, b in zip(people, starts[:-1], starts[1:])}

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
            if isinstance(amodal, AmodalProjection):
                if amodal.image_size_px != (width, height):
                    raise ValueError(f"amodal projection of {uid!r} is for a {amodal.image_size_px} "
                                     f"image, the instance mask is {(width, height)}")
                is_truncated = is_truncated or amodal.truncated
                amodal_box, amodal_count = amodal.box, amodal.pixel_count
                crop, origin = amodal.crop, amodal.origin_px
            else:
                if amodal.shape != mask.shape:
                    raise ValueError(f"amodal mask of {uid!r} has shape {amodal.shape}, "
                                     f"the instance mask {mask.shape}")
                amodal_box, amodal_count = _box_and_count(amodal)
                crop, origin = amodal, (0, 0)
            seen = _pixels_inside(mask, mask_id, visible_box, crop, origin) if amodal_count else 0
            if amodal_count:
                # visible ∩ amodal: mask pixels just outside the exact projection (the render's
                # boundary differs by a fraction of a pixel) must not cancel real occlusion
                fraction = int(seen) / amodal_count
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
        points = None
        if mask_id in flagged_of:
            points = tuple((round(x, 3) + 0.0, round(y, 3) + 0.0, int(v)) for x, y, v in flagged_of[mask_id])
        labels.append(ObjectLabel(uid=uid, class_name=classes.get(uid, ""), mask_id=int(mask_id),
                                  box=visible_box, pixel_count=pixel_count, contours=contours,
                                  amodal_box=amodal_box, amodal_pixel_count=amodal_count,
                                  truncated=bool(is_truncated), visible_fraction=fraction,
                                  keypoints=points))
    return ImageLabels(camera=camera, frame=int(frame), width_px=int(width), height_px=int(height),
                       objects=tuple(labels))


# --------------------------------------------------------------------------------------------
# Polygons → pixels (inverse of contours_of; used by tests and exporters)


def rasterize_contours(contours: Sequence[Contour], shape: tuple[int, int]) -> np.ndarray:
    """Pixels whose centres lie inside an object's contours (even-odd), the inverse of
    :func:`contours_of`: exact for ``epsilon_px`` below half a pixel.

    Args:
        contours: as returned by :func:`contours_of`.
        shape: (H, W) of the result.

    Returns:
        (H, W) bool.
    """
    return fill_rings([c.points_px for c in contours], shape)


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


def label_images(items: Iterable[ImageLabels], *, epsilon_px: float = DEFAULT_EPSILON_PX,
                 min_visible_fraction: float = 0.0) -> Annotations:
    """Collect image labels into :class:`Annotations`, sorted by (frame, camera)."""
    images = sorted(items, key=lambda image: (image.frame, image.camera))
    return Annotations(images=tuple(images), epsilon_px=float(epsilon_px),
                       min_visible_fraction=float(min_visible_fraction))


# --------------------------------------------------------------------------------------------
# Labels of one image ↔ JSON (the per-image label files of an output folder)


def image_labels_to_json(image: ImageLabels) -> dict:
    """A JSON-ready dict of one image's labels; :func:`image_labels_from_json` reads it back
    equal (floats written as Python writes them round-trip exactly)."""
    def box(b: PixelBox | None):
        return None if b is None else [int(b.x_min), int(b.y_min), int(b.x_max), int(b.y_max)]

    def optional(value, kind):
        return None if value is None else kind(value)

    def one(o: ObjectLabel) -> dict:
        out = {"uid": o.uid, "class": o.class_name, "mask_id": int(o.mask_id), "box": box(o.box),
               "pixel_count": int(o.pixel_count),
               "contours": [{"points_px": c.flat(), "is_hole": bool(c.is_hole), "parent": int(c.parent)}
                            for c in o.contours],
               "amodal_box": box(o.amodal_box), "amodal_pixel_count": optional(o.amodal_pixel_count, int),
               "truncated": bool(o.truncated), "visible_fraction": optional(o.visible_fraction, float)}
        if o.keypoints is not None:  # only people have them: other labels keep their bytes
            out["keypoints"] = [[float(x), float(y), int(v)] for x, y, v in o.keypoints]
        return out

    return {"camera": image.camera, "frame": int(image.frame), "width_px": int(image.width_px),
            "height_px": int(image.height_px), "objects": [one(o) for o in image.objects]}


def image_labels_from_json(data: Mapping) -> ImageLabels:
    """Inverse of :func:`image_labels_to_json`.

    Raises:
        KeyError, TypeError, ValueError: not such a dict.
    """
    def box(value):
        return None if value is None else PixelBox(*(int(v) for v in value))

    objects = tuple(
        ObjectLabel(uid=str(o["uid"]), class_name=str(o["class"]), mask_id=int(o["mask_id"]),
                    box=box(o["box"]), pixel_count=int(o["pixel_count"]),
                    contours=tuple(Contour(np.asarray(c["points_px"], dtype=np.float64).reshape(-1, 2),
                                           bool(c["is_hole"]), int(c["parent"])) for c in o["contours"]),
                    amodal_box=box(o["amodal_box"]),
                    amodal_pixel_count=None if o["amodal_pixel_count"] is None else int(o["amodal_pixel_count"]),
                    truncated=bool(o["truncated"]),
                    visible_fraction=None if o["visible_fraction"] is None else float(o["visible_fraction"]),
                    keypoints=(None if o.get("keypoints") is None
                               else tuple((float(x), float(y), int(v)) for x, y, v in o["keypoints"])))
        for o in data["objects"])
    return ImageLabels(camera=str(data["camera"]), frame=int(data["frame"]), width_px=int(data["width_px"]),
                       height_px=int(data["height_px"]), objects=objects)

