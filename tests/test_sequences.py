"""Generated sequence documents: balance, coverage, capacity (they compose), determinism.

On a tiny synthetic car park built in the test (places named ``bay_*``, ``kerb_*``,
``shelf_*``, nothing like the cabin) and on the shipped cabin with a few classes.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math

import numpy as np
import pytest

from test_compose_support import _asset_usda, _environment_usda, _yaw_pose, look_at_cv, pinhole
from usdscene.document import model as m
from usdscene.scene.catalog import load_catalog
from usdscene.cli import main
from usdscene.converters.openlabel import read_openlabel, write_document, write_openlabel
from usdscene.errors import DocumentError
from usdscene.generate.balance import balance_report
from usdscene.generate.combinations import Combination, fitting_combinations
from usdscene.generate.sequence_plans import FrameSlots, plan_random
from usdscene.generate.sequences import GenerateOptions, check_composes, generate_sequence, report_path

CLASSES = {  # class: (extent min, extent max, appearance variants)
    "crate": ((-0.3, -0.2, 0.0), (0.3, 0.2, 0.4), ("wood", "plastic")),
    "cone": ((-0.15, -0.15, 0.0), (0.15, 0.15, 0.5), ("orange", "yellow", "white")),
    "tyre": ((-0.35, -0.35, 0.0), (0.35, 0.35, 0.25), ()),
    "ladder": ((-0.25, -1.2, 0.0), (0.25, 1.2, 0.1), ("alu",)),  # only the bays are long enough
}
SITTER = ((-0.25, -0.25, -0.45), (0.25, 0.25, 0.8))
SITTER_LAP = (_yaw_pose(0.0, 0.0, -0.2, 0.25), (0.6, 0.5, 0.6))  # pose "sitting"; "slumped" has none


def _car_park_places() -> dict:
    places = {}
    for i in range(3):
        places[f"bay_{i + 1:02d}"] = {"kind": "bay", "regions": {
            "is_on": (_yaw_pose(0.0, 3.0 * i, 0.0, 0.0), (2.4, 4.8, 2.5)),
            "is_in_front_of": (_yaw_pose(0.0, 3.0 * i, -3.0, 0.0), (2.0, 1.0, 2.0))}}
    for i in range(2):
        places[f"kerb_{chr(ord('a') + i)}"] = {"kind": "kerb", "regions": {
            "is_on": (_yaw_pose(90.0, -3.0, 4.0 * i, 0.5), (0.8, 0.8, 1.5))}}  # a bench: people sit here
    places["shelf_x"] = {"kind": "shelf", "regions": {
        "is_in": (_yaw_pose(0.0, 10.0, 0.0, 1.0), (0.8, 0.5, 0.45)),
        "is_below": (_yaw_pose(0.0, 10.0, 0.0, 0.0), (0.8, 0.5, 0.3))}}
    return places


@pytest.fixture(scope="module")
def car_park(tmp_path_factory):
    """(catalog, setup scene, catalog folder) of the synthetic car park."""
    folder = tmp_path_factory.mktemp("car_park")
    (folder / "objects").mkdir()
    (folder / "environments").mkdir()
    classes = {}
    for name, (lo, hi, variants) in {**CLASSES, "sitter": (*SITTER, ("red", "blue", "green"))}.items():
        (folder / "objects" / f"{name}.usda").write_text(_asset_usda(name, lo, hi, variants))
        classes[name] = {"kind": "passenger" if name == "sitter" else "object", "usd": f"objects/{name}.usda",
                         "variants": {"appearance": list(variants)} if variants else {},
                         "default_variants": {"appearance": variants[0]} if variants else {},
                         "extent_m": [list(lo), list(hi)],
                         "relations": ["is_on"] if name == "sitter" else ["is_on", "is_in", "is_below", "is_in_front_of"]}
    lap_pose, lap_size = SITTER_LAP
    classes["sitter"]["variants"]["pose"] = ["sitting", "slumped"]
    classes["sitter"]["default_variants"]["pose"] = "sitting"
    classes["sitter"]["variant_places"] = {"pose": {
        "sitting": {"lap": {"kind": "lap", "regions": {"is_on": {"matrix": list(lap_pose.matrix),
                                                                  "size_m": list(lap_size)}}}},
        "slumped": {}}}
    places = _car_park_places()
    (folder / "environments" / "car_park.usda").write_text(_environment_usda(places).replace("test_cabin", "car_park"))
    classes["car_park"] = {"kind": "environment", "usd": "environments/car_park.usda", "extent_m": [[-5, -5, 0], [15, 5, 3]],
                           "places": {n: {"kind": p["kind"], "regions": {
                               rel: {"matrix": list(pose.matrix), "size_m": list(size)}
                               for rel, (pose, size) in p["regions"].items()}} for n, p in places.items()}}
    (folder / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1, "classes": classes}))
    catalog = load_catalog([folder], include_default=False)
    setup = m.SceneSpec(
        name="car_park_setup", environment="car_park", seed=0, asset_paths=(str(folder),),
        cameras=(m.Camera("overview", pinhole(), pose=look_at_cv((4.0, -9.0, 6.0), (4.0, 0.0, 0.0))),),
        render=m.RenderSettings(samples=1, resolution_px=(64, 48)))
    return catalog, setup, folder


def _instances(scene: m.SceneSpec) -> list[tuple[int, str, str, str]]:
    """(frame, class, relation, place name) of every generated relation; an object on a
    passenger's lap is at ``<seat>/lap``."""
    objects = scene.object_by_uid()
    places = {p.uid: p.name for p in scene.places}
    seat_of = {(rel.frame_intervals[0].frame_start, rel.subject_uid): places[rel.object_uid]
               for rel in scene.relations if rel.frame_intervals and rel.object_uid in places}
    return [(rel.frame_intervals[0].frame_start, objects[rel.subject_uid].class_name, rel.type,
             places.get(rel.object_uid) or seat_of[(rel.frame_intervals[0].frame_start, rel.object_uid)] + "/lap")
            for rel in scene.relations if rel.frame_intervals]  # the setup's own relations have none


def test_fitting_combinations_follow_region_sizes(car_park):
    catalog, setup, _ = car_park
    combos = fitting_combinations(catalog, "car_park", sorted(CLASSES))
    ladder = {(c.relation, c.place) for c in combos if c.class_name == "ladder"}
    assert ladder == {("is_on", f"bay_{i:02d}") for i in (1, 2, 3)}  # 2.4 m long: only the bays
    tyre = {(c.relation, c.place) for c in combos if c.class_name == "tyre"}
    assert ("is_in", "shelf_x") not in tyre  # 0.7 m wide does not fit a 0.5 m deep shelf either way
    assert ("is_on", "kerb_a") in tyre


@pytest.mark.parametrize("strategy", ["balanced", "appearance"])
def test_balanced_equal_per_class_and_covers_every_combination(car_park, strategy):
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy=strategy, frames=12, seed=5,
                                                            objects_per_frame=4))
    rows = _instances(gen.scene)
    per_class = collections.Counter(cls for _, cls, _, _ in rows)
    assert set(per_class) == set(CLASSES)
    assert sum(per_class.values()) == 12 * 4
    assert max(per_class.values()) - min(per_class.values()) <= 1
    combos = set(fitting_combinations(catalog, "car_park", sorted(CLASSES)))
    seen = {(cls, rel, place) for _, cls, rel, place in rows}
    assert {(c.class_name, c.relation, c.place) for c in combos} <= seen
    assert gen.report["coverage"]["uncovered_count"] == 0
    # One object per region and frame.
    assert len({(f, rel, place) for f, _, rel, place in rows}) == len(rows)
    counts = {c: v["instance_frames"] for c, v in gen.report["classes"].items()}
    assert counts == dict(per_class)


def test_random_is_unbalanced_but_every_instance_fits_a_free_region(car_park):
    catalog, setup, _ = car_park
    options = GenerateOptions(strategy="random", frames=40, seed=5, objects_per_frame=3)
    gen = generate_sequence(setup, catalog, options)
    rows = _instances(gen.scene)
    fitting = {(c.class_name, c.relation, c.place) for c in fitting_combinations(catalog, "car_park", sorted(CLASSES))}
    assert rows and all((cls, rel, place) in fitting for _, cls, rel, place in rows)
    assert len({(f, rel, place) for f, _, rel, place in rows}) == len(rows)  # one object per region and frame
    per_class = collections.Counter(cls for _, cls, _, _ in rows)
    assert set(per_class) == set(CLASSES)
    # No balancing: the class counts are whatever the draws give (balanced keeps them within 1).
    assert max(per_class.values()) - min(per_class.values()) > 1
    assert gen.report["generator"]["strategy"] == "random"
    again = generate_sequence(setup, catalog, options)
    assert _instances(again.scene) == rows  # same seed, same document


def test_random_draws_classes_then_places_uniformly():
    """Class A fits one region, class B five regions at two places (four at p1, one at p2): a
    uniform class draw gives A about half the instances (a uniform region draw would give 1/6),
    and B's uniform place draw puts about half of B at p2 (a uniform region draw: 1/5)."""
    combos = [Combination("a", "is_on", "p0")]
    combos += [Combination("b", rel, "p1") for rel in ("is_on", "is_in", "is_below", "is_in_front_of")]
    combos += [Combination("b", "is_on", "p2")]
    conflicts = {c.region: frozenset({c.region}) for c in combos}
    plan = plan_random(combos, ("a", "b"), FrameSlots(2000, 1, [set() for _ in range(2000)]), conflicts,
                       np.random.default_rng(3))
    drawn = [c for frame in plan for c in frame]
    assert len(drawn) == 2000
    share_a = sum(c.class_name == "a" for c in drawn) / len(drawn)
    b = [c for c in drawn if c.class_name == "b"]
    share_p2 = sum(c.place == "p2" for c in b) / len(b)
    assert 0.45 < share_a < 0.55 and 0.44 < share_p2 < 0.56
    # A taken region is never drawn again in that frame: two draws per frame, A at most once.
    plan = plan_random(combos, ("a", "b"), FrameSlots(200, 2, [set() for _ in range(200)]), conflicts,
                       np.random.default_rng(4))
    assert all(sum(c.class_name == "a" for c in frame) <= 1 for frame in plan)
    assert any(len(frame) == 1 for frame in plan)  # A drawn twice: the second draw is lost


def test_too_few_frames_reports_uncovered_and_the_frames_that_would(car_park):
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=2, seed=1,
                                                            objects_per_frame=4))
    coverage = gen.report["coverage"]
    assert coverage["uncovered_count"] > 0
    assert coverage["uncovered_count"] == len(coverage["uncovered"])
    more = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=coverage["frames_for_full_coverage"],
                                                             seed=1, objects_per_frame=4))
    assert more.report["coverage"]["uncovered_count"] == 0


def test_single_class_one_class_and_relation_per_frame_every_place(car_park):
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="single-class", seed=2))
    rows = _instances(gen.scene)
    frames = collections.defaultdict(set)
    for f, cls, rel, place in rows:
        frames[f].add((cls, rel))
    assert all(len(v) == 1 for v in frames.values())
    combos = fitting_combinations(catalog, "car_park", sorted(CLASSES))
    assert sorted((cls, rel, place) for _, cls, rel, place in rows) == sorted(
        (c.class_name, c.relation, c.place) for c in combos)
    assert len(frames) == len({(c.class_name, c.relation) for c in combos})


def test_occupancy_seats_passengers_only_where_legs_fit(car_park):
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=6, seed=3,
                                                            objects_per_frame=3, occupancy=1.0))
    rows = _instances(gen.scene)
    seated = [(f, place) for f, cls, _, place in rows if cls == "sitter"]
    assert seated and {p for _, p in seated} <= {"kerb_a", "kerb_b"}  # bays are on the floor: no legroom
    taken = collections.Counter((f, rel, place) for f, _, rel, place in rows)
    assert max(taken.values()) == 1  # a passenger's seat holds nothing else
    looks = {o.appearance for o in gen.scene.objects if o.class_name == "sitter"}
    assert looks <= {"red", "blue", "green"} and None not in looks


def test_generated_documents_compose_with_usd(car_park, tmp_path):
    from usdscene.scene.compose import compose_stage

    catalog, setup, _ = car_park
    for strategy in ("single-class", "balanced", "appearance", "random"):
        frames = None if strategy == "single-class" else 5
        gen = generate_sequence(setup, catalog, GenerateOptions(strategy=strategy, frames=frames, seed=4,
                                                                objects_per_frame=None if frames is None else 4,
                                                                occupancy=0.5))
        scene = read_openlabel(write_openlabel(gen.scene))
        result = compose_stage(scene, catalog, tmp_path / strategy)
        assert result.root_layer.is_file()
        present = {f: sum(1 for p in result.placements.values() if p.pose_at(f) is not None) for f in scene.frames}
        per_frame = collections.Counter(f for f, *_ in _instances(gen.scene))
        assert present == {f: per_frame[f] for f in scene.frames}  # every instance placed in every frame


def test_appearance_provenance_is_in_the_document(car_park):
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="appearance", frames=10, seed=8,
                                                            objects_per_frame=4))
    scene = read_openlabel(write_openlabel(gen.scene))
    objects = [o for o in scene.objects if o.class_name in CLASSES]
    assert all(o.color_rgb is not None and all(0.0 <= c <= 1.0 for c in o.color_rgb) for o in objects)
    for o in objects:
        variants = CLASSES[o.class_name][2]
        assert (o.appearance in variants) if variants else o.appearance is None
    assert len({o.color_rgb for o in objects}) == len(objects)
    # Each object keeps its look for at most 5 frames.
    assert all(sum(len(iv.frames()) for iv in o.frame_intervals) <= 5 for o in objects)
    balanced = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=10, seed=8,
                                                                 objects_per_frame=4))
    assert all(o.color_rgb is None and o.appearance == (CLASSES[o.class_name][2] or (None,))[0]
               for o in balanced.scene.objects)


def test_same_setup_and_seed_give_identical_bytes(car_park, tmp_path, monkeypatch):
    catalog, setup, folder = car_park
    # The catalog lies in another temporary folder than the documents: consent to it.
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(car_park[2]))
    setup_path = tmp_path / "setup.json"
    write_document(setup_path, write_openlabel(setup))
    outputs = []
    for run in ("a", "b", "c"):
        out = tmp_path / run / "seq.json"
        out.parent.mkdir()
        seed = "9" if run != "c" else "10"
        assert main(["generate", "appearance", "--setup", str(setup_path), "-o", str(out), "--frames", "4",
                     "--objects-per-frame", "3", "--occupancy", "0.5", "--seed", seed]) == 0
        outputs.append((out.read_bytes(), report_path(out).read_bytes()))
    assert outputs[0] == outputs[1]
    assert outputs[0][0] != outputs[2][0]
    report = json.loads(report_path(tmp_path / "a" / "seq.json").read_text())
    assert report["generator"]["seed"] == 9 and report["frames"] == 4


def test_generated_document_keeps_the_setups_roi_rules_and_roi_ignore(car_park, tmp_path, monkeypatch):
    """``usdscene generate`` copies what labels the ROI crops; the seated ``sitter`` (kind
    passenger) is named by its kind and must pass the catalog check of the generated document."""
    _, setup, folder = car_park
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(folder))
    setup_path = tmp_path / "setup.json"
    write_document(setup_path, write_openlabel(dataclasses.replace(
        setup, roi_rules={"is_on": "incorrect"}, roi_ignore=("passenger",))))
    out = tmp_path / "seq.json"
    assert main(["generate", "balanced", "--setup", str(setup_path), "-o", str(out), "--frames", "2",
                 "--objects-per-frame", "2", "--occupancy", "0.5", "--seed", "1"]) == 0
    from usdscene.validation import validate_document

    scene = validate_document(out, schema=None).scene  # with the catalog of the document's asset paths
    assert (scene.roi_rules, scene.roi_ignore) == ({"is_on": "incorrect"}, ("passenger",))


def test_fixed_objects_of_the_setup_keep_their_region(car_park):
    catalog, setup, _ = car_park
    fixed = dataclasses.replace(
        setup, objects=(m.SceneObject("100", "parked_crate", "crate"),), places=(m.PlaceRef("200", "bay_01"),),
        relations=(m.Relation("300", "is_on", "100", "200"),))
    gen = generate_sequence(fixed, catalog, GenerateOptions(strategy="single-class", seed=1))
    assert gen.scene.objects[0].uid == "100" and gen.scene.places[0].uid == "200"
    assert all(not (rel == "is_on" and place == "bay_01") for _, _, rel, place in _instances(gen.scene))
    check_composes(read_openlabel(write_openlabel(gen.scene)), catalog)


def test_bad_options_are_one_readable_error(car_park, tmp_path, capsys, monkeypatch):
    catalog, setup, _ = car_park
    # The catalog lies in another temporary folder than the documents: consent to it.
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(car_park[2]))
    with pytest.raises(DocumentError) as info:
        generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", classes=("crate", "sofa"),
                                                          place_patterns=("nowhere_*",)))
    text = str(info.value)
    assert "'sofa'" in text
    with pytest.raises(DocumentError, match="--places"):
        generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", place_patterns=("nowhere_*",)))
    with pytest.raises(DocumentError, match="single-class decides"):
        generate_sequence(setup, catalog, GenerateOptions(strategy="single-class", frames=3))
    setup_path = tmp_path / "setup.json"
    write_document(setup_path, write_openlabel(setup))
    assert main(["generate", "balanced", "--setup", str(setup_path), "-o", str(tmp_path / "x.json"),
                 "--classes", "sofa"]) == 1
    assert "usdscene: error: --classes: unknown object class 'sofa'" in capsys.readouterr().err
    assert main(["generate", "balanced", "--setup", str(setup_path), "-o", "x.json", "--occupancy", "1.5"]) == 2


def test_cabin_balanced_and_single_class_compose(tmp_path):
    """The shipped cabin, a few classes, seats and bins of three rows, passengers."""
    catalog = load_catalog()
    setup = m.SceneSpec(name="cabin", environment="aircraft_cabin", seed=0,
                        cameras=(m.Camera("c", pinhole(), pose=look_at_cv((-1.0, 0.0, 1.9), (-2.0, 1.0, 0.3))),))
    classes = ("backpack", "laptop", "trolley_suitcase")
    places = ("seat_0[123]?", "bin_0[12]?", "aisle_02")
    combos = fitting_combinations(catalog, "aircraft_cabin", classes, places)
    # Frames: what full coverage needs, passengers' laps included (laptops fit a reading lap).
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", seed=3, classes=classes,
                                                            place_patterns=places, objects_per_frame=6, occupancy=0.4))
    rows = _instances(gen.scene)
    on_laps = [r for r in rows if r[3].endswith("/lap")]
    assert on_laps and {cls for _, cls, _, _ in on_laps} == {"laptop"}  # the others do not fit a lap
    per_class = collections.Counter(cls for _, cls, _, _ in rows if cls != "passenger")
    assert max(per_class.values()) - min(per_class.values()) <= 1
    assert {(c.class_name, c.relation, c.place) for c in combos} <= {r[1:] for r in rows}
    assert not any(cls == "trolley_suitcase" and rel == "is_below" for _, cls, rel, _ in rows)  # 0.64 m tall
    assert any(cls == "passenger" for _, cls, _, _ in rows)
    scene = read_openlabel(write_openlabel(gen.scene))
    from usdscene.scene.compose import compose_stage

    result = compose_stage(scene, catalog, tmp_path / "stage")
    assert sum(1 for p in result.placements.values() for s in p.spans for _ in s.frames()) == len(rows)
    single = generate_sequence(setup, catalog, GenerateOptions(strategy="single-class", seed=3, classes=classes,
                                                               place_patterns=places))
    check_composes(read_openlabel(write_openlabel(single.scene)), catalog)
    # seat_01* and seat_02* share the floor under the front row: never both in one frame.
    under = collections.defaultdict(set)
    for f, _, rel, place in _instances(single.scene):
        if rel == "is_below":
            under[f].add(place)
    assert all(not ({"seat_01A", "seat_02A"} <= v) for v in under.values())


def test_balance_report_counts_a_hand_written_scene():
    scene = m.SceneSpec(
        frame_start=0, frame_end=2, environment="aircraft_cabin",
        objects=(m.SceneObject("1", "a", "backpack", (m.FrameInterval(0, 1),)),
                 m.SceneObject("2", "b", "laptop"), m.SceneObject("3", "c", "phone", (m.FrameInterval(2, 2),))),
        places=(m.PlaceRef("10", "seat_03A"),),
        relations=(m.Relation("20", "is_below", "1", "10"), m.Relation("21", "is_on", "2", "10"),
                   m.Relation("22", "is_on", "3", "2")))
    report = balance_report(scene, load_catalog())
    assert report["classes"] == {"backpack": {"objects": 1, "instance_frames": 2},
                                 "laptop": {"objects": 1, "instance_frames": 3},
                                 "phone": {"objects": 1, "instance_frames": 1}}
    assert report["class_relation"]["phone"] == {"is_on": 1}  # on the laptop, on the seat
    assert report["places"] == {"seat_03A": 6} and report["place_kinds"] == {"seat": 6}
    assert report["instance_frames"] == 6


def test_stats_on_a_scene_document(car_park, tmp_path, capsys, monkeypatch):
    import cv2

    catalog, setup, _ = car_park
    # The catalog lies in another temporary folder than the documents: consent to it.
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(car_park[2]))
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=6, seed=2, objects_per_frame=4))
    doc = tmp_path / "seq.json"
    write_document(doc, write_openlabel(gen.scene))
    assert main(["stats", str(doc)]) == 0
    out = capsys.readouterr().out
    assert "instance-frames" in out and "ladder" in out
    chart = cv2.imread(str(tmp_path / "seq.json.stats.png"))
    assert chart is not None and chart.shape[1] == 720 and chart.shape[0] > 200


def test_the_command_offers_exactly_the_library_strategies():
    """``usdscene generate`` keeps its own copy of the strategy names (its module imports only
    the standard library, for a fast --help); it must not drift from the library's."""
    import argparse

    from usdscene.cli import build_parser
    from usdscene.generate.motion import STRATEGY as TRACKS
    from usdscene.generate.sequences import STRATEGIES

    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    strategy = next(a for a in commands.choices["generate"]._actions if a.dest == "strategy")
    assert tuple(strategy.choices) == (*STRATEGIES, TRACKS)


def test_passengers_laps_hold_objects_of_the_poses_that_have_one(car_park):
    """Occupancy: objects go on seated passengers' laps (cones and crates fit the sitter's lap,
    ladders and tyres do not), only of passengers in a pose with a lap; the pose is drawn per
    frame and written into the document; the report counts the laps as ``<seat>/lap``."""
    catalog, setup, _ = car_park
    gen = generate_sequence(setup, catalog, GenerateOptions(strategy="balanced", frames=10, seed=6,
                                                            objects_per_frame=3, occupancy=1.0))
    scene = read_openlabel(write_openlabel(gen.scene))
    objects = scene.object_by_uid()
    rows = _instances(scene)
    on_laps = [r for r in rows if r[3].endswith("/lap")]
    assert on_laps and {cls for _, cls, _, _ in on_laps} <= {"cone", "crate"}
    assert {place for *_, place in on_laps} <= {"kerb_a/lap", "kerb_b/lap"}
    per_class = collections.Counter(cls for _, cls, _, _ in rows if cls != "sitter")
    assert max(per_class.values()) - min(per_class.values()) <= 1
    for rel in scene.relations:
        if rel.object_uid in objects:  # on a lap: of a sitting sitter
            assert rel.type == "is_on" and objects[rel.object_uid].class_name == "sitter"
            assert objects[rel.object_uid].pose_variant == "sitting"
    poses = {o.pose_variant for o in scene.objects if o.class_name == "sitter"}
    assert poses == {"sitting", "slumped"}  # drawn per frame, recorded in the document
    report = gen.report
    assert report["places"].get("kerb_a/lap", 0) + report["places"].get("kerb_b/lap", 0) == len(on_laps)
    assert report["place_kinds"]["lap"] == len(on_laps)
    assert report["class_relation"]["cone"]["is_on"] >= sum(1 for r in on_laps if r[1] == "cone")
    lap_combos = report["coverage"]["combinations"] - len(fitting_combinations(catalog, "car_park", sorted(CLASSES)))
    assert lap_combos == 4  # cone and crate on two laps
    check_composes(scene, catalog)


def test_magazine_on_a_reading_passengers_lap_in_the_composed_cabin(tmp_path):
    """A magazine ``is_on`` a seated passenger lies on its thighs, under its chest: world
    positions read back from the composed stage."""
    from pxr import Usd, UsdGeom

    from usdscene.document import stage_schema as ss
    from usdscene.scene.compose import compose_stage
    from usdscene.errors import CompositionError

    catalog = load_catalog()
    scene = m.SceneSpec(
        name="lap", environment="aircraft_cabin", seed=1, frame_start=0, frame_end=0,
        cameras=(m.Camera("c", pinhole(), pose=look_at_cv((-2.2, 0.0, 1.6), (-3.4, -1.0, 0.6))),),
        objects=(m.SceneObject("1", "pax", "passenger", pose_variant="reading"),
                 m.SceneObject("2", "mag", "magazine")),
        places=(m.PlaceRef("10", "seat_03A"),),
        relations=(m.Relation("20", "is_on", "1", "10"), m.Relation("21", "is_on", "2", "1")))
    result = compose_stage(read_openlabel(write_openlabel(scene)), catalog, tmp_path / "stage")
    stage = Usd.Stage.Open(str(result.root_layer))
    cache = UsdGeom.BBoxCache(Usd.TimeCode(0), [UsdGeom.Tokens.default_])
    pax = stage.GetPrimAtPath(ss.object_prim_path("passenger", "1"))
    assert pax.GetVariantSets().GetVariantSet(ss.VARIANT_SET_POSE).GetVariantSelection() == "reading"

    def box(prim):
        r = cache.ComputeWorldBound(prim).ComputeAlignedRange()
        return np.array(r.GetMin()), np.array(r.GetMax())

    mag_lo, mag_hi = box(stage.GetPrimAtPath(ss.object_prim_path("magazine", "2")))
    hip_z = UsdGeom.Xformable(pax).ComputeLocalToWorldTransform(Usd.TimeCode(0)).ExtractTranslation()[2]
    body_lo, body_hi = box(pax.GetPrimAtPath("Geom/Body"))
    body = pax.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE).GetVariantSelection()
    lap = catalog["passenger"].places_for({ss.VARIANT_SET_POSE: "reading", ss.VARIANT_SET_APPEARANCE: body})
    thigh_top = hip_z + lap["lap"].regions["is_on"].pose.as_array()[2, 3]  # that body's thighs
    assert mag_lo[2] == pytest.approx(thigh_top, abs=0.003)  # resting on the thighs
    assert mag_hi[2] < body_hi[2] - 0.3  # far below the head (not on it)
    centre = (mag_lo + mag_hi) / 2.0
    assert body_lo[0] < centre[0] < body_hi[0] and body_lo[1] < centre[1] < body_hi[1]
    # A trolley case is no lap object.
    trolley = dataclasses.replace(scene, objects=(scene.objects[0], dataclasses.replace(
        scene.objects[1], class_name="trolley_suitcase", name="case")))
    with pytest.raises(CompositionError, match="'2' .trolley_suitcase.*does not fit object '1' .is_on."):
        compose_stage(trolley, catalog, tmp_path / "trolley")

