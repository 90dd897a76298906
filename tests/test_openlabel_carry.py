"""Other people's data survives conversion: what the scene model does not represent is kept in
the ``extra`` fields and written back unchanged (``usdscene.converters.openlabel.carry``)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from usdscene.cli import main
from usdscene.converters.openlabel import load_document, read_openlabel, schema_problems, write_openlabel
from usdscene.converters.openlabel.objects import OBJECT_DATA, POSE_DATA
from usdscene.document.model import Provenance, canonical_json, extra_data

ROOT_SECTIONS = ("actions", "events", "contexts", "ontologies", "resources", "tags")
METADATA_READ = {"schema_version", "name", "comment", "usdscene"}


def carried_of(body: dict, camera_names: set[str]) -> dict:
    """What a converted document must keep of ``body``, gathered from the raw JSON alone:
    object data of names outside usdscene's vocabulary (static and per frame), non-camera
    streams, the root sections usdscene does not read, other metadata keys, per-frame stream
    properties and frame timestamps. Canonical JSON text per item, for byte comparison."""
    out: dict[str, str] = {}
    for uid, obj in (body.get("objects") or {}).items():
        for kind, items in (obj.get("object_data") or {}).items():
            for index, item in enumerate(i for i in items if i.get("name") not in OBJECT_DATA):
                out[f"objects.{uid}.{kind}.{index}"] = canonical_json({"item": item})
    for number, frame in (body.get("frames") or {}).items():
        for uid, entry in (frame.get("objects") or {}).items():
            for kind, items in ((entry or {}).get("object_data") or {}).items():
                for index, item in enumerate(i for i in items if i.get("name") not in POSE_DATA):
                    out[f"frames.{number}.objects.{uid}.{kind}.{index}"] = canonical_json({"item": item})
        for key, value in (frame.get("frame_properties") or {}).items():
            if key != "transforms":
                out[f"frames.{number}.frame_properties.{key}"] = canonical_json({"v": value})
        for key in ("actions", "events", "contexts", "relations"):
            if frame.get(key):
                out[f"frames.{number}.{key}"] = canonical_json({"v": frame[key]})
    for name, stream in (body.get("streams") or {}).items():
        if name not in camera_names:
            out[f"streams.{name}"] = canonical_json(stream)
    for key in ROOT_SECTIONS:
        if body.get(key):
            out[key] = canonical_json({"v": body[key]})
    for key, value in (body.get("metadata") or {}).items():
        if key not in METADATA_READ:
            out[f"metadata.{key}"] = canonical_json({"v": value})
    return out


def _no_provenance(scene):
    return dataclasses.replace(scene, provenance=Provenance())


def test_every_conformance_file_keeps_its_unknown_data_through_convert(openlabel_conformance: Path, tmp_path,
                                                                     openlabel_schema_path: Path):
    files = sorted(openlabel_conformance.glob("*.json"))
    carried_total = 0
    for path in files:
        out = tmp_path / f"{path.stem}.converted.json"
        assert main(["convert", str(path), "-o", str(out), "--no-catalog"]) == 0, path.name
        source, written = load_document(path)["openlabel"], json.loads(out.read_text())
        assert schema_problems(written, openlabel_schema_path) == [], path.name
        cameras = {c.name for c in read_openlabel(path).cameras}
        expected = carried_of(source, cameras)
        assert carried_of(written["openlabel"], cameras) == expected, path.name
        carried_total += len(expected)
        # read → write → read: the same scene, the carried data byte-equal in canonical JSON
        scene, again = read_openlabel(path), read_openlabel(written)
        assert _no_provenance(again) == _no_provenance(scene), path.name
        assert again.extra == scene.extra
        assert [(o.extra, o.frame_extra) for o in again.objects] == [(o.extra, o.frame_extra) for o in scene.objects]
    assert carried_total > 100  # the corpus is full of bboxes, cuboids, actions and lidar streams


def test_kitti_bboxes_cuboids_and_lidar_are_carried(openlabel_conformance: Path):
    scene = read_openlabel(openlabel_conformance / "openlabel100_test_scene_KITTI_Tracking_3.json")
    extra = extra_data(scene.extra)
    assert extra["streams"]["VELO_TOP"]["type"] == "lidar"
    kinds = {kind for o in scene.objects for _, text in o.frame_extra for kind in extra_data(text)["object_data"]}
    assert {"bbox", "cuboid"} <= kinds
    # the coordinate-system transforms that place the cameras are read, not carried
    assert all("transforms" not in f.get("frame_properties", {}) for f in extra.get("frames", {}).values())


def test_unknown_object_data_and_metadata_round_trip_in_order():
    document = {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "annotator": "someone", "file_version": "7"},
        "objects": {"0": {"name": "car", "type": "Car", "ontology_uid": "0",
                          "object_data": {"vec": [{"name": "Position", "val": [1, 2, 3]},
                                                  {"name": "position_m", "val": [4.0, 5.0, 6.0]}],
                                          "bbox": [{"name": "box", "val": [10, 10, 4, 4]}],
                                          "poly2d": [{"name": "outline", "val": [0, 0, 1, 0, 1, 1],
                                                      "mode": "MODE_POLY2D_ABSOLUTE", "closed": True}]},
                          "object_data_pointers": {"box": {"type": "bbox", "frame_intervals": []}}}},
        "ontologies": {"0": "http://example.org/ontology"},
        "actions": {"1": {"name": "driving", "type": "Driving"}}}}
    scene = read_openlabel(document)
    (car,) = scene.objects
    assert car.pose.translation_m.tolist() == [4.0, 5.0, 6.0]  # usdscene's own name is read
    carried = extra_data(car.extra)
    assert carried["object_data"]["vec"] == [{"name": "Position", "val": [1, 2, 3]}]
    assert carried["ontology_uid"] == "0" and "box" in carried["object_data_pointers"]
    assert extra_data(scene.extra) == {"metadata": {"annotator": "someone", "file_version": "7"},
                                       "ontologies": {"0": "http://example.org/ontology"},
                                       "actions": {"1": {"name": "driving", "type": "Driving"}}}
    written = write_openlabel(scene)["openlabel"]
    element = written["objects"]["0"]
    assert element["object_data"]["poly2d"] == document["openlabel"]["objects"]["0"]["object_data"]["poly2d"]
    assert [i["name"] for i in element["object_data"]["vec"]] == ["pose_matrix4x4", "Position"]
    assert written["metadata"]["annotator"] == "someone"
    assert _no_provenance(read_openlabel({"openlabel": written})) == _no_provenance(scene)


def test_keys_of_a_modelled_relation_round_trip():
    document = {"openlabel": {
        "metadata": {"schema_version": "1.0.0"},
        "objects": {"0": {"name": "bag", "type": "bag"}, "1": {"name": "seat_01A", "type": "place"}},
        "ontologies": {"0": "http://example.org/ontology"},
        "relations": {"0": {"name": "bag under its seat", "type": "is_below", "ontology_uid": "0",
                            "rdf_subjects": [{"uid": "0", "type": "object"}],
                            "rdf_objects": [{"uid": "1", "type": "object"}]},
                      "1": {"name": "", "type": "is_on", "rdf_subjects": [{"uid": "0", "type": "object"}],
                            "rdf_objects": [{"uid": "1", "type": "object"}]}}}}
    scene = read_openlabel(document)
    assert extra_data(scene.relations[0].extra) == {"name": "bag under its seat", "ontology_uid": "0"}
    assert scene.relations[1].extra == ""  # the writer's own empty name is nothing to carry
    written = write_openlabel(scene)["openlabel"]["relations"]
    assert written == document["openlabel"]["relations"]


def test_carried_stream_that_clashes_with_a_camera_is_refused():
    from usdscene.errors import DocumentError
    from usdscene.document.model import Camera, Intrinsics, LensModel, SceneSpec

    camera = Camera(name="cam", intrinsics=Intrinsics(LensModel.PERSPECTIVE, 64, 48, 50.0, 50.0, 31.5, 23.5))
    scene = SceneSpec(cameras=(camera,), extra=canonical_json({"streams": {"cam": {"type": "lidar"}}}))
    with pytest.raises(DocumentError, match=r"extra\.streams\.cam"):
        write_openlabel(scene)
