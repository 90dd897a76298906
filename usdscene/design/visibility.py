"""What each candidate camera sees of each target: the fraction of the target's points inside
the image, the fraction seen (inside and unoccluded), the pixel density and its class. Pure.

The work streams: targets near enough to a camera and inside a cone around its view are found
first (a k-d tree on target centres, then the angle of each target's bounding sphere to the
optical axis), only their points are projected, and the rays of many cameras go to Embree in
one batch. Only the (camera, target) pairs with a point in the image are kept, as flat arrays,
so memory grows with the pairs that matter, not with cameras × points.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from usdscene.document.model import Camera, Intrinsics
from usdscene.labels.projection import pixel_rays, project_points
from usdscene.design.occluders import Occluders
from usdscene.design.targets import Target
from usdscene.labels.pixel_density import DoriClass, dori_index, pixel_density

log = logging.getLogger(__name__)

# Rays handed to the ray caster at once (about 100 MB of working arrays).
RAY_BATCH = 1_000_000
# Bytes kept per (camera, target) pair: two int32 indices, three float64 values, one int8.
PAIR_BYTES = 33


@dataclass(frozen=True)
class Visibility:
    """Visibility of the targets from the cameras, as the (camera, target) pairs where at least
    one point of the target lies inside the camera's image (every other pair sees nothing).

    Attributes:
        cameras: C, the number of cameras.
        targets: T, the number of targets.
        camera: (P,) int32 camera index of each pair (pairs sorted by camera, then target).
        target: (P,) int32 target index of each pair.
        in_image_fraction: (P,) float64 fraction of the target's points inside the image.
        visible_fraction: (P,) float64 fraction inside the image and unoccluded.
        px_per_m_pair: (P,) float64 median pixel density over the visible points (0 where none).
        dori_pair: (P,) int8 index of the DORI class reached (-1 = none or not visible).
        point_visible: per pair, (N_t,) bool of the target's points (only when asked for).
    """

    cameras: int
    targets: int
    camera: np.ndarray
    target: np.ndarray
    in_image_fraction: np.ndarray
    visible_fraction: np.ndarray
    px_per_m_pair: np.ndarray
    dori_pair: np.ndarray
    point_visible: tuple[np.ndarray, ...] = field(repr=False, default=())

    @classmethod
    def from_dense(cls, in_image: np.ndarray, visible: np.ndarray, px_per_m: np.ndarray,
                   dori: np.ndarray) -> "Visibility":
        """From (C, T) arrays (pairs where ``in_image`` > 0 or ``visible`` > 0)."""
        in_image = np.asarray(in_image, dtype=np.float64)
        c, t = np.nonzero((in_image > 0) | (np.asarray(visible) > 0))
        return cls(in_image.shape[0], in_image.shape[1], c.astype(np.int32), t.astype(np.int32), in_image[c, t],
                   np.asarray(visible, dtype=np.float64)[c, t], np.asarray(px_per_m, dtype=np.float64)[c, t],
                   np.asarray(dori)[c, t].astype(np.int8))

    def dense(self, name: str, cameras: Sequence[int] | None = None) -> np.ndarray:
        """(len(cameras), T) array of one quantity (``in_image``, ``visible``, ``px_per_m`` or
        ``dori``) for some cameras (all when None); 0 (dori: -1) where the pair sees nothing.
        Meant for few cameras: it is dense."""
        values = {"in_image": self.in_image_fraction, "visible": self.visible_fraction,
                  "px_per_m": self.px_per_m_pair, "dori": self.dori_pair}[name]
        rows = np.arange(self.cameras) if cameras is None else np.asarray(cameras, dtype=np.int64)
        out = np.full((len(rows), self.targets), -1 if name == "dori" else 0.0,
                      dtype=np.int64 if name == "dori" else np.float64)
        where = np.full(self.cameras, -1, dtype=np.int64)
        where[rows] = np.arange(len(rows))
        keep = where[self.camera] >= 0
        out[where[self.camera[keep]], self.target[keep]] = values[keep]
        return out

    @property
    def in_image(self) -> np.ndarray:
        """(C, T) dense fraction of points inside the image (small problems only)."""
        return self.dense("in_image")

    @property
    def visible(self) -> np.ndarray:
        """(C, T) dense visible fraction (small problems only)."""
        return self.dense("visible")

    @property
    def px_per_m(self) -> np.ndarray:
        """(C, T) dense median px/m (small problems only)."""
        return self.dense("px_per_m")

    @property
    def dori(self) -> np.ndarray:
        """(C, T) dense DORI index (small problems only)."""
        return self.dense("dori")

    def pair_index(self, camera: int, target: int) -> int:
        """Index of the (camera, target) pair, -1 when the camera sees none of the target."""
        lo, hi = np.searchsorted(self.camera, [camera, camera + 1])
        i = lo + int(np.searchsorted(self.target[lo:hi], target))
        return i if i < hi and self.target[i] == target else -1

    def per_target_max(self, name: str) -> np.ndarray:
        """(T,) the largest value of a quantity over all cameras (0; dori: -1 where none)."""
        values = {"in_image": self.in_image_fraction, "visible": self.visible_fraction,
                  "px_per_m": self.px_per_m_pair, "dori": self.dori_pair}[name]
        out = np.full(self.targets, -1 if name == "dori" else 0.0, dtype=np.int64 if name == "dori" else np.float64)
        np.maximum.at(out, self.target, values)
        return out


def pairs_in_range(cameras: Sequence[Camera], targets: Sequence[Target], *, max_range_m: float = 30.0) -> int:
    """An upper bound on the (camera, target) pairs :func:`evaluate_visibility` keeps: the
    targets whose centre lies within ``max_range_m`` plus the largest target radius of each
    camera, counted with a k-d tree before any point is projected."""
    from scipy.spatial import cKDTree

    if not len(cameras) or not len(targets):
        return 0
    centres = np.array([t.points_m.mean(axis=0) for t in targets])
    radius = max(float(np.linalg.norm(t.points_m - c, axis=1).max(initial=0.0)) for t, c in zip(targets, centres))
    origins = np.array([c.pose.translation_m for c in cameras], dtype=np.float64)
    return int(cKDTree(centres).query_ball_point(origins, max_range_m + radius, return_length=True).sum())


def view_half_angle_rad(intrinsics: Intrinsics) -> float:
    """The largest angle between the optical axis and the ray of any pixel on the image
    border, radians (π where some border pixel has no ray, e.g. outside a fisheye's circle:
    the field is then bounded by the lens, not the image)."""
    from usdscene.labels.projection import _border_pixels

    rays, ok = pixel_rays(intrinsics, _border_pixels(intrinsics.width_px, intrinsics.height_px))
    if not ok.all():
        return math.pi
    return float(np.arccos(np.clip(rays[:, 2] / np.linalg.norm(rays, axis=1), -1.0, 1.0)).max())


def _pair_medians(pair: np.ndarray, values: np.ndarray, pairs: int) -> np.ndarray:
    """(pairs,) median of ``values`` grouped by ``pair`` (0 for groups without values), as
    ``np.median`` computes it (the mean of the two middle values of an even group)."""
    out = np.zeros(pairs)
    if not len(pair):
        return out
    order = np.lexsort((values, pair))
    p, v = pair[order], values[order]
    counts = np.bincount(p, minlength=pairs)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    has = counts > 0
    lo = starts[has] + (counts[has] - 1) // 2
    hi = starts[has] + counts[has] // 2
    out[has] = (v[lo] + v[hi]) / 2
    return out


def evaluate_visibility(cameras: Sequence[Camera], targets: Sequence[Target], occluders: Occluders,
                        dori_table: Sequence[DoriClass], *, max_range_m: float = 30.0, keep_points: bool = False,
                        progress: Callable[[int, int], None] | None = None,
                        ray_batch: int = RAY_BATCH) -> Visibility:
    """Visibility of every target from every camera by ray casting.

    A point is *visible* when it projects inside the image rectangle through the camera's exact
    lens model (:func:`usdscene.labels.projection.project_points`) and no triangle lies between the
    camera centre and the point (stopping :data:`RAY_MARGIN_M` short of it). Targets whose
    bounding sphere lies beyond ``max_range_m`` or outside the cone of
    :func:`view_half_angle_rad` around the optical axis are skipped before any point is
    projected; neither test drops a point that could be inside the image within range.

    Args:
        cameras: C cameras.
        targets: T targets.
        occluders: the scene's triangles.
        dori_table: ascending image-detail classes.
        max_range_m: points farther than this from a camera count as outside its image.
        keep_points: keep each pair's per-point visibility (for verification; few cameras).
        progress: called with (cameras done, C) after each batch of rays.
        ray_batch: rays per call of the ray caster.

    Returns:
        A :class:`Visibility`.
    """
    from scipy.spatial import cKDTree

    n_c, n_t = len(cameras), len(targets)
    counts = np.array([len(t.points_m) for t in targets], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    all_pts = np.concatenate([t.points_m for t in targets]) if n_t else np.zeros((0, 3))
    owner = np.repeat(np.arange(n_t), counts)
    centres = np.zeros((n_t, 3))
    for axis in range(3):
        centres[:, axis] = np.bincount(owner, weights=all_pts[:, axis], minlength=n_t) / np.maximum(counts, 1)
    radius = np.zeros(n_t)
    if n_t:
        np.maximum.at(radius, owner, np.linalg.norm(all_pts - centres[owner], axis=1))
    tree = cKDTree(centres) if n_t else None
    reach = max_range_m + float(radius.max(initial=0.0))
    half_angles: dict[Intrinsics, float] = {}
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("camera", "target", "in_image", "visible", "px")}
    point_parts: list[np.ndarray] = []
    # The batch waiting for the ray caster: per camera, its index, its in-image point indices
    # (ascending, so each target's points are contiguous), each point's pair (0-based within
    # the camera) and the target of each of its pairs.
    pending: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]] = []
    pending_rays = 0

    def flush(done: int) -> None:
        nonlocal pending, pending_rays
        if pending:
            sizes = np.array([len(e[1]) for e in pending])
            n_pairs = np.array([len(e[3]) for e in pending])
            base = np.concatenate([[0], np.cumsum(n_pairs)[:-1]])
            point = np.concatenate([e[1] for e in pending])
            local = np.concatenate([e[2] + b for e, b in zip(pending, base)])
            tgt = np.concatenate([e[3] for e in pending])
            origins = np.repeat(np.array([cameras[e[0]].pose.translation_m for e in pending], dtype=np.float64),
                                sizes, axis=0)
            seen = ~occluders.blocked(origins, all_pts[point])
            total = int(n_pairs.sum())
            density = np.zeros(len(point))
            for e, s0, s1 in zip(pending, np.cumsum(sizes) - sizes, np.cumsum(sizes)):
                sel = s0 + np.flatnonzero(seen[s0:s1])
                if len(sel):
                    density[sel] = pixel_density(cameras[e[0]], all_pts[point[sel]])
            parts["camera"].append(np.repeat([e[0] for e in pending], n_pairs).astype(np.int32))
            parts["target"].append(tgt.astype(np.int32))
            parts["in_image"].append(np.bincount(local, minlength=total) / counts[tgt])
            parts["visible"].append(np.bincount(local[seen], minlength=total) / counts[tgt])
            parts["px"].append(_pair_medians(local[seen], density[seen], total))
            if keep_points:
                bounds = np.searchsorted(local, np.arange(total + 1))
                for j in range(total):
                    flags = np.zeros(counts[tgt[j]], dtype=bool)
                    a, b = bounds[j], bounds[j + 1]
                    flags[point[a:b][seen[a:b]] - offsets[tgt[j]]] = True
                    point_parts.append(flags)
            pending, pending_rays = [], 0
        if progress is not None:
            progress(done, n_c)

    for c, camera in enumerate(cameras):
        intr = camera.intrinsics
        centre = np.asarray(camera.pose.translation_m, dtype=np.float64)
        near = np.asarray(tree.query_ball_point(centre, reach), dtype=np.int64) if tree is not None else \
            np.zeros(0, np.int64)
        if len(near):
            if intr not in half_angles:
                half_angles[intr] = view_half_angle_rad(intr)
            half = half_angles[intr]
            if half < math.pi:
                v = centres[near] - centre
                d = np.linalg.norm(v, axis=1)
                axis = np.asarray(camera.pose.rotation, dtype=np.float64)[:, 2]
                angle = np.arccos(np.clip((v @ axis) / np.maximum(d, 1e-12), -1.0, 1.0))
                slack = np.arcsin(np.clip(radius[near] / np.maximum(d, 1e-12), 0.0, 1.0))
                near = near[(d <= radius[near]) | (angle <= half + slack + 1e-6)]
            near.sort()
        if len(near):
            # The point indices of the near targets, ascending: each target's run of points.
            n_pts = counts[near]
            idx = np.repeat(offsets[near] - np.cumsum(n_pts) + n_pts, n_pts) + np.arange(int(n_pts.sum()))
            idx = idx[np.linalg.norm(all_pts[idx] - centre, axis=1) <= max_range_m]
            uv, ok = project_points(camera, all_pts[idx])
            inside = ok & (uv[:, 0] >= -0.5) & (uv[:, 0] <= intr.width_px - 0.5) & \
                (uv[:, 1] >= -0.5) & (uv[:, 1] <= intr.height_px - 0.5)
            idx = idx[inside]
            if len(idx):
                owner = np.searchsorted(offsets, idx, side="right") - 1
                tp, local = np.unique(owner, return_inverse=True)
                pending.append((c, idx, local.astype(np.int64).ravel(), tp))
                pending_rays += len(idx)
        if pending_rays >= ray_batch:
            flush(c + 1)
    flush(n_c)
    cat = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in parts.items()}
    visible = cat["visible"].astype(np.float64)
    px = cat["px"].astype(np.float64)
    dori = np.where(visible > 0, dori_index(px, dori_table), -1).astype(np.int8)
    return Visibility(n_c, n_t, cat["camera"].astype(np.int32), cat["target"].astype(np.int32),
                      cat["in_image"].astype(np.float64), visible, px, dori, tuple(point_parts))


def covering_pairs(visibility: Visibility, *, min_visible: float, min_dori: int) -> np.ndarray:
    """(P,) bool: the pair's camera covers its target (visible fraction ≥ ``min_visible`` and
    DORI index ≥ ``min_dori``)."""
    v = visibility
    return (v.visible_fraction >= min_visible - 1e-12) & (v.dori_pair >= min_dori) & (v.visible_fraction > 0)


def coverage_matrix(visibility: Visibility, *, min_visible: float, min_dori: int):
    """(C, T) ``scipy.sparse.csr_matrix`` of bool: camera c covers target t (visible fraction
    ≥ ``min_visible`` and DORI index ≥ ``min_dori``)."""
    from scipy.sparse import csr_matrix

    v = visibility
    ok = covering_pairs(v, min_visible=min_visible, min_dori=min_dori)
    return csr_matrix((np.ones(int(ok.sum()), dtype=bool), (v.camera[ok], v.target[ok])),
                      shape=(v.cameras, v.targets))


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
    best_visible = visibility.per_target_max("visible")
    best_in_image = visibility.per_target_max("in_image")
    best_dori = visibility.per_target_max("dori")
    for t in targets:
        best = int(best_dori[t]) if candidates else -1
        if not candidates:
            reason = "no mount"
        elif float(best_in_image[t]) == 0.0:
            reason = "out of range"
        elif float(best_visible[t]) < min_visible - 1e-12:
            reason = "occluded"
        else:
            reason = "too few pixels"
        out.append(Uncovered(int(t), reason, best))
    return out
