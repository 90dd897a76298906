"""Compiled (numba, cached on disk) loops of the amodal projection (:mod:`usdscene.labels.amodal`).

Imported on first use only: importing numba costs about a second, which ``import
usdscene.labels.amodal`` should not pay.

Conventions shared by the kernels: ``uv`` (V, 2) float64 pixel coordinates of projected
vertices (pixel centres at integers), ``imaged`` (V,) bool (the lens images the vertex),
``inside`` (V,) bool (the vertex lies within a fisheye's field-of-view cone; all True for other
lenses), ``clamped`` (V,) bool (the vertex lies where the lens model has no image and was moved
onto the cone), ``faces`` (T, 3) int64 vertex indices, ``owner`` (T,) int64 object index of
each face, ``circle`` (5,) float64 ``(cx, cy, fx, fy, r)``: the image is empty outside the
ellipse ``((x - cx) / fx)² + ((y - cy) / fy)² <= r²`` (a fisheye's image circle; r <= 0: no
circle).
"""

from __future__ import annotations

import math

import numpy as np

from usdscene.compiled import njit


@njit(nogil=True)
def to_camera(points_world, camera_to_world):
    """(P, 3) world points → (P, 3) camera-frame points, ``R^T (p - t)`` for the (4, 4) camera
    pose ``[R t]`` (a compiled loop: numpy's (P, 3) @ (3, 3) is 15 times slower)."""
    out = np.empty_like(points_world)
    for i in range(points_world.shape[0]):
        x = points_world[i, 0] - camera_to_world[0, 3]
        y = points_world[i, 1] - camera_to_world[1, 3]
        z = points_world[i, 2] - camera_to_world[2, 3]
        for j in range(3):
            out[i, j] = x * camera_to_world[0, j] + y * camera_to_world[1, j] + z * camera_to_world[2, j]
    return out


@njit(nogil=True)
def used_vertices(points, faces):
    """Drop the vertices no face uses: ``(points (P', 3), faces (T, 3) renumbered)``, vertices
    in their first order."""
    new_index = np.full(points.shape[0], -1, dtype=np.int64)
    for t in range(faces.shape[0]):
        for k in range(3):
            new_index[faces[t, k]] = 0
    n = 0
    for i in range(points.shape[0]):
        if new_index[i] == 0:
            new_index[i] = n
            n += 1
    kept = np.empty((n, 3), dtype=points.dtype)
    for i in range(points.shape[0]):
        if new_index[i] >= 0:
            kept[new_index[i], 0] = points[i, 0]
            kept[new_index[i], 1] = points[i, 1]
            kept[new_index[i], 2] = points[i, 2]
    renumbered = np.empty_like(faces)
    for t in range(faces.shape[0]):
        for k in range(3):
            renumbered[t, k] = new_index[faces[t, k]]
    return kept, renumbered


@njit(nogil=True)
def faces_to_fill(points_cam, faces, owner, single_facing):
    """The faces to rasterise: every face of an object, or for objects flagged in
    ``single_facing`` only the faces whose winding turns them towards the camera (see
    :func:`usdscene.labels.amodal.amodal_projections` for why that is exact for closed meshes).

    Args:
        points_cam: (P, 3) float64 camera-frame vertices (camera at the origin), metres.
        faces: (T, 3) int64.
        owner: (T,) int64.
        single_facing: (N,) bool per object.

    Returns:
        ``(faces (T', 3), owner (T',))``, in the given order.
    """
    kept_faces = np.empty_like(faces)
    kept_owner = np.empty_like(owner)
    n = 0
    for t in range(faces.shape[0]):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        if single_facing[owner[t]]:
            ax, ay, az = points_cam[a, 0], points_cam[a, 1], points_cam[a, 2]
            ux, uy, uz = points_cam[b, 0] - ax, points_cam[b, 1] - ay, points_cam[b, 2] - az
            vx, vy, vz = points_cam[c, 0] - ax, points_cam[c, 1] - ay, points_cam[c, 2] - az
            # (u × v) · a: negative when the face turns towards the camera.
            if (uy * vz - uz * vy) * ax + (uz * vx - ux * vz) * ay + (ux * vy - uy * vx) * az > 0.0:
                continue
        kept_faces[n, 0], kept_faces[n, 1], kept_faces[n, 2] = a, b, c
        kept_owner[n] = owner[t]
        n += 1
    return kept_faces[:n], kept_owner[:n]


@njit(nogil=True)
def needs_split(uv, imaged, clamped, faces, max_edge, max_cut_edge):
    """(T,) bool: faces whose three vertices are imaged and one of whose projected edges is
    longer than ``max_edge`` pixels, or, for faces with some but not all vertices clamped
    onto a fisheye's cone, longer than ``max_cut_edge``."""
    out = np.zeros(faces.shape[0], dtype=np.bool_)
    for t in range(faces.shape[0]):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        if not (imaged[a] and imaged[b] and imaged[c]):
            continue
        crossing = (clamped[a] or clamped[b] or clamped[c]) and not (clamped[a] and clamped[b] and clamped[c])
        limit = max_cut_edge * max_cut_edge if crossing else max_edge * max_edge
        for k in range(3):
            i, j = faces[t, k], faces[t, (k + 1) % 3]
            dx = uv[i, 0] - uv[j, 0]
            dy = uv[i, 1] - uv[j, 1]
            if dx * dx + dy * dy > limit:
                out[t] = True
                break
    return out


@njit(nogil=True)
def edge_midpoints(points, pieces):
    """The midpoints of the edges of faces to split, each edge once although the faces on
    both sides of it are split (a corner is shared the same way): half the points to project.

    Args:
        points: (P, 3) float64 vertices.
        pieces: (K, 3) int64 faces to split.

    Returns:
        ``(midpoints (E, 3), edge (K, 3))``: ``(points[a] + points[b]) / 2`` of every edge
        ``{a, b}``, in the order first met, and for each face the index into ``midpoints`` of
        its edges from corner 0 to 1, 1 to 2 and 2 to 0.
    """
    k = pieces.shape[0]
    size = 16
    while size < 6 * k:  # open addressing, at most half full
        size *= 2
    slot_lo = np.full(size, -1, dtype=np.int64)
    slot_hi = np.empty(size, dtype=np.int64)
    slot_edge = np.empty(size, dtype=np.int64)
    edge = np.empty((k, 3), dtype=np.int64)
    midpoints = np.empty((3 * k, 3), dtype=np.float64)
    n = 0
    for t in range(k):
        for j in range(3):
            a, b = pieces[t, j], pieces[t, (j + 1) % 3]
            lo, hi = min(a, b), max(a, b)
            h = (lo * 1000003 + hi * 998244353) & (size - 1)
            while slot_lo[h] >= 0 and not (slot_lo[h] == lo and slot_hi[h] == hi):
                h = (h + 1) & (size - 1)
            if slot_lo[h] < 0:
                slot_lo[h], slot_hi[h], slot_edge[h] = lo, hi, n
                for d in range(3):  # the sum is the same either way round: the same midpoint
                    midpoints[n, d] = (points[lo, d] + points[hi, d]) / 2.0
                n += 1
            edge[t, j] = slot_edge[h]
    return midpoints[:n], edge


@njit(nogil=True)
def split_faces(pieces, piece_owner, edge, first):
    """Each face split into four at its edge midpoints.

    Args:
        pieces: (K, 3) int64 faces ``(a, b, c)``; ``piece_owner`` (K,) their objects.
        edge: (K, 3) int64 their edges' midpoints (:func:`edge_midpoints`), whose vertices
            are numbered from ``first`` on.

    Returns:
        ``(faces (4K, 3), owner (4K,))``: the corner pieces ``(a, ab, ca)`` of every face,
        then ``(ab, b, bc)``, then ``(ca, bc, c)``, then the middle pieces ``(ab, bc, ca)``.
    """
    k = pieces.shape[0]
    out = np.empty((4 * k, 3), dtype=np.int64)
    out_owner = np.empty(4 * k, dtype=np.int64)
    for t in range(k):
        a, b, c = pieces[t, 0], pieces[t, 1], pieces[t, 2]
        ab, bc, ca = first + edge[t, 0], first + edge[t, 1], first + edge[t, 2]
        out[t, 0], out[t, 1], out[t, 2] = a, ab, ca
        out[k + t, 0], out[k + t, 1], out[k + t, 2] = ab, b, bc
        out[2 * k + t, 0], out[2 * k + t, 1], out[2 * k + t, 2] = ca, bc, c
        out[3 * k + t, 0], out[3 * k + t, 1], out[3 * k + t, 2] = ab, bc, ca
        for j in range(4):
            out_owner[j * k + t] = piece_owner[t]
    return out, out_owner


@njit(nogil=True)
def partition_faces(faces, owner, chosen):
    """``(faces[~chosen], owner[~chosen], faces[chosen], owner[chosen])`` in one pass."""
    n = faces.shape[0]
    k = 0
    for t in range(n):
        if chosen[t]:
            k += 1
    rest, rest_owner = np.empty((n - k, 3), dtype=np.int64), np.empty(n - k, dtype=np.int64)
    picked, picked_owner = np.empty((k, 3), dtype=np.int64), np.empty(k, dtype=np.int64)
    i = j = 0
    for t in range(n):
        if chosen[t]:
            picked[j, 0], picked[j, 1], picked[j, 2] = faces[t, 0], faces[t, 1], faces[t, 2]
            picked_owner[j] = owner[t]
            j += 1
        else:
            rest[i, 0], rest[i, 1], rest[i, 2] = faces[t, 0], faces[t, 1], faces[t, 2]
            rest_owner[i] = owner[t]
            i += 1
    return rest, rest_owner, picked, picked_owner


@njit(nogil=True, inline="always")
def _circle_span(py, circle):
    """``(lo, hi)``: the columns of image row ``py`` whose pixel centres lie inside the image
    circle (lo > hi: none). The span only shrinks as rows move away from the circle's centre."""
    dy = (py - circle[1]) / circle[3]
    room = circle[4] * circle[4] - dy * dy
    if room < 0.0:
        return 1, 0
    half = circle[2] * math.sqrt(room)
    return int(math.ceil(circle[0] - half)), int(math.floor(circle[0] + half))


@njit(nogil=True, inline="always")
def _fill_face(uv, a, b, c, x0, y0, w, h, crops, base, circle):
    """Set the pixels of one object's (h, w) crop (at ``crops[base:]``, image origin
    ``(x0, y0)``) whose centre lies inside or on the edge of face ``(a, b, c)`` and inside
    the image circle."""
    ax, ay = uv[a, 0], uv[a, 1]
    bx, by = uv[b, 0], uv[b, 1]
    cx, cy = uv[c, 0], uv[c, 1]
    area2 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    if area2 == 0.0:
        return
    sign = 1.0 if area2 > 0.0 else -1.0
    px0 = max(int(math.ceil(min(ax, bx, cx))), x0)
    px1 = min(int(math.floor(max(ax, bx, cx))), x0 + w - 1)
    py0 = max(int(math.ceil(min(ay, by, cy))), y0)
    py1 = min(int(math.floor(max(ay, by, cy))), y0 + h - 1)
    clip = circle[4] > 0.0 and py0 <= py1
    if clip:  # most faces lie inside the circle: its first and last rows' spans tell
        lo0, hi0 = _circle_span(py0, circle)
        lo1, hi1 = _circle_span(py1, circle)
        clip = not (lo0 <= px0 and px1 <= hi0 and lo1 <= px0 and px1 <= hi1)
    for py in range(py0, py1 + 1):
        row = base + (py - y0) * w - x0
        lo, hi = px0, px1
        if clip:  # the row's span inside the image circle
            lo_circle, hi_circle = _circle_span(py, circle)
            lo, hi = max(lo, lo_circle), min(hi, hi_circle)
        for px in range(lo, hi + 1):
            # Edge functions at the pixel centre, oriented so the interior is >= 0; one test
            # without branches, which the compiler turns into vector code (a third faster).
            outside = ((((bx - ax) * (py - ay) - (by - ay) * (px - ax)) * sign < 0.0)
                       | (((cx - bx) * (py - by) - (cy - by) * (px - bx)) * sign < 0.0)
                       | (((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) * sign < 0.0))
            crops[row + px] |= not outside


@njit(nogil=True)
def rasterize_objects(uv, imaged, inside, clamped, faces, owner, n_objects, width, height, circle):
    """Fill every object's faces by pixel-centre sampling into one crop per object.

    A pixel belongs to an object when its centre lies inside the image circle and inside or
    on the edge of one of the object's projected faces. Faces with a vertex the lens cannot
    image are skipped and make their object truncated; a face with a vertex outside the
    fisheye cone marks its object as cut, and faces whose vertices were all clamped onto the
    cone are dropped.

    Returns:
        ``(crops, offsets, origin, tight, counts, truncated, cut)``: ``crops`` a flat bool
        buffer holding object ``o``'s crop at ``offsets[o]:offsets[o + 1]`` as a row-major
        (h, w) array, ``origin`` (N, 4) int64 ``(x0, y0, w, h)`` of that crop, ``tight``
        (N, 4) int64 ``(x_min, y_min, x_max, y_max)`` of the covered pixels (x_max < x_min
        when none), ``counts`` (N,) covered pixels, ``truncated`` (N,) bool (a vertex outside
        the image area ``[-0.5, W - 0.5] × [-0.5, H - 0.5]``, non-finite or not imaged),
        ``cut`` (N,) bool (a face leaves the fisheye cone).
    """
    n_faces = faces.shape[0]
    lo_x = np.full(n_objects, width, dtype=np.int64)
    lo_y = np.full(n_objects, height, dtype=np.int64)
    hi_x = np.full(n_objects, -1, dtype=np.int64)
    hi_y = np.full(n_objects, -1, dtype=np.int64)
    truncated = np.zeros(n_objects, dtype=np.bool_)
    cut = np.zeros(n_objects, dtype=np.bool_)
    drawn = np.zeros(n_faces, dtype=np.bool_)
    for t in range(n_faces):
        o = owner[t]
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        if not (inside[a] and inside[b] and inside[c]):
            cut[o] = True
            if clamped[a] and clamped[b] and clamped[c]:
                continue
        if not (imaged[a] and imaged[b] and imaged[c]):
            truncated[o] = True
            continue
        min_x = min(uv[a, 0], uv[b, 0], uv[c, 0])
        max_x = max(uv[a, 0], uv[b, 0], uv[c, 0])
        min_y = min(uv[a, 1], uv[b, 1], uv[c, 1])
        max_y = max(uv[a, 1], uv[b, 1], uv[c, 1])
        if not (math.isfinite(min_x) and math.isfinite(max_x) and math.isfinite(min_y)
                and math.isfinite(max_y)):
            truncated[o] = True
            continue
        if min_x < -0.5 or min_y < -0.5 or max_x > width - 0.5 or max_y > height - 0.5:
            truncated[o] = True
        if math.ceil(min_x) > math.floor(max_x) or math.ceil(min_y) > math.floor(max_y):
            continue  # no pixel centre in its box (a third of the faces of a far person)
        drawn[t] = True
        lo_x[o] = min(lo_x[o], max(0, int(math.ceil(min_x))))
        lo_y[o] = min(lo_y[o], max(0, int(math.ceil(min_y))))
        hi_x[o] = max(hi_x[o], min(width - 1, int(math.floor(max_x))))
        hi_y[o] = max(hi_y[o], min(height - 1, int(math.floor(max_y))))

    if circle[4] > 0.0:  # crops end at the circle's box
        for o in range(n_objects):
            lo_x[o] = max(lo_x[o], int(math.ceil(circle[0] - circle[2] * circle[4])))
            hi_x[o] = min(hi_x[o], int(math.floor(circle[0] + circle[2] * circle[4])))
            lo_y[o] = max(lo_y[o], int(math.ceil(circle[1] - circle[3] * circle[4])))
            hi_y[o] = min(hi_y[o], int(math.floor(circle[1] + circle[3] * circle[4])))
    origin = np.zeros((n_objects, 4), dtype=np.int64)
    offsets = np.zeros(n_objects + 1, dtype=np.int64)
    for o in range(n_objects):
        w, h = hi_x[o] - lo_x[o] + 1, hi_y[o] - lo_y[o] + 1
        if w <= 0 or h <= 0:
            w, h = 0, 0
        origin[o, 0], origin[o, 1], origin[o, 2], origin[o, 3] = lo_x[o], lo_y[o], w, h
        offsets[o + 1] = offsets[o] + w * h
    crops = np.zeros(offsets[n_objects], dtype=np.bool_)

    for t in range(n_faces):
        if drawn[t]:
            o = owner[t]
            _fill_face(uv, faces[t, 0], faces[t, 1], faces[t, 2], origin[o, 0], origin[o, 1], origin[o, 2],
                       origin[o, 3], crops, offsets[o], circle)

    # Covered pixels and their box, per crop.
    tight = np.empty((n_objects, 4), dtype=np.int64)
    counts = np.zeros(n_objects, dtype=np.int64)
    for o in range(n_objects):
        x0, y0, w, h = origin[o, 0], origin[o, 1], origin[o, 2], origin[o, 3]
        x_min, y_min, x_max, y_max, count = w, h, -1, -1, 0
        for row in range(h):
            base = offsets[o] + row * w
            first, last = -1, -1
            for col in range(w):
                if crops[base + col]:
                    if first < 0:
                        first = col
                    last = col
                    count += 1
            if first >= 0:
                x_min, x_max = min(x_min, first), max(x_max, last)
                y_min = min(y_min, row)
                y_max = row
        tight[o, 0], tight[o, 1], tight[o, 2], tight[o, 3] = x0 + x_min, y0 + y_min, x0 + x_max, y0 + y_max
        counts[o] = count
    return crops, offsets, origin, tight, counts, truncated, cut
