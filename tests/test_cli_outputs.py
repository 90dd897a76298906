"""Bad output paths, unreadable inputs and a full disk: every sub-command answers with one
readable line naming the path and the cause (exit 1; 2 for usage errors), never a traceback,
and leaves nothing that looks finished.

The tests run as root, which ignores permission bits, so an unwritable folder is simulated
by a path whose parent is a regular file, and a full disk by a file size limit
(``RLIMIT_FSIZE``), which binds root as well.
"""

from __future__ import annotations

import errno
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from usdscene.cli import main
from usdscene.errors import OutputError
from usdscene.files import make_folder, os_problem, write_bytes_atomic, write_json_atomic

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "examples" / "minimal" / "scene.openlabel.json"


@pytest.fixture()
def blocker(tmp_path: Path) -> Path:
    """A regular file: any path below it cannot be created, even by root."""
    path = tmp_path / "a_file"
    path.write_text("not a folder\n")
    return path


def _error_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith("usdscene: error:")]


def _assert_one_readable_error(rc: int, err: str, path_fragment: str) -> str:
    assert rc == 1, err
    assert "Traceback" not in err
    lines = _error_lines(err)
    assert len(lines) == 1, err
    assert path_fragment in lines[0], lines[0]
    return lines[0]


# -- the library's writers ------------------------------------------------------------------

def test_write_below_a_file_names_the_file(blocker):
    with pytest.raises(OutputError) as caught:
        write_json_atomic(blocker / "sub" / "x.json", {"a": 1})
    (problem,) = caught.value.problems
    assert str(blocker) in problem.message and "is a file, not a folder" in problem.message
    assert sorted(p.name for p in blocker.parent.iterdir()) == ["a_file"]


def test_write_onto_a_folder_and_empty_path_are_refused(tmp_path):
    with pytest.raises(OutputError, match="existing folder"):
        write_bytes_atomic(tmp_path, b"x")
    with pytest.raises(OutputError, match="empty path"):
        write_bytes_atomic("", b"x")
    with pytest.raises(OutputError, match="empty path"):
        make_folder("")
    assert list(tmp_path.iterdir()) == []


def test_written_files_follow_the_umask(tmp_path):
    """A temporary file is created 0600; the renamed output must be readable like any file."""
    umask = os.umask(0o022)
    os.umask(umask)
    path = write_bytes_atomic(tmp_path / "x.bin", b"data")
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


@pytest.mark.parametrize(("code", "expected"), [
    (errno.ENOSPC, "no space left on the device"),
    (errno.EFBIG, "file size limit"),
    (errno.EACCES, "permission denied"),
    (errno.EROFS, "read-only"),
])
def test_os_problem_names_path_and_cause(code, expected):
    problem = os_problem(OSError(code, os.strerror(code), "/data/out/x.png"), what="image")
    assert problem.where == "/data/out/x.png"
    assert problem.message.startswith("cannot write the image: ") and expected in problem.message


def test_file_size_limit_leaves_no_partial_file(tmp_path):
    """Below the limit the write fails cleanly; the target keeps its old content."""
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    code = (f"import resource, signal, sys\n"
            f"signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
            f"resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))\n"
            f"from usdscene.errors import OutputError\n"
            f"from usdscene.files import write_bytes_atomic\n"
            f"try:\n"
            f"    write_bytes_atomic({str(target)!r}, b'x' * 5000)\n"
            f"except OutputError as exc:\n"
            f"    print(exc)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert f"{target}: cannot write the file: file too large" in result.stdout
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["x.bin"]


# -- every sub-command, in process -----------------------------------------------------------

def _cases(tmp: Path, blocker: Path) -> list[tuple[list[str], str]]:
    """(argv, fragment the error line must contain)."""
    doc = str(DOC)
    obj = tmp / "box.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    folder = tmp / "folder"
    folder.mkdir()
    return [
        (["run", doc, "-o", str(blocker)], str(blocker)),
        (["render", doc, "-o", str(blocker)], str(blocker)),
        (["compose", doc, "-o", str(blocker)], str(blocker)),
        (["compose", doc, "-o", str(blocker / "out")], str(blocker)),
        (["convert", doc, "-o", str(blocker / "x.json")], str(blocker)),
        (["convert", doc, "-o", str(folder)], str(folder)),
        (["preview", doc, "-o", str(blocker / "sheet.png")], str(blocker)),
        (["preview", doc, "-o", str(folder)], str(folder)),
        (["blend", doc, "-o", str(blocker / "scene.blend")], str(blocker)),
        (["assets", "add", str(obj), "--class", "box", "--catalog", str(blocker / "catalog")], str(blocker)),
        (["assets", "build", "--out", str(blocker / "library")], str(blocker)),
        (["generate", "single-class", "--setup", doc, "-o", str(blocker / "seq.json")], str(blocker)),
        (["stats", doc, "--chart", str(blocker / "chart.png")], str(blocker)),
        # unreadable inputs
        (["convert", str(folder), "-o", str(tmp / "x.json")], str(folder)),
        (["validate", str(tmp / "missing.json")], "missing.json"),
        (["render", str(blocker), "-o", str(tmp / "out")], str(blocker)),
        (["annotate", str(blocker)], str(blocker)),
        (["export", "coco", str(blocker)], str(blocker)),
        (["stats", str(blocker)], str(blocker)),
        (["report", str(blocker)], str(blocker)),
        (["report", str(folder), "-o", str(blocker / "report")], str(folder)),  # nothing to report
    ]


def test_every_command_reports_bad_paths_in_one_line(tmp_path, blocker, capsys):
    cases = _cases(tmp_path, blocker)
    before = sorted(p.name for p in tmp_path.iterdir())
    for argv, fragment in cases:
        rc = main(argv)
        err = capsys.readouterr().err
        _assert_one_readable_error(rc, err, fragment)
    # Nothing was written anywhere: no half-composed stage, no output file.
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert blocker.read_text() == "not a folder\n"


@pytest.mark.parametrize("argv", [
    ["compose", str(DOC), "-o", "out", "--seed", "-5"],
    ["compose", str(DOC), "-o", "out", "--seed", "five"],
    ["generate", "balanced", "--setup", str(DOC), "-o", "x.json", "--seed", "-1"],
    ["convert", str(DOC), "-o", ""],
    ["compose", str(DOC), "-o", ""],
    ["run", str(DOC), "-o", " "],
    ["preview", str(DOC), "-o", ""],
])
def test_usage_errors_exit_2(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error: argument" in err
    assert list(tmp_path.iterdir()) == []


# -- as a user runs it: a separate process, a full disk ----------------------------------------

def _limit_file_size(limit_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return apply


def _usdscene(*argv: str, cwd: Path, fsize: int | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "usdscene", *argv], cwd=cwd, capture_output=True,
                          text=True, timeout=300,
                          preexec_fn=_limit_file_size(fsize) if fsize is not None else None)


@pytest.mark.usd
def test_process_compose_into_a_file_and_a_full_disk(tmp_path, blocker):
    result = _usdscene("compose", str(DOC), "-o", str(blocker), cwd=tmp_path)
    _assert_one_readable_error(result.returncode, result.stderr, str(blocker))

    # The layers are a few KiB each: 2 KiB lets the first through and stops a later one.
    out = tmp_path / "out"
    result = _usdscene("compose", str(DOC), "-o", str(out), cwd=tmp_path, fsize=2048)
    line = _assert_one_readable_error(result.returncode, result.stderr, str(out / "stage"))
    assert "file too large" in line
    stage = out / "stage"
    assert not (stage / "scene.usda").exists()  # no root layer: nothing looks composed
    assert not [p for p in stage.iterdir() if p.name.endswith(".tmp")]

    result = _usdscene("convert", str(DOC), "-o", str(tmp_path / "x.json"), cwd=tmp_path, fsize=2048)
    _assert_one_readable_error(result.returncode, result.stderr, str(tmp_path / "x.json"))
    assert not (tmp_path / "x.json").exists()


@pytest.mark.blender
def test_process_full_disk_during_render_and_annotate(tmp_path):
    """A render whose files pass the limit fails with exit 1 and records no finished image;
    annotate on a finished render fails the same way and writes no annotation file."""
    out = tmp_path / "run"
    result = _usdscene("run", str(DOC), "-o", str(out), "--frames", "0", "--cameras", "cam_01",
                       "--no-progress", cwd=tmp_path, fsize=40 * 1024)
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr and len(_error_lines(result.stderr)) == 1, result.stderr
    assert not list(out.rglob("*.png"))
    assert not (out / "annotations.openlabel.json").exists()

    done = tmp_path / "done"
    result = _usdscene("render", str(DOC), "-o", str(done), "--frames", "0", "--cameras", "cam_01",
                       "--no-progress", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert list((done / "images").rglob("*.png"))
    # A first annotate compiles the amodal rasteriser into numba's on-disk cache; with that
    # cache cold, a full disk stops numba's own cache write before usdscene writes anything.
    assert _usdscene("annotate", str(done), "--no-progress", cwd=tmp_path).returncode == 0
    result = _usdscene("annotate", str(done), "--no-progress", cwd=tmp_path, fsize=1024)
    line = _assert_one_readable_error(result.returncode, result.stderr, str(done / "annotations" / "frames"))
    assert "file too large" in line
    # the old labels' index and copy went first: no half-replaced store is left to read
    assert not (done / "annotations.openlabel.json").exists() and not (done / "annotations" / "index.json").exists()
