"""Render workers started before their job (``prestart_workers``, as ``usdscene run`` does
while it validates and composes): a shard takes one, the images are those of a worker started
for it, and the ones no shard took exit when discarded."""

from __future__ import annotations

from pathlib import Path

import pytest

from usdscene.cli import main
from usdscene.pipeline import compose_document
from usdscene.render import executors, worker_process
from usdscene.render.driver import render

MINIMAL = Path(__file__).resolve().parent.parent / "examples" / "minimal" / "scene.openlabel.json"

pytestmark = [pytest.mark.blender]


def _render(out: Path) -> dict[str, bytes]:
    _, composed = compose_document(MINIMAL, out / "stage")
    render(composed.root_layer, out, frames=[0], progress=False)
    return {p.relative_to(out).as_posix(): p.read_bytes()
            for folder in ("images", "masks") for p in (out / folder).glob("*/*.png")}


def test_a_prestarted_worker_renders_the_same_images_and_unused_ones_exit(tmp_path):
    worker_process.prestart_workers(2)
    started = [proc for proc, _ in worker_process._WARM]
    try:
        warm = _render(tmp_path / "warm")
        assert len(worker_process._WARM) == 1  # the one shard took one worker
        assert started[0].poll() is not None  # ... which rendered and exited
    finally:
        worker_process.discard_prestarted_workers()
    assert not worker_process._WARM
    assert started[1].wait(timeout=30) == 0  # the unused one left cleanly
    cold = _render(tmp_path / "cold")
    assert warm and warm == cold


def test_a_failed_run_leaves_no_prestarted_worker(tmp_path, capsys, monkeypatch):
    started = []
    prestart = executors.prestart_workers

    def recording(count):
        prestart(count)
        started.extend(proc for proc, _ in worker_process._WARM)

    monkeypatch.setattr(executors, "prestart_workers", recording)
    bad = tmp_path / "bad.openlabel.json"
    bad.write_text('{"openlabel": {"metadata": {"schema_version": "1.0.0"}, "frames": 3}}')
    assert main(["run", str(bad), "-o", str(tmp_path / "out"), "--no-progress"]) == 1
    assert "Traceback" not in capsys.readouterr().err
    assert len(started) == 1 and started[0].wait(timeout=30) == 0
    assert not worker_process._WARM
