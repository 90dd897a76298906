"""The top-down plan picture: the scene's triangles from above, targets coloured by how many
chosen cameras see them, and each camera's field of view as a wedge. Pure (numpy, OpenCV).
"""

from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from usdscene.document.model import Camera, Intrinsics
from usdscene.design.occluders import Occluders
from usdscene.design.targets import Target
from usdscene.labels.pixel_density import DoriClass

log = logging.getLogger(__name__)


# BGR colours of coverage counts 0, 1, 2, ≥3 and of the camera wedges.
_COUNT_COLOURS = ((60, 60, 230), (60, 200, 250), (90, 200, 90), (200, 150, 60))
_WEDGE_COLOUR = (180, 90, 200)


def _border_rays(intrinsics: Intrinsics, per_side: int = 12) -> np.ndarray:
    from usdscene.labels.projection import pixel_rays

    w, h = intrinsics.width_px, intrinsics.height_px
    s = np.linspace(0.0, 1.0, per_side, endpoint=False)
    uv = np.concatenate([np.stack([s * (w - 1), np.zeros_like(s)], 1),
                         np.stack([np.full_like(s, w - 1), s * (h - 1)], 1),
                         np.stack([(1 - s) * (w - 1), np.full_like(s, h - 1)], 1),
                         np.stack([np.zeros_like(s), (1 - s) * (h - 1)], 1)])
    rays, ok = pixel_rays(intrinsics, uv)
    return rays[ok]


def plan_picture(triangles_m: np.ndarray, targets: Sequence[Target], cameras: Sequence[Camera],
                 counts: np.ndarray, best_dori: np.ndarray, dori_table: Sequence[DoriClass],
                 occluders: Occluders, *, max_width_px: int = 1600, max_height_px: int = 900,
                 title: str = "") -> np.ndarray:
    """Top-down plan, one panel per target region (``on``, ``below``, ...; targets of different
    regions overlap from above): the scene shaded by height, each target's footprint filled by
    how many chosen cameras cover it and dotted by its best DORI class (darker = finer), and the
    cameras with the outline of their view (where their image border rays first hit the scene).

    Args:
        triangles_m: (T, 3, 3) world triangles of the scene.
        targets: the targets.
        cameras: the chosen cameras.
        counts: (len(targets),) int covering cameras per target.
        best_dori: (len(targets),) int best DORI index per target (-1 = none).
        dori_table: ascending DORI classes (for the legend).
        occluders: for the view outlines.
        max_width_px, max_height_px: size limit of one panel.
        title: text in the legend rows.

    Returns:
        (H, W, 3) uint8 BGR image (x of the world to the right, y of the world up).
    """
    import cv2

    tris = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3, 3)
    pts = [tris.reshape(-1, 3)] + [t.points_m for t in targets] + [c.pose.translation_m[None] for c in cameras]
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0) - 0.3, allp.max(axis=0) + 0.3
    scale = min(max_width_px / (hi[0] - lo[0]), max_height_px / (hi[1] - lo[1]))
    width = int(math.ceil((hi[0] - lo[0]) * scale))
    height = int(math.ceil((hi[1] - lo[1]) * scale))

    def to_px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([(xy[:, 0] - lo[0]) * scale, (hi[1] - xy[:, 1]) * scale], 1)

    def shift(xy: np.ndarray) -> np.ndarray:
        return np.round(to_px(xy) * 16).astype(np.int32)  # 4 fractional bits for cv2

    base = np.full((height, width, 3), 255, np.uint8)
    if len(tris):
        # Painter's order by height: what is seen from above is drawn last.
        top = tris[:, :, 2].max(axis=1)
        zlo, zhi = float(top.min()), float(top.max())
        levels = np.clip(((top - zlo) / max(zhi - zlo, 1e-9) * 10).astype(int), 0, 9)
        for level in range(10):
            sel = tris[levels == level]
            if len(sel):
                shade = int(235 - 10 * level)
                polys = shift(sel[:, :, :2].reshape(-1, 2)).reshape(-1, 3, 2)
                cv2.fillPoly(base, list(polys), (shade, shade, shade), lineType=cv2.LINE_8, shift=4)
    outlines = []
    for camera in cameras:
        rays = _border_rays(camera.intrinsics)
        if not len(rays):
            continue
        world = rays @ camera.pose.rotation.T
        origin = camera.pose.translation_m
        dist = occluders.first_hit(np.tile(origin, (len(world), 1)), world, 30.0)
        dist = np.where(np.isfinite(dist), dist, 5.0)
        outlines.append(shift((origin + world * dist[:, None])[:, :2]))
    n_classes = max(len(dori_table), 1)
    regions = list(dict.fromkeys(t.region for t in targets)) or [""]
    panels = []
    for region in regions:
        image = base.copy()
        cv2.polylines(image, outlines, True, _WEDGE_COLOUR, 1, cv2.LINE_AA, shift=4)
        for t, target in enumerate(targets):
            if target.region != region:
                continue
            hull = np.round(cv2.convexHull(to_px(target.points_m[:, :2]).astype(np.float32)).reshape(-1, 2) * 16)
            hull = hull.astype(np.int32)
            cv2.fillPoly(image, [hull], _COUNT_COLOURS[min(int(counts[t]), 3)], lineType=cv2.LINE_AA, shift=4)
            cv2.polylines(image, [hull], True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)
            c = to_px(target.centre_m[None, :2])[0]
            d = int(best_dori[t])
            grey = 255 - int(255 * (d + 1) / n_classes) if d >= 0 else 255
            cv2.circle(image, (int(round(c[0])), int(round(c[1]))), max(2, int(scale * 0.04)),
                       (grey, grey, grey), -1, cv2.LINE_AA)
        for camera in cameras:
            p = to_px(camera.pose.translation_m[None, :2])[0]
            forward = camera.pose.rotation[:, 2]
            centre = (int(round(p[0])), int(round(p[1])))
            cv2.circle(image, centre, max(3, int(scale * 0.07)), (120, 30, 150), -1, cv2.LINE_AA)
            if np.hypot(forward[0], forward[1]) > 0.1:
                tip = to_px((camera.pose.translation_m[:2] + 0.35 * forward[:2] / np.hypot(*forward[:2]))[None])[0]
                cv2.line(image, centre, (int(round(tip[0])), int(round(tip[1]))), (120, 30, 150), 2, cv2.LINE_AA)
        label = np.full((22, width, 3), 255, np.uint8)
        cv2.putText(label, f"targets: {region}", (8, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        panels += [label, image]
    # A long class table pushes the camera key to a third row.
    key_width = 26 * len(dori_table) + 9 * sum(len(c.name) for c in dori_table) + 360 + 300
    legend = np.full((56 if key_width <= width else 76, width, 3), 255, np.uint8)
    y, x = 20, 8
    for i, text in enumerate(("0 cameras", "1", "2", ">=3")):
        cv2.rectangle(legend, (x, y - 12), (x + 16, y + 2), _COUNT_COLOURS[i], -1)
        cv2.putText(legend, text, (x + 20, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        x += 40 + 9 * len(text)
    x += 10
    for i, dori in enumerate(dori_table):
        grey = 255 - int(255 * (i + 1) / n_classes)
        cv2.circle(legend, (x + 6, y - 5), 6, (grey, grey, grey), -1, cv2.LINE_AA)
        cv2.circle(legend, (x + 6, y - 5), 6, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(legend, dori.name, (x + 16, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        x += 26 + 9 * len(dori.name)
    key_at = (x + 10, y) if key_width <= width else (8, y + 44)
    cv2.putText(legend, "camera (dot, aim) and view outline", key_at, cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                _WEDGE_COLOUR, 1, cv2.LINE_AA)
    if title:
        cv2.putText(legend, title, (8, y + 24), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate(panels + [legend], axis=0)
