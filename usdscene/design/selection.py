"""The smallest set of cameras giving every target >= K cameras: an integer program
(``scipy.optimize.milp``, HiGHS) bounded by a lazy-greedy set, with the gap to the best lower
bound. Works on sparse (camera, target) cover matrices; targets seen by the same cameras are
one row of the program. Pure.
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
        rows: rows of the integer program (targets with demand, merged when the same cameras
            cover them).
        columns: columns of the integer program (cameras left after dropping dominated ones).
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
    rows: int = 0
    columns: int = 0

    @property
    def gap(self) -> float:
        """Relative gap of the chosen set to the lower bound: (n - bound) / n."""
        n = len(self.chosen)
        return 0.0 if n == 0 else (n - self.lower_bound) / n


def _as_csr(cover):
    """``cover`` as a ``scipy.sparse.csr_matrix`` of bool."""
    from scipy.sparse import csr_matrix, issparse

    m = cover.tocsr() if issparse(cover) else csr_matrix(np.asarray(cover, dtype=bool))
    m = m.astype(bool)
    m.sum_duplicates()
    m.sort_indices()
    return m


def greedy_cover(cover, demand: np.ndarray, weights: np.ndarray | None = None) -> list[int]:
    """Lazy greedy multi-cover: repeatedly take the camera that meets the most remaining demand
    (ties: larger weight, then lower index), then drop cameras that became redundant.

    The gains of a camera only shrink as others are taken, so a camera's stale gain is an
    upper bound on its gain: a priority queue re-evaluates only the top (lazy greedy) and
    takes exactly the camera the plain greedy would. For K = 1 the greedy set is within a
    factor H(n) ≤ 1 + ln n of the smallest (n: the most targets a camera covers); with a
    budget of B cameras it covers at least (1 - 1/e) of what the best B cameras cover.

    Args:
        cover: (C, T) bool, dense or ``scipy.sparse``.
        demand: (T,) int cameras asked of each target (must be achievable).
        weights: (C,) tie-breaking scores (larger preferred).

    Returns:
        Chosen camera indices, ascending.
    """
    import heapq

    m = _as_csr(cover)
    n_c = m.shape[0]
    demand = np.asarray(demand, dtype=np.int64)
    remaining = demand.copy()
    w = np.zeros(n_c) if weights is None else np.asarray(weights, dtype=np.float64)
    ptr, ind = m.indptr, m.indices

    def gain(c: int) -> int:
        return int((remaining[ind[ptr[c]:ptr[c + 1]]] > 0).sum())

    heap = [(-gain(c), -w[c], c) for c in range(n_c)]
    heapq.heapify(heap)
    chosen: list[int] = []
    while heap and remaining.max(initial=0) > 0:
        g, neg_w, c = heapq.heappop(heap)
        fresh = -gain(c)
        if fresh != g:
            if fresh < 0:
                heapq.heappush(heap, (fresh, neg_w, c))
            continue
        if fresh == 0:
            break
        chosen.append(c)
        remaining[ind[ptr[c]:ptr[c + 1]]] -= 1
    # Reverse-delete: a camera whose targets keep their demand without it is redundant.
    counts = np.zeros(m.shape[1], dtype=np.int64)
    for c in chosen:
        counts[ind[ptr[c]:ptr[c + 1]]] += 1
    for c in sorted(chosen, key=lambda i: (w[i], -i)):
        mine = ind[ptr[c]:ptr[c + 1]]
        if np.all(counts[mine] - 1 >= demand[mine]):
            counts[mine] -= 1
            chosen.remove(c)
    return sorted(chosen)


def packing_bound(cover, demand: np.ndarray) -> int:
    """A lower bound on the cameras any cover needs: targets that share no covering camera
    need disjoint cameras, so the summed demand of such a set of targets bounds the answer.
    The set is built greedily, targets with the fewest covering cameras first (ties: lower
    index). Cheap (one pass over the sparse cover) where the LP relaxation may not finish.

    Args:
        cover: (C, T) bool, dense or sparse.
        demand: (T,) int cameras asked of each target.

    Returns:
        The bound (0 when no target has demand).
    """
    m = _as_csr(cover).T.tocsr()
    demand = np.asarray(demand, dtype=np.int64)
    able = np.diff(m.indptr)
    used = np.zeros(m.shape[1], dtype=bool)
    bound = 0
    for t in np.lexsort((np.arange(len(able)), able)):
        if demand[t] <= 0:
            continue
        cams = m.indices[m.indptr[t]:m.indptr[t + 1]]
        if not used[cams].any():
            used[cams] = True
            bound += int(demand[t])
    return bound


def merge_targets(cover) -> tuple[np.ndarray, np.ndarray]:
    """Targets covered by exactly the same cameras, merged.

    Args:
        cover: (C, T) sparse bool.

    Returns:
        ``(first, group)``: (G,) the first target of each group (ascending) and (T,) the group
        of every target.
    """
    m = _as_csr(cover).T.tocsr()
    m.sort_indices()
    keys = [m.indices[m.indptr[t]:m.indptr[t + 1]].tobytes() for t in range(m.shape[0])]
    seen: dict[bytes, int] = {}
    group = np.empty(len(keys), dtype=np.int64)
    first = []
    for t, key in enumerate(keys):
        g = seen.get(key)
        if g is None:
            g = seen[key] = len(first)
            first.append(t)
        group[t] = g
    return np.asarray(first, dtype=np.int64), group


def _useful_columns(cover, weights: np.ndarray, *, prune_dominated: bool, chunk: int = 2048) -> np.ndarray:
    """Indices of cameras that cover something, without dominated ones when asked.

    Args:
        cover: (C, R) sparse bool over the targets with demand.
        weights: (C,) preference among cameras with equal target sets.
        prune_dominated: drop a camera whose targets are a strict subset of another's, or
            equal to a better-weighted (then lower-index) camera's.
        chunk: cameras compared at once (bounds the memory of the sparse products).

    Returns:
        Ascending int indices.
    """
    m = _as_csr(cover)
    size = np.diff(m.indptr)
    useful = np.flatnonzero(size > 0)
    if not prune_dominated or not len(useful):
        return useful
    a = m[useful].astype(np.int32)
    at = a.T.tocsc()
    s, w = size[useful], weights[useful]
    order = np.arange(len(useful))
    keep = np.ones(len(useful), dtype=bool)
    for lo in range(0, len(useful), chunk):
        inter = (a[lo:lo + chunk] @ at).tocsr()  # exact integer counts of shared targets
        for i in range(inter.shape[0]):
            g = lo + i
            cols = inter.indices[inter.indptr[i]:inter.indptr[i + 1]]
            vals = inter.data[inter.indptr[i]:inter.indptr[i + 1]]
            sup = cols[(vals == s[g]) & (cols != g)]
            if not len(sup):
                continue
            better = (s[sup] > s[g]) | ((s[sup] == s[g]) & ((w[sup] > w[g]) | ((w[sup] == w[g]) & (order[sup] < g))))
            if better.any():
                keep[g] = False
    return useful[keep]


def select_cameras(cover, k: int = 1, *, time_limit_s: float = 60.0,
                   weights: np.ndarray | None = None) -> Selection:
    """The smallest camera set giving every target ``min(k, coverable)`` covering cameras.

    Integer program ``min Σ x_c  s.t.  Σ_c cover[c, t] x_c ≥ demand_t,  x ∈ {0, 1}`` solved by
    HiGHS through ``scipy.optimize.milp`` with ``time_limit_s``. Targets covered by the same
    cameras are one constraint. For K = 1 a camera whose targets are a subset of another's is
    dropped first (among equal sets the one with the larger weight stays), which shrinks the
    cabin's 2880 candidates to about 400 without changing the optimum; weights are not in the
    objective (a tie-breaking term makes HiGHS several times slower). The lazy-greedy set
    (:func:`greedy_cover`) is computed first; its size bounds the program (``Σ x_c ≤ greedy``,
    so HiGHS starts with that cutoff: scipy's interface takes no start solution) and it is
    returned when the MILP finds nothing better within the limit. The lower bound is the optimum
    when HiGHS proves it, else the highest of HiGHS's dual bound, the LP relaxation's (solved
    within a quarter of the limit) and :func:`packing_bound`; the gap refers to it.

    Args:
        cover: (C, T) bool, dense or ``scipy.sparse``, from :func:`coverage_matrix`.
        k: cameras each target needs.
        time_limit_s: MILP wall-time limit, seconds.
        weights: (C,) preference among equal-size sets (e.g. summed px/m), larger better.

    Returns:
        A :class:`Selection`.
    """
    import time

    from scipy.optimize import Bounds, LinearConstraint, linprog, milp
    from scipy.sparse import vstack

    started = time.perf_counter()
    m = _as_csr(cover)
    n_c, n_t = m.shape
    able = np.asarray(m.sum(axis=0)).ravel().astype(np.int64)
    demand = np.minimum(able, k).astype(np.int64)
    uncoverable = tuple(int(t) for t in np.flatnonzero(able == 0))
    short = tuple(int(t) for t in np.flatnonzero((able > 0) & (able < k)))
    w = np.zeros(n_c) if weights is None else np.asarray(weights, dtype=np.float64)
    greedy = greedy_cover(m, demand, w)
    rows = np.flatnonzero(demand > 0)
    if not len(rows):
        return Selection((), "greedy", True, 0, 0, demand, uncoverable, short, time.perf_counter() - started)
    sub = m[:, rows]
    first, _ = merge_targets(sub)
    rows = rows[first]
    useful = _useful_columns(m[:, rows], w, prune_dominated=k == 1)
    a = m[useful][:, rows].T.tocsr().astype(np.float64)
    cost = np.ones(len(useful))
    bound = 0
    chosen, method, optimal = greedy, "greedy", False
    cutoff = LinearConstraint(np.ones((1, len(useful))), lb=0, ub=len(greedy))
    res = milp(cost, integrality=np.ones(len(useful)), bounds=Bounds(0, 1),
               constraints=[LinearConstraint(a, lb=demand[rows], ub=np.inf), cutoff],
               options={"time_limit": float(time_limit_s), "disp": False})
    if res.x is not None:
        picked = sorted(int(useful[i]) for i in np.flatnonzero(res.x > 0.5))
        if len(picked) <= len(greedy):
            chosen, method = picked, "milp"
            optimal = res.status == 0
    else:
        log.warning("MILP found no set within %.0f s (%s); using the greedy set", time_limit_s, res.message)
    if optimal:
        bound = len(chosen)
    else:
        bound = max(bound, packing_bound(m, demand))
        if getattr(res, "mip_dual_bound", None) is not None and np.isfinite(res.mip_dual_bound):
            bound = max(bound, int(math.ceil(res.mip_dual_bound - 1e-6)))
        # The LP relaxation on its own, within a quarter of the limit again: HiGHS may stop
        # before its root relaxation gives a useful bound.
        lp = linprog(cost, A_ub=-a, b_ub=-demand[rows], bounds=(0, 1), method="highs",
                     options={"time_limit": max(1.0, time_limit_s / 4)})
        if lp.status == 0:
            bound = max(bound, int(math.ceil(lp.fun - 1e-6)))
    return Selection(tuple(chosen), method, optimal, min(bound, len(chosen)), len(greedy), demand, uncoverable,
                     short, time.perf_counter() - started, len(rows), len(useful))
