"""usdscene generate tracks --motion crowd: people simulated by JuPedSim on the car park's footpaths."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely

from usdscene.converters.openlabel import read_openlabel, write_openlabel
from usdscene.document.model import DeclaredRegion, PlaceRef, Pose
from usdscene.errors import DocumentError
from usdscene.generate.crowd import (GROUP_SPREAD_M, GROUP_TYPICAL_SPREAD_M, CrowdOptions, check_crowd, generate_crowd, simulate)
from usdscene.generate.crowd_area import PERSON_RADIUS_M, crowd_layout, crowd_role
from usdscene.generate.motion import environment_obstacles
from usdscene.scene.catalog import load_catalog

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"


def _place(uid: str, name: str, centre, size, numbers: dict | None = None) -> PlaceRef:
    extra = ""
    if numbers:
        from usdscene.document.model import canonical_json

        extra = canonical_json({"object_data": {"num": [{"name": k, "val": v} for k, v in sorted(numbers.items())]}})
    return PlaceRef(uid, name, (DeclaredRegion("is_on", Pose.from_rotation_translation(np.eye(3), centre), size),),
                    extra=extra)


@pytest.fixture(scope="module")
def setup():
    scene = read_openlabel(CAR_PARK / "setup_moving.openlabel.json")
    return scene, load_catalog(scene.asset_paths, base_dir=CAR_PARK)


@pytest.fixture(scope="module")
def obstacles(setup):
    return environment_obstacles(*setup)


@pytest.fixture(scope="module")
def station(setup):
    """The car park with a queue (a kiosk on the north footpath) and a waiting place (south)."""
    scene, catalog = setup
    queue = _place("9101", "queue_kiosk", [4.0, 9.85, 0.15], (5.0, 0.8, 2.0), {"service_per_min": 12})
    wait = _place("9102", "waiting_board", [-4.0, -9.85, 0.15], (3.0, 1.2, 2.0))
    return dataclasses.replace(scene, places=(*scene.places, queue, wait)), catalog


@pytest.fixture(scope="module")
def crowd(setup, obstacles):
    scene, catalog = setup
    return generate_crowd(scene, catalog, CrowdOptions(frames=150, fps=5, people=80, seed=3, group_share=0.3,
                                                       person_classes=("person",)), obstacles=obstacles)


def _people_xy(generated):
    return np.stack([np.where(t.present[:, None], t.position[:, :2], np.nan) for t in generated.tracks])


def test_vocabulary():
    assert crowd_role("ticket_gate_03", "") == "queue"
    assert crowd_role("platform_edge_2", "") == "wait"
    assert crowd_role("platform_2", "") == "walk"
    assert crowd_role("bench_1", "") == "seat"
    assert crowd_role("door_west", "") == "entrance"
    assert crowd_role("x", "waypoint") == "waypoint"
    assert crowd_role("departure_boards", "") == "wait"


def test_walkable_area_is_walk_places_minus_obstacles(setup, obstacles):
    scene, catalog = setup
    layout = crowd_layout(scene, catalog, obstacles)
    assert isinstance(layout.walkable, (shapely.Polygon, shapely.MultiPolygon))
    # the footpaths (2 x 32 x 2.4 m) and the crossing, less the pillars and parapet that reach into them
    assert 100.0 < layout.walkable.area < 2 * 32 * 2.4 + 1.6 * 17.3 + 4 * 2.4
    assert layout.obstacles.area > 0.5
    assert layout.walkable.distance(layout.obstacles) >= PERSON_RADIUS_M - 1e-3
    # the vehicle gate on the lane is no entrance of the crowd
    assert {s.place for s in layout.of_role("entrance")} == {"entrance_ne", "entrance_nw", "entrance_se", "entrance_sw"}


def test_two_hundred_walkers_pass_each_other_on_the_footpaths(setup, obstacles):
    """The route generator refuses 100 walkers here; the crowd holds 200 over 400 frames."""
    scene, catalog = setup
    generated = generate_crowd(scene, catalog, CrowdOptions(frames=400, fps=5, people=200, seed=1,
                                                            person_classes=("person",)), obstacles=obstacles)
    xy = _people_xy(generated)
    inside = np.isfinite(xy[:, :, 0]).sum(axis=0)
    assert inside.min() >= 150 and inside[0] >= 195
    # passing: two people on one footpath going opposite ways swap their order along it
    north = [t for t in generated.tracks if t.route[-1] in ("entrance_ne", "entrance_nw")]
    east = [t for t in north if t.route[-1] == "entrance_ne" and t.present.sum() > 50]
    west = [t for t in north if t.route[-1] == "entrance_nw" and t.present.sum() > 50]
    assert east and west
    crossed = 0
    for a in east:
        for b in west:
            both = np.flatnonzero(a.present & b.present)
            if len(both) > 2:
                d = a.position[both, 0] - b.position[both, 0]
                crossed += bool(d[0] < 0 < d[-1])
    assert crossed >= 10


def test_nobody_closer_than_two_radii_less_5_cm_nor_inside_an_obstacle(crowd, setup, obstacles):
    xy = _people_xy(crowd)
    n, frames = xy.shape[:2]
    worst = math.inf
    for f in range(frames):
        p = xy[:, f][np.isfinite(xy[:, f, 0])]
        d = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(len(p)) * 1e9
        worst = min(worst, float(d.min()))
    assert worst >= 2 * PERSON_RADIUS_M - 0.05
    layout = crowd_layout(*setup, obstacles)
    every = xy.reshape(-1, 2)
    every = every[np.isfinite(every[:, 0])]
    # every centre on the walk places' support (the footpaths' kerb at 0.15 m) ...
    z = layout.support_z(every)
    assert np.all(np.isfinite(z))
    # ... and no disc of a person less 5 cm reaches into an obstacle's footprint
    assert float(shapely.distance(layout.obstacles, shapely.points(every)).min()) >= PERSON_RADIUS_M - 0.05


def test_same_seed_same_bytes_other_seed_other(setup, obstacles, crowd):
    scene, catalog = setup
    options = CrowdOptions(frames=150, fps=5, people=80, seed=3, group_share=0.3, person_classes=("person",))
    again = generate_crowd(scene, catalog, options, obstacles=obstacles)
    assert json.dumps(write_openlabel(again.scene)) == json.dumps(write_openlabel(crowd.scene))
    other = generate_crowd(scene, catalog, dataclasses.replace(options, seed=4), obstacles=obstacles)
    assert write_openlabel(other.scene) != write_openlabel(crowd.scene)


def test_bodies_face_where_they_walk_and_stand_when_still(crowd):
    doc = write_openlabel(crowd.scene)["openlabel"]
    cosines = []
    for track, obj in zip(crowd.tracks, crowd.scene.objects[-len(crowd.tracks):]):
        idx = np.flatnonzero(track.present)
        for f in idx[2:-2]:
            move = track.position[f + 2, :2] - track.position[f - 2, :2]  # over 0.8 s around the frame
            if np.linalg.norm(move) < 0.8 or not track.present[f - 2:f + 3].all():
                continue
            front = np.array([math.sin(track.yaw[f]), -math.cos(track.yaw[f])])  # the asset's -Y
            cosines.append(front @ move / np.linalg.norm(move))
        for f in idx[:3]:
            data = doc["frames"][str(f)]["objects"][obj.uid]["object_data"]
            ground = next(v["val"] for v in data["vec"] if v["name"] == "ground_position_m")
            assert ground == pytest.approx(list(track.position[f]))
            shown = next(t["val"] for t in data["text"] if t["name"] == "walk_pose_variant")
            assert shown == "standing" if not track.moving[f] else shown.startswith("walk_")
    cosines = np.asarray(cosines)
    assert len(cosines) > 1000
    assert np.mean(cosines > 0.7) > 0.95 and np.median(cosines) > 0.98
    assert crowd.report["foot_sliding_m_per_m"]["mean"] < 0.5


def test_queue_forms_and_releases(station, obstacles):
    scene, catalog = station
    layout = crowd_layout(scene, catalog, obstacles)
    options = CrowdOptions(frames=300, fps=5, people=40, seed=2, queue_share=0.5, wait_share=0.5, wait_s=(5.0, 10.0),
                           person_classes=("person",))
    run = simulate(layout, options, check_crowd(layout, options, "setup"))
    counts = run.queue_counts["queue_kiosk"]
    assert counts.max() >= 3  # a line forms ...
    assert run.released["queue_kiosk"] >= 10  # ... and is served at 12 per minute (60 s: at most 12 + 1)
    assert run.released["queue_kiosk"] <= 13
    assert len(run.waited) >= 3 and all(4.5 <= w <= 10.5 for w in run.waited)


def test_group_stays_within_its_spread(setup, obstacles):
    scene, catalog = setup
    layout = crowd_layout(scene, catalog, obstacles)
    options = CrowdOptions(frames=200, fps=5, arrivals_per_min=6, group_share=1.0, seed=5, person_classes=("person",))
    run = simulate(layout, options, check_crowd(layout, options, "setup"))
    groups = sorted(set(run.group[run.group >= 0].tolist()))
    assert len(groups) >= 5
    spreads = []
    for g in groups:
        members = np.flatnonzero(run.group == g)
        xy = run.xy[members]
        all_in = np.all(np.isfinite(xy[:, :, 0]), axis=0)
        if all_in.sum() < 10:
            continue
        frames = np.flatnonzero(all_in)[5:]
        centre = xy[:, frames].mean(axis=0)
        spreads.append(float(np.linalg.norm(xy[:, frames] - centre, axis=2).max()))
    assert len(spreads) >= 5 and max(spreads) <= GROUP_SPREAD_M
    assert float(np.median(spreads)) <= GROUP_TYPICAL_SPREAD_M


def test_speed_falls_as_density_rises(setup, obstacles):
    """The fundamental diagram's direction: the denser the footpaths, the slower the people."""
    scene, catalog = setup
    layout = crowd_layout(scene, catalog, obstacles)
    speeds = []
    for density in (0.1, 0.5, 1.2):
        options = CrowdOptions(frames=60, fps=5, density_p_m2=density, seed=1, speed_range_m_s=(1.2, 1.4))
        run = simulate(layout, options, check_crowd(layout, options, "setup"))
        step = np.linalg.norm(np.diff(run.xy, axis=1), axis=2) * 5
        speeds.append(float(np.nanmean(step)))
    assert speeds[0] > speeds[1] > speeds[2]


def test_bad_input_one_clear_error(setup, obstacles):
    scene, catalog = setup
    with pytest.raises(DocumentError, match=r"--density: .* holds at most \d+ \(2 per m²\)"):
        generate_crowd(scene, catalog, CrowdOptions(frames=10, fps=5, density_p_m2=3.0), obstacles=obstacles)
    with pytest.raises(DocumentError, match=r"place 'entrance_ne': 900 arrivals per minute .* at most 187 per minute"):
        generate_crowd(scene, catalog, CrowdOptions(frames=10, fps=5, arrivals_per_min=900), obstacles=obstacles)
    # a queue on the lane: no entrance reaches it
    lone = _place("9201", "queue_lane", [11.35, 2.1, 0.0], (3.0, 1.0, 2.0))
    walk = _place("9202", "walkway_island", [11.35, 2.1, 0.0], (4.0, 1.4, 2.0))
    cut = dataclasses.replace(scene, places=(*scene.places, lone, walk))
    with pytest.raises(DocumentError, match=r"place 'queue_lane': no entrance reaches this queue place"):
        generate_crowd(cut, catalog, CrowdOptions(frames=10, fps=5, people=5), obstacles=obstacles)
    # an entrance on a walk place of its own, cut off from the others
    door = _place("9203", "entrance_island", [13.6, 2.1, 0.0], (0.6, 1.4, 2.0))
    cut = dataclasses.replace(scene, places=(*scene.places, walk, door))
    with pytest.raises(DocumentError, match=r"place 'entrance_island': the walkable area .* does not connect"):
        generate_crowd(cut, catalog, CrowdOptions(frames=10, fps=5, people=5), obstacles=obstacles)


def test_cli_writes_a_crowd_document(tmp_path, capsys):
    from usdscene.cli import main

    out = tmp_path / "crowd.openlabel.json"
    code = main(["generate", "tracks", "--motion", "crowd", "--setup", str(CAR_PARK / "setup_moving.openlabel.json"),
                 "-o", str(out), "--frames", "20", "--fps", "5", "--people", "12", "--group-share", "0.5",
                 "--conversations", "2", "--seed", "4", "--person-classes", "person"])
    assert code == 0, capsys.readouterr().err
    assert "crowd:" in capsys.readouterr().out
    report = json.loads((tmp_path / "crowd.openlabel.json.report.json").read_text())
    assert report["motion"] == "crowd" and report["crowd"]["standing"] >= 4
    scene = read_openlabel(out)
    assert scene.fps == 5.0 and len(scene.objects) >= 16


def test_crowd_without_the_extra_says_how_to_install(tmp_path, capsys, monkeypatch):
    """Without JuPedSim (an import that fails, as in an install without the extra): one line, exit 1."""
    import sys

    from usdscene.cli import main

    monkeypatch.setitem(sys.modules, "jupedsim", None)  # import jupedsim raises ImportError
    out = tmp_path / "crowd.openlabel.json"
    code = main(["generate", "tracks", "--motion", "crowd", "--setup", str(CAR_PARK / "setup_moving.openlabel.json"),
                 "-o", str(out), "--frames", "20", "--fps", "5", "--people", "12"])
    err = capsys.readouterr().err
    assert code == 1
    assert "pip install 'usdscene[crowd]'" in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_the_library_imports_no_engine_until_a_crowd_is_generated():
    import subprocess
    import sys

    code = ("import sys, usdscene.generate.crowd, usdscene.generate.crowd_area, usdscene.commands.generate; "
            "assert 'jupedsim' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_entrance_beside_the_platform_keeps_people_on_the_floor(setup, obstacles):
    """A user's platform case: the stairs' entrance box sits beside the walk place and reaches
    past the deck's west edge (x = -17 m), where there is no floor. People appear and walk only
    where there is floor: every position stands on a walk place's support surface."""
    from usdscene.generate.crowd_area import floor_missing

    scene, catalog = setup
    platform = _place("9301", "platform_test", [-8.0, 3.0, 0.0], (16.0, 4.0, 2.0))
    stairs = _place("9302", "stairs_test", [-16.6, 3.0, 0.0], (2.0, 3.0, 2.0))  # half of it off the deck
    door = _place("9303", "entrance_test_east", [0.5, 3.0, 0.0], (1.0, 4.0, 2.0))
    cut = dataclasses.replace(scene, places=(platform, stairs, door))
    layout = crowd_layout(cut, catalog, obstacles)
    assert layout.walkable.bounds[0] >= -17.0 - 1e-6  # the part of the stairs' box off the deck is not walkable
    generated = generate_crowd(cut, catalog, CrowdOptions(frames=100, fps=5, people=20, seed=2,
                                                          person_classes=("person",)), obstacles=obstacles)
    xy = _people_xy(generated).reshape(-1, 2)
    xy = xy[np.isfinite(xy[:, 0])]
    assert len(xy) > 1000
    assert np.all(np.isfinite(layout.support_z(xy)))
    assert not floor_missing(obstacles, xy, 0.0).any()
    routes = [t.route for t in generated.tracks]
    # directions drawn fairly: both doors are used as exits
    exits = [r[-1] for r in routes]
    assert exits.count("stairs_test") >= 5 and exits.count("entrance_test_east") >= 5


def test_route_generator_refuses_an_entrance_beside_the_platform_past_the_floor(setup, obstacles):
    """The platform case in the route generator: the stairs' box beside the platform's end,
    past the deck's east edge (x = 17 m); its routes would start in the air, so the setup is
    refused naming the entrance (and with the box on the deck, the routes stand on the floor)."""
    from usdscene.generate.motion import TrackOptions, generate_tracks
    from usdscene.generate.obstacles import floor_missing

    scene, catalog = setup
    platform = _place("9401", "platform_test", [8.5, 3.0, 0.0], (17.0, 4.0, 2.0))
    west = _place("9402", "entrance_test_west", [-0.5, 3.0, 0.0], (1.0, 4.0, 2.0))
    stairs = _place("9403", "stairs_test", [17.6, 5.4, 0.0], (1.2, 0.8, 2.0))
    cut = dataclasses.replace(scene, places=(platform, west, stairs))
    options = TrackOptions(frames=60, fps=5, people=4, seed=1, person_classes=("person",))
    with pytest.raises(DocumentError, match=r"place 'stairs_test': walkers to and from this entrance would walk where "
                                            r"there is no floor, at \(17\.\d\d, "):
        generate_tracks(cut, catalog, options, obstacles=obstacles)
    on_deck = dataclasses.replace(cut, places=(platform, west, _place("9403", "stairs_test", [16.4, 5.4, 0.0],
                                                                      (1.2, 0.8, 2.0))))
    generated = generate_tracks(on_deck, catalog, options, obstacles=obstacles)
    for t in generated.tracks:
        idx = np.flatnonzero(t.present)
        assert not floor_missing(obstacles, t.position[idx, :2], t.position[idx, 2]).any()
