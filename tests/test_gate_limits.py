"""The gate agrees with the work, in linear time: what compose refuses, validate refuses first
with the same message; deep coordinate-system chains and frames outside the declared frame
range; the document size limit; the free-disk check before rendering."""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import pytest

from usdscene.errors import DocumentError, RenderError

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"

pytestmark = pytest.mark.usd


def _minimal() -> dict:
    return json.loads(MINIMAL.read_text(encoding="utf-8"))


def _write(tmp_path: Path, doc: dict, name: str = "doc.openlabel.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _messages(exc) -> list[str]:
    return [p.message for p in exc.problems]


def test_deep_coordinate_chain_is_read_and_a_loop_in_it_is_named(tmp_path):
    from usdscene.validation import validate_document

    doc = _minimal()
    systems = doc["openlabel"]["coordinate_systems"]
    parent = next(name for name, cs in systems.items() if not cs.get("parent"))
    identity = {"matrix4x4": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}
    for i in range(20_000):  # walked once each, not once per system (was 27 s)
        systems[f"chain_{i:05d}"] = {"type": "local_cs", "parent": parent, "pose_wrt_parent": identity}
        parent = f"chain_{i:05d}"
    checked = validate_document(_write(tmp_path, doc))
    assert len(checked.scene.cameras) == 2

    looped = copy.deepcopy(doc)
    looped["openlabel"]["coordinate_systems"]["chain_00000"]["parent"] = "chain_19999"
    with pytest.raises(DocumentError) as info:
        validate_document(_write(tmp_path, looped, "loop.json"))
    loops = [p for p in info.value.problems if "loops through" in p.message]
    assert len(loops) == 1 and loops[0].where.endswith("coordinate_systems.chain_00000.parent")


def test_frames_outside_the_root_frame_intervals_are_refused(tmp_path):
    from usdscene.validation import validate_document

    doc = _minimal()
    last = max(iv["frame_end"] for iv in doc["openlabel"]["frame_intervals"])
    for f in range(last + 1, last + 5001):
        doc["openlabel"]["frames"][str(f)] = {"frame_properties": {"timestamp": f / 30}}
    with pytest.raises(DocumentError) as info:
        validate_document(_write(tmp_path, doc))
    (problem,) = [p for p in info.value.problems if p.where == "openlabel.frames"]
    assert "5000 frame(s) lie outside the root frame_intervals" in problem.message
    assert f"first {last + 1}, last {last + 5000}" in problem.message


def test_a_document_over_the_size_limit_is_refused_naming_the_limit(tmp_path, monkeypatch):
    from usdscene.converters.openlabel import load
    from usdscene.validation import validate_document

    path = _write(tmp_path, _minimal())
    monkeypatch.setattr(load, "MAX_DOCUMENT_BYTES", path.stat().st_size - 1)
    with pytest.raises(DocumentError) as info:
        validate_document(path)
    assert f"over the {path.stat().st_size - 1:,} bytes (MAX_DOCUMENT_BYTES)" in str(info.value)


def _walker_document() -> tuple[dict, str]:
    """The car park's moving example cut to its first walker: a per-frame walk pose to break."""
    doc = json.loads((REPO / "examples" / "car_park" / "moving.openlabel.json").read_text(encoding="utf-8"))
    return doc, "walk_pose_variant"


def test_an_unknown_per_frame_pose_is_refused_by_validate_with_composes_message(tmp_path):
    from usdscene.validation import validate_document

    doc, key = _walker_document()
    frames = doc["openlabel"]["frames"]
    frame, uid = next((f, uid) for f, body in frames.items() for uid, o in body.get("objects", {}).items()
                      if any(t.get("name") == key for t in o.get("object_data", {}).get("text", [])))
    items = frames[frame]["objects"][uid]["object_data"]["text"]
    next(t for t in items if t["name"] == key)["val"] = "no_such_pose"
    path = _write(tmp_path, doc)
    shutil.copytree(REPO / "examples" / "car_park" / "assets", tmp_path / "assets")
    with pytest.raises(DocumentError) as gate:
        validate_document(path)
    wanted = [m for m in _messages(gate.value) if "'no_such_pose' is not a variant" in m]
    assert len(wanted) == 1 and f"object {uid!r}" in wanted[0]


def test_more_objects_than_mask_ids_are_refused_by_validate(tmp_path, monkeypatch):
    from usdscene.document import output_layout
    from usdscene.validation import validate_document

    doc = _minimal()
    # The limit is the uint16 mask's 65,535 ids; a document one object over a lowered limit
    # takes the same path without building 65,536 objects.
    monkeypatch.setattr(output_layout, "MAX_MASK_ID", 2)  # the minimal scene has 3 objects
    with pytest.raises(DocumentError) as info:
        validate_document(_write(tmp_path, doc))
    assert "3 objects present at frame 1 exceed the 2 ids of a uint16 mask" in " ".join(_messages(info.value))


def test_a_render_that_cannot_fit_on_the_disk_is_refused_before_it_starts(tmp_path):
    from usdscene.render.disk_space import check_free_space, estimated_output_bytes

    assert estimated_output_bytes([(640, 480)] * 10) == int(10 * (640 * 480 * 2.25 + 16_384))
    assert estimated_output_bytes([(640, 480)], keep_clean=True) > estimated_output_bytes([(640, 480)])
    check_free_space(tmp_path, [(64, 48)] * 4)  # a few tiny images fit
    free = shutil.disk_usage(tmp_path).free
    frames = free // (1920 * 1080 * 2) + 1  # more 1080p images than the disk holds
    with pytest.raises(RenderError) as info:
        check_free_space(tmp_path / "not" / "made", [(1920, 1080)] * int(frames))
    message = str(info.value)
    assert "the render needs about" in message and "is free on the disk of" in message
    assert not (tmp_path / "not").exists()
