"""Kill and resume, one test per step: ``generate``, ``compose``, ``annotate`` and ``export`` run
in a subprocess, are killed with SIGKILL part-way, and run again; the outputs are byte-identical
to an uninterrupted run's and no temporary file is left. (The render's own test is
``tests/test_render_resume.py::test_kill_mid_way_then_resume``.)

A step is killed once it has used a part of the CPU time its uninterrupted run took (read from
``/proc``), so the kill lands inside the work whatever the machine's load; the test checks that
the process was still running when it was killed. A kill in the middle of an atomic write leaves
its temporary file; the resumed step removes it."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

REPO = Path(__file__).resolve().parents[1]
SETUP = REPO / "examples" / "car_park" / "setup_moving.openlabel.json"
GENERATE = ["generate", "tracks", "--setup", str(SETUP), "--frames", "150", "--fps", "10", "--people", "30",
            "--seed", "11"]


def _cli(args) -> list[str]:
    return [sys.executable, "-m", "usdscene.cli", *map(str, args)]


def _run(args) -> float:
    """Run a command to the end; its CPU seconds (user + system, children included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(_cli(args), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def _kill_part_way(args, *, cpu_s: float | None = None, until=None, timeout_s: float = 600) -> None:
    """Start the command, SIGKILL its process group once it has used ``cpu_s`` CPU seconds or
    ``until()`` holds; fail if it ended first."""
    proc = subprocess.Popen(_cli(args), start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                if (cpu_s is not None and _cpu_seconds(proc.pid) >= cpu_s) or (until is not None and until()):
                    break
            except (FileNotFoundError, ProcessLookupError):
                break
            time.sleep(0.005)
        still_running = proc.poll() is None
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
    assert still_running and proc.returncode == -signal.SIGKILL, "the step ended before it was killed"


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _no_temporaries(folder: Path) -> None:
    assert not [p for p in folder.rglob("*.tmp")], "a temporary file was left behind"


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """The uninterrupted generate: (document path, its CPU seconds)."""
    root = tmp_path_factory.mktemp("generated")
    cpu = _run([*GENERATE, "-o", root / "doc.json"])
    return root / "doc.json", cpu


@pytest.mark.usd
def test_generate_killed_part_way_resumes_to_the_same_document(generated, tmp_path):
    reference, cpu = generated
    target = tmp_path / "doc.json"
    _kill_part_way([*GENERATE, "-o", target], cpu_s=0.7 * cpu)
    assert not target.exists(), "a killed generate left a document"
    _no_temporaries(tmp_path)
    _run([*GENERATE, "-o", target])
    assert target.read_bytes() == reference.read_bytes()
    assert (tmp_path / "doc.json.report.json").read_bytes() == \
        reference.with_name("doc.json.report.json").read_bytes()


@pytest.mark.usd
def test_compose_killed_part_way_resumes_to_the_same_layers(generated, tmp_path):
    document, _ = generated
    reference = tmp_path / "reference"
    cpu = _run(["compose", document, "-o", reference])
    out = tmp_path / "out"
    _kill_part_way(["compose", document, "-o", out], cpu_s=0.5 * cpu)
    _run(["compose", document, "-o", out])
    _no_temporaries(out)
    assert _files(out) == _files(reference) and layout.stage_root(out).exists()


FRAMES = range(0, 12)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A rendered synthetic output (2 cameras x 12 frames, 64 x 48) and its uninterrupted
    annotations."""
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x
    intr = Intrinsics(LensModel.PERSPECTIVE, 64, 48, 50.0, 50.0, 31.5, 23.5)
    cams = (Camera("front", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),
            Camera("side", intr, Pose.from_rotation_translation(r, [-4.0, 0.6, 1.0])))
    spheres = (SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1, class_name="ball"),
               SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2, class_name="ball", frames=tuple(range(3, 9))),
               SphereSpec("c", (0.0, -1.0, 1.0), 0.3, (0.1, 0.2, 0.9), 3, class_name="ball",
                          frame_centres=tuple((f, (0.0, -1.2 + 0.1 * f, 0.6)) for f in FRAMES)))
    root = tmp_path_factory.mktemp("rendered")
    out = root / "out"
    stage = write_synthetic_stage(SyntheticScene(cameras=cams, spheres=spheres, frame_start=FRAMES[0],
                                                 frame_end=FRAMES[-1]), out / "stage")
    render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False)
    reference = root / "reference"
    subprocess.run(["cp", "-a", str(out), str(reference)], check=True)
    cpu = _run(["annotate", reference, "--no-progress"])
    return out, reference, cpu


def _copy(source: Path, target: Path) -> Path:
    subprocess.run(["cp", "-a", str(source), str(target)], check=True)
    return target


@pytest.mark.usd
@pytest.mark.blender
def test_annotate_killed_part_way_resumes_to_the_same_annotations(rendered, tmp_path):
    rendered_out, reference, _ = rendered
    out = _copy(rendered_out, tmp_path / "out")
    labels = out / layout.LABELS_DIR
    total = 2 * len(FRAMES)
    _kill_part_way(["annotate", out, "--no-progress"],
                   until=lambda: len(list(labels.glob("*/*.json"))) >= 3)
    kept = len(list(labels.glob("*/*.json")))
    assert 3 <= kept < total, "annotate was not killed part-way"
    assert not (out / layout.ANNOTATIONS_FILE).exists()
    _run(["annotate", out, "--no-progress"])
    _no_temporaries(out)  # a kill mid-write leaves one; the resumed run removes it
    assert _files(out) == _files(reference)


@pytest.mark.usd
@pytest.mark.blender
@pytest.mark.parametrize("fmt", ["coco", "yolo"])
def test_export_killed_part_way_resumes_to_the_same_files(rendered, tmp_path, fmt):
    _, annotated, _ = rendered
    reference = _copy(annotated, tmp_path / "reference")
    cpu = _run(["export", fmt, reference])
    out = _copy(annotated, tmp_path / "out")
    _kill_part_way(["export", fmt, out], cpu_s=0.8 * cpu)
    _run(["export", fmt, out])
    _no_temporaries(out)
    exported = _files(out / layout.EXPORTS_DIR)
    assert exported and exported == _files(reference / layout.EXPORTS_DIR)


def test_what_a_killed_write_leaves_is_removed_and_nothing_else(tmp_path):
    from usdscene.files import remove_stale_temporaries

    keep = [tmp_path / "doc.json", tmp_path / "sub" / "a.json", tmp_path / "notes.tmp.txt"]
    stale = [tmp_path / ".doc.json.x1.tmp", tmp_path / "sub" / ".a.json.x2.tmp"]
    for path in keep + stale:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("x")
    staged = tmp_path / "exports" / ".mot.x3.partial"  # a staged_folder of a killed export
    (staged / "cam").mkdir(parents=True)
    (staged / "cam" / "gt.txt").write_text("1,2")
    old = tmp_path / "exports" / ".mot.old-1234"
    old.mkdir()
    assert remove_stale_temporaries(tmp_path / "sub", recursive=False, name="other.") == 0
    assert remove_stale_temporaries(tmp_path) == 4
    assert all(p.exists() for p in keep) and not any(p.exists() for p in (*stale, staged, old))
    assert remove_stale_temporaries(tmp_path / "missing") == 0
