"""Split rules carried by the document (``metadata.usdscene.split``): read and checked, accepted
by the official OpenLABEL schema, used by ``usdscene export`` when no ``--split`` is given (the
command line wins), written by ``usdscene generate --split``."""

from __future__ import annotations

import json

import pytest

from test_splits import _annotated_output
from usdscene.cli import main
from usdscene.converters.openlabel import read_openlabel, schema_problems, write_openlabel
from usdscene.errors import DocumentError
from usdscene.document.model import SceneSpec


def test_split_rule_round_trips_and_the_official_schema_accepts_it(openlabel_schema_path):
    scene = SceneSpec(name="s", frame_start=0, frame_end=9, split_rule="frames:train=0:7,val=8:9", split_seed=4)
    document = write_openlabel(scene)
    assert document["openlabel"]["metadata"]["usdscene"]["split"] == {"rule": "frames:train=0:7,val=8:9", "seed": 4}
    assert schema_problems(document, openlabel_schema_path) == []
    back = read_openlabel(document)
    assert (back.split_rule, back.split_seed) == ("frames:train=0:7,val=8:9", 4)


@pytest.mark.parametrize("value, where, words", [
    ({"rule": "train=0.7,val=0.2"}, "metadata.usdscene.split.rule", "add up to 0.9"),
    ({"rule": "train=1", "seed": -2}, "metadata.usdscene.split.seed", "-2"),
    ({"rule": "", "seed": 1}, "metadata.usdscene.split.rule", "''"),
    ({"rule": "train=1", "folds": 5}, "metadata.usdscene.split.folds", "unknown key 'folds'"),
    ("train=1", "metadata.usdscene.split", "expected an object"),
])
def test_a_bad_split_in_the_document_names_the_field_and_value(value, where, words):
    document = write_openlabel(SceneSpec(name="s"))
    document["openlabel"]["metadata"]["usdscene"]["split"] = value
    with pytest.raises(DocumentError) as info:
        read_openlabel(document)
    problem = next(p for p in info.value.problems if "split" in p.where)
    assert problem.where.endswith(where) and words in problem.message


def test_export_uses_the_documents_rule_unless_the_command_line_gives_one(tmp_path, capsys):
    out = _annotated_output(tmp_path / "seq", 10, split="frames:train=0:7,val=8:9")
    assert main(["export", "coco", "yolo", str(out), "--document-classes"]) == 0
    assert "train 16 images (8 frames), val 4 images (2 frames)" in capsys.readouterr().out
    splits = json.loads((out / "exports" / "splits.json").read_text())
    assert splits["rule"] == "frames:train=0:7,val=8:9"
    val = json.loads((out / "exports" / "coco" / "annotations_val.json").read_text())
    assert {i["file_name"].rsplit("/", 1)[1] for i in val["images"]} == {"000008.png", "000009.png"}
    # The command line wins.
    assert main(["export", "coco", str(out), "--document-classes", "--split", "cameras:val=cam_b"]) == 0
    assert "train 10 images (10 frames), val 10 images (10 frames)" in capsys.readouterr().out
    # Two documents carrying different rules: one readable error naming the field.
    other = _annotated_output(tmp_path / "other", 4, split="train=0.5,val=0.5", split_seed=2)
    assert main(["export", "coco", str(out), str(other), "--dataset", str(tmp_path / "ds"),
                 "--document-classes"]) == 1
    err = capsys.readouterr().err
    assert "metadata.usdscene.split: rule 'train=0.5,val=0.5' (seed 2) differs from 'frames:train=0:7,val=8:9'" in err
    assert "Traceback" not in err


def test_generate_writes_the_split_rule_into_the_document(tmp_path, monkeypatch):
    from usdscene.scene.catalog import load_catalog
    from usdscene.converters.openlabel import write_document
    from usdscene.generate.sequences import GenerateOptions, generate_sequence
    from test_compose_support import look_at_cv, pinhole
    from usdscene.document import model as m

    setup = m.SceneSpec(name="cabin", environment="aircraft_cabin", seed=0,
                        cameras=(m.Camera("c", pinhole(), pose=look_at_cv((-1.0, 0.0, 1.9), (-2.0, 1.0, 0.3))),))
    setup_path = tmp_path / "setup.json"
    write_document(setup_path, write_openlabel(setup))
    out = tmp_path / "seq.json"
    assert main(["generate", "balanced", "--setup", str(setup_path), "-o", str(out), "--classes", "backpack",
                 "--places", "seat_03?", "--frames", "3", "--split", "train=0.8,val=0.2", "--split-seed", "5"]) == 0
    written = json.loads(out.read_text())
    assert written["openlabel"]["metadata"]["usdscene"]["split"] == {"rule": "train=0.8,val=0.2", "seed": 5}
    assert json.loads((tmp_path / "seq.json.report.json").read_text())["generator"]["split"] == "train=0.8,val=0.2"
    assert main(["generate", "balanced", "--setup", str(setup_path), "-o", str(out), "--split", "train=2"]) == 2
    with pytest.raises(DocumentError, match="--split"):
        generate_sequence(setup, load_catalog(), GenerateOptions(strategy="balanced", frames=2, split="val=0.5"))
