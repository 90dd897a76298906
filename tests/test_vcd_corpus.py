"""The test files of the ``vcd`` 6.0.3 source distribution (``tests/etc``), written by the VCD
library's authors: every schema-valid OpenLABEL 1.0.0 file converts with its camera
calibrations preserved and its unknown data carried; the rest is refused naming the field.

The corpus is read from ``$USDSCENE_VCD_CORPUS`` if set, else downloaded once into a cache
(``pip download --no-deps --no-binary :all: vcd==6.0.3``) and never committed. Without it the
test fails in CI (``CI`` set) and skips with the reason elsewhere.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest

from test_openlabel_carry import carried_of
from usdscene.cli import main
from usdscene.converters.openlabel import load_document, read_openlabel, schema_problems
from usdscene.labels.projection import project_points

CORPUS_ENV = "USDSCENE_VCD_CORPUS"
CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "usdscene" / "vcd-6.0.3"


def _corpus() -> Path:
    if os.environ.get(CORPUS_ENV):
        return Path(os.environ[CORPUS_ENV])
    folder = CACHE / "vcd-6.0.3" / "tests" / "etc"
    if not any(folder.glob("*.json")):
        CACHE.mkdir(parents=True, exist_ok=True)
        done = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:",
                               "vcd==6.0.3", "-d", str(CACHE)], capture_output=True, text=True, timeout=300)
        archives = sorted(CACHE.glob("vcd-6.0.3.tar.gz"))
        if done.returncode != 0 or not archives:
            return CACHE / f"(download failed: {done.stderr.strip()[-300:]})"
        with tarfile.open(archives[0]) as archive:
            members = [m for m in archive.getmembers() if m.name.startswith("vcd-6.0.3/tests/etc/")]
            archive.extractall(CACHE, members=members, filter="data")
    return folder


@pytest.fixture(scope="module")
def vcd_corpus() -> Path:
    folder = _corpus()
    if not any(folder.glob("*.json")) if folder.is_dir() else True:
        reason = f"vcd 6.0.3 test corpus not available at {folder} (set {CORPUS_ENV} to its tests/etc folder)"
        if os.environ.get("CI"):
            pytest.fail(reason + "; CI must have it")
        pytest.skip(reason)
    return folder


def _sample_points(camera, frame) -> np.ndarray:
    """(N, 3) world points 2 and 7 m in front of ``camera`` at ``frame`` on a cone around its axis."""
    angles = np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    local = [(r * np.cos(a) * d, r * np.sin(a) * d, d) for d in (2.0, 7.0) for r in (0.0, 0.1, 0.3) for a in angles]
    pose = camera.pose if frame is None else camera.pose_at(frame)
    return pose.transform_points(np.array(local))


def test_vcd_corpus_converts_or_is_refused(vcd_corpus: Path, tmp_path, openlabel_schema_path, capsys):
    converted = refused = cameras_checked = 0
    for path in sorted(vcd_corpus.glob("*.json")):
        raw = json.loads(path.read_text(encoding="utf-8"))
        valid = (isinstance(raw, dict) and list(raw) == ["openlabel"]
                 and raw["openlabel"].get("metadata", {}).get("schema_version") == "1.0.0"
                 and schema_problems(raw, openlabel_schema_path) == [])
        out = tmp_path / path.name
        code = main(["convert", str(path), "-o", str(out), "--no-catalog"])
        err = capsys.readouterr().err
        if not valid and "vcd" in raw:  # VCD 4.3, which usdscene also reads
            continue
        if not valid:
            assert code == 1 and not out.exists(), path.name
            assert err.startswith("usdscene: error: ") and "Traceback" not in err, (path.name, err)
            first = err.splitlines()[0].removeprefix("usdscene: error: ")
            assert ":" in first and first.split(":")[0].strip(), (path.name, err)  # names where
            refused += 1
            continue
        assert code == 0, (path.name, err)
        written = json.loads(out.read_text(encoding="utf-8"))
        assert schema_problems(written, openlabel_schema_path) == [], path.name
        source, again = read_openlabel(path), read_openlabel(out)
        assert [c.name for c in again.cameras] == [c.name for c in source.cameras], path.name
        for before, after in zip(source.cameras, again.cameras):
            for frame in sorted({None, *(f for f, _ in before.frame_poses)}, key=lambda f: -1 if f is None else f):
                points = _sample_points(before, frame)
                uv0, ok0 = project_points(before, points, frame)
                uv1, ok1 = project_points(after, points, frame)
                assert np.array_equal(ok0, ok1) and ok0.any(), (path.name, before.name, frame)
                assert np.abs(uv0[ok0] - uv1[ok0]).max() <= 1e-9, (path.name, before.name, frame)
            cameras_checked += 1
        names = {c.name for c in source.cameras}
        assert carried_of(written["openlabel"], names) == carried_of(load_document(path)["openlabel"], names), \
            path.name
        converted += 1
    assert converted >= 55 and refused >= 5 and cameras_checked >= 15, (converted, refused, cameras_checked)
