"""Nothing outside the document's folder, the working folder, the shipped library and the
folders given with ``--asset-path`` is read, and no output is written through a link:
absolute and ``..`` asset folders, symbolic links, catalog entries, USD references, payloads
and sublayers of assets (at compose and at ``assets add``), a symlinked stage folder."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from test_compose_support import build_test_catalog, small_scene
from usdscene.cli import main
from usdscene.document.containment import ASSET_PATH_ENV, is_inside, reading_roots

pytestmark = pytest.mark.usd

OUTSIDE_LAYER = """#usda 1.0
(
    defaultPrim = "evil"
)

def Xform "evil"
{
}
"""


@pytest.fixture()
def project(tmp_path, monkeypatch) -> tuple[Path, Path]:
    """(project folder with a catalog ``cat`` inside, a folder outside with its own catalog and
    a plain USD layer); the working folder is the project folder."""
    inside, outside = tmp_path / "project", tmp_path / "outside"
    build_test_catalog(inside / "cat")
    build_test_catalog(outside / "cat")
    (outside / "evil.usda").write_text(OUTSIDE_LAYER)
    monkeypatch.chdir(inside)
    monkeypatch.delenv(ASSET_PATH_ENV, raising=False)
    return inside, outside


def _document(folder: Path, asset_paths: tuple[str, ...]) -> Path:
    from usdscene.converters.openlabel import write_document, write_openlabel

    path = folder / "doc.openlabel.json"
    write_document(path, write_openlabel(dataclasses.replace(small_scene(), asset_paths=asset_paths)))
    return path


def _refused(argv: list[str], capsys, *fragments: str) -> str:
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith("usdscene: error:"), err
    for fragment in fragments:
        assert fragment in err, err
    return err


def test_reading_roots_follow_links(tmp_path, monkeypatch):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "link").symlink_to(tmp_path / "b")
    monkeypatch.chdir(tmp_path / "a")
    monkeypatch.delenv(ASSET_PATH_ENV, raising=False)
    roots = reading_roots(tmp_path / "a")
    assert is_inside(tmp_path / "a" / "x", roots)
    assert not is_inside(tmp_path / "a" / "link" / "x", roots)
    assert not is_inside(tmp_path / "a" / ".." / "b", roots)
    monkeypatch.setenv(ASSET_PATH_ENV, str(tmp_path / "b"))
    assert is_inside(tmp_path / "a" / "link" / "x", reading_roots(tmp_path / "a"))


def test_asset_folder_inside_the_document_folder_composes(project, capsys):
    inside, _ = project
    doc = _document(inside, ("cat",))
    assert main(["compose", str(doc), "-o", str(inside / "out")]) == 0
    assert (inside / "out" / "stage" / "scene.usda").is_file()


@pytest.mark.parametrize("how", ["absolute", "dotdot", "symlink"])
def test_asset_folder_outside_needs_consent(project, capsys, how):
    inside, outside = project
    if how == "absolute":
        named = str(outside / "cat")
    elif how == "dotdot":
        named = "../outside/cat"
    else:
        (inside / "linked").symlink_to(outside / "cat")
        named = "linked"
    doc = _document(inside, (named,))
    for command in (["validate", str(doc)], ["compose", str(doc), "-o", str(inside / "out")]):
        _refused(command, capsys, "metadata.usdscene.asset_paths[0]", repr(named),
                 str((outside / "cat").resolve()), "--asset-path")
    assert not (inside / "out").exists()
    # Consent on the command line, or through the environment.
    assert main(["compose", str(doc), "-o", str(inside / "out"), "--asset-path", str(outside)]) == 0
    capsys.readouterr()


def test_catalog_entry_outside_is_refused(project, capsys):
    inside, _ = project
    catalog = json.loads((inside / "cat" / "catalog.json").read_text())
    catalog["classes"]["box"]["usd"] = "../../../../../../../../etc/passwd"
    (inside / "cat" / "catalog.json").write_text(json.dumps(catalog))
    doc = _document(inside, ("cat",))
    err = _refused(["compose", str(doc), "-o", str(inside / "out")], capsys,
                   "classes.box.usd", "'../../../../../../../../etc/passwd'", "'/etc/passwd'")
    assert "prepend references" not in err
    assert not (inside / "out" / "stage" / "scene.usda").exists()


def _arc_layer(arc: str, target: str) -> str:
    """A wrapper of the test box (``box_geometry.usda``) with one more arc to ``target``."""
    sublayers = f"@./box_geometry.usda@, @{target}@" if arc == "sublayer" else "@./box_geometry.usda@"
    metadata = {"reference": f"prepend references = @{target}@", "payload": f"prepend payload = @{target}@",
                "sublayer": ""}[arc]
    return (f'#usda 1.0\n(\n    defaultPrim = "box"\n    subLayers = [{sublayers}]\n)\n\n'
            f'over "box" (\n    {metadata}\n)\n{{\n}}\n')


@pytest.mark.parametrize("arc", ["reference", "payload", "sublayer"])
def test_usd_arcs_of_an_asset_are_checked_at_compose(project, capsys, arc):
    inside, outside = project
    objects = inside / "cat" / "objects"
    (objects / "box.usda").rename(objects / "box_geometry.usda")
    (objects / "box.usda").write_text(_arc_layer(arc, "../../../outside/evil.usda"))
    doc = _document(inside, ("cat",))
    _refused(["compose", str(doc), "-o", str(inside / "out")], capsys,
             str(objects / "box.usda"), "asset class 'box'", "USD composition arc",
             "'../../../outside/evil.usda'", str(outside / "evil.usda"))
    assert not (inside / "out" / "stage" / "scene.usda").exists()
    assert main(["compose", str(doc), "-o", str(inside / "out"), "--asset-path", str(outside)]) == 0
    capsys.readouterr()


def test_nested_arcs_are_followed(project, capsys):
    """An inside layer that references an inside layer that references an outside one."""
    inside, outside = project
    objects = inside / "cat" / "objects"
    (objects / "box.usda").rename(objects / "box_geometry.usda")
    (objects / "middle.usda").write_text(_arc_layer("reference", str(outside / "evil.usda"))
                                         .replace('"box"', '"middle"'))
    (objects / "box.usda").write_text(_arc_layer("payload", "./middle.usda"))
    doc = _document(inside, ("cat",))
    _refused(["compose", str(doc), "-o", str(inside / "out")], capsys, str(objects / "middle.usda"),
             str(outside / "evil.usda"))


@pytest.mark.parametrize("arc", ["reference", "payload", "sublayer"])
def test_assets_add_checks_the_arcs_of_a_usd_file(project, capsys, arc):
    inside, outside = project
    (inside / "mine").mkdir()
    (inside / "mine" / "box_geometry.usda").write_text(OUTSIDE_LAYER.replace("evil", "box"))
    (inside / "mine" / "wrapper.usda").write_text(_arc_layer(arc, str(outside / "evil.usda")))
    catalog_before = (inside / "cat" / "catalog.json").read_bytes()
    _refused(["assets", "add", "mine/wrapper.usda", "--class", "wrapped", "--catalog", "cat"], capsys,
             str(inside / "mine" / "wrapper.usda"), str(outside / "evil.usda"))
    assert (inside / "cat" / "catalog.json").read_bytes() == catalog_before
    assert not (inside / "cat" / "imported").exists()


def test_stage_folder_that_is_a_link_is_not_written_through(project, capsys):
    inside, outside = project
    target = outside / "elsewhere"
    target.mkdir()
    (inside / "out").mkdir()
    (inside / "out" / "stage").symlink_to(target)
    doc = _document(inside, ("cat",))
    _refused(["compose", str(doc), "-o", str(inside / "out")], capsys,
             str(inside / "out" / "stage"), "symbolic link")
    assert list(target.iterdir()) == []


def test_output_into_the_root_is_a_usage_error(project, capsys):
    inside, _ = project
    doc = _document(inside, ("cat",))
    assert main(["compose", str(doc), "-o", "/"]) == 2
    assert "root of the file system" in capsys.readouterr().err
