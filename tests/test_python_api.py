"""The public Python API: lazily re-exported from ``usdscene``, documented in
docs/python-api.md, whose example runs here as written."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import usdscene

REPO = Path(__file__).resolve().parent.parent
API_DOC = REPO / "docs" / "python-api.md"


def _code_blocks(markdown: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", markdown, flags=re.S | re.M)


def test_import_is_light():
    code = ("import sys, usdscene\n"
            "heavy = [m for m in ('pxr', 'bpy', 'cv2', 'numpy', 'usdscene.scene.compose') if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "assert callable(usdscene.read_openlabel) and 'usdscene.converters.openlabel' in sys.modules\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_every_public_name_resolves_and_is_documented():
    text = API_DOC.read_text(encoding="utf-8")
    for name in usdscene._LAZY:
        assert getattr(usdscene, name) is not None
        assert re.search(rf"`{name}[(`]", text), f"{name} is not in docs/python-api.md"
    assert set(usdscene._LAZY) <= set(usdscene.__all__) and set(usdscene._LAZY) <= set(dir(usdscene))
    with pytest.raises(AttributeError, match="no_such_function"):
        usdscene.no_such_function  # noqa: B018


@pytest.mark.usd
@pytest.mark.blender
def test_documented_example_runs(tmp_path, monkeypatch, capsys):
    shutil.copytree(REPO / "examples" / "minimal", tmp_path / "examples" / "minimal")
    monkeypatch.chdir(tmp_path)
    blocks = _code_blocks(API_DOC.read_text(encoding="utf-8"))
    assert len(blocks) >= 4
    namespace: dict = {"__name__": "python_api_example"}
    for block in blocks:
        exec(compile(block, str(API_DOC), "exec"), namespace)  # noqa: S102 - our own documentation
    printed = capsys.readouterr().out
    out = tmp_path / "out" / "python-api"
    assert len(list((out / "images").glob("*/*.png"))) == 2  # frame 0 of both cameras
    assert (out / "annotations.openlabel.json").is_file()
    assert (out / "exports" / "coco" / "annotations.json").is_file()
    assert (tmp_path / "out" / "python-api-run" / "exports" / "yolo").is_dir()
    assert namespace["summary"].images_written == 2
    assert "2 cameras" in printed
    # the last block reports both problems of the broken document with their JSON paths
    assert printed.splitlines()[-2:] == [
        "openlabel.objects.0.frame_intervals[0] - frame_start 5 is after frame_end 2",
        "openlabel.objects.1.object_data.vec[0].val[1] - expected a finite number, got 'x'"]
