"""Training splits: rules, assignment, and COCO/YOLO datasets of one or several annotated outputs
(synthetic masks labelled by the real labeller, no renderer needed)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from usdscene.converters.openlabel import write_openlabel
from usdscene.converters.openlabel.annotations import add_annotations
from usdscene.errors import DocumentError
from usdscene.dataset.export import ExportOptions, export_dataset, export_formats
from usdscene.files import write_json_atomic
from usdscene.labels.image_labels import label_image, label_images
from usdscene.document.model import Camera, FrameInterval, Intrinsics, LensModel, SceneObject, SceneSpec
from usdscene.document.splits import ImageKey, assign_splits, parse_split

W, H = 32, 24
CAMERAS = ("cam_a", "cam_b")


def _annotated_output(folder: Path, frames: int, classes=("backpack", "suitcase"), split: str = "",
                      split_seed: int = 0) -> Path:
    """An output folder with ``annotations.openlabel.json`` and placeholder images: one object
    per class moving one pixel per frame, seen by both cameras; the document carries ``split``."""
    intr = Intrinsics(LensModel.PERSPECTIVE, W, H, 20.0, 20.0, (W - 1) / 2, (H - 1) / 2)
    objects = tuple(SceneObject(str(k), f"obj_{k}", cls, (FrameInterval(0, frames - 1),))
                    for k, cls in enumerate(classes))
    scene = SceneSpec(name=folder.name, frame_start=0, frame_end=frames - 1,
                      cameras=tuple(Camera(name, intr) for name in CAMERAS), objects=objects,
                      split_rule=split, split_seed=split_seed)
    images = []
    for frame in range(frames):
        for camera in CAMERAS:
            mask = np.zeros((H, W), np.uint16)
            for k in range(len(classes)):
                x = 2 + frame % 10 + 12 * k
                mask[4 + 8 * k:10 + 8 * k, x:x + 6] = k + 1
            images.append(label_image(mask, {k + 1: str(k) for k in range(len(classes))},
                                      classes={str(k): c for k, c in enumerate(classes)},
                                      camera=camera, frame=frame))
            path = folder / "images" / camera / f"{frame:06d}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"png")
    document = add_annotations(write_openlabel(scene), scene, label_images(images), folder)
    write_json_atomic(folder / "annotations.openlabel.json", document)
    return folder


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp("campaign")
    return (_annotated_output(root / "seq_a", 10), _annotated_output(root / "seq_b", 6, ("backpack",)))


def test_rules_parse():
    rule = parse_split(" train=0.8, val=0.1,test=0.1 ")
    assert rule.kind == "fractions" and dict(rule.entries) == {"train": 0.8, "val": 0.1, "test": 0.1}
    rule = parse_split("frames:train=0:399+500:599,val=400:449,test=450")
    assert rule.entries["train"] == ((0, 399), (500, 599)) and rule.entries["test"] == ((450, 450),)
    rule = parse_split("cameras:val=cam_01,cam_02,test=cam_03")
    assert dict(rule.entries) == {"val": ("cam_01", "cam_02"), "test": ("cam_03",)}
    assert rule.names == ("train", "val", "test")  # the unnamed cameras train
    assert parse_split("documents:val=seq_b").names == ("train", "val")


@pytest.mark.parametrize("text, words", [
    ("train=0.8,val=0.1", ["add up to 0.9"]),
    ("train=0.8,val=x,test=0.1", ["'x'", "'val'"]),
    ("frames:train=0:10,val=10:20", ["0:10 (train)", "10:20 (val)", "overlap"]),
    ("frames:train=9:3", ["3 is before 9"]),
    ("cameras:val=cam_a,test=cam_a", ["'cam_a'", "'val'", "'test'"]),
    ("bycolour:val=red", ["'bycolour'"]),
    ("train=0.5,train=0.5", ["twice"]),
    ("", ["names no split"]),
    ("../x=1", ["'../x'"]),
])
def test_bad_rules_name_the_value(text, words):
    with pytest.raises(DocumentError) as info:
        parse_split(text)
    message = str(info.value)
    assert message.startswith("--split: ")
    for word in words:
        assert word in message


def test_fractions_group_by_frame_deterministically():
    keys = [ImageKey(s, f, c) for s in ("a", "b") for f in range(50) for c in ("c0", "c1", "c2")]
    rule = parse_split("train=0.8,val=0.1,test=0.1")
    first = assign_splits(keys, rule, seed=7)
    assert first == assign_splits(list(reversed(keys)), rule, seed=7)  # order of input is irrelevant
    assert first != assign_splits(keys, rule, seed=8)
    assert set(first) == set(keys)
    per_frame: dict = {}
    for key, split in first.items():
        per_frame.setdefault((key.source, key.frame), set()).add(split)
    assert all(len(s) == 1 for s in per_frame.values())  # no frame in two splits
    frames = {name: sum(1 for s in per_frame.values() if s == {name}) for name in ("train", "val", "test")}
    assert frames == {"train": 80, "val": 10, "test": 10}


def test_listing_rules_rest_and_gaps():
    keys = [ImageKey("a", f, c) for f in range(10) for c in ("c0", "c1")]
    cams = assign_splits(keys, parse_split("cameras:val=c1"))
    assert {k.camera for k, s in cams.items() if s == "val"} == {"c1"}
    assert {k.camera for k, s in cams.items() if s == "train"} == {"c0"}
    frames = assign_splits(keys, parse_split("frames:train=0:5,val=8:9"))
    assert sorted({k.frame for k in frames}) == [0, 1, 2, 3, 4, 5, 8, 9]  # 6, 7: the gap is left out
    assert {frames[ImageKey("a", 9, "c0")], frames[ImageKey("a", 0, "c1")]} == {"val", "train"}
    with pytest.raises(DocumentError, match=r"camera 'c9' of split 'val' is not in the dataset"):
        assign_splits(keys, parse_split("cameras:val=c9"))


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): (os.readlink(p).encode() if p.is_symlink() else p.read_bytes())
            for p in sorted(folder.rglob("*")) if p.is_file() or p.is_symlink()}


def test_campaign_dataset_loads_per_split_in_pycocotools(campaign, tmp_path):
    from pycocotools.coco import COCO

    seq_a, seq_b = campaign
    dataset = tmp_path / "dataset"
    written = export_dataset([seq_a, seq_b], ["coco", "yolo"], dataset, ExportOptions(document_classes=True,
                             split="train=0.6,val=0.2,test=0.2", split_seed=3))
    assert written == {"coco": dataset / "coco", "yolo": dataset / "yolo"}
    seen_ids, seen_ann, frame_split = set(), set(), {}
    for split in ("train", "val", "test"):
        path = dataset / "coco" / f"annotations_{split}.json"
        coco = COCO(str(path))
        assert coco.getImgIds(), split
        data = json.loads(path.read_text())
        assert data["info"]["split"] == split
        assert [c["name"] for c in data["categories"]] == ["backpack", "suitcase"]
        root = path.parent / data["info"]["image_root"]
        for image in data["images"]:
            assert (root / image["file_name"]).is_file()
            source = image["file_name"].split("/")[0]
            assert source in ("seq_a", "seq_b")
            assert frame_split.setdefault((source, image["frame"]), split) == split  # no frame twice
        assert not seen_ids & set(coco.getImgIds())
        assert not seen_ann & set(coco.getAnnIds())
        seen_ids |= set(coco.getImgIds())
        seen_ann |= set(coco.getAnnIds())
    assert seen_ids == set(range(1, 2 * (10 + 6) + 1))  # every image once, ids unique across folders
    assert len(seen_ann) == 2 * 10 * 2 + 2 * 6 * 1
    # 16 (folder, frame) groups: 0.6 / 0.2 / 0.2 rounded at the cumulative cut points
    counts = json.loads((dataset / "splits.json").read_text())["counts"]
    assert {k: v["frames"] for k, v in counts.items()} == {"train": 10, "val": 3, "test": 3}

    for task in ("detect", "segment"):
        yaml = (dataset / "yolo" / task / "data.yaml").read_text()
        assert 'train: "train.txt"' in yaml and 'val: "val.txt"' in yaml and 'test: "test.txt"' in yaml
        listed = []
        for split in ("train", "val", "test"):
            lines = (dataset / "yolo" / task / f"{split}.txt").read_text().splitlines()
            assert len(lines) == counts[split]["images"]
            for line in lines:
                image = dataset / "yolo" / task / line
                assert image.is_file()
                label = Path(str(image.parent).replace("/images/", "/labels/")) / (image.stem + ".txt")
                assert label.is_file() and label.read_text().strip()
            listed += lines
        assert len(listed) == len(set(listed)) == 32

    again = tmp_path / "again"
    export_dataset([seq_a, seq_b], ["coco", "yolo"], again, ExportOptions(document_classes=True,
                   split="train=0.6,val=0.2,test=0.2", split_seed=3))
    assert _tree(again) == _tree(dataset)  # byte-identical


def test_single_output_without_split_keeps_the_one_file_layout(campaign, tmp_path):
    seq_a, _ = campaign
    written = export_formats(seq_a, ["coco", "yolo"], ExportOptions(document_classes=True))
    data = json.loads(written["coco"].read_text())
    assert written["coco"] == seq_a / "exports" / "coco" / "annotations.json"
    assert data["info"]["image_root"] == "../.." and data["images"][0]["file_name"] == "images/cam_a/000000.png"
    assert "train: images" in (written["yolo"] / "detect" / "data.yaml").read_text()
    split = export_formats(seq_a, ["coco", "yolo"],
                           ExportOptions(document_classes=True, split="frames:train=0:6,val=7:9"))
    val = json.loads((split["coco"] / "annotations_val.json").read_text())
    assert sorted({i["frame"] for i in val["images"]}) == [7, 8, 9]
    assert val["images"][0]["file_name"] == "images/cam_a/000007.png"
    assert (split["yolo"] / "detect" / "val.txt").read_text().splitlines()[0] == "./images/cam_a/000007.png"


def test_cli_campaign_by_document_and_errors(campaign, tmp_path, capsys):
    from usdscene.cli import main

    seq_a, seq_b = campaign
    dataset = tmp_path / "by_doc"
    code = main(["export", "coco", "yolo", str(seq_a), str(seq_b), "--dataset", str(dataset),
                 "--document-classes", "--split", "documents:val=seq_b"])
    assert code == 0
    out = capsys.readouterr().out
    assert "train 20 images (10 frames), val 12 images (6 frames)" in out
    val = json.loads((dataset / "coco" / "annotations_val.json").read_text())
    assert {i["file_name"].split("/")[0] for i in val["images"]} == {"seq_b"}

    assert main(["export", "coco", str(seq_a), str(seq_b), "--document-classes"]) == 1
    assert "--dataset" in capsys.readouterr().err
    assert main(["export", "coco", str(seq_a), "--split", "train=0.5,val=0.2"]) == 2
    assert "add up to 0.7" in capsys.readouterr().err
    assert main(["export", "coco", str(seq_a), "--document-classes", "--split", "cameras:val=cam_z"]) == 1
    assert "usdscene: error: --split: camera 'cam_z'" in capsys.readouterr().err
