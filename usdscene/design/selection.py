"""The smallest set of cameras giving every target >= K cameras: an integer program
(HiGHS through ``highspy``) started from a lazy-greedy set, with the gap to the best lower
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
        zones: programs the floor was planned in (1: the whole floor at once).
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
    zones: int = 1

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
    return drop_redundant(m, chosen, demand, w)


def drop_redundant(cover, chosen: list[int], demand: np.ndarray, weights: np.ndarray) -> list[int]:
    """Reverse-delete: drop, smallest weight first (ties: higher index), every camera whose
    targets keep their demand without it.

    Args:
        cover: (C, T) bool, dense or sparse.
        chosen: a camera set meeting ``demand``.
        demand: (T,) int.
        weights: (C,) preference (larger kept first).

    Returns:
        The cameras kept, ascending.
    """
    m = _as_csr(cover)
    ptr, ind = m.indptr, m.indices
    chosen = list(chosen)
    counts = np.zeros(m.shape[1], dtype=np.int64)
    for c in chosen:
        counts[ind[ptr[c]:ptr[c + 1]]] += 1
    for c in sorted(chosen, key=lambda i: (weights[i], -i)):
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


def lagrangian_bound(a, demand: np.ndarray, upper: int, *, iterations: int = 400) -> float:
    """A lower bound on ``min Σ x  s.t.  a x ≥ demand, 0 ≤ x ≤ 1`` from the Lagrangian
    relaxation, improved by subgradient steps.

    For any multipliers u ≥ 0 (one per row), ``L(u) = demand · u + Σ_j min(0, 1 - (aᵀu)_j)`` is
    at most the LP optimum, hence at most the smallest cover (weak duality): each camera is
    taken exactly when its reduced cost ``1 - (aᵀu)_j`` is negative. The steps follow the
    subgradient ``demand - a x`` with Polyak's step towards ``upper``, halving the step after
    20 steps without progress. A fixed number of sparse products (no clock), so the bound is
    the same on every run; it reaches the LP value where HiGHS's root LP does not finish (the
    terminal at 1 m cells: 19,554 rows, 6,553 columns).

    Args:
        a: (R, N) sparse 0/1 rows of the program.
        demand: (R,) int demand.
        upper: size of a known cover (the step target).
        iterations: subgradient steps.

    Returns:
        The best ``L(u)`` found (a float; round it up for a bound on the cover's size).
    """
    rows = _as_csr(a).astype(np.float64)
    cols = rows.T.tocsr()
    d = np.asarray(demand, dtype=np.float64)
    size = np.maximum(np.diff(cols.indptr), 1)
    # Start: each row priced at the cheapest per-row cost of a camera covering it.
    per_row = 1.0 / size
    u = np.zeros(rows.shape[0])
    starts = rows.indptr
    has = np.diff(starts) > 0
    u[has] = np.minimum.reduceat(per_row[rows.indices], starts[:-1][has])
    best, step, stale = -math.inf, 2.0, 0
    for _ in range(iterations):
        reduced = 1.0 - cols @ u
        value = float(d @ u + np.minimum(reduced, 0.0).sum())
        if value > best + 1e-9:
            best, stale = value, 0
        else:
            stale += 1
            if stale >= 20:
                step, stale = step / 2, 0
        g = d - rows @ (reduced < 0).astype(np.float64)
        g[(u <= 0) & (g < 0)] = 0.0
        norm = float(g @ g)
        if norm == 0 or step < 1e-4:
            break
        u = np.maximum(0.0, u + step * max(upper - value, 1e-3) / norm * g)
    return best


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


def _start_solution(cover, chosen: list[int], useful: np.ndarray, demand: np.ndarray) -> np.ndarray:
    """A feasible 0/1 start over the columns ``useful`` from a cover ``chosen`` of all cameras:
    a chosen camera that was dropped as dominated is replaced by a kept camera covering all
    of its rows (for K = 1 that keeps every row covered; for K > 1 nothing is dropped).

    Args:
        cover: (C, R) sparse bool over the program's rows.
        chosen: camera indices of a feasible set.
        useful: (N,) ascending camera indices of the program's columns.
        demand: (R,) int demand of the rows.

    Returns:
        (N,) float64 0/1 start; all ones when no such replacement exists (always feasible).
    """
    start = np.zeros(len(useful))
    where = {int(c): i for i, c in enumerate(useful)}
    lost = [c for c in chosen if c not in where]
    for c in chosen:
        if c in where:
            start[where[c]] = 1.0
    if lost:
        m = _as_csr(cover).astype(np.int32)
        shared = (m[lost] @ m[useful].T).toarray()  # (L, N) rows in common
        size = np.diff(m.indptr)[lost]
        for j in range(len(lost)):
            sup = np.flatnonzero(shared[j] == size[j])
            if not len(sup):
                return np.ones(len(useful))
            start[sup[0]] = 1.0
    a = _as_csr(cover)[useful].T.tocsr().astype(np.int64)
    if np.any(a @ start.astype(np.int64) < demand):
        return np.ones(len(useful))
    return start


def _solve_program(a, demand: np.ndarray, start: np.ndarray, time_limit_s: float):
    """``min Σ x  s.t.  a x ≥ demand, x ∈ {0, 1}`` with HiGHS (``highspy``), from a start set.

    Args:
        a: (R, N) sparse 0/1 rows of the program.
        demand: (R,) int right-hand sides.
        start: (N,) 0/1 feasible start (the greedy set): HiGHS begins with it as its incumbent,
            so whatever the limit it returns a set at most that large.
        time_limit_s: wall-time limit of the whole HiGHS run (presolve included), seconds.

    Returns:
        ``(x, optimal, dual_bound, status)``: (N,) solution (None when HiGHS returned none),
        whether optimality was proved, the dual bound (-inf when none) and HiGHS's status.
    """
    import highspy

    n_r, n_c = a.shape
    col = a.tocsc()
    col.sort_indices()
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("time_limit", float(max(time_limit_s, 1e-3)))
    # One thread: the same program then takes the same path through the search on every run.
    h.setOptionValue("threads", 1)
    h.passModel(n_c, n_r, int(col.nnz), 1, 1, 0.0, np.ones(n_c), np.zeros(n_c), np.ones(n_c),
                np.asarray(demand, dtype=np.float64), np.full(n_r, highspy.kHighsInf),
                col.indptr.astype(np.int32), col.indices.astype(np.int32), col.data.astype(np.float64),
                np.ones(n_c, dtype=np.int32))
    h.setSolution(n_c, np.arange(n_c, dtype=np.int32), np.asarray(start, dtype=np.float64))
    h.run()
    status = h.getModelStatus()
    info = h.getInfo()
    x = np.asarray(h.getSolution().col_value) if info.primal_solution_status == 2 else None
    bound = float(info.mip_dual_bound) if np.isfinite(info.mip_dual_bound) else -math.inf
    return x, status == highspy.HighsModelStatus.kOptimal, bound, h.modelStatusToString(status)


def select_cameras(cover, k: int = 1, *, time_limit_s: float = 60.0,
                   weights: np.ndarray | None = None, demand: np.ndarray | None = None) -> Selection:
    """The smallest camera set giving every target ``min(k, coverable)`` covering cameras.

    Integer program ``min Σ x_c  s.t.  Σ_c cover[c, t] x_c ≥ demand_t,  x ∈ {0, 1}`` solved by
    HiGHS (``highspy``) within ``time_limit_s``. Targets covered by the same cameras are one
    constraint (identical columns of the cover). For K = 1 a camera whose targets are a subset
    of another's is dropped first (among equal sets the one with the larger weight stays),
    which shrinks the cabin's 2880 candidates to about 400 without changing the optimum; weights
    are not in the objective (a tie-breaking term makes HiGHS several times slower). The
    lazy-greedy set (:func:`greedy_cover`) is computed first and handed to HiGHS as its start
    solution, so the answer is never larger than greedy's, whatever the limit. The lower bound
    is the optimum when HiGHS proves it, else the highest of HiGHS's dual bound,
    :func:`lagrangian_bound` (computed first, inside the time limit) and :func:`packing_bound`;
    the gap refers to it. The time limit covers the whole step; HiGHS gets what is left of it.

    Args:
        cover: (C, T) bool, dense or ``scipy.sparse``, from :func:`coverage_matrix`.
        k: cameras each target needs.
        time_limit_s: wall-time limit of the step, seconds (HiGHS stops at it).
        weights: (C,) preference among equal-size sets (e.g. summed px/m), larger better.
        demand: (T,) cameras asked of each target instead of ``min(k, coverable)`` (a zone's
            remaining demand, :mod:`usdscene.design.zones`); never more than it can get.

    Returns:
        A :class:`Selection`.
    """
    import time

    started = time.perf_counter()
    m = _as_csr(cover)
    n_c, n_t = m.shape
    able = np.asarray(m.sum(axis=0)).ravel().astype(np.int64)
    demand = np.minimum(able, k if demand is None else np.asarray(demand, dtype=np.int64)).astype(np.int64)
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
    # The greedy set may hold a dominated camera: its start is the greedy set with each such
    # camera swapped for the one that dominates it (as large, and still a cover).
    start = _start_solution(m[:, rows], greedy, useful, demand[rows])
    # The bound first, so that the time limit covers the whole step (seconds at 1 m cells).
    lagrangian = int(math.ceil(lagrangian_bound(a, demand[rows], len(greedy)) - 1e-6))
    elapsed = time.perf_counter() - started
    x, optimal, dual, status = _solve_program(a, demand[rows], start, max(0.0, time_limit_s - elapsed))
    chosen, method = greedy, "greedy"
    if x is not None:
        picked = sorted(int(useful[i]) for i in np.flatnonzero(x > 0.5))
        if len(picked) < len(greedy) or (optimal and len(picked) <= len(greedy)):
            chosen, method = picked, "milp"
    else:
        log.warning("HiGHS returned no set within %.0f s (%s); using the greedy set", time_limit_s, status)
    if optimal and method == "milp":
        bound = len(chosen)
    else:
        optimal = False
        bound = max(packing_bound(m, demand), lagrangian)
        if np.isfinite(dual):
            bound = max(bound, int(math.ceil(dual - 1e-6)))
    return Selection(tuple(chosen), method, optimal, min(bound, len(chosen)), len(greedy), demand, uncoverable,
                     short, time.perf_counter() - started, len(rows), len(useful))
