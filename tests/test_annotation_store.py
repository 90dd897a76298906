"""The annotation store (usdscene.converters.openlabel.store): frame-range shards, the streamed
single document, bounded reading, resuming a killed ``annotate``, and exports that read the
store exactly as they read the single document."""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdscene.converters.openlabel import store as stores
from usdscene.errors import OutputError
from usdscene.converters.openlabel.write import document_text

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"
CAMERAS = ("pole_north", "entrance_wide")


# --------------------------------------------------------------------------------------------
# Synthetic stores (labels written without rendering)


def _frame(f: int, cameras: int, objects: int) -> dict:
    """One labelled frame: every object seen by every camera (a box, its amodal box, a polygon)."""
    streams = {f"cam{c}": {"uri": f"images/cam{c}/{f:06d}.png"} for c in range(cameras)}
    ours = {f"cam{c}": {"mask_uri": f"masks/cam{c}/{f:06d}.png", "width_px": 64, "height_px": 48}
            for c in range(cameras)}
    frame_objects = {}
    for o in range(objects):
        boxes, polygons = [], []
        for c in range(cameras):
            x = float((f * 7 + o * 3 + c) % 50)
            attributes = {"num": [{"name": "pixel_count", "val": 12 + o}, {"name": "mask_id", "val": o + 1}]}
            boxes.append({"name": f"cam{c}_bbox", "val": [x, 10.0, 4.0, 3.0], "coordinate_system": f"cam{c}",
                          "attributes": attributes})
            boxes.append({"name": f"cam{c}_amodal_bbox", "val": [x, 10.0, 5.0, 3.0], "coordinate_system": f"cam{c}",
                          "attributes": attributes})
            polygons.append({"name": f"cam{c}_poly2d_0", "val": [x, 9.0, x + 1, 9.0, x + 1, 11.0],
                             "mode": "MODE_POLY2D_ABSOLUTE", "closed": True, "coordinate_system": f"cam{c}",
                             "hierarchy": [-1, -1, -1, -1],
                             "attributes": {"boolean": [{"name": "is_hole", "val": False}]}})
        frame_objects[str(o)] = {"object_data": {"bbox": boxes, "poly2d": polygons}}
    return {"objects": frame_objects, "frame_properties": {"streams": streams, "usdscene": {"streams": ours}}}


def _static(frames: int, cameras: int, objects: int) -> dict:
    intervals = [{"frame_start": 0, "frame_end": frames - 1}]
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "synthetic"},
        "streams": {f"cam{c}": {"type": "camera"} for c in range(cameras)},
        "objects": {str(o): {"name": f"walker_{o}", "type": "pedestrian", "frame_intervals": intervals}
                    for o in range(objects)},
        "frames": {},
        "frame_intervals": intervals}}


def _write_synthetic(folder: Path, frames: int, per_shard: int, cameras: int = 2, objects: int = 3,
                     schema=None) -> dict:
    """A store of ``frames`` synthetic frames; returns the whole document it stands for."""
    writer = stores.StoreWriter(folder, per_shard, schema=schema)
    document = _static(frames, cameras, objects)
    every = {}
    for first in range(0, frames, per_shard):
        last = first + per_shard - 1
        part = {str(f): _frame(f, cameras, objects) for f in range(first, min(last, frames - 1) + 1)}
        writer.write_shard(first, last, part)
        every.update(part)
    writer.finish(document)
    return {"openlabel": {**document["openlabel"], "frames": every}}


def test_the_streamed_document_is_the_whole_document_and_schema_valid(tmp_path, openlabel_schema_path):
    from usdscene.converters.openlabel import schema_problems

    whole = _write_synthetic(tmp_path / "store", frames=23, per_shard=5, schema=openlabel_schema_path)
    store = stores.AnnotationStore(tmp_path / "store")
    assert [(e["frame_start"], e["frame_end"], e["frames"]) for e in store.shards] == \
        [(0, 4, 5), (5, 9, 5), (10, 14, 5), (15, 19, 5), (20, 24, 3)]
    assert store.index["labels"] == 23 * 2 * 3 and store.index["images"] == 23 * 2
    written = store.write_document(tmp_path / "one.json")
    data = (tmp_path / "one.json").read_bytes()
    assert data == document_text(whole).encode("utf-8")
    assert written["bytes"] == len(data)
    assert schema_problems(json.loads(data), openlabel_schema_path) == []
    # each shard alone is an OpenLABEL fragment the official schema accepts
    for entry in store.shards:
        assert schema_problems(json.loads((store.folder / entry["file"]).read_bytes()), openlabel_schema_path) == []


def test_reading_a_long_store_holds_one_shard_of_frames(tmp_path):
    from usdscene.converters.openlabel.annotations import LabelIndex, image_records

    frames, per_shard = 3000, 40
    _write_synthetic(tmp_path / "store", frames=frames, per_shard=per_shard)
    store = stores.AnnotationStore(tmp_path / "store")
    document = store.document()
    records = image_records(document)
    assert len(records) == frames * 2
    index = LabelIndex(document)
    visible = sum(label["bbox"] is not None for r in records for label in index.labels(r["frame"], r["camera"]))
    assert visible == store.index["labels"] == frames * 2 * 3
    assert store.most_frames_held == per_shard  # one shard parsed at a time, never the run
    assert index.most_frames_held <= LabelIndex.MAX_FRAMES
    assert store.shards_read == 2 * (frames // per_shard)  # one pass for the records, one for the labels


def test_a_changed_shard_is_refused_naming_it(tmp_path):
    _write_synthetic(tmp_path / "store", frames=10, per_shard=5)
    shard = tmp_path / "store" / "frames" / "000005-000009.json"
    shard.write_bytes(shard.read_bytes().replace(b'cam0_bbox', b'cam9_bbox', 1))
    store = stores.AnnotationStore(tmp_path / "store")
    with pytest.raises(OutputError) as caught:
        list(store.frames())
    assert "sha256" in str(caught.value) and "000005-000009.json" in str(caught.value)


def test_files_the_index_does_not_name_are_never_read_and_are_removed(tmp_path):
    folder = tmp_path / "store"
    _write_synthetic(folder, frames=12, per_shard=4)
    stray = folder / "frames" / "000100-000103.json"  # a killed writer's shard of another labelling
    stray.write_text('{"openlabel": {"frames": {"100": {}}}}')
    assert "100" not in dict(stores.AnnotationStore(folder).frames())
    _write_synthetic(folder, frames=12, per_shard=6)  # rewritten with other shards: the old ones go
    assert sorted(p.name for p in (folder / "frames").iterdir()) == ["000000-000005.json", "000006-000011.json"]


def test_an_edited_single_document_wins_over_the_store(tmp_path):
    out = tmp_path / "out"
    _write_synthetic(stores.store_folder(out), frames=4, per_shard=2)
    store = stores.AnnotationStore(stores.store_folder(out))
    record = store.write_document(out / "annotations.openlabel.json")
    stores.record_single_document(store.folder, record)
    assert stores.annotations_source(out)[0] == "store"
    assert isinstance(stores.open_annotations(out)["openlabel"]["frames"], stores.StoredFrames)
    edited = json.loads((out / "annotations.openlabel.json").read_text())
    del edited["openlabel"]["frames"]["3"]
    (out / "annotations.openlabel.json").write_text(json.dumps(edited))
    assert stores.annotations_source(out)[0] == "document"
    assert sorted(stores.open_annotations(out)["openlabel"]["frames"]) == ["0", "1", "2"]


def test_no_annotations_is_one_error_naming_the_folder(tmp_path):
    with pytest.raises(OutputError) as caught:
        stores.open_annotations(tmp_path)
    assert "run `usdscene annotate OUT` first" in str(caught.value) and str(tmp_path) in str(caught.value)


# --------------------------------------------------------------------------------------------
# A rendered moving car park (real Cycles, 64x48, 1 sample)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 6-frame moving car park seen by two cameras, rendered and labelled by ``usdscene run``."""
    from usdscene.cli import main

    folder = tmp_path_factory.mktemp("store_car_park")
    for name in ("assets", "source"):
        shutil.copytree(CAR_PARK / name, folder / name)
    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    for stream in setup["openlabel"]["streams"].values():
        stream["stream_properties"]["usdscene"]["resolution_px"] = [64, 48]
    setup["openlabel"]["metadata"]["usdscene"]["render"].update(samples=1, denoise=False, max_bounces=1)
    (folder / "setup.json").write_text(json.dumps(setup))
    doc, out = folder / "doc.json", folder / "out"
    assert main(["generate", "tracks", "--setup", str(folder / "setup.json"), "-o", str(doc), "--frames", "6",
                 "--fps", "5", "--people", "3", "--standing", "0", "--vehicles", "1", "--seed", "2"]) == 0
    assert main(["run", str(doc), "-o", str(out), "--cameras", *CAMERAS, "--no-progress"]) == 0
    return out


@pytest.mark.blender
def test_store_in_shards_reads_as_one_labelling_of_the_whole_run(run, tmp_path, openlabel_schema_path):
    from usdscene.cli import main
    from usdscene.converters.openlabel import schema_problems
    from usdscene.dataset.annotation import annotate_output, write_annotations

    whole, _ = annotate_output(run)  # every label of the run in memory at once, as before the store
    expected = document_text(whole).encode("utf-8")
    _, summary = write_annotations(run, frames_per_shard=2)
    store = stores.AnnotationStore(stores.store_folder(run))
    assert [e["file"] for e in store.shards] == ["frames/000000-000001.json", "frames/000002-000003.json",
                                                 "frames/000004-000005.json"]
    assert summary.single_document == run / "annotations.openlabel.json"
    assert (run / "annotations.openlabel.json").read_bytes() == expected
    assert main(["export-openlabel", str(run), "-o", str(tmp_path / "one.json")]) == 0
    assert (tmp_path / "one.json").read_bytes() == expected
    assert schema_problems(json.loads(expected), openlabel_schema_path) == []
    assert len(summary) == 12 and sum(1 for _ in summary) == 12


def _tree_bytes(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.blender
def test_exports_and_stats_read_the_store_as_they_read_the_single_document(run, capsys):
    from usdscene.cli import main
    from usdscene.dataset.annotation import write_annotations

    write_annotations(run, frames_per_shard=2)
    formats = ["coco", "yolo", "mot", "multiview"]
    # beside the run: its stage names the assets by relative paths
    from_single = run.parent / "single"
    shutil.copytree(run, from_single, ignore=shutil.ignore_patterns("annotations", "exports", "report"))
    from_store = run.parent / "store"
    shutil.copytree(run, from_store, ignore=shutil.ignore_patterns("annotations.openlabel.json", "exports", "report"))
    printed = []
    for out in (from_single, from_store):
        assert main(["export", *formats, str(out)]) == 0
        capsys.readouterr()
        assert main(["stats", str(out), "--chart", str(out / "stats.png")]) == 0
        printed.append(capsys.readouterr().out.replace(str(out), "OUT"))
    assert printed[0] == printed[1] and "pedestrian" in printed[0]
    assert stores.annotations_source(from_store)[0] == "store"
    left, right = _tree_bytes(from_single / "exports"), _tree_bytes(from_store / "exports")
    assert sorted(left) == sorted(right) and len(left) > 20
    assert [name for name in left if left[name] != right[name]] == []
    assert filecmp.cmp(from_single / "stats.png", from_store / "stats.png", shallow=False)


@pytest.mark.blender
def test_annotate_killed_mid_way_resumes_to_identical_bytes(run):
    from usdscene.dataset.annotation import write_annotations

    write_annotations(run, frames_per_shard=1)
    reference = _tree_bytes(stores.store_folder(run))
    reference_single = (run / "annotations.openlabel.json").read_bytes()
    killed = run.parent / "killed"  # beside the run: its stage names the assets by relative paths
    shutil.copytree(run, killed, ignore=shutil.ignore_patterns("annotations*", "labels", "exports", "report"))
    command = [sys.executable, "-m", "usdscene", "annotate", str(killed), "--frames-per-shard", "1", "--no-progress"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first_shard = stores.store_folder(killed) / "frames" / "000000-000000.json"
    while not first_shard.exists() and process.poll() is None:
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    assert process.returncode == -signal.SIGKILL  # killed, not finished
    assert first_shard.exists() and not (stores.store_folder(killed) / "index.json").exists()
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert _tree_bytes(stores.store_folder(killed)) == reference
    assert (killed / "annotations.openlabel.json").read_bytes() == reference_single
