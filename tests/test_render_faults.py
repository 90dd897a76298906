"""Faults of the local executor: a worker killed mid-run is retried (the message names the
signal) and the outputs equal an undisturbed run's; scratch folders of dead workers go."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys

import pytest

from usdscene.document import output_layout as layout


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_scratch_of_dead_workers_is_removed_and_live_ones_kept(tmp_path):
    from usdscene.render.scratch import host_tag, remove_stale_scratch

    host = host_tag()
    dead = tmp_path / f"usdscene-render-{_dead_pid()}-{host}-abcd1234"
    dead_task = tmp_path / f"usdscene-task-{_dead_pid()}-{host}-x_y9z8w7"
    live = tmp_path / f"usdscene-render-{os.getpid()}-{host}-abcd1234"
    other_host = tmp_path / f"usdscene-render-{_dead_pid()}-{host}x-abcd1234"
    legacy = tmp_path / "usdscene-render-abcd1234"  # no owner in the name: never touched
    unrelated = tmp_path / "something-else"
    for folder in (dead, dead_task, live, other_host, legacy, unrelated):
        folder.mkdir()
        (folder / "render-1.exr").write_bytes(b"x" * 10)
    removed = remove_stale_scratch(tmp_path)
    assert sorted(removed) == sorted([dead, dead_task])
    assert not dead.exists() and not dead_task.exists()
    assert live.is_dir() and other_host.is_dir() and legacy.is_dir() and unrelated.is_dir()


def test_make_scratch_names_its_owner():
    from usdscene.render.scratch import make_scratch, remove_stale_scratch

    folder = make_scratch("job")
    try:
        assert folder.name.startswith(f"usdscene-job-{os.getpid()}-")
        remove_stale_scratch(folder.parent)
        assert folder.is_dir(), "a live process's scratch folder was removed"
    finally:
        folder.rmdir()
    with pytest.raises(ValueError):
        make_scratch("other")


def test_exit_of_a_killed_worker_names_the_signal():
    from usdscene.render.worker_process import describe_exit

    killed = describe_exit(-signal.SIGKILL, None, ["Fra:0 Mem:12M"])
    assert not killed.ok and killed.retryable
    assert "SIGKILL" in killed.message and "OOM" in killed.message
    assert "SIGSEGV" in describe_exit(-signal.SIGSEGV, None, []).message
    failed = describe_exit(1, "RuntimeError: USD import of x failed", ["tail"])
    assert not failed.ok and not failed.retryable and "USD import of x failed" in failed.message
    assert describe_exit(0, None, []).ok


@pytest.mark.usd
@pytest.mark.blender
def test_local_worker_killed_mid_run_is_retried_with_identical_outputs(tmp_path, caplog):
    from usdscene.render.driver import render
    from usdscene.render.scratch import scratch_root
    from usdscene.render.synthetic import write_synthetic_stage
    from test_render_resume import _scene

    stage = write_synthetic_stage(_scene(), tmp_path / "stage")
    settings = {"samples": 1, "denoise": False}
    frames = list(range(0, 6))
    reference = render(stage, tmp_path / "reference", frames=frames, settings_override=settings, progress=False)
    assert reference.pairs_rendered == 12 and reference.retries == 0

    killed: list[int] = []

    def kill_first_worker(event: dict) -> None:
        if event.get("event") == "imported" and not killed:
            killed.append(event["pid"])
        elif event.get("event") == "done" and len(killed) == 1:
            os.kill(killed[0], signal.SIGKILL)  # after its first image: mid-shard
            killed.append(-1)

    root = scratch_root()
    before = set(root.iterdir()) if root else set()
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING, logger="usdscene.render.driver"):
        report = render(stage, out, frames=frames, settings_override=settings, progress=False,
                        on_event=kill_first_worker)
    assert len(killed) == 2, "no worker was killed"
    assert report.retries == 1
    assert report.pairs_rendered == 12
    assert any("killed by SIGKILL" in r.getMessage() and "retry 1 of 3" in r.getMessage()
               for r in caplog.records), [r.getMessage() for r in caplog.records]
    for camera in ("front", "moving"):
        for frame in frames:
            for path_of in (layout.image_path, layout.mask_path):
                got = path_of(out, camera, frame).read_bytes()
                assert got == path_of(tmp_path / "reference", camera, frame).read_bytes(), (camera, frame)
    assert not list(out.rglob("*.tmp")), "a temporary file of the killed worker was left behind"
    if root:
        left = {p for p in set(root.iterdir()) - before if f"-{os.getpid()}-" in p.name}
        assert not left, f"scratch folders left behind: {left}"


@pytest.mark.usd
@pytest.mark.blender
def test_no_retry_left_fails_with_the_signal_and_resume_finishes(tmp_path):
    from usdscene.errors import RenderError
    from usdscene.render.driver import render
    from usdscene.render.synthetic import write_synthetic_stage
    from test_render_resume import _scene

    stage = write_synthetic_stage(_scene(), tmp_path / "stage")
    settings = {"samples": 1, "denoise": False}

    def kill(event: dict) -> None:
        if event.get("event") == "imported":
            os.kill(event["pid"], signal.SIGKILL)

    with pytest.raises(RenderError, match="killed by SIGKILL.*gave up after 1 attempt"):
        render(stage, tmp_path / "out", frames=[0, 1], settings_override=settings, progress=False,
               retries=0, on_event=kill)
    again = render(stage, tmp_path / "out", frames=[0, 1], settings_override=settings, progress=False)
    assert again.pairs_rendered + again.pairs_skipped == 4 and again.pairs_rendered >= 1
