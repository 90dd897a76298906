"""Validate is the whole gate: an object related to a support too small to hold it fails
``validate`` (naming both objects) with the same check composition runs, instead of passing
validation and failing in compose."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from usdscene.errors import DocumentError

REPO = Path(__file__).resolve().parent.parent
MINIMAL = json.loads((REPO / "examples" / "minimal" / "scene.openlabel.json").read_text(encoding="utf-8"))


def _document(subject_class: str, support_class: str) -> dict:
    document = copy.deepcopy(MINIMAL)
    body = document["openlabel"]
    frames = [{"frame_start": 0, "frame_end": 2}]
    body["objects"]["55"] = {"name": "support", "type": support_class, "frame_intervals": frames,
                             "object_data": {"vec": [{"name": "position_m", "val": [1.0, 0.3, 0.45]}]}}
    body["objects"]["56"] = {"name": "on_top", "type": subject_class, "frame_intervals": frames}
    body["relations"]["56"] = {"name": "on top", "type": "is_on",
                               "rdf_subjects": [{"uid": "56", "type": "object"}],
                               "rdf_objects": [{"uid": "55", "type": "object"}]}
    return document


def _write(tmp_path, document) -> Path:
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


def test_validate_refuses_an_object_on_a_support_too_small(tmp_path):
    from usdscene.validation import validate_document

    path = _write(tmp_path, _document("trolley_suitcase", "coffee_cup"))
    with pytest.raises(DocumentError) as error:
        validate_document(path)
    misfits = [p for p in error.value.problems if "does not fit" in p.message]
    assert len(misfits) == 1, error.value.problems
    assert misfits[0].where == "objects.56"
    assert "'56'" in misfits[0].message and "object '55' (is_on)" in misfits[0].message
    assert "trolley_suitcase" in misfits[0].message


def test_cli_validate_exits_1_naming_both_objects(tmp_path, capsys):
    from usdscene.cli import main

    path = _write(tmp_path, _document("trolley_suitcase", "coffee_cup"))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert "objects.56" in err and "does not fit object '55'" in err


@pytest.mark.usd
def test_validate_accepts_what_fits_and_compose_agrees(tmp_path):
    from usdscene.scene.compose import compose_stage
    from usdscene.validation import validate_document

    path = _write(tmp_path, _document("phone", "trolley_suitcase"))
    checked = validate_document(path)
    result = compose_stage(checked.scene, checked.catalog, tmp_path / "stage")
    assert "56" in result.placements


def test_compose_refuses_the_misfit_with_the_same_problem(tmp_path):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.errors import CompositionError
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.placement import place_objects

    scene = read_openlabel(_document("trolley_suitcase", "coffee_cup"))
    with pytest.raises(CompositionError) as error:
        place_objects(scene, load_catalog(), np.random.default_rng(0))
    assert [p.where for p in error.value.problems if "does not fit" in p.message] == ["objects.56"]
