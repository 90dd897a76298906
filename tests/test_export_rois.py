"""ROI crops of place regions: projection, visibility rules, labels from roi_rules and roi_ignore."""

from __future__ import annotations

import csv
import json

import dataclasses

import cv2
import numpy as np
import pytest

from usdscene.converters.openlabel import write_openlabel
from usdscene.converters.openlabel.annotations import add_annotations
from usdscene.converters.exports.rois import export_rois, plan_rois, region_corners
from usdscene.scene.catalog import load_catalog
from usdscene.labels.image_labels import ImageLabels, label_images
from usdscene.document.model import (Camera, FrameInterval, Intrinsics, LensModel, PlaceRef, Pose, Relation,
                            SceneObject, SceneSpec)
from usdscene.labels.projection import project_points

W, H = 64, 48


def _matrix(x, y, z):
    return [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, z, 0, 0, 0, 1]


@pytest.fixture()
def catalog(tmp_path):
    folder = tmp_path / "assets"
    folder.mkdir()
    places = {
        "seat_01A": {"kind": "seat", "regions": {
            "is_on": {"matrix": _matrix(0.0, 0.0, 0.45), "size_m": [0.5, 0.5, 0.5]},
            "is_below": {"matrix": _matrix(0.0, 0.0, 0.0), "size_m": [0.5, 0.5, 0.3]}}},
        "aisle_01": {"kind": "aisle", "regions": {
            "is_on": {"matrix": _matrix(0.8, 0.0, 0.0), "size_m": [0.4, 0.9, 0.5]}}},
        "bin_01": {"kind": "bin", "regions": {  # above the camera: never seen
            "is_in": {"matrix": _matrix(0.0, 0.0, 4.0), "size_m": [0.5, 0.5, 0.3]}}},
    }
    (folder / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1, "classes": {
        "cabin": {"kind": "environment", "usd": "cabin.usda", "places": places},
        "backpack": {"kind": "object", "usd": "backpack.usda", "extent_m": [[-0.1, -0.1, 0], [0.1, 0.1, 0.3]],
                     "relations": ["is_on", "is_below", "is_in"]},
        "traveller": {"kind": "passenger", "usd": "traveller.usda", "extent_m": [[-0.3, -0.3, 0], [0.3, 0.3, 1.2]],
                      "relations": ["is_on"]}}}))
    return load_catalog([folder], include_default=False)


def _scene() -> SceneSpec:
    # 3 m above the floor looking straight down (OpenCV z forward = world -Z, image y = world -Y).
    camera = Camera("top", Intrinsics(LensModel.PERSPECTIVE, W, H, 60.0, 60.0, (W - 1) / 2, (H - 1) / 2),
                    pose=Pose.from_rotation_translation(np.diag([1.0, -1.0, -1.0]), (0.3, 0.0, 3.0)))
    return SceneSpec(
        name="rois", frame_start=0, frame_end=1, cameras=(camera,), environment="cabin",
        objects=(SceneObject("0", "bag", "backpack"), SceneObject("1", "small_bag", "backpack")),
        places=(PlaceRef("10", "seat_01A"), PlaceRef("11", "aisle_01"), PlaceRef("12", "bin_01")),
        relations=(Relation("20", "is_below", "0", "10", (FrameInterval(0, 0),)),
                   Relation("21", "is_on", "0", "11", (FrameInterval(1, 1),)),
                   Relation("22", "is_on", "1", "0")),  # rides on the bag wherever it is
        roi_rules={"is_below": "correct", "is_on": "incorrect", "seat:is_on": "incorrect_seat"})


def _annotated(tmp_path, scene=None):
    scene = scene or _scene()
    images = []
    for frame in (0, 1):
        path = tmp_path / "images" / "top" / f"{frame:06d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        # Pixel values encode their own position: channel 0 = x * 3, channel 1 = y * 5.
        yy, xx = np.mgrid[0:H, 0:W]
        cv2.imwrite(str(path), np.dstack([xx * 3, yy * 5, np.full_like(xx, frame)]).astype(np.uint8))
        images.append(ImageLabels("top", frame, W, H, ()))
    return scene, add_annotations(write_openlabel(scene), scene, label_images(images), tmp_path)


def test_plan_labels_and_visibility(tmp_path, catalog):
    scene, document = _annotated(tmp_path)
    crops = plan_rois(document, catalog, min_size_px=4)
    by_key = {(c.frame, c.place, c.relation): c for c in crops}
    assert not any(c.place == "bin_01" for c in crops)  # behind the camera
    assert by_key[(0, "seat_01A", "is_below")].label == "correct"
    assert by_key[(0, "seat_01A", "is_below")].objects == ("0", "1")
    assert by_key[(1, "aisle_01", "is_on")].objects == ("0", "1")
    assert by_key[(0, "aisle_01", "is_on")].label == "empty"
    assert by_key[(1, "aisle_01", "is_on")].label == "incorrect"
    assert by_key[(1, "seat_01A", "is_below")].label == "empty"
    assert by_key[(0, "seat_01A", "is_on")].label == "empty"
    # Crop bounds = the pixels holding the projected corners.
    region = catalog.places("cabin")["aisle_01"].regions["is_on"]
    uv, ok = project_points(scene.cameras[0], region_corners(region), 0)
    crop = by_key[(0, "aisle_01", "is_on")]
    assert ok.all()
    assert (crop.x_min, crop.y_min) == tuple(int(v) for v in np.floor(uv.min(axis=0) + 0.5))
    assert (crop.x_max, crop.y_max) == tuple(int(v) for v in np.ceil(uv.max(axis=0) + 0.5) - 1)


def test_document_records_resolved_places(tmp_path, openlabel_schema_path):
    from usdscene.converters.openlabel import schema_problems

    _, document = _annotated(tmp_path)
    assert schema_problems(json.loads(json.dumps(document)), openlabel_schema_path) == []
    texts = {t["name"]: t["val"] for t in document["openlabel"]["frames"]["0"]["objects"]["1"]["object_data"]["text"]}
    assert texts == {"resolved_place": "seat_01A", "resolved_relation": "is_below"}
    pointers = document["openlabel"]["objects"]["1"]["object_data_pointers"]
    assert pointers["resolved_place"]["type"] == "text"


def test_export_writes_crops_and_index(tmp_path, catalog):
    _, document = _annotated(tmp_path)
    root = export_rois(document, tmp_path, catalog, min_size_px=4)
    rows = list(csv.DictReader((root / "index.csv").open()))
    assert len(rows) == 6  # 3 visible regions × 2 frames
    assert {r["label"] for r in rows} == {"correct", "incorrect", "empty"}
    for row in rows:
        crop = cv2.imread(str(root / row["path"]), cv2.IMREAD_UNCHANGED)
        assert row["path"].startswith(row["label"] + "/")
        assert crop.shape[:2] == (int(row["h"]), int(row["w"]))
        # The crop really comes from (x, y) of its source image.
        assert crop[0, 0, 0] == int(row["x"]) * 3 and crop[0, 0, 1] == int(row["y"]) * 5
        assert crop[0, 0, 2] == int(row["frame"])


def test_min_size_filter_drops_small_regions(tmp_path, catalog):
    _, document = _annotated(tmp_path)
    assert plan_rois(document, catalog, min_size_px=200) == []


def _seated_scene(roi_ignore) -> SceneSpec:
    """A traveller (catalog kind ``passenger``) sits on seat_01A in both frames; in frame 1 the
    bag rests on the traveller's lap, so it is in the seat's ``is_on`` region through them."""
    scene = _scene()
    return dataclasses.replace(
        scene, objects=(*scene.objects, SceneObject("2", "traveller", "traveller")),
        relations=(Relation("20", "is_below", "1", "10"), Relation("21", "is_on", "2", "10"),
                   Relation("22", "is_on", "0", "2", (FrameInterval(1, 1),))),
        roi_ignore=roi_ignore)


@pytest.mark.parametrize("roi_ignore", [("passenger",), ("traveller",)], ids=["kind", "class"])
def test_ignored_occupant_leaves_the_region_empty(tmp_path, catalog, roi_ignore):
    _, document = _annotated(tmp_path, _seated_scene(roi_ignore))
    by_key = {(c.frame, c.place, c.relation): c for c in plan_rois(document, catalog, min_size_px=4)}
    seated = by_key[(0, "seat_01A", "is_on")]
    assert (seated.label, seated.objects, seated.ignored) == ("empty", (), ("2",))
    with_bag = by_key[(1, "seat_01A", "is_on")]  # the bag on the lap is judged by the seat rule
    assert (with_bag.label, with_bag.objects, with_bag.ignored) == ("incorrect_seat", ("0",), ("2",))
    assert by_key[(0, "seat_01A", "is_below")].label == "correct"  # other objects are judged as before
    root = export_rois(document, tmp_path, catalog, min_size_px=4)
    rows = {(r["frame"], r["place"], r["relation"]): r for r in csv.DictReader((root / "index.csv").open())}
    assert rows[("0", "seat_01A", "is_on")]["label"] == "empty"
    assert rows[("0", "seat_01A", "is_on")]["path"].startswith("empty/")
    assert (rows[("0", "seat_01A", "is_on")]["objects"], rows[("0", "seat_01A", "is_on")]["ignored"]) == ("", "2")
    assert rows[("1", "seat_01A", "is_on")]["label"] == "incorrect_seat"


def test_without_roi_ignore_every_occupant_is_judged(tmp_path, catalog):
    _, document = _annotated(tmp_path, _seated_scene(()))
    by_key = {(c.frame, c.place, c.relation): c for c in plan_rois(document, catalog, min_size_px=4)}
    assert (by_key[(0, "seat_01A", "is_on")].label, by_key[(0, "seat_01A", "is_on")].objects) == ("incorrect_seat", ("2",))


def test_unknown_roi_ignore_name_is_refused(tmp_path, catalog):
    from usdscene.errors import AssetError

    _, document = _annotated(tmp_path, _seated_scene(("passenger", "travel")))
    with pytest.raises(AssetError) as info:
        plan_rois(document, catalog, min_size_px=4)
    assert [p.where for p in info.value.problems] == ["openlabel.metadata.usdscene.roi_ignore[1]"]
    assert "'travel' is no object class or kind" in str(info.value.problems[0])
    assert "did you mean 'traveller'?" in str(info.value.problems[0])
