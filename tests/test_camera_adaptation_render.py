"""Exposure that adapts over frames, through the real renderer (Blender Cycles, the minimal
example at 64x48, 4 samples, frames 0-5): the world's light steps up 8 times at frame 2, the
exposure follows it by ``exposure_speed`` per frame from pre-pass meter readings, and two
shardings of the same document (one shard; shards of two frames, whose workers pre-pass the
frames before their first) write the same bytes and the same exposures."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from usdscene.document import output_layout as layout
from usdscene.sensor import exposure

pytestmark = [pytest.mark.usd, pytest.mark.blender]

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"
FRAMES = range(0, 6)
SPEED = 0.8  # a window of 3 frames before each: (1 - 0.8)^3 < 1 % of a step is left
SENSOR = {"auto_exposure": True, "exposure_speed": SPEED, "target_grey": 0.18, "iso": 400}


def document() -> dict:
    doc = json.loads(MINIMAL.read_text())
    body = doc["openlabel"]
    meta = body["metadata"]["usdscene"]
    meta["frame_range"] = {"frame_start": FRAMES.start, "frame_end": FRAMES.stop - 1}
    meta.pop("exports", None)
    meta["asset_paths"] = [str((MINIMAL.parent / p).resolve()) for p in meta["asset_paths"]]
    # a grey sky that lights the room, 8 times brighter from frame 2 on
    meta["world"] = {"color_rgb": [0.5, 0.5, 0.5], "strength": 1.0,
                     "per_frame": {str(f): {"strength": 8.0} for f in FRAMES if f >= 2}}
    body["streams"]["cam_01"]["stream_properties"]["usdscene"]["sensor"] = SENSOR
    return doc


def run(tmp_path: Path, name: str, **options) -> Path:
    from usdscene.pipeline import RunOptions, run_pipeline

    path = tmp_path / f"{name}.openlabel.json"
    path.write_text(json.dumps(document()))
    out = tmp_path / name
    run_pipeline(path, out, RunOptions(cameras=["cam_01"], exports=[], report=False, **options), progress=False)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from usdscene.render import shards

    folder = tmp_path_factory.mktemp("adapting")
    one = run(folder, "one_shard")
    patch = pytest.MonkeyPatch()
    patch.setattr(shards, "MAX_RENDERS_PER_WORKER", 2)  # shards of frames 0-1, 2-3, 4-5
    try:
        split = run(folder, "three_shards")
    finally:
        patch.undo()
    return one, split


def records(out: Path) -> list[dict]:
    return [json.loads(layout.exposure_path(out, "cam_01", f).read_text()) for f in FRAMES]


def test_the_exposure_follows_a_step_of_light_at_its_speed(runs):
    one, _ = runs
    rows = records(one)
    warmup = exposure.warmup_frames(SPEED)
    assert warmup == 3
    # the step: the meter reads more light and the instant exposure falls by stops
    assert rows[2]["metered_luminance"] > 2.0 * rows[1]["metered_luminance"]
    assert rows[2]["target_ev"] < rows[1]["target_ev"] - 1.0
    assert rows[0]["exposure_ev"] == rows[0]["target_ev"]  # the sequence starts instant
    for f in FRAMES:  # each frame: the adaptation over its window's readings, as recorded
        window = exposure.meter_window(f, warmup, FRAMES.start)
        ev, target = exposure.sequence_ev([rows[g]["metered_luminance"] for g in window], 0.18, -10.0, 10.0, SPEED)
        assert (rows[f]["exposure_ev"], rows[f]["target_ev"]) == pytest.approx((ev, target), abs=2e-4)
    # within the stated speed: 80 % of the step at frame 2, 96 % at frame 3
    step = rows[2]["target_ev"] - rows[1]["exposure_ev"]
    assert rows[2]["exposure_ev"] - rows[1]["exposure_ev"] == pytest.approx(SPEED * step, abs=0.02 + 0.1 * abs(step))
    assert abs(rows[3]["exposure_ev"] - rows[3]["target_ev"]) < 0.25 * abs(step)
    # the annotations carry the same records
    document = json.loads((one / "annotations.openlabel.json").read_text())
    for f in FRAMES:
        streams = document["openlabel"]["frames"][str(f)]["frame_properties"]["usdscene"]["streams"]
        assert streams["cam_01"]["sensor"]["exposure"] == rows[f]


def test_two_shardings_write_the_same_bytes(runs):
    one, split = runs
    assert records(one) == records(split)
    for f in FRAMES:
        assert layout.image_path(one, "cam_01", f).read_bytes() == layout.image_path(split, "cam_01", f).read_bytes()
        assert layout.mask_path(one, "cam_01", f).read_bytes() == layout.mask_path(split, "cam_01", f).read_bytes()
