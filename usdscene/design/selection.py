"""The smallest set of cameras giving every target >= K cameras: an integer program
(``scipy.optimize.milp``, HiGHS) with a greedy fallback and its gap to the LP bound. Pure.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np


log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Selection:
    """The chosen camera set.

    Attributes:
        chosen: indices of the chosen cameras, ascending.
        method: ``milp`` (optimal, or the best found within the time limit) or ``greedy``.
        optimal: the MILP proved optimality.
        lower_bound: a lower bound on the smallest set (LP relaxation, rounded up; or the
            MILP's dual bound when it is higher).
        greedy_size: size of the greedy set (always computed, for comparison).
        demand: (T,) cameras asked of each target: min(K, cameras that can cover it).
        uncoverable: indices of targets no candidate covers at all.
        short: indices of targets with fewer than K covering candidates (but some).
        seconds: solver wall time.
    """

    chosen: tuple[int, ...]
    method: str
    optimal: bool
    lower_bound: int
    greedy_size: int
    demand: np.ndarray
    uncoverable: tuple[int, ...]
    short: tuple[int, ...]
    seconds: float = 0.0

    @property
    def gap(self) -> float:
        """Relative gap of the chosen set to the lower bound: (n - bound) / n."""
        n = len(self.chosen)
        return 0.0 if n == 0 else (n - self.lower_bound) / n


def greedy_cover(cover: np.ndarray, demand: np.ndarray, weights: np.ndarray | None = None) -> list[int]:
    """Greedy multi-cover: repeatedly take the camera that meets the most remaining demand
    (ties: larger weight, then lower index). Then drop cameras that became redundant.

    Args:
        cover: (C, T) bool.
        demand: (T,) int cameras asked of each target (must be achievable).
        weights: (C,) tie-breaking scores (larger preferred).

    Returns:
        Chosen camera indices, ascending.
    """
    cover = np.asarray(cover, dtype=bool)
    remaining = np.asarray(demand, dtype=np.int64).copy()
    w = np.zeros(len(cover)) if weights is None else np.asarray(weights, dtype=np.float64)
    chosen: list[int] = []
    available = np.ones(len(cover), dtype=bool)
    while remaining.max(initial=0) > 0:
        gain = (cover & (remaining > 0)).sum(axis=1).astype(np.float64)
        gain[~available] = -1
        best = np.flatnonzero(gain == gain.max())
        c = int(best[np.argmax(w[best])])
        if gain[c] <= 0:
            break
        chosen.append(c)
        available[c] = False
        remaining -= cover[c]
    # Reverse-delete: a camera whose targets keep their demand without it is redundant.
    counts = cover[chosen].sum(axis=0) if chosen else np.zeros(cover.shape[1], int)
    for c in sorted(chosen, key=lambda i: (w[i], -i)):
        if np.all(counts - cover[c] >= demand):
            counts = counts - cover[c]
            chosen.remove(c)
    return sorted(chosen)


def _useful_columns(cover: np.ndarray, weights: np.ndarray, *, prune_dominated: bool) -> np.ndarray:
    """Indices of cameras that cover something, without dominated ones when asked.

    Args:
        cover: (C, R) bool over the targets with demand.
        weights: (C,) preference among cameras with equal target sets.
        prune_dominated: drop a camera whose targets are a strict subset of another's, or
            equal to a better-weighted (then lower-index) camera's.

    Returns:
        Ascending int indices.
    """
    size = cover.sum(axis=1)
    useful = np.flatnonzero(size > 0)
    if not prune_dominated or not len(useful):
        return useful
    a = cover[useful].astype(np.float32)
    inter = a @ a.T  # exact: counts far below 2**24
    s, w = size[useful], weights[useful]
    order = np.arange(len(useful))
    keep = []
    for i in range(len(useful)):
        subset_of = inter[i] == s[i]
        subset_of[i] = False
        better = (s > s[i]) | ((s == s[i]) & ((w > w[i]) | ((w == w[i]) & (order < i))))
        if not (subset_of & better).any():
            keep.append(useful[i])
    return np.asarray(keep, dtype=np.int64)


def select_cameras(cover: np.ndarray, k: int = 1, *, time_limit_s: float = 60.0,
                   weights: np.ndarray | None = None) -> Selection:
    """The smallest camera set giving every target ``min(k, coverable)`` covering cameras.

    Integer program ``min Σ x_c  s.t.  Σ_c cover[c, t] x_c ≥ demand_t,  x ∈ {0, 1}`` solved by
    HiGHS through ``scipy.optimize.milp`` with ``time_limit_s``. For K = 1 a camera whose
    targets are a subset of another's is dropped first (among equal sets the one with the
    larger weight stays), which shrinks the cabin's 2880 candidates to about 400 without
    changing the optimum; weights are not in the objective (a tie-breaking term makes HiGHS
    several times slower). The greedy set is computed too and returned when the MILP finds
    nothing better (or fails); the LP relaxation gives the lower bound that the reported gap
    refers to.

    Args:
        cover: (C, T) bool from :func:`coverage_matrix`.
        k: cameras each target needs.
        time_limit_s: MILP wall-time limit, seconds.
        weights: (C,) preference among equal-size sets (e.g. summed px/m), larger better.

    Returns:
        A :class:`Selection`.
    """
    import time

    from scipy.optimize import Bounds, LinearConstraint, linprog, milp

    started = time.perf_counter()
    cover = np.asarray(cover, dtype=bool)
    n_c, n_t = cover.shape
    able = cover.sum(axis=0)
    demand = np.minimum(able, k).astype(np.int64)
    uncoverable = tuple(int(t) for t in np.flatnonzero(able == 0))
    short = tuple(int(t) for t in np.flatnonzero((able > 0) & (able < k)))
    w = np.zeros(n_c) if weights is None else np.asarray(weights, dtype=np.float64)
    greedy = greedy_cover(cover, demand, w)
    rows = np.flatnonzero(demand > 0)
    if not len(rows):
        return Selection((), "greedy", True, 0, 0, demand, uncoverable, short, time.perf_counter() - started)
    useful = _useful_columns(cover[:, rows], w, prune_dominated=k == 1)
    a = cover[np.ix_(useful, rows)].T.astype(np.float64)
    cost = np.ones(len(useful))
    lp = linprog(cost, A_ub=-a, b_ub=-demand[rows], bounds=(0, 1), method="highs")
    bound = int(math.ceil(lp.fun - 1e-6)) if lp.status == 0 else 0
    chosen, method, optimal = greedy, "greedy", False
    res = milp(cost, integrality=np.ones(len(useful)), bounds=Bounds(0, 1),
               constraints=LinearConstraint(a, lb=demand[rows], ub=np.inf),
               options={"time_limit": float(time_limit_s), "disp": False})
    if res.x is not None:
        picked = sorted(int(useful[i]) for i in np.flatnonzero(res.x > 0.5))
        if len(picked) <= len(greedy):
            chosen, method = picked, "milp"
            optimal = res.status == 0
            if optimal:
                bound = max(bound, len(picked))
            elif getattr(res, "mip_dual_bound", None) is not None and np.isfinite(res.mip_dual_bound):
                bound = max(bound, int(math.ceil(res.mip_dual_bound - 1e-6)))
    else:
        log.warning("MILP found no solution within %.0f s (%s); using the greedy set", time_limit_s, res.message)
    return Selection(tuple(chosen), method, optimal, bound, len(greedy), demand, uncoverable, short,
                     time.perf_counter() - started)
