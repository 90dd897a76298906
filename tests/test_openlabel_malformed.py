"""Malformed scene documents: ``usdscene validate`` exits 1, names the JSON path of every
problem, and never prints a traceback."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path

import pytest

from usdscene.cli import main

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "minimal" / "scene.openlabel.json"
BASE = json.loads(EXAMPLE.read_text(encoding="utf-8"))


@pytest.fixture(autouse=True)
def _no_schema_env(monkeypatch):
    monkeypatch.delenv("USDSCENE_OPENLABEL_SCHEMA", raising=False)


def edit(change):
    """A copy of the minimal example changed by ``change(body)``."""
    doc = copy.deepcopy(BASE)
    change(doc["openlabel"])
    return doc


def _set(path: str, value):
    """``change`` that sets a dotted path (list indices as ints) to ``value``."""
    def change(body):
        keys = path.split("/")
        node = body
        for key in keys[:-1]:
            node = node[int(key)] if isinstance(node, list) else node[key]
        last = keys[-1]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return change


def _delete(path: str):
    def change(body):
        keys = path.split("/")
        node = body
        for key in keys[:-1]:
            node = node[int(key)] if isinstance(node, list) else node[key]
        del node[keys[-1]]
    return change


def _cam01(**friendly):
    def change(body):
        block = body["streams"]["cam_01"]["stream_properties"]["usdscene"]
        for key, value in friendly.items():
            if value is None:
                block.pop(key, None)
            else:
                block[key] = value
    return change


def _fisheye(**values):
    def change(body):
        body["streams"]["cam_02"]["stream_properties"]["intrinsics_fisheye"].update(values)
    return change


def _pose02(pose):
    return _set("coordinate_systems/cam_02/pose_wrt_parent", pose)


def _transform_to_second_root(body):
    """A per-frame transform from cam_02 to a coordinate system of another tree."""
    body["coordinate_systems"]["island"] = {"type": "scene_cs", "parent": ""}
    body["frames"]["1"]["frame_properties"] = {"transforms": {"t": {
        "src": "cam_02", "dst": "island",
        "transform_src_to_dst": {"matrix4x4": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}}}}


def _text(text: str):
    return text


def _nan_text():
    return EXAMPLE.read_text(encoding="utf-8").replace('"val": 60.0', '"val": NaN', 1)


def _inf_text():
    return EXAMPLE.read_text(encoding="utf-8").replace('"position_m": [3.0, 0.0, 1.95]',
                                                       '"position_m": [1e999, 0.0, 1.95]', 1)


def _add(section: str, key: str, value):
    def change(body):
        body.setdefault(section, {})[key] = value
    return change


def _many(*changes):
    def change(body):
        for c in changes:
            c(body)
    return change


PINHOLE = {"width_px": 64, "height_px": 48,
           "camera_matrix": [30.0, 0.0, 31.5, 0.0, 0.0, 30.0, 23.5, 0.0, 0.0, 0.0, 1.0, 0.0],
           "distortion_coeffs": [0.0, 0.0, 0.0, 0.0, 0.0]}

# (id, document text or change, text that must appear in stderr: the JSON path and a hint)
CASES = [
    ("bad_json", _text('{"openlabel": {"metadata": }'), ["line 1, column 28", "invalid JSON"]),
    ("root_is_list", _text("[1, 2, 3]"), ["root must be a JSON object"]),
    ("root_key_unknown", _text('{"scene": {}}'), ["'openlabel'", "'vcd'"]),
    ("nan_in_text", _nan_text(), ["openlabel.objects.0.object_data.num[0].val", "non-finite"]),
    ("infinity_in_text", _inf_text(), ["openlabel.streams.cam_01.stream_properties.usdscene.position_m[0]"]),
    ("schema_version", _set("metadata/schema_version", "0.9"), ["openlabel.metadata.schema_version"]),
    ("metadata_typo", _set("metadata/usdscene/sed", 3), ["openlabel.metadata.usdscene.sed", "did you mean 'seed'"]),
    ("render_unknown_key", _set("metadata/usdscene/render/sample", 4),
     ["openlabel.metadata.usdscene.render.sample", "did you mean 'samples'"]),
    ("render_samples_string", _set("metadata/usdscene/render/samples", "4"),
     ["openlabel.metadata.usdscene.render.samples", "expected an integer"]),
    ("render_engine", _set("metadata/usdscene/render/engine", "cycle"), ["openlabel.metadata.usdscene.render.engine"]),
    ("render_input_passes", _set("metadata/usdscene/render/denoising_input_passes", "rgb_normal"),
     ["openlabel.metadata.usdscene.render.denoising_input_passes", "'rgb_normal'", "rgb_albedo_normal"]),
    ("render_light_tree_string", _set("metadata/usdscene/render/light_tree", "off"),
     ["openlabel.metadata.usdscene.render.light_tree"]),
    ("render_clamp_negative", _set("metadata/usdscene/render/clamp_indirect", -1),
     ["openlabel.metadata.usdscene.render.clamp_indirect", "-1"]),
    ("render_fast_gi_method", _set("metadata/usdscene/render/fast_gi_method", "multiply"),
     ["openlabel.metadata.usdscene.render.fast_gi_method", "'multiply'", "replace, add"]),
    ("render_fast_gi_string", _set("metadata/usdscene/render/fast_gi", "yes"),
     ["openlabel.metadata.usdscene.render.fast_gi", "expected true or false"]),
    ("render_fast_gi_ao_bounces", _set("metadata/usdscene/render/fast_gi_ao_bounces", 1.5),
     ["openlabel.metadata.usdscene.render.fast_gi_ao_bounces", "expected an integer", "1.5"]),
    ("render_fast_gi_distance", _set("metadata/usdscene/render/fast_gi_distance_m", -2),
     ["openlabel.metadata.usdscene.render.fast_gi_distance_m", "-2"]),
    ("render_scrambling_distance", _set("metadata/usdscene/render/scrambling_distance", 1.5),
     ["openlabel.metadata.usdscene.render.scrambling_distance", "1.5", "[0, 1]"]),
    ("exports_unknown", _set("metadata/usdscene/exports", ["tfrecord"]), ["openlabel.metadata.usdscene.exports[0]"]),
    ("roi_ignore_not_list", _set("metadata/usdscene/roi_ignore", "passenger"),
     ["openlabel.metadata.usdscene.roi_ignore: expected a list of strings, got"]),
    ("roi_ignore_empty_name", _set("metadata/usdscene/roi_ignore", ["passenger", ""]),
     ["openlabel.metadata.usdscene.roi_ignore[1]"]),
    ("fov_inconsistent", _cam01(focal_length_mm=2.13, sensor_size_mm=[4.0, 3.0], fov_deg=118.0),
     ["openlabel.streams.cam_01.stream_properties.usdscene.fov_deg", "86.4°", "fisheye_equisolid lens gives 112.0°"]),
    ("lens_model_unknown", _cam01(model="fisheye"), ["openlabel.streams.cam_01.stream_properties.usdscene.model"]),
    ("resolution_negative", _cam01(resolution_px=[-64, 48]),
     ["openlabel.streams.cam_01.stream_properties.usdscene.resolution_px[0]"]),
    ("friendly_key_typo", _cam01(fov_degs=90.0), ["openlabel.streams.cam_01.stream_properties.usdscene.fov_degs",
                                                  "did you mean 'fov_deg'"]),
    ("distortion_on_perspective", _cam01(distortion=[0.1, 0.0, 0.0, 0.0]),
     ["openlabel.streams.cam_01.stream_properties.usdscene.distortion"]),
    ("target_equals_position", _cam01(target_m=[3.0, 0.0, 1.95]),
     ["openlabel.streams.cam_01.stream_properties.usdscene.target_m"]),
    ("camera_matrix_3x3", _set("streams/cam_01/stream_properties",
                               {"intrinsics_pinhole": {**PINHOLE, "camera_matrix": [30.0, 0, 31.5, 0, 30.0, 23.5, 0, 0, 1]},
                                "usdscene": {"position_m": [0, 0, 1], "target_m": [1, 0, 1]}}),
     ["openlabel.streams.cam_01.stream_properties.intrinsics_pinhole.camera_matrix", "3x3"]),
    ("focal_negative", _set("streams/cam_01/stream_properties",
                            {"intrinsics_pinhole": {**PINHOLE, "camera_matrix": [-30.0, 0.0, 31.5, 0.0, 0.0, 30.0, 23.5, 0.0,
                                                                                 0.0, 0.0, 1.0, 0.0]},
                             "usdscene": {"position_m": [0, 0, 1], "target_m": [1, 0, 1]}}),
     ["openlabel.streams.cam_01.stream_properties.intrinsics_pinhole.camera_matrix[0]", "positive"]),
    ("distortion_length", _set("streams/cam_01/stream_properties",
                               {"intrinsics_pinhole": {**PINHOLE, "distortion_coeffs": [0.1, 0.2, 0.3]},
                                "usdscene": {"position_m": [0, 0, 1], "target_m": [1, 0, 1]}}),
     ["openlabel.streams.cam_01.stream_properties.intrinsics_pinhole.distortion_coeffs"]),
    ("friendly_optics_with_calibration", _set("streams/cam_02/stream_properties/usdscene/resolution_px", [64, 48]),
     ["openlabel.streams.cam_02.stream_properties.usdscene.resolution_px", "cannot be combined"]),
    ("width_not_integer", _fisheye(width_px=64.5),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.width_px"]),
    ("lens_coeffs_count", _fisheye(lens_coeffs=[0.1, 0.2, 0.3]),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.lens_coeffs"]),
    ("both_dialects", _fisheye(center_x=31.5),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.center_x_px", "not both"]),
    ("radial_poly_flat_at_the_axis", _fisheye(model="radial_poly", lens_coeffs=[0.0, 1.0, 0.1, 0.0]),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.lens_coeffs[0]", "must be positive"]),
    ("kannala_negative_first", _fisheye(model="kannala", lens_coeffs=[-1.0, 0.0, 0.0, 0.0, 0.0]),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.lens_coeffs[0]", "-1.0"]),
    ("matrix_3x3_as_4x4", _pose02({"matrix4x4": [1, 0, 0, 0, 1, 0, 0, 0, 1]}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent.matrix4x4", "3x3"]),
    ("matrix_scaled", _pose02({"matrix4x4": [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent.matrix4x4", "not a rotation"]),
    ("matrix_last_row", _pose02({"matrix4x4": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent.matrix4x4", "last row"]),
    ("quaternion_zero", _pose02({"quaternion": [0, 0, 0, 0], "translation": [0, 0, 1]}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent.quaternion", "zero length"]),
    ("euler_sequence", _pose02({"euler_angles": [0, 0, 0], "translation": [0, 0, 1], "sequence": "ZZX"}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent.sequence"]),
    ("pose_two_forms", _pose02({"matrix4x4": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
                                "quaternion": [0, 0, 0, 1]}),
     ["openlabel.coordinate_systems.cam_02.pose_wrt_parent", "one pose form"]),
    ("parent_missing", _set("coordinate_systems/cam_02/parent", "vehicle"),
     ["openlabel.coordinate_systems.cam_02.parent", "'vehicle' does not exist"]),
    # validate is the gate: what Blender, USD and memory cannot take is refused here
    ("width_px_beyond_blender", _fisheye(width_px=2 ** 40),
     ["openlabel.streams.cam_02.stream_properties.intrinsics_fisheye.width_px", "above 65536"]),
    ("samples_beyond_cycles", _set("metadata/usdscene/render/samples", 10 ** 12),
     ["openlabel.metadata.usdscene.render.samples", "above 16777216"]),
    ("frame_end_beyond_blender", _set("metadata/usdscene/frame_range/frame_end", 10 ** 12),
     ["openlabel.metadata.usdscene.frame_range.frame_end", "above 1048574"]),
    ("frame_key_beyond_blender", _add("frames", "9" * 40, {}),
     ["openlabel.frames." + "9" * 40, "above 1048574"]),
    ("lone_surrogate_in_name", _set("metadata/name", "cabin \ud800"),
     ["openlabel.metadata.name", "lone UTF-16 surrogate"]),
    ("integer_of_5000_digits",
     _text(EXAMPLE.read_text(encoding="utf-8").replace('"seed": 7', '"seed": ' + "9" * 5000, 1)),
     ["4300 digits"]),
    ("integer_beyond_float", _set("objects/4/object_data/vec/0/val", [10 ** 400, 0, 0]),
     ["openlabel.objects.4.object_data.vec[0].val[0]", "finite number"]),
    ("transform_between_trees", _transform_to_second_root,
     ["openlabel.frames.1.frame_properties.transforms.t", "different trees"]),
    ("camera_without_cs", _add("streams", "cam_04", {"type": "camera", "stream_properties": {"intrinsics_pinhole": PINHOLE}}),
     ["openlabel.streams.cam_04", "no coordinate system"]),
    ("transform_unknown_cs", _set("frames/1/frame_properties",
                                  {"transforms": {"t": {"src": "cam_02", "dst": "odom",
                                                        "transform_src_to_dst": {"matrix4x4": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}}}}),
     ["openlabel.frames.1.frame_properties.transforms.t.dst"]),
    ("interval_reversed", _set("objects/3/frame_intervals", [{"frame_start": 2, "frame_end": 0}]),
     ["openlabel.objects.3.frame_intervals[0]", "after frame_end"]),
    ("interval_float", _set("objects/3/frame_intervals", [{"frame_start": 0.5, "frame_end": 2}]),
     ["openlabel.objects.3.frame_intervals[0].frame_start"]),
    ("root_interval_missing_end", _set("frame_intervals", [{"frame_start": 0}]),
     ["openlabel.frame_intervals[0].frame_end"]),
    ("relation_dangling", _set("relations/0/rdf_objects", [{"uid": "42", "type": "object"}]),
     ["openlabel.relations.0.rdf_objects[0].uid", "'42'"]),
    ("relation_subject_is_place", _set("relations/0/rdf_subjects", [{"uid": "2", "type": "object"}]),
     ["openlabel.relations.0.rdf_subjects[0].uid"]),
    ("relation_uid_not_integer", _many(_add("relations", "r1", {"name": "", "type": "is_on",
                                                                "rdf_subjects": [{"uid": "5", "type": "object"}],
                                                                "rdf_objects": [{"uid": "2", "type": "object"}]})),
     ["openlabel.relations.r1"]),
    ("light_kind", _set("objects/0/object_data/text/0/val", "laser"),
     ["openlabel.objects.0.object_data.text[0].val", "'laser'"]),
    ("light_data_typo", _set("objects/0/object_data/num/0/name", "powr_w"),
     ["openlabel.objects.0.object_data.num[0].name", "did you mean 'power_w'"]),
    ("light_without_pose", _set("objects/0/object_data/vec", [{"name": "color_rgb", "val": [1, 1, 1]}]),
     ["openlabel.objects.0.object_data", "needs a pose"]),
    ("colour_out_of_range", _set("objects/5/object_data/vec/2/val", [1.2, 0.3, 0.6]),
     ["openlabel.objects.5.object_data.vec[2].val", "[0, 1]"]),
    ("object_knob_typo", _set("objects/3/object_data/num/0/name", "position_noise"),
     ["openlabel.objects.3.object_data.num[0].name", "did you mean 'position_noise_m'"]),
    ("knob_wrong_kind", _set("objects/4/object_data/boolean/0", {"name": "random_color", "val": 1}),
     ["openlabel.objects.4.object_data.boolean[0].val"]),
    ("duplicate_data_name", _set("objects/3/object_data/num/1/name", "position_noise_m"),
     ["openlabel.objects.3.object_data.num[1].name", "duplicate"]),
    ("duplicate_place", _add("objects", "6", {"name": "seat_01A", "type": "place"}),
     ["openlabel.objects.6.name", "seat_01A"]),
    ("frame_key_not_number", _add("frames", "first", {}), ["openlabel.frames.first"]),
    ("frame_object_dangling", _set("frames/0/objects/99", {}), ["openlabel.frames.0.objects.99", "does not exist"]),
    ("frame_pose_not_rigid", _set("frames/2/objects/4/object_data/vec",
                                  [{"name": "pose_matrix4x4", "val": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]),
     ["openlabel.frames.2.objects.4.object_data.vec[0].val"]),
    ("object_type_missing", _delete("objects/5/type"), ["openlabel.objects.5.type"]),
    ("objects_not_object", _set("objects", []), ["openlabel.objects", "expected a JSON object"]),
    ("frame_relation_dangling", _set("frames/1/relations", {"7": {}}), ["openlabel.frames.1.relations.7"]),
    ("duplicate_uid_key", _text(EXAMPLE.read_text(encoding="utf-8").replace(
        '"2": {"name": "seat_01A", "type": "place"},',
        '"2": {"name": "seat_01A", "type": "place"}, "2": {"name": "seat_02A", "type": "place"},', 1)),
     ["openlabel.objects.2", "more than once"]),
]


def _write_case(tmp_path: Path, payload) -> Path:
    path = tmp_path / "doc.json"
    if isinstance(payload, str):
        path.write_text(payload, encoding="utf-8")
    else:
        path.write_text(json.dumps(edit(payload)), encoding="utf-8")
    return path


def test_enough_cases():
    assert len(CASES) >= 30


@pytest.mark.parametrize("payload, expected", [(p, e) for _, p, e in CASES], ids=[c[0] for c in CASES])
def test_malformed_document_exit_1_names_field(tmp_path, capsys, payload, expected):
    path = _write_case(tmp_path, payload)
    code = main(["validate", "--no-catalog", str(path)])
    captured = capsys.readouterr()
    assert code == 1, captured.out
    assert "Traceback" not in captured.err
    for text in expected:
        assert text in captured.err, captured.err
    assert all(line.startswith("usdscene: ") for line in captured.err.strip().splitlines())


def test_valid_example_exit_0(capsys):
    assert main(["validate", "--no-catalog", str(EXAMPLE)]) == 0
    assert "valid" in capsys.readouterr().out


def test_valid_example_with_official_schema(capsys, openlabel_schema_path):
    assert main(["validate", "--no-catalog", "--schema", str(openlabel_schema_path), str(EXAMPLE)]) == 0
    assert openlabel_schema_path.name in capsys.readouterr().out


def test_schema_problems_are_reported_with_paths(tmp_path, capsys, openlabel_schema_path):
    # The schema forbids unknown keys in an object; usdscene's own reader ignores them.
    path = _write_case(tmp_path, _set("objects/3/colour", "red"))
    assert main(["validate", "--no-catalog", "--schema", str(openlabel_schema_path), str(path)]) == 1
    assert "openlabel.objects.3: schema:" in capsys.readouterr().err


def test_official_schema_is_used_by_default(tmp_path, capsys):
    # The packaged copy of the official schema applies without --schema or the environment.
    path = _write_case(tmp_path, _set("objects/3/colour", "red"))
    assert main(["validate", "--no-catalog", str(path)]) == 1
    assert "openlabel.objects.3: schema:" in capsys.readouterr().err


# sha256 of ASAM's openlabel_json_schema-v1.0.0.json as published (the file is used unchanged).
OFFICIAL_SCHEMA_SHA256 = "0e03719cc6d7a245f589d59da9e65e0936bbcce3b848f9e8f7b2592e5013e9c2"


def test_packaged_schema_is_the_official_file(openlabel_schema_path):
    import hashlib

    assert hashlib.sha256(openlabel_schema_path.read_bytes()).hexdigest() == OFFICIAL_SCHEMA_SHA256


def test_schema_from_environment(tmp_path, capsys, monkeypatch, openlabel_schema_path):
    path = _write_case(tmp_path, _set("objects/3/colour", "red"))
    monkeypatch.setenv("USDSCENE_OPENLABEL_SCHEMA", str(openlabel_schema_path))
    assert main(["validate", "--no-catalog", str(path)]) == 1
    assert "schema:" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["validate"], ["validate", "--bogus", "x.json"], ["convert", "x.json"]])
def test_usage_errors_exit_2(argv, capsys):
    assert main(argv) == 2
    assert "usage:" in capsys.readouterr().err


def test_missing_file_exit_1(tmp_path, capsys):
    assert main(["validate", "--no-catalog", str(tmp_path / "nope.json")]) == 1
    err = capsys.readouterr().err
    assert "nope.json" in err and "Traceback" not in err


def test_all_problems_reported_at_once(tmp_path, capsys):
    path = _write_case(tmp_path, _many(_cam01(model="fisheye"), _set("objects/0/object_data/text/0/val", "laser"),
                                       _set("metadata/usdscene/sed", 1)))
    assert main(["validate", "--no-catalog", str(path)]) == 1
    err = capsys.readouterr().err
    assert "usdscene.model" in err and "objects.0.object_data.text[0].val" in err and "usdscene.sed" in err


def test_subprocess_validate_reports_without_traceback(tmp_path):
    path = _write_case(tmp_path, _pose02({"matrix4x4": [1, 0, 0, 0, 1, 0, 0, 0, 1]}))
    result = subprocess.run([sys.executable, "-m", "usdscene", "validate", "--no-catalog", str(path)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert "openlabel.coordinate_systems.cam_02.pose_wrt_parent.matrix4x4" in result.stderr
    assert "Traceback" not in result.stderr


def test_convert_writes_normalised_document(tmp_path, capsys, openlabel_schema_path):
    from usdscene.converters.openlabel import read_openlabel, schema_problems

    out = tmp_path / "out" / "scene.json"
    assert main(["convert", "--no-catalog", str(EXAMPLE), "-o", str(out)]) == 0
    document = json.loads(out.read_text(encoding="utf-8"))
    assert document["openlabel"]["metadata"]["schema_version"] == "1.0.0"
    assert schema_problems(document, openlabel_schema_path) == []
    assert read_openlabel(out).cameras == read_openlabel(EXAMPLE).cameras
    assert not [p for p in out.parent.iterdir() if p.name != out.name]  # no temp files left


def test_convert_refuses_invalid_input(tmp_path, capsys):
    path = _write_case(tmp_path, _cam01(model="fisheye"))
    out = tmp_path / "out.json"
    assert main(["convert", "--no-catalog", str(path), "-o", str(out)]) == 1
    assert not out.exists()
    assert "usdscene.model" in capsys.readouterr().err


def test_example_validates_against_the_shipped_catalog(capsys):
    assert main(["validate", str(EXAMPLE)]) == 0
    assert "asset catalog)" in capsys.readouterr().out


def test_relation_type_typos_against_the_shipped_catalog(tmp_path, capsys):
    """A misspelt placement relation would leave its object at the world origin; other
    vocabularies' relation types pass."""
    for typo, intended in (("IS_BELOW", "is_below"), ("is below", "is_below"), ("is_inside", "is_in")):
        path = _write_case(tmp_path, _set("relations/0/type", typo))
        assert main(["validate", str(path)]) == 1
        err = capsys.readouterr().err
        assert f"openlabel.relations.0.type: relation type {typo!r} is not a placement relation " \
               f"(did you mean {intended!r}?)" in err
    path = _write_case(tmp_path, _set("relations/0/type", "is_behind"))
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def test_unknown_class_against_the_shipped_catalog(tmp_path, capsys):
    path = _write_case(tmp_path, _many(_set("objects/5/type", "pasenger"), _set("objects/2/name", "seat_99Z")))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert "openlabel.objects.5.type: unknown object class 'pasenger' (did you mean 'passenger'?)" in err
    assert "openlabel.objects.2.name: place 'seat_99Z' is not in environment 'aircraft_cabin'" in err


def test_roi_ignore_against_the_shipped_catalog(tmp_path, capsys):
    """roi_ignore names object classes or catalog kinds: a typo and an environment are refused
    with the field and the value, and the shipped cabin example's ``passenger`` kind passes."""
    assert BASE["openlabel"]["metadata"]["usdscene"]["roi_ignore"] == ["passenger"]
    path = _write_case(tmp_path, _set("metadata/usdscene/roi_ignore", ["pasenger", "object", "aircraft_cabin"]))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert ("openlabel.metadata.usdscene.roi_ignore[0]: 'pasenger' is no object class or kind of the asset "
            "catalog (did you mean 'passenger'?); kinds: object, passenger; classes: backpack,") in err
    assert "openlabel.metadata.usdscene.roi_ignore[2]: 'aircraft_cabin' is no object class or kind" in err
    assert "roi_ignore[1]" not in err  # a kind
    path = _write_case(tmp_path, _set("metadata/usdscene/roi_ignore", ["handbag", "passenger"]))
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def _vcd(pose):
    return {"vcd": {"metadata": {"schema_version": "4.3.0"},
                    "coordinate_systems": {"odom": {"type": "scene_cs", "parent": "", "children": ["cam"]},
                                           "cam": {"type": "sensor_cs", "parent": "odom", "children": [],
                                                   "pose_wrt_parent": pose}},
                    "streams": {"cam": {"type": "camera", "uri": "", "stream_properties": {"intrinsics_pinhole": {
                        "width_px": 64, "height_px": 48,
                        "camera_matrix_3x4": [50, 0, 32, 0, 0, 50, 24, 0, 0, 0, 1, 0],
                        "distortion_coeffs_1xN": []}}}}}}


def test_vcd_convert_and_vcd_problem_paths(tmp_path, capsys, openlabel_schema_path):
    good = tmp_path / "good.vcd.json"
    good.write_text(json.dumps(_vcd([1, 0, 0, 1, 0, 1, 0, 2, 0, 0, 1, 3, 0, 0, 0, 1])))
    out = tmp_path / "good.openlabel.json"
    assert main(["convert", "--no-catalog", "--schema", str(openlabel_schema_path), str(good), "-o", str(out)]) == 0
    body = json.loads(out.read_text())["openlabel"]
    assert body["coordinate_systems"]["cam"]["pose_wrt_parent"]["matrix4x4"][3:12:4] == [1.0, 2.0, 3.0]
    bad = tmp_path / "bad.vcd.json"
    bad.write_text(json.dumps(_vcd([1, 0, 0, 0, 1, 0, 0, 0, 1])))
    assert main(["validate", "--no-catalog", str(bad)]) == 1
    assert "vcd.coordinate_systems.cam.pose_wrt_parent.matrix4x4: a 3x3 matrix" in capsys.readouterr().err


def test_fast_schema_screen_agrees_with_the_full_validator(openlabel_schema_path):
    """The compiled screen decides validity exactly as jsonschema does: it passes every
    document without violations and fails every document with one (the listing itself always
    comes from jsonschema)."""
    import fastjsonschema

    from usdscene.converters.openlabel.checks import _validator

    fast, full = _validator(str(openlabel_schema_path.resolve()))
    assert fast is not None
    documents = [edit(_set("objects/3/colour", "red")), edit(_set("metadata/schema_version", 1)),
                 edit(_set("frame_intervals/0/frame_start", "0")), edit(_set("objects/3/type", 7)),
                 edit(lambda body: None)]
    documents += [edit(change) for _, change, _ in CASES if getattr(change, "__name__", "") == "change"]
    verdicts = set()
    for document in documents:
        data = json.loads(json.dumps(document))
        try:
            fast(data)
            screened_valid = True
        except fastjsonschema.JsonSchemaValueException:
            screened_valid = False
        fully_valid = not any(True for _ in full.iter_errors(data))
        assert screened_valid == fully_valid, document
        verdicts.add(fully_valid)
    assert verdicts == {True, False}


def test_the_compiled_schema_check_is_cached_and_a_bad_cache_is_regenerated(openlabel_schema_path, tmp_path,
                                                                           monkeypatch):
    import fastjsonschema

    from usdscene.converters.openlabel.checks import _compiled_check

    monkeypatch.setenv("USDSCENE_CACHE_DIR", str(tmp_path / "cache"))
    schema_bytes = openlabel_schema_path.read_bytes()
    schema = json.loads(schema_bytes)
    bad = json.loads(json.dumps(edit(_set("metadata/schema_version", 1))))
    good = json.loads(json.dumps(edit(lambda body: None)))

    def verdicts(check) -> list[bool]:
        out = []
        for document in (good, bad):
            try:
                check(document)
                out.append(True)
            except fastjsonschema.JsonSchemaValueException:
                out.append(False)
        return out

    generated = _compiled_check(schema, schema_bytes)
    [cached] = (tmp_path / "cache").glob("openlabel-schema-check-*.marshal")
    assert verdicts(generated) == [True, False]
    assert verdicts(_compiled_check(schema, schema_bytes)) == [True, False]  # from the cache
    cached.write_bytes(b"not marshal data")
    assert verdicts(_compiled_check(schema, schema_bytes)) == [True, False]
    assert cached.read_bytes() != b"not marshal data"  # written anew
    # An unwritable cache folder costs nothing but the time.
    monkeypatch.setenv("USDSCENE_CACHE_DIR", str(cached / "not-a-folder"))
    assert verdicts(_compiled_check(schema, schema_bytes)) == [True, False]
