"""Placement from relations (pure: numpy only, no pxr)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from test_compose_support import OBJECT_CLASSES, build_test_catalog, load_test_catalog
from usdscene.document import model as m
from usdscene.errors import CompositionError
from usdscene.scene.placement import boxes_overlap, place_objects


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    return load_test_catalog(build_test_catalog(tmp_path_factory.mktemp("catalog")))


def _scene(objects, relations, places=None, frames=(0, 5), seed=1):
    places = places if places is not None else tuple(
        m.PlaceRef(f"p_{n}", n) for n in ("seat_01A", "seat_01B", "seat_01C", "seat_01D", "aisle_01", "hall", "bin_01"))
    return m.SceneSpec(frame_start=frames[0], frame_end=frames[1], objects=tuple(objects), places=places,
                       relations=tuple(relations), environment="test_cabin", seed=seed)


def _corners(class_name: str) -> np.ndarray:
    lo, hi, _ = OBJECT_CLASSES[class_name]
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _support_frame(scene, catalog, rel: m.Relation, placements, frame) -> tuple[np.ndarray, tuple]:
    """Support region → world computed from the catalog and the target's pose (independent of
    the span's own record)."""
    places = scene.place_by_uid()
    if rel.object_uid in places:
        region = catalog.places("test_cabin")[places[rel.object_uid].name].regions[rel.type]
        return region.pose.as_array(), region.size_m
    target = scene.object_by_uid()[rel.object_uid]
    lo, hi, _ = OBJECT_CLASSES[target.class_name]
    assert rel.type == "is_on"
    top = np.eye(4)
    top[:3, 3] = ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2])
    return placements[rel.object_uid].pose_at(frame).as_array() @ top, (hi[0] - lo[0], hi[1] - lo[1], math.inf)


def _random_scene(n_objects: int, seed: int) -> m.SceneSpec:
    rng = np.random.default_rng(seed)
    n_frames = 6
    objects, relations = [], []
    boxes = []
    hall, aisle = "p_hall", "p_aisle_01"
    for i in range(n_objects):
        uid = f"o{i:03d}"
        noise = m.Randomization(position_noise_m=float(rng.uniform(0, 0.1)), rotation_noise_deg=float(rng.uniform(0, 30)))
        kind = rng.random()
        if i < 20:  # always present boxes that cups stand on
            objects.append(m.SceneObject(uid, uid, "box", (), randomization=noise))
            relations.append(m.Relation(f"r{i}", "is_on", uid, hall))
            boxes.append(uid)
            continue
        a = int(rng.integers(0, n_frames))
        b = int(rng.integers(a, n_frames))
        intervals = (m.FrameInterval(a, b),)
        if kind < 0.65:
            cls = str(rng.choice(["box", "bag", "cup"]))
            objects.append(m.SceneObject(uid, uid, cls, intervals, randomization=noise))
            relations.append(m.Relation(f"r{i}", "is_on", uid, hall))
        elif kind < 0.7:
            objects.append(m.SceneObject(uid, uid, "bag", intervals, randomization=noise))
            # switches place half way: hall, then the aisle
            relations.append(m.Relation(f"r{i}a", "is_on", uid, hall, (m.FrameInterval(0, 2),)))
            relations.append(m.Relation(f"r{i}b", "is_on", uid, aisle, (m.FrameInterval(3, 5),)))
        elif kind < 0.85:
            objects.append(m.SceneObject(uid, uid, "cup", intervals, randomization=noise))
            relations.append(m.Relation(f"r{i}", "is_on", uid, str(rng.choice(boxes))))
        else:
            seat = str(rng.choice(["seat_01A", "seat_01B", "seat_01C", "seat_01D"]))
            rel = str(rng.choice(["is_on", "is_below", "is_in_front_of"]))
            objects.append(m.SceneObject(uid, uid, "cup", intervals, randomization=noise))
            relations.append(m.Relation(f"r{i}", rel, uid, f"p_{seat}"))
    return _scene(objects, relations, frames=(0, n_frames - 1), seed=seed)


def _yaw_rectangles(poses: list[np.ndarray], classes: list[str]):
    """(N, 4, 2) world footprint corners and (N, 2) z ranges of yaw-only placed boxes."""
    rects, zs = [], []
    for pose, cls in zip(poses, classes):
        assert np.allclose(pose[2, :3], [0, 0, 1], atol=1e-12), "placement tilted an object"
        lo, hi, _ = OBJECT_CLASSES[cls]
        local = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        rects.append(local @ pose[:2, :2].T + pose[:2, 3])
        zs.append((pose[2, 3] + lo[2], pose[2, 3] + hi[2]))
    return np.array(rects), np.array(zs)


def _intersecting_pairs(rects: np.ndarray, zs: np.ndarray, tol: float = 1e-6) -> list[tuple[int, int]]:
    """Pairs of yaw-only boxes that overlap by more than ``tol`` (2-D separating axes of the
    footprints and the z intervals); written independently of usdscene.scene.placement."""
    n = len(rects)
    edges = np.stack([rects[:, 1] - rects[:, 0], rects[:, 3] - rects[:, 0]], axis=1)  # (N, 2, 2)
    normals = edges / np.linalg.norm(edges, axis=2, keepdims=True)
    pairs = []
    for i in range(n):
        j = np.arange(i + 1, n)
        if len(j) == 0:
            break
        z_overlap = np.minimum(zs[i, 1], zs[j, 1]) - np.maximum(zs[i, 0], zs[j, 0]) > tol
        axes = np.concatenate([np.broadcast_to(normals[i], (len(j), 2, 2)), normals[j]], axis=1)  # (J, 4, 2)
        proj_i = np.einsum("cd,jad->jac", rects[i], axes)   # (J, 4 axes, 4 corners)
        proj_j = np.einsum("jcd,jad->jac", rects[j], axes)
        gap = np.maximum(proj_i.min(2) - proj_j.max(2), proj_j.min(2) - proj_i.max(2))  # (J, 4)
        xy_overlap = (gap < -tol).all(axis=1)
        pairs += [(i, int(k)) for k in j[z_overlap & xy_overlap]]
    return pairs


def test_200_random_objects_rest_on_their_support_and_never_intersect(catalog):
    scene = _random_scene(200, seed=11)
    placements = place_objects(scene, catalog, np.random.default_rng(scene.seed))
    rel_by_uid = {r.uid: r for r in scene.relations}
    checked = 0
    for frame in scene.frames:
        present = [o for o in scene.objects_present(frame)]
        poses = [placements[o.uid].pose_at(frame).as_array() for o in present]
        for obj, pose in zip(present, poses):
            span = placements[obj.uid].span_at(frame)
            rel = rel_by_uid[span.relation_uid]
            support, size = _support_frame(scene, catalog, rel, placements, frame)
            pts = _corners(obj.class_name) @ pose[:3, :3].T + pose[:3, 3]
            in_support = (pts - support[:3, 3]) @ support[:3, :3]
            assert abs(in_support[:, 2].min()) <= 0.005, f"{obj.uid} floats/sinks at frame {frame}"
            assert np.all(np.abs(in_support[:, 0]) <= size[0] / 2 + 1e-9), f"{obj.uid} leaves its region in x"
            assert np.all(np.abs(in_support[:, 1]) <= size[1] / 2 + 1e-9), f"{obj.uid} leaves its region in y"
            assert in_support[:, 2].max() <= size[2] + 1e-9
            checked += 1
        rects, zs = _yaw_rectangles(poses, [o.class_name for o in present])
        bad = _intersecting_pairs(rects, zs)
        assert not bad, [(present[i].uid, present[j].uid, frame) for i, j in bad[:5]]
    assert checked > 400  # object-frames actually checked


def test_independent_overlap_check_detects_overlap():
    """The test's own intersection check is not vacuous."""
    pose_a = np.eye(4)
    pose_b = np.eye(4)
    pose_b[:3, 3] = (0.35, 0.0, 0.0)  # boxes 0.4 wide: 5 cm overlap
    rects, zs = _yaw_rectangles([pose_a, pose_b], ["box", "box"])
    assert _intersecting_pairs(rects, zs) == [(0, 1)]
    pose_b[:3, 3] = (0.4, 0.0, 0.0)  # touching
    rects, zs = _yaw_rectangles([pose_a, pose_b], ["box", "box"])
    assert _intersecting_pairs(rects, zs) == []


def test_separating_axis_test_handles_rotated_boxes():
    half = np.array([0.5, 0.5, 0.5])
    a = math.radians(45)
    rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    # A 45° box at distance 1.2: its corner reaches 0.5 + 0.707 > 1.2 → overlap; at 1.25 → free.
    for dist, expected in ((1.2, True), (1.25, False)):
        got = boxes_overlap((np.zeros(3), np.eye(3), half), (np.array([[dist, 0, 0]]), rot[None], half[None]))
        assert bool(got[0]) is expected


def test_pose_is_kept_while_the_relation_holds_and_resampled_when_it_changes(catalog):
    noisy = m.Randomization(position_noise_m=0.05, rotation_noise_deg=10)
    objects = [m.SceneObject("bag", "bag", "bag", (m.FrameInterval(0, 5),), randomization=noisy),
               m.SceneObject("cup", "cup", "cup", (m.FrameInterval(0, 1), m.FrameInterval(3, 5)), randomization=noisy)]
    relations = [m.Relation("r1", "is_on", "bag", "p_seat_01A", (m.FrameInterval(0, 2),)),
                 m.Relation("r2", "is_below", "bag", "p_seat_01B", (m.FrameInterval(3, 5),)),
                 m.Relation("r3", "is_on", "cup", "p_aisle_01")]
    placements = place_objects(_scene(objects, relations), catalog, np.random.default_rng(0))
    bag = placements["bag"]
    assert [(s.frame_start, s.frame_end, s.relation_uid) for s in bag.spans] == [(0, 2, "r1"), (3, 5, "r2")]
    assert bag.pose_at(0) == bag.pose_at(2) != bag.pose_at(3)
    cup = placements["cup"]
    # Absent at frame 2: it re-appears with a fresh sample.
    assert [(s.frame_start, s.frame_end) for s in cup.spans] == [(0, 1), (3, 5)]
    assert cup.pose_at(2) is None
    assert cup.pose_at(0) != cup.pose_at(3)


def test_object_on_a_moving_object_follows_it(catalog):
    moved = m.Pose.from_rotation_translation(np.eye(3), (1.0, 5.0, 0.0))
    objects = [m.SceneObject("box", "box", "box", pose=m.Pose.from_rotation_translation(np.eye(3), (0.0, 5.0, 0.0)),
                             frame_poses=((4, moved), (5, moved))),
               m.SceneObject("cup", "cup", "cup", randomization=m.Randomization(position_noise_m=0.05))]
    placements = place_objects(_scene(objects, [m.Relation("r", "is_on", "cup", "box")]), catalog,
                               np.random.default_rng(0))
    cup = placements["cup"]
    before, after = cup.pose_at(3).as_array(), cup.pose_at(4).as_array()
    assert np.allclose(after[:3, 3] - before[:3, 3], (1.0, 0.0, 0.0))
    assert np.allclose(before[:3, :3], after[:3, :3])
    assert before[2, 3] == pytest.approx(0.3)  # the box top
    assert [(s.frame_start, s.frame_end) for s in cup.spans] == [(0, 3), (4, 5)]


def test_explicit_pose_wins_over_relations(catalog):
    pose = m.Pose.from_rotation_translation(np.eye(3), (7.0, 7.0, 1.0))
    frame_pose = m.Pose.from_rotation_translation(np.eye(3), (8.0, 8.0, 1.0))
    objects = [m.SceneObject("a", "a", "cup", pose=pose, frame_poses=((2, frame_pose),))]
    placements = place_objects(_scene(objects, [m.Relation("r", "is_on", "a", "p_hall")]), catalog,
                               np.random.default_rng(0))
    assert placements["a"].pose_at(0) == pose
    assert placements["a"].pose_at(2) == frame_pose
    assert placements["a"].span_at(0).relation_uid is None


def test_same_seed_same_placements_other_seed_other_placements(catalog):
    scene = _random_scene(40, seed=3)
    one = place_objects(scene, catalog, np.random.default_rng(5))
    two = place_objects(scene, catalog, np.random.default_rng(5))
    three = place_objects(scene, catalog, np.random.default_rng(6))
    assert one == two
    assert one != three


def test_lone_object_without_noise_sits_in_the_middle_of_its_place(catalog):
    placements = place_objects(_scene([m.SceneObject("c", "c", "cup")], [m.Relation("r", "is_below", "c", "p_seat_01A")]),
                               catalog, np.random.default_rng(0))
    region = catalog.places("test_cabin")["seat_01A"].regions["is_below"]
    assert np.allclose(placements["c"].pose_at(0).as_array(), region.pose.as_array())


@pytest.mark.parametrize("objects, relations, uid, words", [
    ([m.SceneObject("o1", "o1", "cup")], [m.Relation("r1", "is_on", "o1", "p_nowhere")], "r1",
     ("'nowhere'", "lacks")),
    ([m.SceneObject("o7", "o7", "unicorn")], [], "o7", ("unknown class", "'unicorn'")),
    ([m.SceneObject("a", "a", "cup"), m.SceneObject("b", "b", "cup"), m.SceneObject("c", "c", "cup")],
     [m.Relation("r1", "is_on", "a", "b"), m.Relation("r2", "is_on", "b", "c"), m.Relation("r3", "is_on", "c", "a")],
     "'a'", ("cyclic",)),
    ([m.SceneObject(f"bag{i}", "b", "bag") for i in range(5)],
     [m.Relation(f"r{i}", "is_below", f"bag{i}", "p_seat_01A") for i in range(5)], "bag2",
     ("seat_01A", "holds 2 object", "in the way: 'bag")),
    ([m.SceneObject("pole1", "pole", "pole")], [m.Relation("r", "is_below", "pole1", "p_seat_01A")], "pole1",
     ("clearance",)),
    ([m.SceneObject("o1", "o1", "cup")], [m.Relation("r9", "is_on", "o1", "ghost")], "r9", ("neither a place",)),
])
def test_bad_input_names_the_element(catalog, objects, relations, uid, words):
    places = (m.PlaceRef("p_nowhere", "nowhere"), m.PlaceRef("p_seat_01A", "seat_01A"))
    with pytest.raises(CompositionError) as err:
        place_objects(_scene(objects, relations, places=places), catalog, np.random.default_rng(0))
    text = str(err.value)
    assert uid in text
    for word in words:
        assert word in text


def test_seated_asset_rests_on_its_origin_and_claims_its_seat(catalog):
    objects = [m.SceneObject("s", "s", "sitter"), m.SceneObject("c", "c", "cup")]
    relations = [m.Relation("r1", "is_on", "s", "p_seat_01A"), m.Relation("r2", "is_in_front_of", "c", "p_seat_01A")]
    placements = place_objects(_scene(objects, relations), catalog, np.random.default_rng(0))
    pose = placements["s"].pose_at(0).as_array()
    assert pose[2, 3] == pytest.approx(0.45)  # hip on the cushion
    feet = (pose @ [0.0, 0.0, -0.45, 1.0])[2]
    assert feet == pytest.approx(0.0)  # feet on the floor
    # The cup in the legroom is fine; a cup on the occupied seat is not.
    relations[1] = m.Relation("r2", "is_on", "c", "p_seat_01A")
    with pytest.raises(CompositionError, match="'c'.*seat_01A"):
        place_objects(_scene(objects, relations), catalog, np.random.default_rng(0))


def test_object_too_tall_for_its_place_lies_down(catalog):
    objects = [m.SceneObject("b", "b", "tall_bag", randomization=m.Randomization(0.02, 5.0))]
    placements = place_objects(_scene(objects, [m.Relation("r", "is_below", "b", "p_seat_01A")]), catalog,
                               np.random.default_rng(0))
    region = catalog.places("test_cabin")["seat_01A"].regions["is_below"]
    pose = placements["b"].pose_at(0).as_array()
    pts = _corners("tall_bag") @ pose[:3, :3].T + pose[:3, 3]
    local = (pts - region.pose.translation_m) @ region.pose.rotation
    assert local[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert local[:, 2].max() == pytest.approx(0.15)  # lying: its thickness is its height
    assert np.all(np.abs(local[:, :2]) <= np.asarray(region.size_m[:2]) / 2 + 1e-9)


def test_objects_sharing_a_region_are_packed(catalog):
    """Two 0.30 × 0.20 m bags fit side by side under a 0.44 × 0.40 m seat only when packed
    (turned a quarter, from the corners): a centred first bag would leave no room."""
    objects = [m.SceneObject(f"bag{i}", "b", "bag") for i in range(2)]
    relations = [m.Relation(f"r{i}", "is_below", f"bag{i}", "p_seat_01A") for i in range(2)]
    placements = place_objects(_scene(objects, relations), catalog, np.random.default_rng(0))
    poses = [placements[f"bag{i}"].pose_at(0).as_array() for i in range(2)]
    rects, zs = _yaw_rectangles(poses, ["bag", "bag"])
    assert _intersecting_pairs(rects, zs) == []
