"""usdscene generate tracks: walkers and vehicles of the car park example, without rendering."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.scene.catalog import load_catalog
from usdscene.converters.openlabel import read_openlabel, write_openlabel
from usdscene.errors import DocumentError
from usdscene.document.model import DeclaredRegion, PlaceRef, Pose
from usdscene.generate.motion import generate_tracks
from usdscene.generate.movers import STRIDE_M, TrackOptions, overlapping_frames
from usdscene.generate.obstacles import OBSTACLE_CELL_M, STEP_HEIGHT_M, Obstacles, environment_obstacles
from usdscene.generate.routes import ground_areas
from usdscene.generate.vehicles import VEHICLE_MARGIN_M
from usdscene.generate.walkers import PERSON_MARGIN_M, foot_sliding, locked_stride, walk_phases

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"


@pytest.fixture(scope="module")
def setup():
    scene = read_openlabel(CAR_PARK / "setup_moving.openlabel.json")
    return scene, load_catalog(scene.asset_paths, base_dir=CAR_PARK)


@pytest.fixture(scope="module")
def obstacles(setup):
    return environment_obstacles(*setup)


@pytest.fixture(scope="module")
def generated(setup, obstacles):
    scene, catalog = setup
    return generate_tracks(scene, catalog, TrackOptions(frames=120, fps=5, people=12, standing=3, vehicles=4, seed=7),
                           obstacles=obstacles)


def test_same_seed_same_document_other_seed_other(setup, generated, obstacles):
    scene, catalog = setup
    options = TrackOptions(frames=120, fps=5, people=12, standing=3, vehicles=4, seed=7)
    again = generate_tracks(scene, catalog, options)  # its own obstacles, from the setup
    assert write_openlabel(again.scene) == write_openlabel(generated.scene)
    other = generate_tracks(scene, catalog, dataclasses.replace(options, seed=8), obstacles=obstacles)
    assert write_openlabel(other.scene) != write_openlabel(generated.scene)


def test_no_two_movers_overlap_at_any_frame(generated):
    tracks = generated.tracks
    assert len(tracks) == 19
    for i, a in enumerate(tracks):
        for b in tracks[i + 1:]:
            assert len(overlapping_frames(a, b)) == 0, (a.kind, b.kind)


def test_overlap_test_sees_a_collision(generated):
    walker = next(t for t in generated.tracks if t.kind == "walking")
    shifted = dataclasses.replace(walker, position=walker.position + [0.2, 0.0, 0.0])
    assert len(overlapping_frames(walker, shifted)) == int(walker.present.sum())


def test_walkers_move_continuously_at_their_speed_between_entrances(setup, generated):
    scene, catalog = setup
    areas = {a.place: a for a in ground_areas(catalog, scene)}
    walkers = [t for t in generated.tracks if t.kind == "walking"]
    assert len(walkers) == 12
    for t in walkers:
        assert 0.8 <= t.speed_m_s <= 1.8
        idx = np.flatnonzero(t.present)
        assert np.all(np.diff(idx) == 1)  # one appearance, no gaps
        steps = np.linalg.norm(np.diff(t.position[idx, :2], axis=0), axis=1)
        assert steps.max() <= t.speed_m_s / 5.0 + 1e-6  # never faster than the speed (corners: shorter)
        assert np.median(steps) == pytest.approx(t.speed_m_s / 5.0, rel=0.02)
        assert t.route[0].startswith("entrance") and t.route[-1].startswith("entrance")
        assert t.route[0] != t.route[-1]
        if idx[0] > 0:  # entered during the sequence: at its entrance
            entrance = areas[t.route[0]]
            local = np.abs((t.position[idx[0], :2] - entrance.centre[:2]) @ entrance.axes)
            assert np.all(local <= entrance.half + 0.5)
        # on the walk places' ground (kerb height 0.15 m or the deck)
        assert np.all((t.position[idx, 2] >= -1e-9) & (t.position[idx, 2] <= 0.15 + 1e-9))


def test_vehicles_stay_upright_on_the_ground_and_park_in_their_bay(setup, generated):
    scene, catalog = setup
    areas = {a.place: a for a in ground_areas(catalog, scene)}
    vehicles = [o for o in generated.scene.objects if o.class_name == "vehicle"]
    assert len(vehicles) == 4
    for obj in vehicles:
        for _, pose in obj.frame_poses:
            m = pose.as_array()
            assert m[2, 3] == pytest.approx(0.0)
            assert np.allclose(m[:3, 2], [0, 0, 1]) and np.allclose(m[2, :3], [0, 0, 1])
    for track in (t for t in generated.tracks if t.kind == "arriving"):
        bay = areas[track.route[-1]]
        assert bay.role == "bay"
        last = np.flatnonzero(track.present)[-1]
        if last == len(track.present) - 1 and np.allclose(track.position[-1], track.position[-2]):
            assert np.allclose(track.position[-1, :2], bay.centre[:2], atol=1e-6)
            front = np.array([math.sin(track.yaw[-1]), -math.cos(track.yaw[-1])])  # the asset's -Y
            inwards = bay.centre[:2] - areas[track.route[-2]].centre[:2]  # from its lane spot
            assert front @ inwards / np.linalg.norm(inwards) == pytest.approx(1.0, abs=1e-6)  # nose first
    leaving = [t for t in generated.tracks if t.kind == "leaving"]
    assert leaving
    for track in leaving:  # parked nose first in its bay at frame 0
        bay = areas[track.route[0]]
        assert np.allclose(track.position[0, :2], bay.centre[:2])
        front = np.array([math.sin(track.yaw[0]), -math.cos(track.yaw[0])])
        inwards = bay.centre[:2] - areas[track.route[1]].centre[:2]
        assert front @ inwards / np.linalg.norm(inwards) == pytest.approx(1.0, abs=1e-6)
    # Backed out into the lane, a leaving vehicle waits along it, not across it.
    waited = 0
    for track in leaving:
        lane = areas[track.route[1]]
        idx = np.flatnonzero(track.present)
        still = idx[1:][np.all(track.position[idx[1:]] == track.position[idx[:-1]], axis=1)]
        for f in still[np.linalg.norm(track.position[still, :2] - areas[track.route[0]].centre[:2], axis=1) > 1.0]:
            front = np.array([math.sin(track.yaw[f]), -math.cos(track.yaw[f])])
            assert abs(front @ lane.axes[:, int(np.argmax(lane.half))]) == pytest.approx(1.0, abs=0.01)
            waited += 1
    assert waited


def test_document_has_fps_ground_positions_and_round_trips(generated):
    doc = write_openlabel(generated.scene)
    body = doc["openlabel"]
    assert body["metadata"]["usdscene"]["fps"] == 5.0
    assert body["frames"]["10"]["frame_properties"]["timestamp"] == 2.0
    walker = next(o for o in generated.scene.objects if o.name == "walking_000")
    frame = walker.frame_intervals[0].frame_start
    data = body["frames"][str(frame)]["objects"][walker.uid]["object_data"]
    ground = next(v["val"] for v in data["vec"] if v["name"] == "ground_position_m")
    pose = next(v["val"] for v in data["vec"] if v["name"] == "pose_matrix4x4")
    assert ground == [pose[3], pose[7], pose[11]]
    assert write_openlabel(read_openlabel(json.loads(json.dumps(doc)))) == doc


def test_report(generated):
    report = generated.report
    assert report["people_per_frame"]["count"] == 120 and report["people_per_frame"]["min"] >= 3
    assert report["track_frames"]["walking"]["count"] == 12
    assert set(report["cameras"]) == {"pole_north", "pole_east", "ceiling_fisheye", "entrance_wide"}
    assert all(c["tracks_in_view"] >= 1 for c in report["cameras"].values())
    assert report["foot_sliding_m_per_m"]["max"] == 1.0  # the car park's pedestrian has no walk cycle


def test_walk_cycle_phase_follows_distance(setup):
    scene, catalog = setup
    entry = catalog["pedestrian"]
    cycle = tuple(f"walk_{k}" for k in range(8))
    walking = dataclasses.replace(entry, variants={**entry.variants, "pose": (*cycle, "stand", "idle")},
                                  default_variants={**entry.default_variants, "pose": "stand"})
    catalog = dataclasses.replace(catalog, entries={**catalog.entries, "pedestrian": walking})
    generated = generate_tracks(scene, catalog, TrackOptions(frames=60, fps=10, people=6, standing=2, seed=2,
                                                             person_classes=("pedestrian",)))
    doc = write_openlabel(generated.scene)["openlabel"]
    for track, obj in zip(generated.tracks, generated.scene.objects[-len(generated.tracks):]):
        if track.kind == "standing":
            assert obj.pose_variant in ("stand", "idle")
            continue
        phases = walk_phases(track)
        assert np.allclose(phases, np.mod(track.walked / track.stride_m, 1.0))
        for f in np.flatnonzero(track.present):
            data = doc["frames"][str(f)]["objects"][obj.uid]["object_data"]
            shown = next(t["val"] for t in data["text"] if t["name"] == "walk_pose_variant")
            assert shown == f"walk_{int(phases[f] * 8 + 1e-6) % 8}"
        sliding = foot_sliding(track, 8)
        if track.speed_m_s >= 1.125:  # locked to 10 fps: the shown poses keep pace with the ground
            assert 0.9 <= track.stride_m <= 1.8 and sliding < 1e-6
        else:
            assert track.stride_m == STRIDE_M and sliding > 0.3
        unlocked = dataclasses.replace(track, stride_m=STRIDE_M * 1.03)
        assert foot_sliding(unlocked, 8) > 0.1
        assert foot_sliding(track, 0) == 1.0


def test_cabin_walker_walks_the_aisle():
    """In the cabin a walker comes in at the front door and walks the aisle (to its end and back)."""
    cabin = read_openlabel(Path(__file__).resolve().parents[1] / "examples" / "aircraft_cabin" / "cabin.openlabel.json")
    catalog = load_catalog([CAR_PARK / "assets"])
    door = PlaceRef("9001", "entrance_front", (DeclaredRegion("is_on", Pose.from_rotation_translation(
        np.eye(3), [-0.05, 0.0, 0.0]), (0.5, 0.8, 2.0)),))
    setup = dataclasses.replace(cabin, objects=(), relations=(), places=(door,))
    generated = generate_tracks(setup, catalog, TrackOptions(frames=40, fps=5, people=1, seed=0,
                                                             person_classes=("person",)))
    track = generated.tracks[0]
    assert track.route[0] == "entrance_front" and any(p.startswith("aisle_") for p in track.route)
    idx = np.flatnonzero(track.present)
    assert np.all(np.abs(track.position[idx, 1]) <= 0.26)  # within the 0.5 m aisle
    assert track.position[idx, 0].min() < -3.0  # walked down the aisle
    assert track.position[idx, 0].min() < -7.0  # to the aisle's far end (aisle_20) and back
    # Nobody passes anybody in a 0.44 m aisle: a walker fits only where it never meets the others
    # (one following another the same way, 0.32 m deep along the aisle, may; the walkers of a
    # steady flow are spread along the 24 s route), so 9 fit in these 8 s and 10 do not.
    with pytest.raises(DocumentError, match=r"--people: only [0-9] of 10 walkers fit"):
        generate_tracks(setup, catalog, TrackOptions(frames=40, fps=5, people=10, seed=0, person_classes=("person",)))


def test_every_walking_speed_locks_at_5_fps_with_8_poses():
    for speed in np.linspace(0.8, 1.8, 201):
        stride = locked_stride(float(speed), 5.0, 8)
        steps = speed / 5.0 * 8 / stride
        assert 0.9 <= stride <= 1.8 and abs(steps - round(steps)) < 1e-9, speed
    assert locked_stride(0.9, 10.0, 8) == STRIDE_M  # too slow for 10 fps: keeps the nominal stride


def _without_places(scene, words):
    return dataclasses.replace(scene, places=tuple(p for p in scene.places if not p.name.startswith(words)))


def test_bad_input_is_one_clear_error(setup, tmp_path):
    scene, catalog = setup
    options = TrackOptions(frames=20, fps=5, people=2, seed=0)
    walkless = dataclasses.replace(catalog, entries={**catalog.entries, "car_park": dataclasses.replace(
        catalog["car_park"], places={k: v for k, v in catalog["car_park"].places.items() if not k.startswith("walkway")})})
    cases = [
        (_without_places(scene, ("footpath", "entrance")), walkless, options, "no walkable space"),
        (_without_places(scene, ("entrance",)), catalog, options, "no entrance for walkers"),
        (scene, catalog, dataclasses.replace(options, people=400), "--people: about 400 people would be on"),
        (scene, catalog, dataclasses.replace(options, people=0, vehicles=11), "--vehicles"),
        (_without_places(scene, ("entrance_vehicles",)), catalog, dataclasses.replace(options, vehicles=1),
         "no entrance for vehicles"),
        (scene, catalog, dataclasses.replace(options, fps=0.0), "--fps"),
        (scene, catalog, dataclasses.replace(options, fps=5000.0), "--fps"),
    ]
    for setup_scene, cat, opts, message in cases:
        with pytest.raises(DocumentError) as info:
            generate_tracks(setup_scene, cat, opts)
        assert message in str(info.value), str(info.value)


def test_cli_writes_nothing_on_error(tmp_path, capsys):
    from usdscene.cli import main

    out = tmp_path / "doc.json"
    code = main(["generate", "tracks", "--setup", str(CAR_PARK / "setup_moving.openlabel.json"), "-o", str(out),
                 "--frames", "10", "--fps", "5", "--people", "500"])
    assert code == 1
    assert "--people" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    assert main(["generate", "tracks", "--setup", "x.json", "-o", str(out), "--fps", "-1"]) == 2


def test_movers_face_where_they_go(setup, generated):
    """Every mover's front is its asset's -Y (the catalog's contract, whatever its footprint):
    the rotated -Y axis points along the walked or driven direction, and against it while a
    leaving vehicle backs out of its bay. The person is wider across the shoulders than deep
    and the car park's vehicle, added with ``--forward-axis +X``, longer along y."""
    scene, catalog = setup
    size = np.subtract(catalog["person"].extent_max_m, catalog["person"].extent_min_m)
    assert size[0] > 1.5 * size[1]
    size = np.subtract(catalog["vehicle"].extent_max_m, catalog["vehicle"].extent_min_m)
    assert catalog["vehicle"].forward_axis == "+X" and size[1] > 1.5 * size[0]
    seen = set()
    for t in generated.tracks:
        if t.kind == "standing":
            continue
        idx = np.flatnonzero(t.present)
        step = np.diff(t.position[idx, :2], axis=0)
        moving = np.linalg.norm(step, axis=1) > 1e-6
        direction = step[moving] / np.linalg.norm(step[moving], axis=1)[:, None]
        yaw = t.yaw[idx[1:]][moving]
        front = np.stack([np.sin(yaw), -np.cos(yaw)], axis=1)  # the asset's -Y turned by the yaw
        along = np.sum(front * direction, axis=1)
        if t.kind == "leaving":
            assert along[0] < -0.95 and along[-1] > 0.95  # backs out, then drives off nose first
            assert np.median(np.abs(along)) > 0.95
        else:
            assert np.median(along) > 0.95, (t.kind, t.class_name)
        seen.add(t.kind)
    assert seen == {"walking", "arriving", "leaving"}


def test_a_vehicle_class_longer_across_than_along_is_warned_about(setup, caplog):
    """A vehicle whose front was never turned to -Y (added without ``--forward-axis``, long
    along x) follows the contract, so it would drive sideways: the generator says so."""
    scene, catalog = setup
    entry = catalog["vehicle"]
    lo, hi = entry.extent_min_m, entry.extent_max_m
    turned = dataclasses.replace(entry, extent_min_m=(lo[1], lo[0], lo[2]), extent_max_m=(hi[1], hi[0], hi[2]),
                                 forward_axis="-Y")
    catalog = dataclasses.replace(catalog, entries={**catalog.entries, "vehicle": turned})
    with caplog.at_level("WARNING", logger="usdscene.generate.vehicles"):
        generate_tracks(scene, catalog, TrackOptions(frames=20, fps=5, vehicles=1, seed=1))
    assert "--forward-axis" in caplog.text and "'vehicle'" in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="usdscene.generate.vehicles"):
        generate_tracks(scene, setup[1], TrackOptions(frames=20, fps=5, vehicles=1, seed=1))
    assert "--forward-axis" not in caplog.text


def test_standing_people_take_an_idle_pose_of_their_class(setup):
    scene, catalog = setup
    generated = generate_tracks(scene, catalog, TrackOptions(frames=10, fps=5, standing=12, seed=3,
                                                             person_classes=("person",)))
    poses = {t.pose_variant for t in generated.tracks}
    assert poses <= {"standing", "idle", "phone"} and len(poses) >= 2
    assert set(catalog["person"].variants["pose"]) >= poses


def _obstacle_boxes(setup) -> list[tuple[np.ndarray, np.ndarray]]:
    """The car park's pillars, walls and parapet, each a box (lo (3,), hi (3,)): the connected
    parts of the environment's triangles that reach above the kerbs and start below the roof."""
    import tempfile

    import trimesh

    from usdscene.scene.compose import compose_stage
    from usdscene.scene.stage_geometry import environment_triangles

    scene, catalog = setup
    with tempfile.TemporaryDirectory() as folder:
        compose_stage(dataclasses.replace(scene, objects=(), relations=(), places=(), lights=()), catalog, folder)
        triangles = environment_triangles(Path(folder) / "scene.usda")
    mesh = trimesh.Trimesh(vertices=triangles.reshape(-1, 3), faces=np.arange(3 * len(triangles)).reshape(-1, 3))
    boxes = [part.bounds for part in mesh.split(only_watertight=False)]
    return [(lo, hi) for lo, hi in boxes if hi[2] > STEP_HEIGHT_M and lo[2] < 2.0]


def _frames_in_obstacles(track, boxes, height_m: float, margin_m: float) -> list[int]:
    """Frames where the track's bare footprint, less the obstacle grid's tolerance of one cube,
    overlaps a box that reaches into its height band (separating axes, exact)."""
    offset, half = track.footprint
    half = half - margin_m - OBSTACLE_CELL_M
    hits = []
    for f in np.flatnonzero(track.present):
        c, s = math.cos(track.yaw[f]), math.sin(track.yaw[f])
        axes = np.array([[c, -s], [s, c]])
        centre = track.position[f, :2] + axes @ offset
        ground = track.position[f, 2]
        for lo, hi in boxes:
            if hi[2] <= ground + STEP_HEIGHT_M or lo[2] >= ground + height_m:
                continue
            d = (lo[:2] + hi[:2]) / 2.0 - centre
            box_half = (hi[:2] - lo[:2]) / 2.0
            separated = any(abs(d @ n) >= np.abs(n @ axes) @ half + np.abs(n) @ box_half
                            for n in (*axes.T, np.array([1.0, 0.0]), np.array([0.0, 1.0])))
            if not separated:
                hits.append(int(f))
                break
    return hits


def test_movers_keep_out_of_the_pillars_and_walls(setup, obstacles):
    """Sequences of the moving example's size keep every walker, standing person and vehicle out
    of the environment's pillars, walls, parapet and clutter at every frame; the same draws without the
    obstacles walk people into them (seeds where they do: a pillar reaches 0.2 m into the
    south footpath, so it takes a walker offset to that side passing it)."""
    scene, catalog = setup
    boxes = _obstacle_boxes(setup)
    # 8 pillars, 2 walls, the parapet; the clutter beside the footpaths: 4 lamp posts, 4 bins,
    # 8 bollards, a sign's pole and plate (the backdrop is no obstacle).
    assert len(boxes) == 29
    blind_obstacles = Obstacles.from_triangles(np.zeros((0, 3, 3)))

    def crossings(generated):
        out = []
        for t in generated.tracks:
            margin = VEHICLE_MARGIN_M if t.kind in ("arriving", "leaving") else PERSON_MARGIN_M
            if _frames_in_obstacles(t, boxes, catalog[t.class_name].extent_max_m[2], margin):
                out.append((t.kind, t.route))
        return out

    blind = []
    for seed in (5, 11, 20):
        options = TrackOptions(frames=100, fps=5, people=12, standing=3, vehicles=4, seed=seed,
                               person_classes=("person",))
        assert crossings(generate_tracks(scene, catalog, options, obstacles=obstacles)) == []
        blind += crossings(generate_tracks(scene, catalog, options, obstacles=blind_obstacles))
    assert any(kind == "walking" for kind, _ in blind)


def test_a_route_only_through_an_obstacle_is_one_clear_error(setup):
    """A ceiling 1 m above the whole deck (over its floor): no walker can come through, and the
    error says why."""
    scene, catalog = setup
    ceiling = np.array([[[-20.0, -15.0, z], [20.0, -15.0, z], [20.0, 15.0, z]] for z in (0.0, 1.0)]
                       + [[[-20.0, -15.0, z], [20.0, 15.0, z], [-20.0, 15.0, z]] for z in (0.0, 1.0)])
    with pytest.raises(DocumentError, match=r"--people: only 0 of 1 walkers fit: every one of 200 routes .* "
                                            r"meets an obstacle of the environment"):
        generate_tracks(scene, catalog, TrackOptions(frames=100, fps=5, people=1, seed=5, person_classes=("person",)),
                        obstacles=Obstacles.from_triangles(ceiling))


def test_vehicles_turn_on_a_turning_circle(generated):
    """Vehicles turn on arcs of about their turning radius (3 m where the places leave room), not
    on the spot: between frames where a vehicle drives at least 0.2 m its heading turns by at
    most the step over 1.8 m (the arcs' 5-degree chords make a frame's estimate low by up to
    a third). Backing out of a bay runs on a 3 m arc too."""
    tight = []
    for t in generated.tracks:
        if t.kind not in ("arriving", "leaving"):
            continue
        idx = np.flatnonzero(t.present)
        step = np.linalg.norm(np.diff(t.position[idx, :2], axis=0), axis=1)
        turn = np.abs(np.angle(np.exp(1j * np.diff(t.yaw[idx]))))
        driving = (step > 0.2) & (turn < math.pi / 2)  # not the switch from reverse to forward
        tight += list(step[driving & (turn > 0)] / turn[driving & (turn > 0)])
    assert len(tight) > 10 and min(tight) > 1.8
