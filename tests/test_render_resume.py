"""Resume: kill a render mid-way, re-run, only the missing pairs are rendered and the masks are
byte-identical to an uninterrupted run. Also per-frame presence and motion in the masks."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

FRAMES = range(0, 16)
SETTINGS = {"samples": 4, "denoise": True}


def _scene():
    from usdscene.render.synthetic import BoxSpec, PointLightSpec, SphereSpec, SyntheticScene

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x
    intr = Intrinsics(LensModel.PERSPECTIVE, 96, 72, 70.0, 70.0, 47.5, 35.5)
    cams = (Camera("front", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),
            Camera("moving", intr, Pose.from_rotation_translation(r, [-4.0, 0.5, 1.0]),
                   frame_poses=tuple((f, Pose.from_rotation_translation(r, [-4.0, 0.5 - 0.05 * f, 1.0]))
                                     for f in FRAMES)))
    spheres = (
        SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1),
        SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2, frames=tuple(range(3, 11))),
        SphereSpec("c", (0.0, -1.0, 1.0), 0.3, (0.1, 0.2, 0.9), 3,
                   frame_centres=tuple((f, (0.0, -1.2 + 0.1 * f, 0.6)) for f in FRAMES)),
    )
    return SyntheticScene(cameras=cams, spheres=spheres, frame_start=FRAMES[0], frame_end=FRAMES[-1],
                          boxes=(BoxSpec("room", (0.0, 0.0, 1.5), (12.0, 8.0, 3.0), (0.6, 0.6, 0.6), inward=True),),
                          lights=(PointLightSpec("lamp", (-2.0, 0.0, 2.5), 200.0),))


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from usdscene.render.synthetic import write_synthetic_stage

    return write_synthetic_stage(_scene(), tmp_path_factory.mktemp("resume") / "stage")


@pytest.fixture(scope="module")
def reference(stage, tmp_path_factory):
    from usdscene.render.driver import render

    out = tmp_path_factory.mktemp("reference")
    report = render(stage, out, settings_override=SETTINGS, progress=False)
    assert report.pairs_rendered == 2 * len(FRAMES)
    return out


def test_presence_and_motion_reach_the_masks(reference):
    ids = {f: np.unique(cv2.imread(str(layout.mask_path(reference, "front", f)), cv2.IMREAD_UNCHANGED))
           for f in FRAMES}
    for f in FRAMES:
        assert (2 in ids[f]) == (3 <= f <= 10), f"frame {f}: ids {ids[f]}"
        assert 1 in ids[f] and 3 in ids[f]
    xs = []
    for f in (0, 15):  # sphere c moves along +y: to the left in the image
        mask = cv2.imread(str(layout.mask_path(reference, "front", f)), cv2.IMREAD_UNCHANGED)
        xs.append(np.nonzero(mask == 3)[1].mean())
    assert xs[1] < xs[0] - 10
    # The moving camera slides along -y (its image's right): sphere a drifts left in its image.
    m0 = cv2.imread(str(layout.mask_path(reference, "moving", 0)), cv2.IMREAD_UNCHANGED)
    m15 = cv2.imread(str(layout.mask_path(reference, "moving", 15)), cv2.IMREAD_UNCHANGED)
    assert np.nonzero(m15 == 1)[1].mean() < np.nonzero(m0 == 1)[1].mean() - 5
    id_map = json.loads((reference / layout.ID_MAP_FILE).read_text())
    assert {k: v["uid"] for k, v in id_map.items()} == {"1": "a", "2": "b", "3": "c"}


def test_kill_mid_way_then_resume(stage, reference, tmp_path):
    from usdscene.render.driver import render

    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "usdscene.cli", "render", str(stage), "-o", str(out),
                             "--samples", str(SETTINGS["samples"]), "--no-progress"],
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    manifest_path = out / layout.MANIFEST_FILE
    done_before = 0
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                done_before = sum(len(v) for v in json.loads(manifest_path.read_text())["done"].values())
            except (FileNotFoundError, json.JSONDecodeError, KeyError):
                done_before = 0
            if done_before >= 3:
                break
            time.sleep(0.01)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and its worker, mid-way
        proc.wait()
    done_before = sum(len(v) for v in json.loads(manifest_path.read_text())["done"].values())
    total = 2 * len(FRAMES)
    assert 3 <= done_before < total, "the render was not interrupted mid-way"

    events = []
    report = render(stage, out, settings_override=SETTINGS, progress=False, on_event=events.append)
    rendered = {(e["frame"], e["camera"]) for e in events if e.get("event") == "done"}
    assert report.pairs_skipped == done_before
    assert report.pairs_rendered == total - done_before == len(rendered)
    for camera in ("front", "moving"):
        for f in FRAMES:
            a = layout.mask_path(out, camera, f).read_bytes()
            b = layout.mask_path(reference, camera, f).read_bytes()
            assert a == b, f"mask {camera}/{f} differs from the uninterrupted run"
    assert not list(out.rglob("*.tmp")), "a temporary file was left behind"

    again = render(stage, out, settings_override=SETTINGS, progress=False)
    assert again.pairs_rendered == 0 and again.pairs_skipped == total


def test_worker_recycling_gives_identical_masks(stage, reference, tmp_path, monkeypatch):
    """With a small per-process budget the run is split over several worker processes (each
    importing only its frames); the masks do not change."""
    from usdscene.render import driver, shards

    monkeypatch.setattr(shards, "MAX_RENDERS_PER_WORKER", 7)
    starts = []
    report = driver.render(stage, tmp_path, settings_override=SETTINGS, progress=False,
                           on_event=lambda e: starts.append(e) if e.get("event") == "imported" else None)
    assert report.pairs_rendered == 2 * len(FRAMES)
    assert len(starts) == 6  # 16 frames x 2 cameras, at most 7 renders per process: 3 frames each
    for camera in ("front", "moving"):
        for frame in FRAMES:
            got = layout.mask_path(tmp_path, camera, frame).read_bytes()
            assert got == layout.mask_path(reference, camera, frame).read_bytes(), (camera, frame)


def test_chunks_cut_at_frame_boundaries_and_respect_the_limit():
    from usdscene.render.shards import chunks as split_into_chunks

    pairs = [(f, c) for f in range(5) for c in ("a", "b", "c")]
    chunks = split_into_chunks(pairs, 7)
    assert [p for chunk in chunks for p in chunk] == pairs
    assert all(len(chunk) <= 7 for chunk in chunks)
    assert [sorted({f for f, _ in chunk}) for chunk in chunks] == [[0, 1], [2, 3], [4]]
    # A frame with more cameras than the limit is split inside the frame.
    wide = [(0, str(c)) for c in range(5)]
    assert split_into_chunks(wide, 2) == [wide[0:2], wide[2:4], wide[4:5]]
