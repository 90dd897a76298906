"""Places declared in the document itself: a place object with one OpenLABEL ``cuboid`` per
relation (name = the relation) adds a place the environment asset lacks, so a user with a bare
mesh needs no round trip through a modelling tool."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.converters.openlabel import read_openlabel, schema_problems, write_openlabel

REPO = Path(__file__).resolve().parent.parent
MINIMAL = json.loads((REPO / "examples" / "minimal" / "scene.openlabel.json").read_text(encoding="utf-8"))
# a bench top of 0.6 x 0.4 m in the aisle at 0.4 m height, turned 90° about z, with 0.6 m of
# clearance above it (the cuboid's bottom face is the support, its height the clearance)
YAW = math.radians(90.0)
CUBOID = [2.5, 0.0, 0.7, 0.0, 0.0, math.sin(YAW / 2), math.cos(YAW / 2), 0.6, 0.4, 0.6]


def _document(cuboid=CUBOID) -> dict:
    document = copy.deepcopy(MINIMAL)
    body = document["openlabel"]
    body["objects"]["90"] = {"name": "bench_01", "type": "place",
                             "object_data": {"cuboid": [{"name": "is_on", "val": list(cuboid)}]}}
    body["objects"]["91"] = {"name": "bag_on_bench", "type": "backpack",
                             "frame_intervals": [{"frame_start": 0, "frame_end": 2}]}
    body["relations"]["90"] = {"name": "bag on bench", "type": "is_on",
                               "rdf_subjects": [{"uid": "91", "type": "object"}],
                               "rdf_objects": [{"uid": "90", "type": "object"}]}
    return document


def test_declared_place_reads_writes_back_and_passes_the_schema(openlabel_schema_path):
    scene = read_openlabel(_document())
    bench = next(p for p in scene.places if p.name == "bench_01")
    (region,) = bench.regions
    assert region.relation == "is_on" and region.size_m == pytest.approx((0.6, 0.4, 0.6))
    assert np.allclose(region.pose.as_array()[:3, 3], (2.5, 0.0, 0.4))  # the bottom-face centre
    written = write_openlabel(scene)
    assert schema_problems(written, openlabel_schema_path) == []
    assert read_openlabel(written).places == scene.places


@pytest.mark.usd
def test_objects_rest_on_a_declared_place_and_the_stage_reads_it_back(tmp_path):
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage
    from usdscene.converters.stage.usd_stage import scene_from_stage
    from usdscene.validation import validate_document

    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(_document()), encoding="utf-8")
    scene = validate_document(path).scene  # the shipped cabin has no bench_01: declared, so accepted
    result = compose_stage(scene, load_catalog(), tmp_path / "stage")
    placement = result.placements["91"]
    for frame in (0, 1, 2):
        m = placement.pose_at(frame).as_array()
        assert m[2, 3] == pytest.approx(0.4, abs=1e-6)  # resting on the bottom face
        assert abs(m[0, 3] - 2.5) <= 0.2 + 1e-6 and abs(m[1, 3]) <= 0.3 + 1e-6  # inside the turned footprint
    back = scene_from_stage(result.root_layer)
    assert next(p for p in back.places if p.name == "bench_01").regions == \
        next(p for p in scene.places if p.name == "bench_01").regions


@pytest.mark.parametrize("change, message", [
    (lambda c: c.__setitem__(7, 0.0), "sizes must be positive"),
    (lambda c: c.__setitem__(6, 3.0), "not of unit length"),
])
def test_bad_cuboids_are_named(change, message):
    from usdscene.errors import DocumentError

    cuboid = list(CUBOID)
    change(cuboid)
    with pytest.raises(DocumentError) as error:
        read_openlabel(_document(cuboid))
    assert "openlabel.objects.90.object_data.cuboid[0].val" in str(error.value)
    assert message in str(error.value)


def test_an_undeclared_unknown_place_is_still_refused(tmp_path):
    from usdscene.scene.catalog import load_catalog
    from usdscene.errors import DocumentError

    document = _document()
    del document["openlabel"]["objects"]["90"]["object_data"]
    with pytest.raises(DocumentError) as error:
        read_openlabel(document, catalog=load_catalog())
    assert "bench_01" in str(error.value) and "declare it with a cuboid" in str(error.value)


def test_other_data_of_a_place_is_carried_not_refused(openlabel_schema_path):
    """Someone's 3D box on a place (a cuboid not named by a relation) and other object data are
    not regions: they are carried through and written back."""
    document = _document()
    place = document["openlabel"]["objects"]["90"]
    place["object_data"]["cuboid"].append({"name": "annotated_box", "val": list(CUBOID)})
    place["object_data"]["text"] = [{"name": "description", "val": "bench by the gate"}]
    scene = read_openlabel(document)
    bench = next(p for p in scene.places if p.name == "bench_01")
    assert [r.relation for r in bench.regions] == ["is_on"]
    written = write_openlabel(scene)
    assert schema_problems(written, openlabel_schema_path) == []
    out = next(o for o in written["openlabel"]["objects"].values() if o["name"] == "bench_01")
    assert [c["name"] for c in out["object_data"]["cuboid"]] == ["is_on", "annotated_box"]
    assert out["object_data"]["text"] == [{"name": "description", "val": "bench by the gate"}]
    assert read_openlabel(written).places == scene.places
