"""End to end on the shipped cabin: document → composed stage → Cycles → annotate → exports.

A laptop stowed below seat_01A is hidden by the seat from the corridor camera: it gets an
amodal box but no visible pixel; the ROI of that seat's below region is ``correct``. The rules
judge luggage (``roi_ignore: ["passenger"]``): seat_01C holding only a seated passenger is
``empty``, seat_01D whose passenger holds a magazine on the lap is ``incorrect``.
"""

from __future__ import annotations

import csv
import json

import pytest

pytestmark = [pytest.mark.usd, pytest.mark.blender]

W, H = 128, 96


def _document() -> dict:
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "labels_cabin", "usdscene": {
            "seed": 3, "environment": "aircraft_cabin",
            "render": {"samples": 1, "denoise": False, "resolution_px": [W, H]},
            "roi_rules": {"is_below": "correct", "is_on": "incorrect", "is_in_front_of": "incorrect"},
            "roi_ignore": ["passenger"],
            "frame_range": {"frame_start": 0, "frame_end": 0}}},
        "streams": {"corridor": {"type": "camera", "uri": "", "stream_properties": {"usdscene": {
            "model": "perspective", "resolution_px": [W, H], "sensor_size_mm": [5.6, 4.2], "fov_deg": 90.0,
            "position_m": [3.0, 0.0, 1.95], "target_m": [1.0, 0.0, 0.6], "clip_range_m": [0.05, 50.0]}}}},
        "objects": {
            "0": {"name": "ceiling_light", "type": "light", "object_data": {
                "text": [{"name": "kind", "val": "point"}],
                "num": [{"name": "power_w", "val": 60.0}],
                "vec": [{"name": "position_m", "val": [1.5, 0.0, 2.0]}]}},
            "1": {"name": "seat_01A", "type": "place"},
            "2": {"name": "laptop_under_seat", "type": "laptop",
                  "frame_intervals": [{"frame_start": 0, "frame_end": 0}]},
            "3": {"name": "passenger_aisle", "type": "passenger",
                  "frame_intervals": [{"frame_start": 0, "frame_end": 0}],
                  "object_data": {"vec": [{"name": "position_m", "val": [2.0, 0.0, 0.0]},
                                          {"name": "rotation_xyz_deg", "val": [0.0, 0.0, 90.0]}]}},
            "4": {"name": "seat_01C", "type": "place"},
            "5": {"name": "seat_01D", "type": "place"},
            "6": {"name": "passenger_01C", "type": "passenger"},
            "7": {"name": "passenger_01D", "type": "passenger",
                  "object_data": {"text": [{"name": "pose_variant", "val": "reading"}]}},
            "8": {"name": "magazine_on_lap", "type": "magazine"},
        },
        "relations": {"0": {"name": "laptop below seat", "type": "is_below",
                            "rdf_subjects": [{"uid": "2", "type": "object"}],
                            "rdf_objects": [{"uid": "1", "type": "object"}]},
                      **{str(k): {"name": name, "type": "is_on", "rdf_subjects": [{"uid": subject, "type": "object"}],
                                  "rdf_objects": [{"uid": obj, "type": "object"}]}
                         for k, (name, subject, obj) in enumerate((("seated 01C", "6", "4"), ("seated 01D", "7", "5"),
                                                                   ("magazine on lap", "8", "7")), start=1)}},
        "frame_intervals": [{"frame_start": 0, "frame_end": 0}],
    }}


@pytest.fixture(scope="module")
def output(tmp_path_factory):
    from usdscene.cli import main

    root = tmp_path_factory.mktemp("cabin")
    doc = root / "scene.openlabel.json"
    doc.write_text(json.dumps(_document()))
    out = root / "out"
    assert main(["render", str(doc), "-o", str(out), "--no-progress"]) == 0
    assert main(["annotate", str(out), "--no-progress"]) == 0
    assert main(["export", "coco", "yolo", "rois", str(out)]) == 0
    return out


def test_seat_hides_the_stowed_laptop(output):
    from usdscene.converters.openlabel.annotations import labels_in

    document = json.loads((output / "annotations.openlabel.json").read_text())
    assert document["openlabel"]["metadata"]["name"] == "labels_cabin"  # the source document
    labels = {lab["name"]: lab for lab in labels_in(document, 0, "corridor")}
    laptop = labels["laptop_under_seat"]
    assert laptop["amodal_bbox"] is not None and laptop["attributes"]["amodal_pixel_count"] > 0
    assert laptop["bbox"] is None and laptop["attributes"]["visible_fraction"] == 0.0
    passenger = labels["passenger_aisle"]
    assert passenger["bbox"] is not None and passenger["attributes"]["pixel_count"] > 100


def test_document_valid_and_exports_consistent(output, openlabel_schema_path):
    from usdscene.converters.openlabel import read_openlabel, schema_problems

    document = json.loads((output / "annotations.openlabel.json").read_text())
    assert schema_problems(document, openlabel_schema_path) == []
    assert read_openlabel(document).relations[0].type == "is_below"
    coco = json.loads((output / "exports" / "coco" / "annotations.json").read_text())
    names = [c["name"] for c in coco["categories"]]
    assert names == sorted(names) and "laptop" in names and "passenger" in names
    assert "aircraft_cabin" not in names  # environments are not detection classes
    rows = list(csv.DictReader((output / "exports" / "rois" / "index.csv").open()))
    below = [r for r in rows if r["place"] == "seat_01A" and r["relation"] == "is_below"]
    assert below and below[0]["label"] == "correct" and below[0]["objects"] == "2"
    seats = {r["place"]: r for r in rows if r["relation"] == "is_on"}
    assert (seats["seat_01C"]["label"], seats["seat_01C"]["objects"], seats["seat_01C"]["ignored"]) == ("empty", "", "6")
    assert (seats["seat_01D"]["label"], seats["seat_01D"]["objects"], seats["seat_01D"]["ignored"]) == ("incorrect", "8", "7")
    assert all(r["label"] == "empty" for r in rows
               if r["relation"] != "is_below" and (r["place"], r["relation"]) != ("seat_01D", "is_on"))
