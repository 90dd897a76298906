"""Mask → labels maths on synthetic masks and synthetic geometry built here."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usdscene.labels.amodal import AmodalProjection, rasterize_triangles
from usdscene.labels.pixel_outline import fill_rings
from usdscene.labels.image_labels import (
    PixelBox,
    box_of,
    bridge_rings,
    contours_of,
    label_image,
    rasterize_contours,
)

H, W = 48, 64


def _ring_mask() -> np.ndarray:
    """(H, W) bool: a square ring (one hole) with an island inside the hole."""
    m = np.zeros((H, W), bool)
    m[5:35, 5:35] = True
    m[10:30, 10:30] = False
    m[17:22, 17:22] = True  # island inside the hole: a second outer contour
    return m


def _random_masks(count: int) -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    masks = []
    for k in range(count):
        noise = rng.random((H, W)) < (0.45 + 0.1 * (k % 3))
        if k % 2:
            noise = cv2.morphologyEx(noise.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) > 0
        masks.append(noise)
    return masks


def test_contours_exact_with_epsilon_zero_holes_and_parts():
    for region in [_ring_mask(), *_random_masks(40)]:
        contours = contours_of(region, epsilon_px=0)
        back = rasterize_contours(contours, region.shape)
        assert np.array_equal(back, region)


def test_ring_has_hole_and_two_outer_contours():
    contours = contours_of(_ring_mask(), epsilon_px=0)
    outers = [c for c in contours if not c.is_hole]
    holes = [c for c in contours if c.is_hole]
    assert len(outers) == 2 and len(holes) == 1
    assert not contours[holes[0].parent].is_hole
    # The outer square runs on the pixel outline: the outer edges of the outermost pixels.
    outer = max(outers, key=lambda c: np.ptp(c.points_px[:, 0]))
    assert outer.points_px.min(axis=0).tolist() == [4.5, 4.5]
    assert outer.points_px.max(axis=0).tolist() == [34.5, 34.5]
    assert len(outer.points_px) == 4
    hole = holes[0].points_px
    assert hole.min(axis=0).tolist() == [9.5, 9.5] and hole.max(axis=0).tolist() == [29.5, 29.5]


def test_default_simplification_keeps_the_pixels_exactly():
    """Below half a pixel from the outline, a simplified polygon keeps every pixel centre on
    its side: the default tolerance fills back to the mask, with fewer vertices."""
    yy, xx = np.mgrid[0:H, 0:W]
    for k, radius in enumerate((0.6, 1.5, 4.2, 15.2)):
        disc = (xx - 30.3 - k * 0.11) ** 2 + (yy - 22.7) ** 2 <= radius ** 2
        contours = contours_of(disc)
        assert np.array_equal(rasterize_contours(contours, disc.shape), disc), radius
    assert sum(len(c.points_px) for c in contours) < sum(
        len(c.points_px) for c in contours_of(disc, epsilon_px=0))
    for region in _random_masks(20):
        assert np.array_equal(rasterize_contours(contours_of(region), region.shape), region)


def test_single_pixels_and_thin_lines_are_squares_and_bands():
    region = np.zeros((6, 8), bool)
    region[1, 1] = True
    region[3, 2:7] = True
    contours = contours_of(region)
    assert [c.points_px.tolist() for c in contours] == [
        [[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [0.5, 1.5]],
        [[1.5, 2.5], [6.5, 2.5], [6.5, 3.5], [1.5, 3.5]]]


def test_diagonal_neighbours_share_one_outer_contour():
    """8-connected parts: pixels touching at a corner are one part with one outer contour
    passing through that corner twice; the background inside is a 4-connected hole."""
    region = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], bool)
    contours = contours_of(region, epsilon_px=0)
    assert len(contours) == 1 and not contours[0].is_hole
    assert np.array_equal(rasterize_contours(contours, region.shape), region)
    diamond = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], bool)
    contours = contours_of(diamond, epsilon_px=0)
    assert [c.is_hole for c in contours] == [False, True] and contours[1].parent == 0
    assert np.array_equal(rasterize_contours(contours, diamond.shape), diamond)


def test_simplified_polygons_stay_within_documented_tolerance():
    """epsilon 0.75 px: re-rasterised polygons differ from the mask only on its boundary."""
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - 30.3) ** 2 + (yy - 22.7) ** 2 <= 15.2 ** 2
    contours = contours_of(disc, epsilon_px=0.75)
    back = rasterize_contours(contours, disc.shape)
    diff = back ^ disc
    boundary = disc ^ cv2.erode(disc.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    outer_ring = cv2.dilate(disc.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~disc
    assert diff.sum() > 0  # simplification did drop vertices
    assert not (diff & ~(boundary | outer_ring)).any()
    assert sum(len(c.points_px) for c in contours) < sum(
        len(c.points_px) for c in contours_of(disc, epsilon_px=0))


def test_label_image_boxes_counts_polygons_match_masks():
    mask = np.zeros((H, W), np.uint16)
    ring = _ring_mask()
    mask[ring] = 3
    mask[40:46, 50:60] = 7          # a plain rectangle
    mask[0:4, 60:64] = 9            # touches the image corner
    split = np.zeros((H, W), bool)  # one object split in two by an occluder (id 7 column)
    split[38:44, 40:58] = True
    split[38:44, 47:50] = False
    mask[split] = 11
    mask[45, 2] = 12                # a single pixel
    ids = {3: "a", 7: "b", 9: "c", 11: "d", 12: "e", 13: "never_seen"}
    labels = label_image(mask, ids, classes={"a": "bag"}, epsilon_px=0, camera="cam", frame=4)
    assert labels.camera == "cam" and labels.frame == 4 and (labels.width_px, labels.height_px) == (W, H)
    by_uid = {o.uid: o for o in labels.objects}
    assert set(by_uid) == {"a", "b", "c", "d", "e"}
    assert by_uid["a"].class_name == "bag"
    for uid, obj in by_uid.items():
        region = mask == obj.mask_id
        assert obj.pixel_count == int(region.sum())
        assert obj.box == box_of(region)
        assert np.array_equal(rasterize_contours(obj.contours, region.shape), region), uid
        assert obj.visible_fraction is None and obj.amodal_box is None
    assert by_uid["b"].box == PixelBox(50, 40, 59, 45)
    assert by_uid["b"].box.center_size() == (54.5, 42.5, 10.0, 6.0)
    assert PixelBox.from_center_size(by_uid["b"].box.center_size()) == by_uid["b"].box
    assert len([c for c in by_uid["d"].contours if not c.is_hole]) == 2
    assert by_uid["c"].truncated and not by_uid["b"].truncated
    assert by_uid["e"].box == PixelBox(2, 45, 2, 45) and by_uid["e"].pixel_count == 1


def test_unknown_mask_ids_are_ignored():
    mask = np.zeros((H, W), np.uint16)
    mask[1:3, 1:3] = 5
    mask[10:12, 10:12] = 500
    labels = label_image(mask, {5: "x"})
    assert [o.uid for o in labels.objects] == ["x"]


# --- synthetic geometry: an ideal pinhole camera and squares at known depths ---------------

F_PX, CX, CY = 50.0, (W - 1) / 2, (H - 1) / 2


def _project(tris_cam: np.ndarray) -> np.ndarray:
    """(T, 3, 3) camera-frame points (OpenCV axes) → (T, 3, 2) pixels."""
    uv = tris_cam[..., :2] / tris_cam[..., 2:3] * F_PX
    return uv + np.array([CX, CY])


def _square(x0: float, y0: float, x1: float, y1: float, z: float) -> np.ndarray:
    """Two triangles of an axis-aligned rectangle at depth z (metres, camera frame)."""
    a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
    return np.array([[a, b, c], [a, c, d]], dtype=np.float64)


def _render(objects: dict[int, np.ndarray]) -> tuple[np.ndarray, dict[int, AmodalProjection]]:
    """Instance mask by painter's algorithm (far to near; flat squares) + amodal projections."""
    amodal = {i: rasterize_triangles(_project(t), W, H) for i, t in objects.items()}
    mask = np.zeros((H, W), np.uint16)
    for i in sorted(objects, key=lambda i: -objects[i][..., 2].mean()):
        mask[amodal[i].mask] = i
    return mask, amodal


def test_fully_hidden_object_has_amodal_box_and_zero_visibility():
    bag = _square(-0.2, -0.2, 0.2, 0.2, 4.0)      # behind
    seat = _square(-0.5, -0.5, 0.5, 0.5, 2.0)     # in front, covers the bag completely
    mask, amodal = _render({1: bag, 2: seat})
    assert not (mask == 1).any()
    labels = label_image(mask, {1: "bag", 2: "seat"}, {"bag": amodal[1], "seat": amodal[2]})
    bag_label = next(o for o in labels.objects if o.uid == "bag")
    assert bag_label.box is None and bag_label.contours == () and bag_label.pixel_count == 0
    assert bag_label.amodal_box is not None and bag_label.amodal_pixel_count > 0
    assert bag_label.visible_fraction == 0.0
    # The bag projects to ±0.05 rad · 50 px = ±2.5 px around the centre.
    assert bag_label.amodal_box.width_px == pytest.approx(5, abs=1)
    # Dropped by a minimum-visibility filter.
    filtered = label_image(mask, {1: "bag", 2: "seat"}, {"bag": amodal[1], "seat": amodal[2]},
                           min_visible_fraction=0.1)
    assert [o.uid for o in filtered.objects] == ["seat"]


@pytest.mark.parametrize("true_fraction", [0.5, 0.25, 0.8])
def test_partly_hidden_visible_fraction_matches_geometry(true_fraction):
    # Bag: 0.8 m wide at 2 m → 20 px wide; the seat covers the bag's left part from x = -0.4 m
    # to x_cut, at 1 m depth (so its extent there is halved).
    bag = _square(-0.4, -0.3, 0.4, 0.3, 2.0)
    x_cut = -0.4 + 0.8 * (1.0 - true_fraction)
    seat = _square(-1.0, -0.5, x_cut / 2.0, 0.5, 1.0)
    mask, amodal = _render({1: bag, 2: seat})
    labels = label_image(mask, {1: "bag", 2: "seat"},
                         {"bag": amodal[1].mask, "seat": amodal[2].mask})
    bag_label = next(o for o in labels.objects if o.uid == "bag")
    assert bag_label.visible_fraction == pytest.approx(true_fraction, abs=0.05)
    assert bag_label.box.width_px < bag_label.amodal_box.width_px
    assert bag_label.box.y_min == bag_label.amodal_box.y_min


def test_truncation_flag_and_clipping():
    # 2 m wide at 2 m depth → 50 px half-width: leaves the 64 px wide image on both sides.
    wide = _square(-2.0, -0.1, 2.0, 0.1, 2.0)
    proj = rasterize_triangles(_project(wide), W, H)
    assert proj.truncated
    assert box_of(proj.mask) == PixelBox(0, box_of(proj.mask).y_min, W - 1, box_of(proj.mask).y_max)
    inside = rasterize_triangles(_project(_square(-0.1, -0.1, 0.1, 0.1, 2.0)), W, H)
    assert not inside.truncated
    # Invalid vertices (the lens cannot image them) drop the triangle and count as truncated.
    tris = _project(_square(-0.1, -0.1, 0.1, 0.1, 2.0))
    invalid = rasterize_triangles(tris, W, H, valid=np.array([[True, True, False], [True, True, True]]))
    assert invalid.truncated and invalid.mask.sum() < inside.mask.sum()
    # A vertex far outside (near-plane blow-up) is clipped, not overflowed.
    far = np.array([[[10.0, 10.0], [1e9, 20.0], [10.0, 40.0]]])
    huge = rasterize_triangles(far, W, H)
    assert huge.truncated and huge.mask[20, 30] and not huge.mask[5, 30]


def test_rasterize_triangles_overlaps_are_united():
    tris = np.concatenate([_project(_square(-0.2, -0.2, 0.2, 0.2, 2.0)),
                           _project(_square(-0.1, -0.1, 0.3, 0.3, 2.0))])
    proj = rasterize_triangles(tris, W, H)
    cx, cy = int(round(CX)), int(round(CY))
    assert proj.mask[cy, cx]  # covered by both squares (an XOR fill would clear it)


def test_bridge_rings_keeps_area_and_holes():
    region = _ring_mask()
    contours = contours_of(region, epsilon_px=0)
    ring = bridge_rings([c.points_px for c in contours])
    assert len(ring) == sum(len(c.points_px) for c in contours) + 2 * (len(contours) - 1)
    # Filled by pixel centres (even-odd), the bridged ring is exactly the region.
    assert np.array_equal(fill_rings([ring], region.shape), region)


def test_contours_exact_for_arbitrary_masks_property():
    from hypothesis import given, settings
    from hypothesis import strategies as st
    from hypothesis.extra.numpy import arrays

    @settings(max_examples=80, deadline=None)
    @given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
    def check(region):
        back = rasterize_contours(contours_of(region, epsilon_px=0), region.shape)
        assert np.array_equal(back, region)
        box = box_of(region)
        if region.any():
            ys, xs = np.nonzero(region)
            assert (box.x_min, box.y_min, box.x_max, box.y_max) == (xs.min(), ys.min(), xs.max(), ys.max())
        else:
            assert box is None

    check()


def test_min_pixel_count_drops_slivers_but_keeps_hidden_objects():
    mask = np.zeros((H, W), np.uint16)
    mask[0:2, 0:2] = 1                # 4-pixel sliver
    mask[10:20, 10:20] = 2
    amodal = {"sliver": np.zeros((H, W), bool), "hidden": np.zeros((H, W), bool)}
    amodal["sliver"][0:5, 0:5] = True
    amodal["hidden"][30:35, 30:35] = True
    labels = label_image(mask, {1: "sliver", 2: "big", 3: "hidden"}, amodal, min_pixel_count=5)
    assert [o.uid for o in labels.objects] == ["big", "hidden"]
