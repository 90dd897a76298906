"""Two forms that other people's files use, read exactly and written schema-valid:

* VCD 4.3 ``poly2d`` values as a list of ``[x, y]`` pairs (OpenLABEL wants a flat list);
* OpenLABEL ``intrinsics_fisheye`` of a polynomial lens without ``focal_length_x``/``_y``: the
  coefficients are in pixels, ``r_px = c1·θ + c2·θ² + ...``.

Both start from files by others in the shared OpenLABEL folder (never copied here) and are
checked against the official schema there and the one ``uai-openlabel`` ships."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from usdscene.converters.openlabel import load_document, read_openlabel, schema_problems, write_openlabel
from usdscene.labels.projection import project_camera_points


@pytest.fixture(scope="module")
def schemas(openlabel_conformance, openlabel_schema_path):
    shared = openlabel_conformance.parent / "schema" / "openlabel_json_schema-v1.0.0.json"
    assert shared.is_file(), shared
    return [shared, openlabel_schema_path]


def _valid(document, schemas) -> list:
    serialized = json.loads(json.dumps(document, allow_nan=False))
    return [p for schema in schemas for p in schema_problems(serialized, schema)]


def _vcd43_with_pairs(conformance) -> dict:
    """A VCD 4.3 document: the cameras and objects of a file by others, one object carrying a
    ``poly2d`` of pairs statically and one per frame."""
    body = copy.deepcopy(load_document(conformance / "openlabel100_test_create_streams_simple.json")["openlabel"])
    body["metadata"] = {"schema_version": "4.3.1"}
    for cs in body.get("coordinate_systems", {}).values():  # VCD 4.3 poses are bare 4x4 lists
        if isinstance(cs.get("pose_wrt_parent"), dict) and "matrix4x4" in cs["pose_wrt_parent"]:
            cs["pose_wrt_parent"] = cs["pose_wrt_parent"]["matrix4x4"]
    square = [[10, 12], [40.5, 12], [40.5, 30], [10, 30]]
    body.setdefault("objects", {})["77"] = {
        "name": "sign", "type": "sign", "frame_intervals": [{"frame_start": 0, "frame_end": 0}],
        "object_data": {"poly2d": [{"name": "outline", "val": square, "mode": "MODE_POLY2D_ABSOLUTE",
                                    "closed": True}]}}
    frames = body.setdefault("frames", {})
    frame = frames.setdefault("0", {})
    frame.setdefault("objects", {})["77"] = {"object_data": {"poly2d": [
        {"name": "outline_f", "val": [[1, 2], [3, 4], [5, 6]], "mode": "MODE_POLY2D_ABSOLUTE", "closed": False}]}}
    return {"vcd": body}


def test_vcd43_poly2d_pairs_are_flattened_and_written_schema_valid(openlabel_conformance, schemas, tmp_path):
    from usdscene.cli import main

    vcd = _vcd43_with_pairs(openlabel_conformance)
    path = tmp_path / "vcd43.json"
    path.write_text(json.dumps(vcd), encoding="utf-8")
    as_openlabel = {"openlabel": copy.deepcopy(vcd["vcd"])}
    as_openlabel["openlabel"]["metadata"]["schema_version"] = "1.0.0"
    assert _valid(as_openlabel, schemas[:1])  # pairs as they are: the schema refuses them
    out = tmp_path / "converted.json"
    assert main(["convert", str(path), "-o", str(out), "--no-catalog"]) == 0
    written = json.loads(out.read_text(encoding="utf-8"))
    assert _valid(written, schemas) == []
    static = written["openlabel"]["objects"]["77"]["object_data"]["poly2d"][0]
    assert static["val"] == [10, 12, 40.5, 12, 40.5, 30, 10, 30]
    per_frame = written["openlabel"]["frames"]["0"]["objects"]["77"]["object_data"]["poly2d"][0]
    assert per_frame["val"] == [1, 2, 3, 4, 5, 6]
    assert read_openlabel(out).objects == read_openlabel(path).objects


def _pixel_polynomial_document(conformance) -> tuple[dict, list[float]]:
    """The fisheye camera of a file by others, as a radial polynomial in pixels without focal
    lengths; returns the document and its coefficients."""
    document = copy.deepcopy(load_document(conformance / "openlabel100_test_intrinsics.json"))
    streams = document["openlabel"]["streams"]
    fisheye = streams["CAM_FISHEYE"]["stream_properties"]["intrinsics_fisheye"]
    coeffs = list(fisheye["lens_coeffs_1xN"])  # 333.4 px per rad, then higher powers
    for key in ("focal_length_x", "focal_length_y", "aspect_ratio"):
        fisheye.pop(key, None)
    fisheye.update(model="radial_poly", center_x=639.5, center_y=539.5)
    return document, coeffs


def test_fisheye_polynomial_in_pixels_reads_exactly_and_round_trips(openlabel_conformance, schemas):
    document, coeffs = _pixel_polynomial_document(openlabel_conformance)
    assert _valid(document, schemas) == []
    scene = read_openlabel(document)
    camera = next(c for c in scene.cameras if c.name == "CAM_FISHEYE")
    theta = np.linspace(0.0, 0.5, 11)
    phi = 0.7
    rays = np.stack([np.sin(theta) * math.cos(phi), np.sin(theta) * math.sin(phi), np.cos(theta)], axis=1)
    uv, ok = project_camera_points(camera.intrinsics, rays)
    r_px = sum(c * theta ** (k + 1) for k, c in enumerate(coeffs))
    expected = np.stack([639.5 + r_px * math.cos(phi), 539.5 + r_px * math.sin(phi)], axis=1)
    assert ok.all() and np.abs(uv - expected).max() <= 1e-9 * max(1.0, float(r_px.max()))
    written = write_openlabel(scene)
    assert _valid(written, schemas) == []
    again = next(c for c in read_openlabel(written).cameras if c.name == "CAM_FISHEYE")
    uv2, ok2 = project_camera_points(again.intrinsics, rays)
    assert ok2.all() and np.abs(uv2 - uv).max() <= 1e-9


def test_opencv_fisheye_still_needs_its_focal_lengths(openlabel_conformance):
    from usdscene.errors import DocumentError

    document = copy.deepcopy(load_document(openlabel_conformance / "openlabel100_test_intrinsics.json"))
    fisheye = document["openlabel"]["streams"]["CAM_FISHEYE"]["stream_properties"]["intrinsics_fisheye"]
    del fisheye["focal_length_x"]
    with pytest.raises(DocumentError) as error:
        read_openlabel(document)
    assert any("focal_length_x" in p.where for p in error.value.problems)


def test_a_polynomial_lens_with_one_focal_length_is_refused(openlabel_conformance):
    from usdscene.errors import DocumentError

    document, _ = _pixel_polynomial_document(openlabel_conformance)
    document["openlabel"]["streams"]["CAM_FISHEYE"]["stream_properties"]["intrinsics_fisheye"]["focal_length_x"] = 2.0
    with pytest.raises(DocumentError) as error:
        read_openlabel(document)
    assert any("focal_length_y" in p.where for p in error.value.problems)
