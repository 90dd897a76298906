"""Labels exact at the pixel: polygons that pycocotools fills back to the mask, the visible
fraction on |visible ∩ amodal|, and the export's label filter (synthetic masks, no renderer)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.converters.exports.coco import LabelFilter, coco_dataset
from usdscene.converters.openlabel.annotations import add_annotations
from usdscene.converters.exports.yolo import yolo_lines
from usdscene.document.model import Camera, Intrinsics, LensModel, SceneObject, SceneSpec
from usdscene.labels.amodal import AmodalProjection
from usdscene.labels.image_labels import label_image, label_images

W, H = 96, 72


def _instance_mask(seed: int) -> np.ndarray:
    """(H, W) uint16: objects of every kind of shape that trips polygon tools: single pixels,
    one-pixel lines (straight and diagonal), discs with holes, blobs touching at corners,
    ragged noise; ids 1..N, one id per shape."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((H, W), np.uint16)
    yy, xx = np.mgrid[0:H, 0:W]
    next_id = 1

    def put(region):
        nonlocal next_id
        mask[region & (mask == 0)] = next_id
        next_id += 1

    for _ in range(4):  # single pixels
        region = np.zeros((H, W), bool)
        region[rng.integers(0, H), rng.integers(0, W)] = True
        put(region)
    for _ in range(2):  # diagonal one-pixel lines
        region = np.zeros((H, W), bool)
        x0, y0 = rng.integers(0, W - 20), rng.integers(0, H - 20)
        n = int(rng.integers(3, 20))
        region[y0 + np.arange(n), x0 + np.arange(n)] = True
        put(region)
    region = np.zeros((H, W), bool)  # a horizontal line
    region[rng.integers(0, H), 10:40] = True
    put(region)
    for _ in range(5):  # discs, some with holes, radius 2..14 px
        cx, cy, r = rng.uniform(0, W), rng.uniform(0, H), rng.uniform(2, 14)
        disc = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
        if r > 6:
            disc &= (xx - cx) ** 2 + (yy - cy) ** 2 > (r / 3) ** 2
        put(disc)
    put((rng.random((H, W)) < 0.15) & (xx > 60) & (yy > 40))  # ragged noise
    return mask


def _document_of(masks: list[np.ndarray]) -> dict:
    ids = {i: str(i) for i in range(1, max(int(m.max()) for m in masks) + 1)}
    images = [label_image(m, ids, classes={u: "thing" for u in ids.values()}, camera="cam", frame=f)
              for f, m in enumerate(masks)]
    intr = Intrinsics(LensModel.PERSPECTIVE, W, H, 60.0, 60.0, (W - 1) / 2, (H - 1) / 2)
    scene = SceneSpec(name="shapes", frame_start=0, frame_end=len(masks) - 1, cameras=(Camera("cam", intr),),
                      objects=tuple(SceneObject(u, f"o{u}", "thing") for u in ids.values()))
    source = {"openlabel": {
        "metadata": {"schema_version": "1.0.0"},
        "streams": {"cam": {"type": "camera", "stream_properties": {"intrinsics_pinhole": {
            "width_px": W, "height_px": H,
            "camera_matrix_3x4": [60.0, 0, (W - 1) / 2, 0, 0, 60.0, (H - 1) / 2, 0, 0, 0, 1, 0],
            "distortion_coeffs_1xN": []}}}},
        "objects": {u: {"name": f"o{u}", "type": "thing",
                        "frame_intervals": [{"frame_start": 0, "frame_end": len(masks) - 1}]} for u in ids.values()}}}
    document = add_annotations(source, scene, label_images(images), "out")
    return json.loads(json.dumps(document))


@pytest.fixture(scope="module")
def shapes():
    masks = [_instance_mask(seed) for seed in range(6)]
    return masks, _document_of(masks)


def test_pycocotools_fills_every_polygon_back_to_its_mask(shapes):
    from pycocotools import mask as mask_utils

    masks, document = shapes
    coco = coco_dataset(document)
    frame_of = {image["id"]: image["frame"] for image in coco["images"]}
    ious, small_ious, empty = [], [], 0
    for ann in coco["annotations"]:
        truth = masks[frame_of[ann["image_id"]]] == int(ann["uid"])
        rles = mask_utils.frPyObjects(ann["segmentation"], H, W)
        filled = mask_utils.decode(mask_utils.merge(rles)).astype(bool)
        if not filled.any():
            empty += 1
        iou = (filled & truth).sum() / (filled | truth).sum()
        (ious if truth.sum() >= 100 else small_ious).append(iou)
    assert empty == 0
    assert len(ious) >= 12 and min(ious) >= 0.95, sorted(ious)[:3]
    # at the default tolerance (below half a pixel) the fill is exact whatever the size
    assert min(ious) == 1.0 and min(small_ious) == 1.0, (min(ious), min(small_ious))


def test_coco_polygons_have_integer_corners(shapes):
    _, document = shapes
    for ann in coco_dataset(document)["annotations"]:
        for polygon in ann["segmentation"]:
            assert all(float(v).is_integer() for v in polygon), polygon[:8]


def test_rle_below_a_pixel_count_decodes_to_the_mask(shapes):
    from pycocotools import mask as mask_utils

    masks, document = shapes
    coco = coco_dataset(document, rle_below_px=50)
    frame_of = {image["id"]: image["frame"] for image in coco["images"]}
    rle_count = 0
    for ann in coco["annotations"]:
        truth = masks[frame_of[ann["image_id"]]] == int(ann["uid"])
        if isinstance(ann["segmentation"], dict):
            rle_count += 1
            assert truth.sum() < 50
            rle = mask_utils.frPyObjects(ann["segmentation"], H, W)
            assert np.array_equal(mask_utils.decode(rle).astype(bool), truth)
        else:
            assert truth.sum() >= 50
    assert rle_count >= 6 * 7  # the single pixels and lines of every image at least


def test_label_filter_drops_small_and_hidden_labels_in_coco_and_yolo(shapes):
    _, document = shapes
    every = coco_dataset(document)["annotations"]
    kept = coco_dataset(document, label_filter=LabelFilter(min_pixels=10))["annotations"]
    assert all(a["area"] >= 10 for a in kept)
    assert len(kept) == sum(a["area"] >= 10 for a in every) and len(kept) < len(every)
    detect, _ = yolo_lines(document, 0, "cam", W, H, {"thing": 0}, label_filter=LabelFilter(min_pixels=10))
    assert len(detect) == sum(a["area"] >= 10 for a in every if a["image_id"] == 1)
    # Without amodal projections the fraction is unknown: a visibility filter keeps the label.
    assert len(coco_dataset(document, label_filter=LabelFilter(min_visible_fraction=0.5))["annotations"]) == len(every)


def test_visible_fraction_counts_only_pixels_inside_the_projection():
    """Mask pixels just outside the exact projection (the render's boundary moves by a
    fraction of a pixel) must not cancel occlusion: 26 occluded pixels of 400 stay 0.935
    even with 30 stray pixels on the far side."""
    amodal = np.zeros((40, 60), bool)
    amodal[10:30, 10:30] = True  # 400 px
    mask = np.zeros((40, 60), np.uint16)
    mask[amodal] = 1
    mask[10:23, 15:17] = 2  # a post hides 26 px
    mask[10:25, 30:32] = 1  # 30 stray pixels beyond the projection's right edge
    labels = label_image(mask, {1: "van", 2: "post"}, {"van": AmodalProjection.from_mask(amodal)})
    van = {o.uid: o for o in labels.objects}["van"]
    assert van.pixel_count == 400 - 26 + 30
    assert van.visible_fraction == pytest.approx((400 - 26) / 400)
    crop = AmodalProjection(amodal[5:35, 5:35].copy(), (5, 5), (60, 40))
    van = label_image(mask, {1: "van"}, {"van": crop}).objects[0]
    assert van.visible_fraction == pytest.approx((400 - 26) / 400)


def test_export_command_filters_labels(shapes, tmp_path, capsys):
    from usdscene.cli import main

    _, document = shapes
    out = tmp_path / "out"
    out.mkdir()
    (out / "annotations.openlabel.json").write_text(json.dumps(document), encoding="utf-8")
    every = coco_dataset(document)["annotations"]
    assert main(["export", "coco", str(out), "--document-classes", "--min-pixels", "10",
                 "--coco-rle-below", "20"]) == 0
    written = json.loads((out / "exports" / "coco" / "annotations.json").read_text(encoding="utf-8"))
    assert len(written["annotations"]) == sum(a["area"] >= 10 for a in every)
    assert {isinstance(a["segmentation"], dict) for a in written["annotations"]} == {True, False}
    assert all(isinstance(a["segmentation"], dict) == (a["area"] < 20) for a in written["annotations"])
    assert main(["export", "coco", str(out), "--document-classes", "--min-visible", "1.5"]) == 2
    assert "between 0 and 1" in capsys.readouterr().err
