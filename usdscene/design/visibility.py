"""What each candidate camera sees of each target: the fraction of the target's points inside
the image, the fraction seen (inside and unoccluded), the pixel density and its class. Pure.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from usdscene.document.model import Camera
from usdscene.labels.projection import project_points
from usdscene.design.occluders import Occluders
from usdscene.design.targets import Target
from usdscene.labels.pixel_density import DoriClass, dori_index, pixel_density

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Visibility:
    """Visibility of every target from every camera.

    Attributes:
        in_image: (C, T) float64 fraction of each target's points inside the image.
        visible: (C, T) float64 fraction of each target's points inside the image and
            unoccluded.
        px_per_m: (C, T) float64 median pixel density over the visible points (0 where none).
        dori: (C, T) int index of the best DORI class reached (-1 = none or not visible).
        point_visible: per target, (C, N_t) bool of its points (for verification).
    """

    in_image: np.ndarray
    visible: np.ndarray
    px_per_m: np.ndarray
    dori: np.ndarray
    point_visible: tuple[np.ndarray, ...] = field(repr=False, default=())


def evaluate_visibility(cameras: Sequence[Camera], targets: Sequence[Target], occluders: Occluders,
                        dori_table: Sequence[DoriClass], *, max_range_m: float = 30.0) -> Visibility:
    """Visibility of every target from every camera by ray casting.

    A point is *visible* when it projects inside the image rectangle through the camera's exact
    lens model (:func:`usdscene.labels.projection.project_points`) and no triangle lies between the
    camera centre and the point (stopping :data:`RAY_MARGIN_M` short of it).

    Args:
        cameras: C cameras.
        targets: T targets.
        occluders: the scene's triangles.
        dori_table: ascending image-detail classes.
        max_range_m: points farther than this from a camera count as outside its image.

    Returns:
        A :class:`Visibility`.
    """
    n_c, n_t = len(cameras), len(targets)
    counts = np.array([len(t.points_m) for t in targets], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    all_pts = np.concatenate([t.points_m for t in targets]) if n_t else np.zeros((0, 3))
    owner = np.repeat(np.arange(n_t), counts)
    in_image = np.zeros((n_c, n_t))
    visible = np.zeros((n_c, n_t))
    density = np.zeros((n_c, n_t))
    per_point = np.zeros((n_c, len(all_pts)), dtype=bool)
    for c, camera in enumerate(cameras):
        intr = camera.intrinsics
        centre = camera.pose.translation_m
        near = np.linalg.norm(all_pts - centre, axis=1) <= max_range_m
        idx = np.flatnonzero(near)
        uv, ok = project_points(camera, all_pts[idx])
        inside = ok & (uv[:, 0] >= -0.5) & (uv[:, 0] <= intr.width_px - 0.5) & \
            (uv[:, 1] >= -0.5) & (uv[:, 1] <= intr.height_px - 0.5)
        idx = idx[inside]
        if not len(idx):
            continue
        seen = ~occluders.blocked(centre, all_pts[idx])
        in_image[c] = np.bincount(owner[idx], minlength=n_t) / counts
        vis_idx = idx[seen]
        per_point[c, vis_idx] = True
        visible[c] = np.bincount(owner[vis_idx], minlength=n_t) / counts
        if len(vis_idx):
            d = pixel_density(camera, all_pts[vis_idx])
            for t in np.unique(owner[vis_idx]):
                density[c, t] = float(np.median(d[owner[vis_idx] == t]))
    dori = np.where(visible > 0, dori_index(density, dori_table), -1)
    return Visibility(in_image=in_image, visible=visible, px_per_m=density, dori=dori,
                      point_visible=tuple(per_point[:, offsets[t]:offsets[t + 1]] for t in range(n_t)))


def coverage_matrix(visibility: Visibility, *, min_visible: float, min_dori: int) -> np.ndarray:
    """(C, T) bool: camera c covers target t (visible fraction ≥ ``min_visible`` and DORI
    index ≥ ``min_dori``)."""
    return (visibility.visible >= min_visible - 1e-12) & (visibility.dori >= min_dori) & (visibility.visible > 0)


# Reasons a target has no covering candidate, in the order they are tested.
UNCOVERED_REASONS = ("no mount", "out of range", "occluded", "too few pixels")


@dataclass(frozen=True)
class Uncovered:
    """Why no candidate covers one target.

    Attributes:
        target: target index.
        reason: one of :data:`UNCOVERED_REASONS`: no candidate camera at all; no candidate has
            any of its points in its image within range; none sees the required fraction of
            them unoccluded; or those that do see it below the required class.
        best_dori: index of the best class any candidate reaches on it (-1: none or below the
            lowest class).
    """

    target: int
    reason: str
    best_dori: int


def why_uncovered(visibility: Visibility, targets: Sequence[int], *, min_visible: float,
                  candidates: int) -> list[Uncovered]:
    """The reason each of ``targets`` (indices of targets no candidate covers) is uncovered.

    Args:
        visibility: of every candidate.
        targets: target indices.
        min_visible: the fraction a camera must see.
        candidates: number of candidate cameras.

    Returns:
        One :class:`Uncovered` per target, in the given order.
    """
    out = []
    for t in targets:
        seen = visibility.visible[:, t] if candidates else np.zeros(0)
        best = int(visibility.dori[:, t].max(initial=-1)) if candidates else -1
        if not candidates:
            reason = "no mount"
        elif float(visibility.in_image[:, t].max(initial=0.0)) == 0.0:
            reason = "out of range"
        elif float(seen.max(initial=0.0)) < min_visible - 1e-12:
            reason = "occluded"
        else:
            reason = "too few pixels"
        out.append(Uncovered(int(t), reason, best))
    return out
