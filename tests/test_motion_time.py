"""Time: ``metadata.usdscene.fps`` read, checked, written as frame timestamps and as the stage's
time-codes-per-second; a document without it keeps its bytes."""

from __future__ import annotations

import json

import pytest

from usdscene.converters.openlabel import read_openlabel, write_openlabel
from usdscene.errors import DocumentError
from usdscene.document.model import Pose, SceneObject, SceneSpec


def _scene(fps):
    walker = SceneObject(uid="0", name="walker", class_name="backpack",
                         frame_poses=tuple((f, Pose.from_rotation_translation(
                             [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.1 * f, 0.0, 0.0])) for f in range(4)))
    return SceneSpec(name="t", frame_start=0, frame_end=3, objects=(walker,), fps=fps)


def test_fps_is_written_as_timestamps_and_reads_back():
    doc = write_openlabel(_scene(12.5))
    body = doc["openlabel"]
    assert body["metadata"]["usdscene"]["fps"] == 12.5
    stamps = {int(k): f["frame_properties"]["timestamp"] for k, f in body["frames"].items()}
    assert stamps == {0: 0.0, 1: 0.08, 2: 0.16, 3: 0.24}
    back = read_openlabel(doc)
    assert back.fps == 12.5
    assert back.extra == ""  # derived timestamps are not carried
    assert write_openlabel(back) == doc


def test_no_fps_writes_no_timestamp():
    doc = write_openlabel(_scene(None))
    assert "fps" not in doc["openlabel"]["metadata"]["usdscene"]
    assert all("timestamp" not in f.get("frame_properties", {}) for f in doc["openlabel"]["frames"].values())
    assert read_openlabel(doc).fps is None


@pytest.mark.parametrize("bad", [0, -5, 1e6, "ten", True])
def test_bad_fps_is_one_error_naming_the_field(bad):
    doc = write_openlabel(_scene(10.0))
    doc["openlabel"]["metadata"]["usdscene"]["fps"] = bad
    with pytest.raises(DocumentError) as info:
        read_openlabel(json.loads(json.dumps(doc)))
    assert "metadata.usdscene.fps" in str(info.value)


@pytest.mark.usd
def test_stage_states_the_rate_only_when_the_document_does(tmp_path):
    from pxr import Sdf

    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage
    from usdscene.converters.stage.usd_stage import scene_from_stage

    catalog = load_catalog()
    with_rate = compose_stage(_scene(25.0), catalog, tmp_path / "a")
    layer = Sdf.Layer.FindOrOpen(str(with_rate.root_layer))
    assert layer.timeCodesPerSecond == 25.0 and layer.framesPerSecond == 25.0
    assert scene_from_stage(str(with_rate.root_layer)).fps == 25.0
    without = compose_stage(_scene(None), catalog, tmp_path / "b")
    assert "timeCodesPerSecond" not in without.root_layer.read_text()
    assert scene_from_stage(str(without.root_layer)).fps is None
    # Poses are time samples: one per frame for a moving object, read back at the document's
    # frames through the composed stage (every layer states the rate, or USD rescales the samples).
    objects = Sdf.Layer.FindOrOpen(str(with_rate.stage_dir / "objects.usda"))
    assert objects.timeCodesPerSecond == 25.0
    path = [p for p in objects.rootPrims[0].nameChildren[0].nameChildren][0].path
    samples = objects.ListTimeSamplesForPath(path.AppendProperty("xformOp:transform"))
    assert list(samples) == [0.0, 1.0, 2.0, 3.0]
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(with_rate.root_layer))
    xform = UsdGeom.Xformable(stage.GetPrimAtPath(path))
    for frame in range(4):
        assert xform.ComputeLocalToWorldTransform(frame).ExtractTranslation()[0] == pytest.approx(0.1 * frame)


def test_staged_folder_appears_whole_or_not_at_all(tmp_path):
    from usdscene.files import staged_folder

    target = tmp_path / "exports" / "mot"
    with staged_folder(target) as staging:
        (staging / "a.txt").write_text("one")
    assert (target / "a.txt").read_text() == "one"
    with pytest.raises(RuntimeError):
        with staged_folder(target) as staging:
            (staging / "a.txt").write_text("two")
            raise RuntimeError("interrupted")
    assert (target / "a.txt").read_text() == "one"  # the old folder, untouched
    with staged_folder(target) as staging:
        (staging / "b.txt").write_text("three")
    assert sorted(p.name for p in target.iterdir()) == ["b.txt"]
    assert sorted(p.name for p in target.parent.iterdir()) == ["mot"]  # no staging or old folders left
