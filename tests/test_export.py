"""Labels → OpenLABEL → COCO / YOLO on synthetic masks (no renderer needed)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from usdscene.converters.exports.coco import coco_dataset, export_coco
from usdscene.converters.openlabel.annotations import add_annotations, image_records, labels_in
from usdscene.converters.exports.yolo import export_yolo
from usdscene.labels.amodal import AmodalProjection
from usdscene.labels.image_labels import box_of, label_image, label_images, rasterize_contours, Contour
from usdscene.document.model import Camera, Intrinsics, LensModel, SceneObject, SceneSpec

W, H = 64, 48
CAMERAS = ("cam_a", "cam_b")
OBJECTS = {"0": ("bag_0", "backpack"), "1": ("case_1", "suitcase"), "2": ("bag_2", "backpack")}


def _scene() -> SceneSpec:
    intr = Intrinsics(LensModel.PERSPECTIVE, W, H, 40.0, 40.0, (W - 1) / 2, (H - 1) / 2)
    return SceneSpec(name="synthetic", frame_start=0, frame_end=1,
                     cameras=tuple(Camera(name, intr) for name in CAMERAS),
                     objects=tuple(SceneObject(uid, name, cls) for uid, (name, cls) in OBJECTS.items()))


def _document() -> dict:
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "synthetic"},
        "streams": {name: {"type": "camera", "stream_properties": {"intrinsics_pinhole": {
            "width_px": W, "height_px": H,
            "camera_matrix_3x4": [40.0, 0, (W - 1) / 2, 0, 0, 40.0, (H - 1) / 2, 0, 0, 0, 1, 0],
            "distortion_coeffs_1xN": []}}} for name in CAMERAS},
        "objects": {uid: {"name": name, "type": cls, "frame_intervals": [{"frame_start": 0, "frame_end": 1}]}
                    for uid, (name, cls) in OBJECTS.items()},
        "relations": {"0": {"name": "r0", "type": "is_below", "rdf_subjects": [{"uid": "0", "type": "object"}],
                            "rdf_objects": [{"uid": "1", "type": "object"}]}},
    }}


def _masks(frame: int, camera: str) -> tuple[np.ndarray, dict[str, AmodalProjection]]:
    """Synthetic instance mask + amodal projections: a ring with a hole (object 0), a box
    split by object 2 in front of it (object 1), object 2; in cam_b frame 1 object 0 is fully
    hidden behind object 1."""
    shift = 3 * frame + (5 if camera == "cam_b" else 0)
    amodal = {uid: np.zeros((H, W), bool) for uid in OBJECTS}
    amodal["0"][4 + frame:20, 3 + shift:25 + shift] = True
    amodal["1"][22:40, 10:50] = True
    amodal["2"][18:46, 26 + frame:32 + frame] = True
    if camera == "cam_b" and frame == 1:
        amodal["0"][:] = False
        amodal["0"][25:35, 15:25] = True  # entirely behind object 1
    mask = np.zeros((H, W), np.uint16)
    ring = amodal["0"].copy()
    if not (camera == "cam_b" and frame == 1):
        ring[8 + frame:14, 8 + shift:18 + shift] = False  # a hole (see-through handle)
    mask[ring] = 1
    mask[amodal["1"]] = 2
    mask[amodal["2"]] = 3
    amodal["0"] = ring | amodal["0"] if camera == "cam_b" and frame == 1 else amodal["0"]
    truncated = {"1": False, "0": False, "2": False}
    return mask, {uid: AmodalProjection.from_mask(m, truncated[uid]) for uid, m in amodal.items()}


IDS = {1: "0", 2: "1", 3: "2"}
CLASSES = {uid: cls for uid, (_, cls) in OBJECTS.items()}


@pytest.fixture(scope="module")
def annotated(tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    images, masks = [], {}
    for frame in (0, 1):
        for camera in CAMERAS:
            mask, amodal = _masks(frame, camera)
            masks[(frame, camera)] = mask
            images.append(label_image(mask, IDS, amodal, classes=CLASSES, camera=camera, frame=frame,
                                      epsilon_px=0))
            # Placeholder images so the YOLO export can link them.
            path = out / "images" / camera / f"{frame:06d}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"png")
    annotations = label_images(images, epsilon_px=0)
    source = _document()
    pristine = copy.deepcopy(source)
    document = add_annotations(source, _scene(), annotations, out)
    assert source == pristine  # the input is not mutated
    # The serialized form is what other tools read.
    document = json.loads(json.dumps(document, allow_nan=False))
    return out, document, annotations, masks


def test_document_validates_against_official_schema(annotated, openlabel_schema_path):
    import jsonschema

    _, document, _, _ = annotated
    schema = json.loads(Path(openlabel_schema_path).read_text())
    errors = sorted(jsonschema.Draft7Validator(schema).iter_errors(document), key=str)
    assert not errors, errors[:3]


def test_document_layout(annotated):
    _, document, _, _ = annotated
    root = document["openlabel"]
    frame1 = root["frames"]["1"]
    assert frame1["frame_properties"]["streams"]["cam_b"]["uri"] == "images/cam_b/000001.png"
    assert frame1["frame_properties"]["usdscene"]["streams"]["cam_b"]["mask_uri"] == "masks/cam_b/000001.png"
    data = frame1["objects"]["0"]["object_data"]
    names = [b["name"] for b in data["bbox"]]
    assert "cam_a_bbox" in names and "cam_b_amodal_bbox" in names
    assert "cam_b_bbox" not in names  # fully hidden from cam_b in frame 1
    assert all(b["coordinate_system"] in CAMERAS for b in data["bbox"])
    pointers = root["objects"]["0"]["object_data_pointers"]
    assert pointers["cam_b_bbox"]["frame_intervals"] == [{"frame_start": 0, "frame_end": 0}]
    assert pointers["cam_a_bbox"]["attribute_pointers"]["visible_fraction"] == "num"
    assert pointers["cam_a_poly2d_0"]["type"] == "poly2d"
    assert root["frame_intervals"] == [{"frame_start": 0, "frame_end": 1}]
    assert root["relations"] == _document()["openlabel"]["relations"]
    for frame in root["frames"].values():
        for entry in frame.get("objects", {}).values():
            for kind, items in entry["object_data"].items():
                assert len({i["name"] for i in items}) == len(items)


def test_hidden_object_has_amodal_box_and_zero_visibility(annotated):
    _, document, _, _ = annotated
    hidden = next(label for label in labels_in(document, 1, "cam_b") if label["uid"] == "0")
    assert hidden["bbox"] is None and hidden["polygons"] == []
    assert hidden["amodal_bbox"] == [19.5, 29.5, 10.0, 10.0]
    assert hidden["attributes"]["visible_fraction"] == 0.0


def test_document_boxes_and_polygons_equal_masks(annotated):
    _, document, _, masks = annotated
    for (frame, camera), mask in masks.items():
        for label in labels_in(document, frame, camera):
            region = mask == label["attributes"]["mask_id"]
            if label["bbox"] is None:
                assert not region.any()
                continue
            box = box_of(region)
            assert label["bbox"] == list(box.center_size())
            contours = [Contour(np.asarray(p["points"]).reshape(-1, 2), p["is_hole"], p["parent"])
                        for p in label["polygons"]]
            assert np.array_equal(rasterize_contours(contours, mask.shape), region)
            assert label["attributes"]["pixel_count"] == int(region.sum())


def test_coco_loads_in_pycocotools_and_self_evaluation_gives_ap_one(annotated, tmp_path):
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    out, document, _, masks = annotated
    path = export_coco(document, out)
    data = json.loads(path.read_text())
    assert len(data["images"]) == 4
    assert [c["name"] for c in data["categories"]] == ["backpack", "suitcase"]
    assert {(i["camera"], i["frame"]) for i in data["images"]} == {(c, f) for c in CAMERAS for f in (0, 1)}
    assert len(data["annotations"]) == 11  # 3 objects × 4 images − 1 fully hidden
    image = next(i for i in data["images"] if (i["camera"], i["frame"]) == ("cam_a", 0))
    ann = next(a for a in data["annotations"] if a["image_id"] == image["id"] and a["uid"] == "1")
    region = masks[(0, "cam_a")] == 2
    box = box_of(region)
    assert ann["bbox"] == [box.x_min, box.y_min, box.width_px, box.height_px]
    assert ann["area"] == region.sum() and ann["iscrowd"] == 0
    assert len(ann["segmentation"]) == 2  # split in two by object 2

    gt = COCO(str(path))
    # pycocotools rasterises the polygons; they must cover the mask region closely.
    rle_mask = gt.annToMask(gt.anns[ann["id"]]).astype(bool)
    assert (rle_mask & region).sum() / (rle_mask | region).sum() > 0.8
    for iou_type in ("bbox", "segm"):
        detections = [dict(a, score=1.0) for a in copy.deepcopy(data["annotations"])]
        dt = gt.loadRes(detections)
        evaluator = COCOeval(gt, dt, iou_type)
        evaluator.evaluate()
        evaluator.accumulate()
        evaluator.summarize()
        assert evaluator.stats[0] == pytest.approx(1.0)  # AP @ IoU .50:.95


def test_yolo_files_parse_and_boxes_lie_inside_images(annotated):
    out, document, _, _ = annotated
    root = export_yolo(document, out)
    records = {(r["camera"], r["frame"]): r for r in image_records(document)}
    for task in ("detect", "segment"):
        yaml = (root / task / "data.yaml").read_text()
        assert '0: "backpack"' in yaml and '1: "suitcase"' in yaml
        files = sorted((root / task / "labels").rglob("*.txt"))
        assert len(files) == 4
        for file in files:
            assert (root / task / "images" / file.parent.name / (file.stem + ".png")).exists()
            lines = file.read_text().splitlines()
            expected = 2 if (file.parent.name, int(file.stem)) == ("cam_b", 1) else 3
            assert len(lines) == expected
            for line in lines:
                cls, *values = line.split()
                assert int(cls) in (0, 1)
                values = np.array([float(v) for v in values])
                assert ((values >= 0) & (values <= 1)).all()
                if task == "detect":
                    cx, cy, w, h = values
                    assert len(values) == 4
                    assert cx - w / 2 >= 0 and cx + w / 2 <= 1 + 1e-9
                    assert cy - h / 2 >= 0 and cy + h / 2 <= 1 + 1e-9
                else:
                    assert len(values) >= 6 and len(values) % 2 == 0
    # Pixel check of one box: object 1 in cam_a frame 0 spans columns 10..49, rows 22..39.
    line = (root / "detect" / "labels" / "cam_a" / "000000.txt").read_text().splitlines()[1]
    cls, cx, cy, w, h = line.split()
    assert int(cls) == 1
    assert float(cx) * W == pytest.approx(30.0, abs=1e-4) and float(w) * W == pytest.approx(40, abs=1e-4)
    assert float(cy) * H == pytest.approx(31.0, abs=1e-4) and float(h) * H == pytest.approx(18, abs=1e-4)
    assert records[("cam_a", 0)]["width_px"] == W


def test_coco_categories_from_catalog_classes(annotated):
    _, document, _, _ = annotated
    data = coco_dataset(document, classes=["suitcase", "passenger", "backpack"])
    assert [(c["id"], c["name"]) for c in data["categories"]] == [(1, "backpack"), (2, "passenger"), (3, "suitcase")]
    assert {a["category_id"] for a in data["annotations"]} == {1, 3}


def test_annotated_document_from_writer_validates_and_reads_back(openlabel_schema_path, tmp_path):
    from usdscene.converters.openlabel import read_openlabel, schema_problems, write_openlabel

    scene = _scene()
    images = []
    for frame in (0, 1):
        for camera in CAMERAS:
            mask, amodal = _masks(frame, camera)
            images.append(label_image(mask, IDS, amodal, classes=CLASSES, camera=camera, frame=frame))
    document = add_annotations(write_openlabel(scene), scene, label_images(images), tmp_path)
    document = json.loads(json.dumps(document, allow_nan=False))
    assert schema_problems(document, openlabel_schema_path) == []
    again = read_openlabel(document)
    assert [o.uid for o in again.objects] == [o.uid for o in scene.objects]
    assert [c.name for c in again.cameras] == list(CAMERAS)
    assert (again.frame_start, again.frame_end) == (0, 1)
    assert labels_in(document, 0, "cam_a")[0]["bbox"] is not None


def test_label_statistics_counts(annotated):
    from usdscene.dataset.statistics import draw_chart, label_statistics

    _, document, annotations, _ = annotated
    stats = label_statistics(document)
    assert stats["images"] == 4
    assert stats["classes"]["backpack"] == {"labels": 7, "hidden": 1, "objects": 2}
    assert stats["classes"]["suitcase"] == {"labels": 4, "hidden": 0, "objects": 1}
    assert stats["cameras"]["cam_b"] == {"images": 2, "labels": 5, "hidden": 1}
    fractions = [o.visible_fraction for image in annotations for o in image.objects]
    assert sum(stats["visibility"]) == len(fractions)
    assert stats["visibility"][0] >= 1  # the hidden bag
    chart = draw_chart(stats)
    assert chart.ndim == 3 and chart.shape[2] == 3 and (chart < 255).any()


def _friendly_document() -> dict:
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "friendly",
                     "usdscene": {"frame_range": {"frame_start": 0, "frame_end": 1}}},
        "streams": {"corridor": {"type": "camera", "uri": "rtsp://cam", "stream_properties": {"usdscene": {
            "model": "perspective", "resolution_px": [W, H], "sensor_size_mm": [5.6, 4.2], "fov_deg": 90.0,
            "position_m": [3.0, 0.0, 1.95], "target_m": [1.0, 0.0, 0.6]}}}},
        "objects": {"0": {"name": "bag_0", "type": "backpack"}},
    }}


def test_cameras_are_written_in_exact_calibrated_form(openlabel_schema_path, tmp_path):
    from usdscene.converters.openlabel import read_openlabel, schema_problems

    source = _friendly_document()
    scene = read_openlabel(source)
    mask = np.zeros((H, W), np.uint16)
    mask[10:20, 10:20] = 1
    images = [label_image(mask, {1: "0"}, camera="corridor", frame=f) for f in (0, 1)]
    document = json.loads(json.dumps(add_annotations(source, scene, label_images(images), tmp_path)))
    assert schema_problems(document, openlabel_schema_path) == []
    stream = document["openlabel"]["streams"]["corridor"]
    assert "intrinsics_pinhole" in stream["stream_properties"] and stream["uri"] == "rtsp://cam"
    assert "position_m" not in json.dumps(stream)
    assert "pose_wrt_parent" in document["openlabel"]["coordinate_systems"]["corridor"]
    again = read_openlabel(document).camera("corridor")
    original = scene.camera("corridor")
    assert again.intrinsics == original.intrinsics
    assert np.allclose(again.pose.as_array(), original.pose.as_array(), atol=1e-9)


def test_moving_camera_keeps_one_exact_transform_per_frame(tmp_path):
    from usdscene.converters.openlabel import read_openlabel, write_openlabel
    from usdscene.document.model import Pose

    base = _scene()
    moving = Camera("cam_a", base.cameras[0].intrinsics, Pose(),
                    frame_poses=((0, Pose.from_rotation_translation(np.eye(3), (0.0, 0.0, 0.0))),
                                 (1, Pose.from_rotation_translation(np.eye(3), (0.5, 0.0, 0.0)))))
    scene = SceneSpec(name="moving", frame_start=0, frame_end=1, cameras=(moving,), objects=base.objects)
    images = [label_image(np.zeros((H, W), np.uint16), IDS, camera="cam_a", frame=f) for f in (0, 1)]
    document = add_annotations(write_openlabel(scene), scene, label_images(images), tmp_path)
    transforms = document["openlabel"]["frames"]["1"]["frame_properties"]["transforms"]
    assert len([t for t in transforms.values() if t["src"] == "cam_a"]) == 1
    again = read_openlabel(document).camera("cam_a")
    assert np.allclose(again.pose_at(1).translation_m, (0.5, 0.0, 0.0))


def test_resolve_places_follows_chains_and_stops_at_cycles():
    from usdscene.converters.openlabel.annotations import resolve_places
    from usdscene.document.model import FrameInterval, PlaceRef, Relation

    objects = tuple(SceneObject(uid, uid, "backpack", (FrameInterval(0, 5),)) for uid in "abcxy")
    scene = SceneSpec(objects=objects, places=(PlaceRef("p", "seat_03A"),), relations=(
        Relation("1", "is_on", "a", "b"),                        # a on b ...
        Relation("2", "is_below", "b", "p"),                     # ... b below the seat
        Relation("3", "is_in_front_of", "c", "a", (FrameInterval(2, 3),)),
        Relation("4", "is_on", "x", "y"), Relation("5", "is_on", "y", "x"),  # a cycle
        Relation("6", "looks_at", "a", "p"),                     # not a placement relation
    ))
    assert resolve_places(scene, 0) == {"a": ("p", "is_below"), "b": ("p", "is_below")}
    assert resolve_places(scene, 2)["c"] == ("p", "is_below")
    assert resolve_places(scene, 9) == {}  # nobody present
