"""Planning a large floor in zones: the targets split into square zones of the floor, one
camera program per zone, the programs solved in turn. Pure.

The overlap rule: a target belongs to the one zone its centre lies in (zones are half-open
squares ``[x0, x0 + size) × [y0, y0 + size)`` from the targets' lowest corner); any candidate,
wherever it is mounted, may serve any zone; a camera chosen for an earlier zone counts for
every later zone it covers, so a target it already covers K times asks nothing more of its own
zone. Every target is thus asked exactly what the whole-floor program asks of it, and the
union covers what the whole plan covers. Cameras that the later zones made redundant are
dropped at the end (reverse-delete over the whole floor).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from usdscene.design.selection import (Selection, _as_csr, drop_redundant, greedy_cover, lagrangian_bound,
                                       packing_bound, select_cameras)

log = logging.getLogger(__name__)


def zone_index(centres_m: np.ndarray, zone_m: float) -> np.ndarray:
    """(T,) zone of each target: the ``zone_m`` square its centre's X, Y lies in, numbered
    row-major (Y then X) from the lowest corner, only zones that hold a target counted.

    Args:
        centres_m: (T, 2 or 3) target centres, metres.
        zone_m: zone side, metres (> 0).
    """
    xy = np.asarray(centres_m, dtype=np.float64)[:, :2]
    if not len(xy):
        return np.zeros(0, dtype=np.int64)
    cell = np.floor((xy - xy.min(axis=0)) / zone_m).astype(np.int64)
    key = cell[:, 1] * (int(cell[:, 0].max()) + 1) + cell[:, 0]
    return np.unique(key, return_inverse=True)[1].ravel().astype(np.int64)


def select_by_zones(cover, k: int, zones: np.ndarray, *, time_limit_s: float = 60.0,
                    weights: np.ndarray | None = None) -> Selection:
    """The camera set of :func:`usdscene.design.selection.select_cameras`, planned zone by
    zone under the overlap rule of this module.

    Each zone's program gets a share of ``time_limit_s`` in proportion to its targets. The
    lower bound is the highest of the zones' bounds (each zone's program asks no more than the
    whole one, so its bound bounds the whole), :func:`packing_bound` and
    :func:`lagrangian_bound` of the whole floor.

    Args:
        cover: (C, T) bool, dense or sparse.
        k: cameras each target needs.
        zones: (T,) int zone of each target (:func:`zone_index`).
        time_limit_s: HiGHS time for all zones together, seconds.
        weights: (C,) preference among equal-size sets.

    Returns:
        A :class:`Selection` (``method`` ``zones``, ``zones`` the number of programs).
    """
    started = time.perf_counter()
    m = _as_csr(cover)
    n_c, n_t = m.shape
    zones = np.asarray(zones, dtype=np.int64)
    able = np.asarray(m.sum(axis=0)).ravel().astype(np.int64)
    demand = np.minimum(able, k).astype(np.int64)
    w = np.zeros(n_c) if weights is None else np.asarray(weights, dtype=np.float64)
    covered = np.zeros(n_t, dtype=np.int64)
    taken = np.zeros(n_c, dtype=bool)
    chosen: list[int] = []
    bound, rows, columns, programs = 0, 0, 0, 0
    total = max(1, int((demand > 0).sum()))
    for z in np.unique(zones):
        mine = np.flatnonzero((zones == z) & (demand > 0))
        need = np.maximum(demand[mine] - covered[mine], 0)
        mine, need = mine[need > 0], need[need > 0]
        if not len(mine):
            continue
        # The cameras already taken are out of this zone's program: what they cover is in `covered`.
        sub = m[:, mine].multiply((~taken)[:, None]).tocsr()
        sel = select_cameras(sub, k, time_limit_s=max(0.1, time_limit_s * len(mine) / total), weights=w,
                             demand=need)
        programs += 1
        bound = max(bound, sel.lower_bound)
        rows, columns = rows + sel.rows, columns + sel.columns
        picked = list(sel.chosen)
        taken[picked] = True
        chosen += picked
        if picked:
            covered += np.asarray(m[picked].sum(axis=0)).ravel().astype(np.int64)
    chosen = drop_redundant(m, chosen, demand, w)
    greedy = greedy_cover(m, demand, w)
    program = np.flatnonzero(demand > 0)
    if len(program):
        a = m[:, program].T.tocsr()
        bound = max(bound, packing_bound(m, demand),
                    int(math.ceil(lagrangian_bound(a, demand[program], len(chosen)) - 1e-6)))
    uncoverable = tuple(int(t) for t in np.flatnonzero(able == 0))
    short = tuple(int(t) for t in np.flatnonzero((able > 0) & (able < k)))
    optimal = bound >= len(chosen)
    log.info("%d zone programs: %d cameras, lower bound %d", programs, len(chosen), bound)
    return Selection(tuple(chosen), "zones", optimal, min(bound, len(chosen)), len(greedy), demand, uncoverable,
                     short, time.perf_counter() - started, rows, columns, programs)
