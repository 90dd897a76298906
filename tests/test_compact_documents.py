"""Documents that scale: ``write_document`` writes each frame of a document on one line (the
same JSON value, a third of the bytes of the indented text for a moving sequence), and a
document so written reads and composes exactly as the indented one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from usdscene.converters.openlabel import read_openlabel, write_openlabel
from usdscene.converters.openlabel.write import document_text, write_document
from usdscene.files import dumps_json
from usdscene.generate.motion import generate_tracks
from usdscene.generate.movers import TrackOptions
from usdscene.scene.catalog import load_catalog

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"


@pytest.fixture(scope="module")
def moving():
    setup = read_openlabel(CAR_PARK / "setup_moving.openlabel.json")
    catalog = load_catalog(setup.asset_paths, base_dir=CAR_PARK)
    result = generate_tracks(setup, catalog, TrackOptions(frames=40, fps=10, people=10, vehicles=2, seed=4))
    return write_openlabel(result.scene)


def test_one_line_per_frame_is_the_same_document_in_a_third_of_the_bytes(moving):
    text = document_text(moving)
    assert json.loads(text) == moving
    lines = text.splitlines()
    start = lines.index('    "frames": {')
    frame_lines = lines[start + 1:start + 1 + len(moving["openlabel"]["frames"])]
    assert [json.loads("{" + line.rstrip(",") + "}") for line in frame_lines] == \
        [{key: value} for key, value in moving["openlabel"]["frames"].items()]
    assert lines[start + 1 + len(frame_lines)] in ("    }", "    },")
    indented = dumps_json(moving)
    assert len(text) < 0.4 * len(indented)
    # The rest of the document stays as readable as before.
    assert text[:text.index('"frames"')] == indented[:indented.index('"frames"')]


def test_a_document_without_frames_is_written_indented():
    doc = {"openlabel": {"metadata": {"schema_version": "1.0.0"}, "objects": {}}}
    assert document_text(doc) == dumps_json(doc)
    doc["openlabel"]["frames"] = {}
    assert document_text(doc) == dumps_json(doc)


def test_frame_keys_and_text_are_escaped_as_json_writes_them():
    doc = {"openlabel": {"frames": {"0": {"frame_properties": {"note": "é \"q\" \n"}}}, "metadata": {}}}
    assert json.loads(document_text(doc)) == doc


@pytest.mark.usd
def test_the_one_line_document_composes_to_the_same_layers(moving, tmp_path):
    from usdscene.pipeline import compose_document
    from usdscene.document import stage_schema as ss

    stages = {}
    for name, text in (("one_line", document_text(moving)), ("indented", dumps_json(moving))):
        folder = tmp_path / name
        folder.mkdir()
        path = folder / "doc.openlabel.json"
        if name == "one_line":
            write_document(path, moving)
        else:
            path.write_text(text, encoding="utf-8")
        assert path.read_text(encoding="utf-8") == text
        (folder / "assets").symlink_to(CAR_PARK / "assets")  # the setup's asset_paths: ["assets"]
        _, result = compose_document(path, folder / "stage")
        stages[name] = result.stage_dir
    # Every layer but the root, which records the source file's digest.
    for layer in ss.SUBLAYERS:
        assert (stages["one_line"] / layer).read_bytes() == (stages["indented"] / layer).read_bytes(), layer


def test_the_annotation_store_streams_the_same_text(moving, tmp_path):
    from usdscene.converters.openlabel.store import AnnotationStore, StoreWriter

    frames = moving["openlabel"]["frames"]
    keys = list(frames)
    writer = StoreWriter(tmp_path / "store", frames_per_shard=16)
    for first in range(0, len(keys), 16):
        part = {k: frames[k] for k in keys[first:first + 16]}
        writer.write_shard(int(keys[first]), int(keys[first]) + 15, part)
    writer.finish(moving)
    target = tmp_path / "single.json"
    AnnotationStore(tmp_path / "store").write_document(target)
    assert target.read_text(encoding="utf-8") == document_text(moving)
