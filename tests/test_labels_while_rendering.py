"""`usdscene run` labels each image as soon as it is written, while the next ones render: the
labels are the ones `usdscene annotate` computes afterwards, an interrupted run keeps the
labels of its finished images, and the resumed run's annotations are byte-identical to an
uninterrupted run's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdscene.document import output_layout as layout
from usdscene.cli import main

pytestmark = [pytest.mark.usd, pytest.mark.blender]

REPO = Path(__file__).resolve().parent.parent
FRAMES = 8  # x 2 cameras of the minimal example


def _longer_minimal(folder: Path) -> Path:
    """The minimal example with its objects present over frames 0..FRAMES-1."""
    text = (REPO / "examples" / "minimal" / "scene.openlabel.json").read_text(encoding="utf-8")
    document = json.loads(text)

    def stretch(node):
        if isinstance(node, dict):
            if node.get("frame_end") == 2:
                node["frame_end"] = FRAMES - 1
            for value in node.values():
                stretch(value)
        elif isinstance(node, list):
            for value in node:
                stretch(value)

    stretch(document)
    path = folder / "scene.openlabel.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


def _done(out: Path) -> set[tuple[int, str]]:
    data = json.loads((out / layout.MANIFEST_FILE).read_text())["done"]
    return {(int(frame), camera) for camera, frames in data.items() for frame in frames}


def _labelled(out: Path) -> set[tuple[int, str]]:
    return {(int(p.stem), p.parent.name) for p in (out / layout.LABELS_DIR).glob("*/*.json")}


def _rendered(out: Path) -> set[tuple[int, str]]:
    return {(int(p.stem), p.parent.name) for p in (out / layout.MASKS_DIR).glob("*/*.png")
            if layout.image_path(out, p.parent.name, int(p.stem)).is_file()}


@pytest.fixture(scope="module")
def document(tmp_path_factory):
    return _longer_minimal(tmp_path_factory.mktemp("doc"))


@pytest.fixture(scope="module")
def uninterrupted(document, tmp_path_factory):
    out = tmp_path_factory.mktemp("uninterrupted") / "out"
    assert main(["run", str(document), "-o", str(out), "--export", "--no-progress"]) == 0
    return out


def test_every_image_is_labelled_while_rendering(uninterrupted, capsys):
    pairs = _rendered(uninterrupted)
    assert len(pairs) == 2 * FRAMES
    assert _labelled(uninterrupted) == pairs


def test_labels_while_rendering_equal_labels_afterwards(uninterrupted, tmp_path):
    import shutil

    during = (uninterrupted / layout.ANNOTATIONS_FILE).read_bytes()
    copy = tmp_path / "out"
    shutil.copytree(uninterrupted, copy)
    shutil.rmtree(copy / layout.LABELS_DIR)
    (copy / layout.ANNOTATIONS_FILE).unlink()
    assert main(["annotate", str(copy), "--no-progress"]) == 0
    assert (copy / layout.ANNOTATIONS_FILE).read_bytes() == during
    assert _labelled(copy) == _rendered(copy)


def test_killed_run_keeps_the_labels_of_finished_images_and_resumes_identically(document, uninterrupted,
                                                                                 tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "usdscene.cli", "run", str(document), "-o", str(out),
                             "--export", "--no-progress"],
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 180
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                if len(_done(out)) >= 3:
                    break
            except (FileNotFoundError, json.JSONDecodeError, KeyError):
                pass
            time.sleep(0.01)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and its worker, mid-way
        proc.wait()
    finished = _done(out)
    assert 3 <= len(finished) < 2 * FRAMES, "the run was not interrupted mid-way"
    labelled = _labelled(out)
    # every image the manifest lists as finished has its labels, and no label lacks its image
    assert finished <= labelled <= _rendered(out)
    assert not (out / layout.ANNOTATIONS_FILE).exists()

    assert main(["run", str(document), "-o", str(out), "--export", "--no-progress"]) == 0
    assert (out / layout.ANNOTATIONS_FILE).read_bytes() == \
        (uninterrupted / layout.ANNOTATIONS_FILE).read_bytes()
    assert _labelled(out) == _rendered(out)
