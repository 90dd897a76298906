"""Amodal projection of world triangles through the project's camera models."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.labels.amodal import amodal_projection
from usdscene.labels.image_labels import box_of, label_image
from usdscene.document.model import Camera, Intrinsics, LensModel

W, H = 64, 48


def _camera(lens: LensModel = LensModel.PERSPECTIVE, distortion=(), fov_deg=None) -> Camera:
    # Identity pose: camera frame = world frame (OpenCV axes, looking along +Z).
    return Camera("cam", Intrinsics(lens, W, H, 40.0, 40.0, (W - 1) / 2, (H - 1) / 2,
                                    distortion=tuple(distortion), fov_deg=fov_deg))


def _quad(x0, y0, x1, y1, z) -> np.ndarray:
    a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
    return np.array([[a, b, c], [a, c, d]], dtype=np.float64)


def _ray_cast_quad(camera: Camera, x0, y0, x1, y1, z) -> np.ndarray:
    """(H, W) bool ground truth: pixels whose centre's ray (the lens model inverted) meets the
    axis-aligned quad [x0, x1] × [y0, y1] on the plane z (camera frame, metres)."""
    from usdscene.labels.projection import pixel_rays

    v, u = np.mgrid[0:H, 0:W]
    rays, ok = pixel_rays(camera.intrinsics, np.stack([u.ravel(), v.ravel()], axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        hit = rays * (z / rays[:, 2:3])
    return (ok & (rays[:, 2] > 0) & (hit[:, 0] >= x0) & (hit[:, 0] <= x1)
            & (hit[:, 1] >= y0) & (hit[:, 1] <= y1)).reshape(H, W)


def test_perspective_box_matches_analytic_projection():
    proj = amodal_projection(_camera(), _quad(-0.5, -0.25, 0.5, 0.25, 2.0))
    # x = ±0.5 m at 2 m → ±10 px around cx = 31.5: pixel centres 22..41 inclusive.
    box = box_of(proj.mask)
    assert (box.x_min, box.x_max) == (22, 41)
    assert (box.y_min, box.y_max) == (19, 28)  # y = ±0.25 m → 18.5 .. 28.5
    assert not proj.truncated


def test_near_plane_clipping_keeps_front_part_only():
    # A floor strip from 3 m in front of the camera to 3 m behind it: the part behind must not
    # fold back into the image, the front part reaches the bottom edge.
    tris = np.array([[[-0.2, 0.5, 3.0], [0.2, 0.5, 3.0], [0.2, 0.5, -3.0]],
                     [[-0.2, 0.5, 3.0], [0.2, 0.5, -3.0], [-0.2, 0.5, -3.0]]])
    proj = amodal_projection(_camera(), tris)
    assert proj.truncated
    rows = np.flatnonzero(proj.mask.any(axis=1))
    assert rows.min() >= (H - 1) / 2 + 40 * 0.5 / 3.0 - 1  # nothing above the 3 m horizon line
    assert rows.max() == H - 1


@pytest.mark.parametrize("lens,distortion,fov", [
    (LensModel.OPENCV_PINHOLE, (-0.3, 0.08, 0.001, -0.002, 0.0), None),
    (LensModel.FISHEYE_EQUIDISTANT, (), 170.0),
    (LensModel.OPENCV_FISHEYE, (0.05, -0.01, 0.002, 0.0), 170.0),
])
def test_curved_lenses_match_per_pixel_ray_casting(lens, distortion, fov):
    """Ground truth: cast each pixel centre's ray onto the quad's plane (z = 1.2 m)."""
    camera = _camera(lens, distortion, fov)
    x0, y0, x1, y1, z = -0.8, -0.5, 0.6, 0.55, 1.2
    proj = amodal_projection(camera, _quad(x0, y0, x1, y1, z))
    truth = _ray_cast_quad(camera, x0, y0, x1, y1, z)
    # Triangles are split until projected edges are <= 8 px; the straight chords then stay
    # within a small fraction of a pixel of the curved edges.
    assert truth.sum() > 200
    assert (truth ^ proj.mask).sum() <= 0.02 * truth.sum()


def test_amodal_projection_feeds_visible_fraction():
    camera = _camera()
    bag = _quad(-0.3, -0.3, 0.3, 0.3, 2.0)
    seat = _quad(-0.5, -0.5, 0.0, 0.5, 1.0)  # covers the left half of the bag (x < 0 at 2 m)
    bag_proj, seat_proj = amodal_projection(camera, bag), amodal_projection(camera, seat)
    mask = np.zeros((H, W), np.uint16)
    mask[bag_proj.mask] = 1
    mask[seat_proj.mask] = 2
    labels = label_image(mask, {1: "bag", 2: "seat"}, {"bag": bag_proj, "seat": seat_proj})
    bag_label = next(o for o in labels.objects if o.uid == "bag")
    assert bag_label.visible_fraction == pytest.approx(0.5, abs=0.05)


def _box_mesh(lo, hi) -> np.ndarray:
    """(12, 3, 3) triangles of a closed axis-aligned box, wound counter-clockwise from outside."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                  (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], dtype=np.float64)
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
    return np.array([v[[a, b, c]] for a, b, c, d in quads] + [v[[a, c, d]] for a, b, c, d in quads])


def _touching_boxes() -> np.ndarray:
    """(24, 3, 3) triangles of two closed boxes that share the face x = -0.7."""
    return np.concatenate([_box_mesh((-1.0, 0.3, 2.0), (-0.7, 0.7, 2.6)), _box_mesh((-0.7, 0.3, 2.0), (-0.4, 0.7, 2.6))])


def test_closed_meshes_are_recognised():
    from usdscene.labels.amodal import _indexed_mesh

    box = _box_mesh((-0.3, -0.2, 2.0), (0.4, 0.3, 2.5))
    assert _indexed_mesh(box).closed
    assert not _indexed_mesh(box[1:].copy()).closed  # a face missing
    flipped = box.copy()
    flipped[0] = flipped[0, ::-1]  # one face wound the other way
    assert not _indexed_mesh(flipped).closed
    assert not _indexed_mesh(np.concatenate([box, box[:1]])).closed  # an edge used three times
    assert _indexed_mesh(box[:, ::-1].copy()).closed  # wound inwards everywhere: still closed
    # Two boxes sharing a face (a surface touching itself, as a posed body's does): the shared
    # face's edges are run along twice each way, and the boundaries still cancel.
    pair = _touching_boxes()
    assert len(_indexed_mesh(pair).points) == 12 and _indexed_mesh(pair).closed
    assert not _indexed_mesh(pair[1:].copy()).closed


@pytest.mark.parametrize("lens, distortion, fov", [
    (LensModel.PERSPECTIVE, (), None),
    (LensModel.OPENCV_PINHOLE, (-0.3, 0.1, 0.0, 0.0, 0.0), None),
    (LensModel.FISHEYE_EQUISOLID, (), 150.0),
])
@pytest.mark.parametrize("inwards", [False, True])
def test_one_facing_of_a_closed_mesh_covers_what_every_face_covers(lens, distortion, fov, inwards):
    from usdscene.labels import amodal

    camera = _camera(lens, distortion, fov)
    # Boxes seen from several sides, one of them cut by the image border.
    meshes = {"a": _box_mesh((-0.3, -0.2, 1.5), (0.2, 0.3, 2.5)),
              "b": _box_mesh((0.5, 0.1, 1.0), (1.6, 0.6, 1.8)),
              "c": _box_mesh((-1.2, -0.9, 0.8), (-0.6, -0.5, 1.4)), "d": _touching_boxes()}
    if inwards:
        meshes = {uid: tris[:, ::-1].copy() for uid, tris in meshes.items()}
    fast = amodal.amodal_projections(camera, meshes)
    assert all(amodal._indexed_mesh(tris).closed for tris in meshes.values())
    # Every face, as for an open mesh: the same triangles with the closing test defeated.
    open_meshes = {uid: np.concatenate([tris, tris[:1]]) for uid, tris in meshes.items()}
    full = amodal.amodal_projections(camera, open_meshes)
    for uid in meshes:
        assert fast[uid].pixel_count > 0 and fast[uid].truncated == full[uid].truncated
        if lens is LensModel.PERSPECTIVE:  # straight edges: exactly the same pixels
            assert np.array_equal(fast[uid].mask, full[uid].mask), uid
            assert fast[uid].box == full[uid].box
        else:
            # Curved edges are split to within MAX_PROJECTED_EDGE_PX: a silhouette edge can be
            # split differently in the face kept and in the face dropped, so pixel centres
            # within a fraction of a pixel of the curve may differ.
            assert np.count_nonzero(fast[uid].mask ^ full[uid].mask) <= 0.01 * full[uid].pixel_count, uid
            a, b = fast[uid].box, full[uid].box
            assert max(abs(a.x_min - b.x_min), abs(a.y_min - b.y_min), abs(a.x_max - b.x_max),
                       abs(a.y_max - b.y_max)) <= 1, uid


def test_camera_inside_a_closed_mesh_sees_it_everywhere():
    # A room around the camera: every ray leaves it through a face that turns away from the
    # camera, so it must not be filled from one facing.
    proj = amodal_projection(_camera(), _box_mesh((-3.0, -3.0, -3.0), (3.0, 3.0, 3.0)))
    assert proj.pixel_count == W * H


@pytest.mark.parametrize("lens, distortion", [
    (LensModel.FISHEYE_EQUISOLID, ()),
    (LensModel.FISHEYE_EQUIDISTANT, ()),
    (LensModel.OPENCV_FISHEYE, (0.05, -0.01, 0.002, 0.0)),
])
def test_fisheye_image_circle_cuts_the_projection_where_the_rays_do(lens, distortion):
    """A wall reaching far beyond a 100° image circle, corner to corner: its projection ends
    at the circle as the pixel rays do (ground truth: each pixel centre's ray onto the wall)."""
    camera = Camera("cam", Intrinsics(lens, W, H, 22.0, 22.0, (W - 1) / 2, (H - 1) / 2,
                                      distortion=tuple(distortion), fov_deg=100.0))
    x0, y0, x1, y1, z = -4.0, -0.6, 0.5, 3.0, 1.0
    proj = amodal_projection(camera, _quad(x0, y0, x1, y1, z))
    truth = _ray_cast_quad(camera, x0, y0, x1, y1, z)
    assert proj.truncated and truth.sum() > 300
    assert not truth[0, 0] and not truth[H - 1, 0]  # the corners lie beyond the circle
    # (Moving the vertices beyond the circle onto its cone, as before, missed 14 of the
    # equisolid's 747 pixels along the circle.)
    assert (truth ^ proj.mask).sum() <= 0.003 * truth.sum()
    expected, got = box_of(truth), proj.box
    assert max(abs(expected.x_min - got.x_min), abs(expected.y_min - got.y_min),
               abs(expected.x_max - got.x_max), abs(expected.y_max - got.y_max)) <= 1


def test_distorted_pinhole_samples_the_pixels_its_mask_does():
    """A distorted pinhole is rendered through a perspective lens and remapped to its image
    nearest-neighbour (the instance mask's path, cv2.remap here as in the render worker): the
    amodal projection covers exactly the output pixels whose remapped render pixel's ray meets
    the object. Sub-pixel slivers (a far person's leg) between the output's pixel centres
    included: sampled at those centres, some of them covered no pixel while the mask showed
    them (an empty amodal box for a visible person)."""
    import cv2

    from usdscene.labels.projection import pixel_rays, remap_grids, undistorted_render_intrinsics

    camera = Camera("cam", Intrinsics(LensModel.OPENCV_PINHOLE, W, H, 24.0, 24.0, (W - 1) / 2, (H - 1) / 2,
                                      distortion=(-0.2, 0.04, 0.0, 0.0, 0.0)))
    render = undistorted_render_intrinsics(camera.intrinsics)
    rv, ru = np.mgrid[0:render.height_px, 0:render.width_px].astype(np.float32)
    map_x, map_y = remap_grids(camera.intrinsics, render)
    pick_u = cv2.remap(ru, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
    pick_v = cv2.remap(rv, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
    taken = pick_u >= 0
    rays, _ = pixel_rays(render, np.stack([pick_u[taken], pick_v[taken]], axis=1).astype(np.float64))
    z = 3.0
    hit = rays * (z / rays[:, 2:3])
    missed_by_centres = 0
    # Slivers 2 cm wide (a third of an output pixel near the axis, less at the edges), 0.5 m
    # tall, across the image.
    for x0 in np.linspace(-3.6, 3.4, 41):
        x1, y0, y1 = x0 + 0.02, -0.2, 0.3
        expected = np.zeros((H, W), dtype=bool)
        expected[taken] = (hit[:, 0] >= x0) & (hit[:, 0] <= x1) & (hit[:, 1] >= y0) & (hit[:, 1] <= y1)
        got = amodal_projection(camera, _quad(x0, y0, x1, y1, z)).mask
        assert np.array_equal(got, expected), x0
        missed_by_centres += bool(expected.any() and not _ray_cast_quad(camera, x0, y0, x1, y1, z).any())
    assert missed_by_centres >= 3
