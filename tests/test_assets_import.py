"""``usdscene assets add``: bring-your-own meshes and USD files, and every way it refuses."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from usdscene.scene.catalog import load_catalog
from usdscene.cli import main

pytestmark = pytest.mark.usd


@pytest.fixture()
def workdir(tmp_path, monkeypatch) -> Path:
    """A working folder (the allowed root) with a catalog folder holding one class."""
    work = tmp_path / "work"
    (work / "my_assets").mkdir(parents=True)
    monkeypatch.chdir(work)
    return work


def _box_file(path: Path, size, offset=(0.0, 0.0, 0.0)) -> Path:
    import trimesh

    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(offset)
    mesh.export(str(path))
    return path


def test_obj_is_converted_to_z_up_metres_and_registered(workdir, capsys):
    # A Y-up OBJ box: 0.3 wide (x), 0.5 tall (y), 0.2 deep (z), floating off the origin.
    _box_file(workdir / "crate.obj", (0.3, 0.5, 0.2), offset=(1.0, 2.0, 3.0))
    assert main(["assets", "add", "crate.obj", "--class", "crate", "--catalog", "my_assets"]) == 0
    assert "registered crate" in capsys.readouterr().err
    catalog = load_catalog(["my_assets"], include_default=False, base_dir=workdir)
    entry = catalog["crate"]
    assert entry.kind == "object"
    np.testing.assert_allclose(entry.extent_min_m, (-0.15, -0.1, 0.0), atol=1e-4)
    np.testing.assert_allclose(entry.extent_max_m, (0.15, 0.1, 0.5), atol=1e-4)
    assert entry.usd_path == (workdir / "my_assets" / "imported" / "crate.usda").resolve()

    from pxr import Usd, UsdGeom, UsdValidation

    stage = Usd.Stage.Open(str(entry.usd_path))
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{stage.GetDefaultPrim().GetPath()}/Geom/Mesh"))
    points = np.array(mesh.GetPointsAttr().Get())
    np.testing.assert_allclose(np.array(mesh.GetExtentAttr().Get()), [points.min(0), points.max(0)])
    context = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    assert [e.GetMessage() for e in context.Validate(stage)
            if e.GetType() == UsdValidation.ValidationErrorType.Error] == []
    # No temporary files left next to the outputs (atomic writes rename over the target).
    leftovers = [p.name for p in (workdir / "my_assets").rglob("*") if p.name.startswith(".")]
    assert leftovers == []


def test_stl_in_millimetres_keeps_z_up(workdir):
    _box_file(workdir / "case.stl", (400.0, 250.0, 550.0))
    assert main(["assets", "add", "case.stl", "--class", "big_case", "--catalog", "my_assets",
                 "--unit-scale", "0.001"]) == 0
    entry = load_catalog(["my_assets"], include_default=False, base_dir=workdir)["big_case"]
    np.testing.assert_allclose(entry.size_m, (0.4, 0.25, 0.55), atol=1e-4)
    assert entry.extent_min_m[2] == 0.0


def test_usd_file_is_referenced_with_its_units(workdir):
    from pxr import Usd, UsdGeom

    from usdscene.assetgen import mesh as m
    from usdscene.assetgen.usd_write import define_mesh

    stage = Usd.Stage.CreateNew(str(workdir / "cone.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)  # centimetres, Y up
    root = UsdGeom.Xform.Define(stage, "/Cone").GetPrim()
    stage.SetDefaultPrim(root)
    define_mesh(stage, "/Cone/Mesh", m.box((10.0, 40.0, 20.0)))  # 40 cm tall along Y
    stage.GetRootLayer().Save()
    assert main(["assets", "add", "cone.usda", "--class", "cone", "--catalog", "my_assets"]) == 0
    entry = load_catalog(["my_assets"], include_default=False, base_dir=workdir)["cone"]
    np.testing.assert_allclose(entry.size_m, (0.1, 0.2, 0.4), atol=1e-4)
    text = entry.usd_path.read_text()
    assert "@../../cone.usda@" in text  # relative reference, no machine path
    composed = Usd.Stage.Open(str(entry.usd_path))
    from usdscene.assetgen.usd_write import bounds_of_stage

    lo, hi = bounds_of_stage(composed)
    np.testing.assert_allclose(hi - lo, (0.1, 0.2, 0.4), atol=1e-4)


def _bad_files(workdir: Path, outside: Path) -> dict[str, tuple[Path, str]]:
    (workdir / "empty.obj").write_text("# exported nothing\n")
    (workdir / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    (workdir / "model.fbx").write_bytes(b"Kaydara FBX Binary")
    (workdir / "folder.obj").mkdir()
    _box_file(outside / "elsewhere.obj", (0.1, 0.1, 0.1))
    (workdir / "nodefault.usda").write_text('#usda 1.0\ndef Xform "A" {}\n')
    return {
        "empty": (workdir / "empty.obj", "no triangle mesh"),
        "unreadable": (workdir / "broken.glb", "cannot read mesh file"),
        "unknown format": (workdir / "model.fbx", "unknown asset format '.fbx'"),
        "not a file": (workdir / "folder.obj", "not a file"),
        # A file named on the command line may lie anywhere (the user's consent); see
        # test_other_peoples_files.py. Containment is for paths inside documents and catalogs.
        "missing": (workdir / "missing.stl", "does not exist"),
        "usd without default prim": (workdir / "nodefault.usda", "no defaultPrim"),
    }


def test_bad_files_fail_cleanly_and_leave_the_catalog_untouched(workdir, tmp_path, capsys):
    _box_file(workdir / "ok.obj", (0.2, 0.2, 0.2))
    assert main(["assets", "add", "ok.obj", "--class", "ok_box", "--catalog", "my_assets"]) == 0
    catalog_file = workdir / "my_assets" / "catalog.json"
    before = catalog_file.read_bytes()
    files_before = sorted(os.listdir(workdir / "my_assets" / "imported"))
    outside = tmp_path / "outside"
    outside.mkdir()
    capsys.readouterr()
    for case, (path, message) in _bad_files(workdir, outside).items():
        code = main(["assets", "add", str(path), "--class", "new_thing", "--catalog", "my_assets"])
        err = capsys.readouterr().err
        assert code == 1, case
        assert err.startswith("usdscene: error: ") and message in err, f"{case}: {err}"
        assert "Traceback" not in err
        assert catalog_file.read_bytes() == before, case
        assert sorted(os.listdir(workdir / "my_assets" / "imported")) == files_before, case


def test_bad_options_and_duplicates_are_refused(workdir, capsys):
    _box_file(workdir / "ok.obj", (0.2, 0.2, 0.2))
    assert main(["assets", "add", "ok.obj", "--class", "ok_box", "--catalog", "my_assets"]) == 0
    before = (workdir / "my_assets" / "catalog.json").read_bytes()
    cases = [
        (["--class", "Bad Name"], "lower_snake_case"),
        (["--class", "ok_box"], "already exists"),
        (["--class", "other", "--unit-scale", "-2"], "positive number"),
    ]
    for extra, message in cases:
        capsys.readouterr()
        assert main(["assets", "add", "ok.obj", "--catalog", "my_assets", *extra]) == 1
        assert message in capsys.readouterr().err
        assert (workdir / "my_assets" / "catalog.json").read_bytes() == before
    assert main(["assets", "add", "ok.obj", "--class", "ok_box", "--catalog", "my_assets", "--replace",
                 "--description", "replaced"]) == 0
    data = json.loads((workdir / "my_assets" / "catalog.json").read_text())
    assert data["classes"]["ok_box"]["description"] == "replaced"


def test_imported_catalog_combines_with_the_shipped_library(workdir):
    _box_file(workdir / "ok.obj", (0.2, 0.2, 0.2))
    assert main(["assets", "add", "ok.obj", "--class", "ok_box", "--catalog", "my_assets"]) == 0
    catalog = load_catalog(["my_assets"], base_dir=workdir)
    assert "ok_box" in catalog and "aircraft_cabin" in catalog and "backpack" in catalog


def test_rebuilding_a_library_keeps_imported_classes(workdir):
    from usdscene.assetgen.cabin import CabinConfig
    from usdscene.assetgen.library import build_library

    library = workdir / "library"
    build_library(library, CabinConfig(rows=2))
    _box_file(workdir / "ok.obj", (0.2, 0.2, 0.2))
    assert main(["assets", "add", "ok.obj", "--class", "ok_box", "--catalog", "library"]) == 0
    build_library(library, CabinConfig(rows=2))
    catalog = load_catalog([library], include_default=False)
    assert "ok_box" in catalog and "backpack" in catalog
