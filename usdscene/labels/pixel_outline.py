"""Polygons on the pixel outline of a binary region, and their fill by pixel centres. Pure
(numpy + numba; no pxr, no bpy).

Pixel convention (the one of :class:`usdscene.document.model.Intrinsics`): pixel ``(x, y)`` has
its centre at integer coordinates and covers ``[x - 0.5, x + 0.5] × [y - 0.5, y + 0.5]``. The
outline of a region runs along the edges between its pixels and the others, so its vertices
lie on pixel corners, at half-integer coordinates. That is the polygon COCO tools and
pycocotools expect (in their convention, where pixel ``i`` covers ``[i, i + 1)``, the corners
are integers): a pixel belongs to the polygon when its centre lies inside it, and every pixel
centre lies at least half a pixel from the outline, so the fill gives back exactly the region.

A polygon through the centres of the boundary pixels (``cv2.findContours``) lies half a pixel
inside the outline instead: filled by pixel centres it loses about half of its boundary pixels,
and a one-pixel-wide object has no area at all.

* :func:`outline_rings`: the outer ring and the hole rings of every 8-connected part of a
  region (holes are 4-connected, as ``cv2.findContours`` has them). Where two pixels of a part
  touch only at a corner, its outer ring passes through that corner twice (a pinch), so each
  part has exactly one outer ring.
* :func:`simplify_ring`: Douglas-Peucker with a tolerance in pixels. Below half a pixel the
  simplified ring still fills to exactly the same pixels (every pixel centre keeps its side).
* :func:`fill_rings`: pixels whose centres lie inside rings, even-odd: a part's outer ring and
  its holes, or one ring whose parts and holes are joined by zero-width bridges, fill alike.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

# Outgoing edge directions at a pixel corner (bits) and their steps (dx, dy), in the order
# east, south, west, north: turning right is +1, turning left is +3 (mod 4).
_STEPS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.int64)


def outline_rings(region: np.ndarray, offset_px: tuple[int, int] = (0, 0)
                  ) -> list[tuple[np.ndarray, bool, int]]:
    """Outer and hole rings of a binary region along its pixel edges.

    Args:
        region: (H, W) bool or integer array (non-zero = inside).
        offset_px: ``(dx, dy)`` image position of ``region[0, 0]``.

    Returns:
        ``(points_px, is_hole, parent)`` per ring: (N, 2) float64 corner vertices ``(x, y)`` at
        half-integer image coordinates, one per change of direction (N >= 4, even); outer rings
        run clockwise on the image (y down) with the region on their right, holes the other
        way; ``parent`` is the index in the returned list of a hole's outer ring (-1 for outer
        rings). Order: the outer ring of each part (parts ordered by their top-left pixel), each
        followed by its holes (ordered by their top-left corner).
    """
    inside = np.asarray(region) != 0
    if not inside.any():
        return []
    padded = np.zeros((inside.shape[0] + 2, inside.shape[1] + 2), dtype=np.uint8)
    padded[1:-1, 1:-1] = inside
    corners, starts, seeds, holes = _trace_kernel()(padded)
    # padded corner (row r, column c) is the top-left corner of padded pixel (r, c), i.e. of
    # region pixel (r - 1, c - 1), at image coordinates (c - 1.5, r - 1.5) + offset
    points = np.empty(corners.shape, dtype=np.float64)
    points[:, 0] = corners[:, 1] - 1.5 + offset_px[0]
    points[:, 1] = corners[:, 0] - 1.5 + offset_px[1]
    rings = [points[starts[k]:starts[k + 1]] for k in range(len(starts) - 1)]
    if not holes.any():
        return [(ring, False, -1) for ring in rings]
    # a hole belongs to the 8-connected part of the region pixel on its right
    _, parts = cv2.connectedComponents(padded, connectivity=8)
    part_of = parts[seeds[:, 0], seeds[:, 1]]
    holes_of: dict[int, list[int]] = {}
    for k in np.flatnonzero(holes).tolist():
        holes_of.setdefault(int(part_of[k]), []).append(k)
    result = []
    for k in np.flatnonzero(~holes).tolist():
        parent = len(result)
        result.append((rings[k], False, -1))
        result += [(rings[j], True, parent) for j in holes_of.get(int(part_of[k]), ())]
    return result


def _signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed ring (positive when clockwise on an image, y down)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1]) + x[-1] * y[0] - x[0] * y[-1])


@functools.cache
def _trace_kernel():
    """Compiled (numba, cached on disk): the rings of a zero-padded (H, W) uint8 region along
    pixel edges. Returns ``(corners, starts, seeds, holes)``: (M, 2) int64 corner (row, column)
    of every direction change, ring ``k`` being ``corners[starts[k]:starts[k + 1]]`` from its
    top-left corner; (K, 2) the (row, column) of a region pixel on each ring's right (to find
    its 8-connected part); (K,) bool, True for holes."""
    from usdscene.compiled import njit

    @njit(nogil=True)
    def trace(padded):
        height, width = padded.shape
        # outgoing edges per corner with the region on the right: east below-right pixel in,
        # above-right out; south: below-left in, below-right out; and so on around the corner
        out = np.zeros((height + 1, width + 1), dtype=np.uint8)
        for r in range(1, height):
            for c in range(1, width):
                tl = padded[r - 1, c - 1]
                tr = padded[r - 1, c]
                bl = padded[r, c - 1]
                br = padded[r, c]
                bits = 0
                if br and not tr:
                    bits |= 1
                if bl and not br:
                    bits |= 2
                if tl and not bl:
                    bits |= 4
                if tr and not tl:
                    bits |= 8
                out[r, c] = bits
        used = np.zeros_like(out)
        corners = []
        starts = [0]
        seeds = []
        holes = []
        dr = (0, 1, 0, -1)
        dc = (1, 0, -1, 0)
        # Rings are started in scan order, so each at its top-left corner, which is a turn and
        # never a pinch: an outer ring leaves it east, a hole south.
        for r0 in range(1, height):
            for c0 in range(1, width):
                while out[r0, c0] & ~used[r0, c0]:
                    free = out[r0, c0] & ~used[r0, c0]
                    h0 = 0
                    while not (free >> h0) & 1:
                        h0 += 1
                    holes.append(h0 == 1)
                    # the region pixel on the right of the first edge
                    if h0 == 0:
                        seeds.append((r0, c0))
                    else:
                        seeds.append((r0, c0 - 1))
                    corners.append((r0, c0))
                    r, c, h = r0, c0, h0
                    while True:
                        used[r, c] |= 1 << h
                        r += dr[h]
                        c += dc[h]
                        bits = out[r, c]
                        if bits == 1 or bits == 2 or bits == 4 or bits == 8:
                            nh = 0
                            while not (bits >> nh) & 1:
                                nh += 1
                        else:
                            # a corner where two pixels touch diagonally: turning left keeps them
                            # on one ring (8-connected region, 4-connected holes)
                            nh = (h + 3) % 4
                        if r == r0 and c == c0 and nh == h0:
                            break
                        if nh != h:
                            corners.append((r, c))
                        h = nh
                    starts.append(len(corners))
        corners_out = np.empty((len(corners), 2), dtype=np.int64)
        for i in range(len(corners)):
            corners_out[i, 0] = corners[i][0]
            corners_out[i, 1] = corners[i][1]
        seeds_out = np.empty((len(seeds), 2), dtype=np.int64)
        holes_out = np.empty(len(holes), dtype=np.bool_)
        for i in range(len(seeds)):
            seeds_out[i, 0] = seeds[i][0]
            seeds_out[i, 1] = seeds[i][1]
            holes_out[i] = holes[i]
        return corners_out, np.array(starts, dtype=np.int64), seeds_out, holes_out

    return trace


def simplify_ring(points: np.ndarray, epsilon_px: float) -> np.ndarray:
    """Douglas-Peucker simplification of a closed ring (``cv2.approxPolyDP``).

    Every dropped vertex, and so the whole dropped chain, lies within ``epsilon_px`` of the
    simplified ring. A ring whose simplification would have no area keeps all its vertices.

    Args:
        points: (N, 2) float vertices.
        epsilon_px: tolerance in pixels; 0 returns ``points``.

    Returns:
        (M, 2) float64 vertices, a subset of ``points`` in the same order.
    """
    if epsilon_px <= 0 or len(points) <= 4:
        return points
    kept = cv2.approxPolyDP(points.astype(np.float32).reshape(-1, 1, 2), float(epsilon_px), True)
    result = kept.reshape(-1, 2).astype(np.float64)
    # below half a pixel the ring keeps every pixel centre it encloses, so it keeps its area
    if epsilon_px >= 0.5 and (len(result) < 3 or abs(_signed_area(result)) < 0.5):
        return points
    return result


def fill_rings(rings, shape: tuple[int, int]) -> np.ndarray:
    """Pixels whose centres lie inside the rings, even-odd (each ring toggles what it encloses).

    Args:
        rings: (N, 2) float vertex arrays ``(x, y)``, closed implicitly.
        shape: (H, W) of the result.

    Returns:
        (H, W) bool.
    """
    height, width = shape
    toggles = np.zeros((height, width + 1), dtype=np.int64)
    for ring in rings:
        ring = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
        if len(ring) < 3:
            continue
        x0, y0 = ring[:, 0], ring[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        for a_x, a_y, b_x, b_y in zip(x0, y0, x1, y1):
            if a_y == b_y:
                continue
            lo, hi = min(a_y, b_y), max(a_y, b_y)
            # rows whose centre line y meets the edge, half-open [lo, hi)
            rows = np.arange(max(0, int(np.ceil(lo))), min(height, int(np.ceil(hi))))
            if rows.size == 0:
                continue
            x = a_x + (rows - a_y) * (b_x - a_x) / (b_y - a_y)
            first = np.clip(np.floor(x).astype(np.int64) + 1, 0, width)  # centres right of x
            np.add.at(toggles, (rows, first), 1)
    return (np.cumsum(toggles, axis=1)[:, :width] % 2).astype(bool)
