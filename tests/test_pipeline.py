"""End to end: `usdscene run` on the shipped minimal example (64x48 px, few samples)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from usdscene.cli import main

REPO = Path(__file__).resolve().parent.parent
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"

pytestmark = [pytest.mark.blender, pytest.mark.slow]


@pytest.fixture(scope="module")
def run_output(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "out"
    code = main(["run", str(MINIMAL), "-o", str(out), "--export", "coco", "yolo", "--no-progress"])
    assert code == 0
    return out


def test_run_writes_every_product(run_output, capsys):
    out = run_output
    assert sorted(p.name for p in (out / "images").iterdir()) == ["cam_01", "cam_02"]
    assert len(list((out / "images").glob("*/*.png"))) == 6  # 2 cameras x 3 frames
    assert len(list((out / "masks").glob("*/*.png"))) == 6
    assert (out / "stage" / "scene.usda").is_file()
    assert (out / "exports" / "coco" / "annotations.json").is_file()
    assert (out / "exports" / "yolo" / "detect" / "data.yaml").is_file()
    assert (out / "report" / "index.html").is_file() and (out / "report" / "data" / "index.js").is_file()


def test_annotations_validate_and_read_back(run_output, openlabel_schema_path):
    from usdscene.converters.openlabel import load_document, read_openlabel, schema_problems

    document = load_document(run_output / "annotations.openlabel.json")
    assert schema_problems(document, openlabel_schema_path) == []
    scene = read_openlabel(document)
    assert {c.name for c in scene.cameras} == {"cam_01", "cam_02"}
    frames = document["openlabel"]["frames"]
    labelled = [uid for f in frames.values() for uid, o in f.get("objects", {}).items()
                if any(k.endswith("bbox") for k in json.dumps(o.get("object_data", {})).split('"'))]
    assert labelled, "no object got a box in any frame"


def test_coco_export_loads_in_pycocotools(run_output):
    from pycocotools.coco import COCO

    coco = COCO(str(run_output / "exports" / "coco" / "annotations.json"))
    assert len(coco.getImgIds()) == 6
    assert len(coco.getAnnIds()) > 0


def test_rerun_resumes_without_rendering_and_gives_identical_labels(run_output, capsys):
    before = (run_output / "annotations.openlabel.json").read_bytes()
    masks_before = {p: p.read_bytes() for p in (run_output / "masks").glob("*/*.png")}
    capsys.readouterr()
    assert main(["run", str(MINIMAL), "-o", str(run_output), "--export", "--no-progress"]) == 0
    summary = capsys.readouterr().out
    assert "0 rendered, 6 already done" in summary
    assert (run_output / "annotations.openlabel.json").read_bytes() == before
    assert {p: p.read_bytes() for p in masks_before} == masks_before


def test_two_workers_give_byte_identical_outputs(run_output, tmp_path):
    out = tmp_path / "two"
    assert main(["run", str(MINIMAL), "-o", str(out), "--export", "--workers", "2", "--no-progress"]) == 0
    for mask in (run_output / "masks").glob("*/*.png"):
        assert (out / mask.relative_to(run_output)).read_bytes() == mask.read_bytes(), mask
    for layer in (run_output / "stage").glob("*.usda"):
        assert (out / "stage" / layer.name).read_bytes() == layer.read_bytes(), layer.name
    assert (out / "annotations.openlabel.json").read_bytes() == (run_output / "annotations.openlabel.json").read_bytes()


def test_run_exports_with_the_documents_split_rule(tmp_path, capsys):
    document = json.loads(MINIMAL.read_text())
    metadata = document["openlabel"]["metadata"].setdefault("usdscene", {})
    metadata["split"] = {"rule": "cameras:val=cam_02", "seed": 0}
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(document))
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "--export", "coco", "--no-progress"]) == 0
    val = json.loads((out / "exports" / "coco" / "annotations_val.json").read_text())
    train = json.loads((out / "exports" / "coco" / "annotations_train.json").read_text())
    assert {i["file_name"].split("/")[-2] for i in val["images"]} == {"cam_02"}
    assert {i["file_name"].split("/")[-2] for i in train["images"]} == {"cam_01"}


def test_run_on_missing_document_is_a_clear_error(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.json"), "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "nope.json" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
