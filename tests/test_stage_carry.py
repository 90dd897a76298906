"""Other people's content survives the route through the USD stage: document → compose →
(DCC edit) → ``usdscene export-openlabel`` keeps what usdscene does not model (the ``extra``
fields, ``usdscene.converters.openlabel.carry``), carried in the stage's customData."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from test_compose_support import build_test_catalog, load_test_catalog, small_scene
from test_openlabel_carry import carried_of
from usdscene.cli import main
from usdscene.converters.openlabel import load_document, read_openlabel, write_document, write_openlabel
from usdscene.document import model as m
from usdscene.document import stage_schema as ss
from usdscene.document.model import extra_data
from usdscene.scene.compose import compose_stage

pytestmark = pytest.mark.usd


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    root = tmp_path_factory.mktemp("stage_carry")
    return load_test_catalog(build_test_catalog(root / "cat"))


def _foreign_document() -> dict:
    """The golden scene's document with other people's content on the scene, a camera stream,
    a place, an object (static and per frame) and a relation to an event."""
    document = write_openlabel(small_scene())
    body = document["openlabel"]
    body["metadata"]["annotator"] = "someone else"
    body["metadata"]["file_version"] = "3"
    body["contexts"] = {"0": {"name": "weather", "type": "Weather",
                              "context_data": {"text": [{"name": "sky", "val": "overcast, ünïcode"}]}}}
    body["events"] = {"0": {"name": "door opens", "type": "DoorOpen",
                            "frame_intervals": [{"frame_start": 2, "frame_end": 2}]}}
    body["ontologies"] = {"0": "http://example.org/cabin"}
    body["streams"]["LIDAR"] = {"type": "lidar", "description": "a roof lidar"}
    cam = body["streams"]["cam_aisle"]
    cam["uri"] = "rtsp://example.org/cam_aisle"
    cam["stream_properties"]["sync"] = {"frame_shift": 1}
    uids = {element["name"]: uid for uid, element in body["objects"].items()}
    bag, seat = uids["bag one"], uids["seat_01A"]
    body["objects"][bag]["ontology_uid"] = "0"
    body["objects"][bag]["object_data"].setdefault("vec", []).append({"name": "Position", "val": [1, 2, 3]})
    body["objects"][bag]["object_data"]["bbox"] = [{"name": "drawn", "val": [10, 12, 4, 6]}]
    body["objects"][seat].setdefault("object_data", {})["text"] = [{"name": "row", "val": "1"}]
    frames = body.setdefault("frames", {})
    for number in ("1", "3"):
        entry = frames.setdefault(number, {}).setdefault("objects", {}).setdefault(bag, {})
        entry.setdefault("object_data", {})["bbox"] = [{"name": "tracked", "val": [int(number), 5, 4, 4]}]
    frame = frames.setdefault("2", {})
    frame.setdefault("frame_properties", {})["weather_id"] = "0"
    frame["events"] = {"0": {}}
    below = next(r for r in body["relations"].values() if r["type"] == "is_below")
    below.update({"name": "bag under its seat", "ontology_uid": "0"})
    body["relations"]["90"] = {"name": "", "type": "causes",
                               "rdf_subjects": [{"uid": "0", "type": "event"}],
                               "rdf_objects": [{"uid": bag, "type": "object"}]}
    return document


def _carried(body: dict, cameras: set[str]) -> dict:
    """``carried_of`` and, beside it, the carried keys of the camera streams and of the place."""
    out = carried_of(body, cameras)
    cam = body["streams"]["cam_aisle"]
    out["cam_aisle"] = json.dumps([cam.get("uri"), cam["stream_properties"].get("sync")])
    out["places"] = json.dumps([o.get("object_data", {}).get("text") for o in body["objects"].values()
                                if o["type"] == "place"])
    out["ontology_uid"] = json.dumps(sorted(o.get("ontology_uid", "") for o in body["objects"].values()))
    out["relations"] = json.dumps(sorted([r["type"], r["name"], r.get("ontology_uid", "")]
                                         for r in body["relations"].values()))
    return out


def test_foreign_content_survives_compose_and_export_openlabel(tmp_path, catalog):
    document = _foreign_document()
    write_document(tmp_path / "in.json", document)
    scene = read_openlabel(tmp_path / "in.json")
    assert scene.extra and scene.cameras[0].extra and scene.objects[0].frame_extra  # the test carries something
    result = compose_stage(scene, catalog, tmp_path / "stage")
    assert main(["export-openlabel", str(result.stage_dir), "-o", str(tmp_path / "out.json")]) == 0
    back = load_document(tmp_path / "out.json")["openlabel"]
    cameras = {c.name for c in scene.cameras}
    expected = _carried(document["openlabel"], cameras)
    assert _carried(back, cameras) == expected
    assert len(expected) > 12
    again = read_openlabel(tmp_path / "out.json")
    assert again.extra == scene.extra
    assert [c.extra for c in again.cameras] == [c.extra for c in scene.cameras]
    assert [p.extra for p in again.places] == [p.extra for p in scene.places]
    assert [r.extra for r in again.relations] == [r.extra for r in scene.relations]
    assert any(r.extra for r in scene.relations)
    assert [(o.extra, o.frame_extra) for o in again.objects] == [(o.extra, o.frame_extra) for o in scene.objects]


def test_stage_carries_in_customdata_and_the_layers_stay_byte_identical(tmp_path, catalog):
    scene = read_openlabel(_foreign_document())
    first = compose_stage(scene, catalog, tmp_path / "a")
    second = compose_stage(scene, catalog, tmp_path / "b")
    assert [p.read_bytes() for p in first.layers] == [p.read_bytes() for p in second.layers]
    from pxr import Usd

    stage = Usd.Stage.Open(str(first.root_layer))
    bag = next(o for o in scene.objects if o.name == "bag one")
    prim = stage.GetPrimAtPath(ss.object_prim_path(bag.class_name, bag.uid))
    assert prim.GetCustomDataByKey(ss.CUSTOM_EXTRA) == bag.extra
    assert set(json.loads(prim.GetCustomDataByKey(ss.CUSTOM_FRAME_EXTRA))) == {"1", "3"}
    data = stage.GetRootLayer().customLayerData[ss.LAYER_DATA_KEY]
    assert data[ss.LAYER_EXTRA] == scene.extra
    # a document without carried content gets no carry keys (its layers stay as they were)
    plain = compose_stage(small_scene(), catalog, tmp_path / "plain")
    assert not any(key in path.read_text() for path in plain.layers
                   for key in ("extra =", "frameExtra", ss.LAYER_EXTRA))


def test_renamed_prim_keeps_its_carry_and_a_deleted_one_loses_it(tmp_path, catalog):
    """What a DCC user does: rename (move) one object prim, delete another."""
    from pxr import Sdf

    from usdscene.converters.stage.usd_stage import scene_from_stage

    scene = read_openlabel(_foreign_document())
    result = compose_stage(scene, catalog, tmp_path / "stage")
    bag = next(o for o in scene.objects if o.name == "bag one")
    pinned = next(o for o in scene.objects if o.name == "pinned")
    layer = Sdf.Layer.FindOrOpen(str(result.stage_dir / "objects.usda"))
    old = ss.object_prim_path(bag.class_name, bag.uid)
    assert Sdf.CopySpec(layer, old, layer, f"{ss.OBJECTS}/renamed_by_hand")
    parent = layer.GetPrimAtPath(ss.OBJECTS)
    del parent.nameChildren[old.rsplit("/", 1)[1]]
    del parent.nameChildren[ss.object_prim_path(pinned.class_name, pinned.uid).rsplit("/", 1)[1]]
    layer.Save()
    back = scene_from_stage(result.root_layer)
    by_uid = back.object_by_uid()
    assert pinned.uid not in by_uid
    assert (by_uid[bag.uid].extra, by_uid[bag.uid].frame_extra) == (bag.extra, bag.frame_extra)


def test_malformed_carry_is_reported(tmp_path, catalog):
    from pxr import Sdf

    from usdscene.converters.stage.usd_stage import scene_from_stage
    from usdscene.errors import DocumentError

    scene = read_openlabel(_foreign_document())
    result = compose_stage(scene, catalog, tmp_path / "stage")
    layer = Sdf.Layer.FindOrOpen(str(result.stage_dir / "cameras.usda"))
    prim = layer.GetPrimAtPath(ss.camera_prim_path("cam_aisle"))
    data = dict(prim.customData)
    data[ss.LAYER_DATA_KEY] = {**dict(data[ss.LAYER_DATA_KEY]), "extra": "{not json"}
    prim.customData = data
    layer.Save()
    with pytest.raises(DocumentError, match="usdscene:extra"):
        scene_from_stage(result.root_layer)



def test_one_frame_range_keeps_presence_and_intervals(tmp_path, catalog):
    """A one-frame range (the golden scene cut to frame 0): an object absent on that frame stays
    absent, and every object's intervals beyond the range come back as the document gives them."""
    from pxr import Usd

    from usdscene.converters.stage.usd_stage import scene_from_stage

    document = write_openlabel(small_scene())
    document["openlabel"]["metadata"]["usdscene"]["frame_range"] = {"frame_start": 0, "frame_end": 0}
    scene = read_openlabel(document)
    by_name = {o.name: o for o in scene.objects}
    assert by_name["cup on box"].frame_intervals == (m.FrameInterval(1, 4),)  # absent on frame 0
    result = compose_stage(scene, catalog, tmp_path / "stage")
    stage = Usd.Stage.Open(str(result.root_layer))
    cup = by_name["cup on box"]
    visibility = stage.GetPrimAtPath(ss.object_prim_path(cup.class_name, cup.uid)).GetAttribute("visibility")
    assert visibility.Get() == "invisible" and visibility.GetNumTimeSamples() == 0  # any reader sees it
    assert main(["export-openlabel", str(result.stage_dir), "-o", str(tmp_path / "out.json")]) == 0
    back = read_openlabel(tmp_path / "out.json")
    assert {o.name for o in back.objects_present(0)} == {o.name for o in scene.objects_present(0)} \
        == {"bag one", "box", "pinned"}
    assert {o.name: o.frame_intervals for o in back.objects} == {o.name: o.frame_intervals for o in scene.objects}
    assert back.objects == scene_from_stage(result.root_layer).objects == result.resolved.objects


def test_edited_visibility_decides_the_range_and_the_document_the_rest(tmp_path, catalog):
    from pxr import Sdf, Usd, UsdGeom

    from usdscene.converters.stage.usd_stage import scene_from_stage

    document = write_openlabel(small_scene())
    document["openlabel"]["metadata"]["usdscene"]["frame_range"] = {"frame_start": 0, "frame_end": 0}
    scene = read_openlabel(document)
    bag = next(o for o in scene.objects if o.name == "bag one")
    result = compose_stage(scene, catalog, tmp_path / "stage")
    stage = Usd.Stage.Open(str(result.root_layer))
    edits = Sdf.Layer.CreateNew(str(result.stage_dir / "edits.usda"))
    stage.GetRootLayer().subLayerPaths.insert(0, "./edits.usda")
    stage.SetEditTarget(edits)
    UsdGeom.Imageable(stage.GetPrimAtPath(ss.object_prim_path(bag.class_name, bag.uid))).MakeInvisible()
    back = scene_from_stage(stage).object_by_uid()[bag.uid]
    assert bag.frame_intervals == (m.FrameInterval(0, 5),)
    # hidden on the range's one frame by the stage's word, present after it by the document's
    assert back.frame_intervals == (m.FrameInterval(1, 5),)


def test_every_conformance_file_keeps_its_content_through_the_stage(openlabel_conformance: Path, tmp_path,
                                                                   openlabel_schema_path: Path):
    """Files written by others (KITTI tracking with bboxes, cuboids and a lidar stream, a driver
    monitoring sequence with actions and contexts, RailLabel, ...), their object classes stood in
    for by a test asset: document → compose → ``export-openlabel`` keeps everything the scene
    model does not hold, exactly as ``convert`` does."""
    from usdscene.converters.openlabel import schema_problems
    from usdscene.scene.catalog import load_catalog

    carried_total = 0
    for path in sorted(openlabel_conformance.glob("*.json")):
        scene = read_openlabel(path)
        folder = build_test_catalog(tmp_path / path.stem / "cat")
        entries = json.loads((folder / "catalog.json").read_text())
        for obj in scene.objects:  # the file's classes look like a box
            entries["classes"].setdefault(obj.class_name, entries["classes"]["box"])
        (folder / "catalog.json").write_text(json.dumps(entries))
        result = compose_stage(scene, load_catalog([folder], include_default=False), tmp_path / path.stem / "stage")
        out = tmp_path / path.stem / "back.json"
        assert main(["export-openlabel", str(result.stage_dir), "-o", str(out)]) == 0, path.name
        source, written = load_document(path)["openlabel"], json.loads(out.read_text())
        assert schema_problems(written, openlabel_schema_path) == [], path.name
        cameras = {c.name for c in scene.cameras}
        expected = carried_of(source, cameras)
        assert carried_of(written["openlabel"], cameras) == expected, path.name
        carried_total += len(expected)
        again = read_openlabel(out)
        assert again.extra == scene.extra, path.name
        assert [c.extra for c in again.cameras] == [c.extra for c in scene.cameras], path.name
        assert [(o.extra, o.frame_extra) for o in again.objects] == [(o.extra, o.frame_extra)
                                                                     for o in scene.objects], path.name
        assert [r.extra for r in again.relations] == [r.extra for r in scene.relations], path.name
    assert carried_total > 100
