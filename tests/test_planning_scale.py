"""Planning at scale: streamed visibility equals the per-camera computation it replaces, lazy
greedy equals plain greedy, merged targets and pruned cameras keep the optimum, long regions
become floor cells, and requests too large for memory are refused before any ray is cast."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.design.candidates import look_rotation
from usdscene.design.lenses import lens_intrinsics, load_lenses
from usdscene.design.occluders import Occluders
from usdscene.design.selection import greedy_cover, merge_targets, select_cameras
from usdscene.design.targets import Target, region_cells
from usdscene.design.visibility import coverage_matrix, evaluate_visibility, pairs_in_range
from usdscene.document.model import Camera, Pose
from usdscene.errors import DocumentError
from usdscene.labels.pixel_density import dori_index, load_dori, pixel_density
from usdscene.labels.projection import project_points


def _box_triangles(lo, hi) -> np.ndarray:
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    p = np.array([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1),
                  (x0, y1, z1)])
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return np.array([[p[a], p[b], p[c]] for q in quads for a, b, c in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))])


def _scene(seed: int):
    """A 30 x 20 m floor with pillars, targets on it, cameras of every shipped lens."""
    rng = np.random.default_rng(seed)
    tris = [_box_triangles((-15, -10, -0.2), (15, 10, 0.0))]
    for _ in range(8):
        x, y = rng.uniform(-13, 13), rng.uniform(-8, 8)
        tris.append(_box_triangles((x - 0.4, y - 0.4, 0.0), (x + 0.4, y + 0.4, 4.0)))
    targets = []
    for i in range(60):
        x, y = rng.uniform(-14, 14), rng.uniform(-9, 9)
        gx, gy, gz = np.meshgrid(np.linspace(-0.5, 0.5, 3), np.linspace(-0.5, 0.5, 3), [0.03, 0.9], indexing="ij")
        pts = np.stack([gx.ravel() + x, gy.ravel() + y, gz.ravel()], axis=1)
        targets.append(Target(f"t{i}", "", "box", pts, 1.0))
    cameras = []
    lenses = list(load_lenses().values())
    for i in range(40):
        p = np.array([rng.uniform(-15, 15), rng.uniform(-10, 10), rng.uniform(2.5, 5.0)])
        forward = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1.5, -0.2)])
        lens = lenses[i % len(lenses)]
        cameras.append(Camera(name=f"c{i}", intrinsics=lens_intrinsics(lens),
                              pose=Pose.from_rotation_translation(look_rotation(forward), p), model_name=lens.name))
    return cameras, targets, Occluders(np.concatenate(tris))


def _reference(cameras, targets, occ, table, max_range_m=30.0):
    """The dense per-camera computation the streamed one replaced: (C, T) arrays and the
    per-point visibility."""
    counts = np.array([len(t.points_m) for t in targets])
    pts = np.concatenate([t.points_m for t in targets])
    owner = np.repeat(np.arange(len(targets)), counts)
    shape = (len(cameras), len(targets))
    in_image, visible, density = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    per_point = np.zeros((len(cameras), len(pts)), dtype=bool)
    for c, cam in enumerate(cameras):
        centre = cam.pose.translation_m
        idx = np.flatnonzero(np.linalg.norm(pts - centre, axis=1) <= max_range_m)
        uv, ok = project_points(cam, pts[idx])
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        idx = idx[ok & (uv[:, 0] >= -0.5) & (uv[:, 0] <= w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= h - 0.5)]
        if not len(idx):
            continue
        seen = ~occ.blocked(centre, pts[idx])
        in_image[c] = np.bincount(owner[idx], minlength=len(targets)) / counts
        vis = idx[seen]
        per_point[c, vis] = True
        visible[c] = np.bincount(owner[vis], minlength=len(targets)) / counts
        d = pixel_density(cam, pts[vis])
        for t in np.unique(owner[vis]):
            density[c, t] = float(np.median(d[owner[vis] == t]))
    dori = np.where(visible > 0, dori_index(density, table), -1)
    return in_image, visible, density, dori, per_point


@pytest.mark.parametrize("seed,batch", [(0, 1_000_000), (1, 500)])
def test_streamed_visibility_equals_the_dense_per_camera_computation(seed, batch):
    cameras, targets, occ = _scene(seed)
    table = load_dori()
    in_image, visible, density, dori, per_point = _reference(cameras, targets, occ, table)
    vis = evaluate_visibility(cameras, targets, occ, table, keep_points=True, ray_batch=batch)
    assert (in_image > 0).sum() > 50 and 0 < (visible > 0).sum() < (in_image > 0).sum()  # a real test
    np.testing.assert_array_equal(vis.in_image, in_image)
    np.testing.assert_array_equal(vis.visible, visible)
    np.testing.assert_allclose(vis.px_per_m, density, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(vis.dori, dori)
    offsets = np.concatenate([[0], np.cumsum([len(t.points_m) for t in targets])])
    for i, (c, t) in enumerate(zip(vis.camera, vis.target)):
        np.testing.assert_array_equal(vis.point_visible[i], per_point[c, offsets[t]:offsets[t + 1]])
    # Every pair with a point in the image is kept, and no other.
    assert len(vis.camera) == int((in_image > 0).sum())
    assert pairs_in_range(cameras, targets) >= len(vis.camera)


def test_progress_reports_every_camera_once_at_the_end():
    cameras, targets, occ = _scene(2)
    calls = []
    evaluate_visibility(cameras, targets, occ, load_dori(), progress=lambda done, total: calls.append((done, total)),
                        ray_batch=200)
    assert len(calls) > 2 and calls[-1] == (len(cameras), len(cameras))
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def _plain_greedy(cover, demand, w):
    remaining, chosen, available = demand.copy(), [], np.ones(len(cover), bool)
    while remaining.max(initial=0) > 0:
        gain = (cover & (remaining > 0)).sum(axis=1).astype(float)
        gain[~available] = -1
        best = np.flatnonzero(gain == gain.max())
        c = int(best[np.argmax(w[best])])
        if gain[c] <= 0:
            break
        chosen.append(c)
        available[c] = False
        remaining -= cover[c]
    counts = cover[chosen].sum(axis=0)
    for c in sorted(chosen, key=lambda i: (w[i], -i)):
        if np.all(counts - cover[c] >= demand):
            counts = counts - cover[c]
            chosen.remove(c)
    return sorted(chosen)


@pytest.mark.parametrize("seed,k", [(0, 1), (1, 1), (2, 2), (3, 3)])
def test_lazy_greedy_takes_the_cameras_plain_greedy_takes(seed, k):
    rng = np.random.default_rng(seed)
    cover = rng.random((60, 80)) < 0.08
    w = rng.integers(0, 3, 60).astype(float)  # ties in gain and weight both happen
    demand = np.minimum(cover.sum(axis=0), k)
    assert greedy_cover(cover, demand, w) == _plain_greedy(cover, demand, w)


def test_targets_seen_by_the_same_cameras_are_merged_and_the_optimum_is_kept():
    rng = np.random.default_rng(4)
    base = rng.random((30, 12)) < 0.2
    cover = np.concatenate([base, base, base[:, :5]], axis=1)  # 29 targets, at most 12 distinct
    first, group = merge_targets(coverage_like(cover))
    assert len(first) <= 12 and np.all(group[:12] == group[12:24])
    for t in range(cover.shape[1]):
        assert np.array_equal(cover[:, t], cover[:, first[group[t]]])
    merged = select_cameras(coverage_like(cover), 1, time_limit_s=10)
    alone = select_cameras(base, 1, time_limit_s=10)
    assert merged.optimal and len(merged.chosen) == len(alone.chosen) and merged.rows <= 12


def coverage_like(dense):
    from scipy.sparse import csr_matrix

    return csr_matrix(dense)


def test_an_unreachable_time_limit_gives_the_best_plan_found_and_its_gap():
    rng = np.random.default_rng(5)
    cover = rng.random((400, 600)) < 0.02
    sel = select_cameras(coverage_like(cover), 2, time_limit_s=0.1)
    demand = np.minimum(cover.sum(axis=0), 2)
    assert np.all(cover[list(sel.chosen)].sum(axis=0) >= demand)
    assert sel.greedy_size >= len(sel.chosen) >= sel.lower_bound > 0
    assert 0.0 <= sel.gap < 1.0 and sel.gap == (len(sel.chosen) - sel.lower_bound) / len(sel.chosen)


def test_a_long_walkway_becomes_cells_whose_areas_add_up():
    cells = region_cells((35.7, 2.5, 1.8), 5.0)
    assert len(cells) == 8 and all(size[0] <= 5.0 and size[1] == 2.5 for _, size, _ in cells)
    assert sum(size[0] * size[1] for _, size, _ in cells) == pytest.approx(35.7 * 2.5)
    assert [origin[0] for _, _, origin in cells][0] == pytest.approx(-35.7 / 2 + 35.7 / 16)
    assert len(region_cells((5.0, 2.5, 1.8), 5.0)) == 1  # a 5 m bay stays one target


def test_coverage_matrix_is_sparse_and_agrees_with_the_pairs():
    cameras, targets, occ = _scene(3)
    vis = evaluate_visibility(cameras, targets, occ, load_dori())
    cover = coverage_matrix(vis, min_visible=0.25, min_dori=0)
    dense = (vis.visible >= 0.25) & (vis.dori >= 0)
    assert cover.nnz == int(dense.sum()) > 0 and np.array_equal(cover.toarray(), dense)


def test_a_request_too_large_for_memory_is_refused_naming_targets_and_candidates():
    from usdscene.design.camera_design import check_pair_memory

    with pytest.raises(DocumentError) as err:
        check_pair_memory(400_000_000, 20_000, 50_000, 8.0)
    text = str(err.value)
    assert "20000 targets" in text and "50000 candidate" in text and "--cell" in text and "zones" in text
    assert "\n" not in text
    check_pair_memory(1000, 10, 100, 8.0)  # small enough: nothing raised


def test_mount_search_says_why_no_pole_stands_on_a_deck_above_lower_stairs():
    from types import SimpleNamespace

    from usdscene.design.candidates import open_air_mounts
    from usdscene.design.mount_surfaces import mount_surfaces

    # A 40 x 8 m platform deck 1.2 m up, with stairs at one end going down to 2.1 m below it
    # (the scene's lowest point), and a tree whose crown overhangs the deck.
    deck = _box_triangles((-20, -4, 0.9), (20, 4, 1.2))
    stairs = _box_triangles((20, -1, -0.9), (23, 1, 1.2))
    crown = _box_triangles((-2, -2, 4.0), (2, 2, 7.0))
    meshes = [SimpleNamespace(path="/Platform/Deck", triangles_m=deck, mountable=None),
              SimpleNamespace(path="/Platform/Stairs", triangles_m=stairs, mountable=None),
              SimpleNamespace(path="/Platform/Tree/Crown", triangles_m=crown, mountable=None)]
    tris = np.concatenate([deck, stairs, crown])
    occ = Occluders(tris)
    left_out: dict[str, int] = {}
    mounts = open_air_mounts(occ, tris, mount_surfaces(meshes, 0), occ.bounds_m, left_out=left_out)
    assert mounts == []
    high = [n for reason, n in left_out.items() if "more than 1 m above the scene's lowest point" in reason]
    tree = [n for reason, n in left_out.items() if "unmountable" in reason and "first surface" in reason]
    assert len(high) == 1 and high[0] > 10 and "z = -0.90 m" in next(r for r in left_out if "lowest" in r)
    assert tree and tree[0] >= 1


@pytest.mark.parametrize("seed,k", [(0, 1), (1, 1), (2, 2)])
def test_the_packing_bound_never_exceeds_the_optimum(seed, k):
    from usdscene.design.selection import packing_bound

    rng = np.random.default_rng(seed)
    cover = rng.random((40, 120)) < 0.05
    demand = np.minimum(cover.sum(axis=0), k)
    sel = select_cameras(coverage_like(cover), k, time_limit_s=20)
    bound = packing_bound(coverage_like(cover), demand)
    assert sel.optimal and 0 < bound <= len(sel.chosen)
    # Two targets that share no camera need two cameras.
    assert packing_bound(np.array([[1, 0], [0, 1]], bool), np.array([1, 1])) == 2
    assert packing_bound(np.array([[1, 1], [0, 1]], bool), np.array([1, 1])) == 1


@pytest.mark.parametrize("seed,k", [(0, 1), (3, 1), (4, 2)])
def test_the_lagrangian_bound_lies_below_the_lp_optimum_and_near_it(seed, k):
    from scipy.optimize import linprog

    from usdscene.design.selection import lagrangian_bound

    rng = np.random.default_rng(seed)
    cover = rng.random((80, 300)) < 0.04
    demand = np.minimum(cover.sum(axis=0), k)
    rows = np.flatnonzero(demand > 0)
    a = cover[:, rows].T.astype(float)
    lp = linprog(np.ones(cover.shape[0]), A_ub=-a, b_ub=-demand[rows], bounds=(0, 1), method="highs")
    bound = lagrangian_bound(coverage_like(a), demand[rows], int(cover.shape[0]))
    assert lp.status == 0 and bound <= lp.fun + 1e-6
    assert bound >= 0.9 * lp.fun


def test_the_program_starts_from_the_greedy_set_so_a_tiny_limit_never_returns_more():
    rng = np.random.default_rng(6)
    cover = rng.random((600, 900)) < 0.01
    sel = select_cameras(coverage_like(cover), 1, time_limit_s=0.1)
    demand = np.minimum(cover.sum(axis=0), 1)
    assert np.all(cover[list(sel.chosen)].sum(axis=0) >= demand)
    assert len(sel.chosen) <= sel.greedy_size and sel.lower_bound <= len(sel.chosen)
    assert sel.method in ("milp", "greedy") and (sel.optimal or sel.gap > 0)
