"""The shipped procedural asset library: catalog content, USD conventions, validation,
places, byte-identical rebuild, recolouring and variants."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from usdscene.document import stage_schema
from usdscene.scene.catalog import REGION_RELATIONS, load_catalog
from usdscene.shipped import default_asset_folder

ASSETS = default_asset_folder()
RELATIONS = set(REGION_RELATIONS.values())


@pytest.fixture(scope="module")
def catalog():
    return load_catalog(include_default=True)


def _usd_files() -> list[Path]:
    return sorted(p for p in ASSETS.rglob("*.usda") if "imported" not in p.parts)


# --- catalog (pure) ----------------------------------------------------------------------------

def test_catalog_has_22_object_classes_with_two_variants_each(catalog):
    objects = catalog.classes("object")
    assert len(objects) >= 22
    for name in objects:
        entry = catalog[name]
        names = entry.variants[stage_schema.VARIANT_SET_APPEARANCE]
        assert len(names) >= 2, name
        assert entry.default_variants[stage_schema.VARIANT_SET_APPEARANCE] in names
        assert set(entry.relations) <= RELATIONS and entry.relations, name
        lo, hi = np.array(entry.extent_min_m), np.array(entry.extent_max_m)
        assert lo[2] == 0.0, f"{name}: origin must be on the bottom face"
        np.testing.assert_allclose((lo + hi)[:2], 0.0, atol=2e-4, err_msg=name)
        assert 0.005 < max(entry.size_m) < (2.0 if name == "person" else 1.0), name


def test_catalog_passenger_and_cabin_entries(catalog):
    passenger = catalog["passenger"]
    assert passenger.kind == "passenger" and passenger.relations == ("is_on",)
    assert len(passenger.variants[stage_schema.VARIANT_SET_POSE]) >= 3
    assert len(passenger.variants[stage_schema.VARIANT_SET_APPEARANCE]) >= 3
    # Feet reach the floor when the hip contact point is on a 0.45 m cushion.
    assert passenger.extent_min_m[2] == pytest.approx(-0.45, abs=0.01)
    cabin = catalog["aircraft_cabin"]
    assert cabin.kind == "environment"
    places = cabin.places
    seats = [p for p in places.values() if p.kind == "seat"]
    assert len(seats) >= 19
    assert {p.kind for p in places.values()} == {"seat", "bin", "aisle"}
    for seat in seats:
        assert set(seat.regions) == {"is_on", "is_below", "is_in_front_of", "is_in"}, seat.name
    assert set(places["bin_05L"].regions) == {"is_in"}
    assert set(places["aisle_05"].regions) == {"is_on"}


def test_cabin_geometry_conventions(catalog):
    places = catalog["aircraft_cabin"].places
    on_a = places["seat_05A"].regions["is_on"].pose.translation_m
    on_f = places["seat_05F"].regions["is_on"].pose.translation_m
    on_next = places["seat_06A"].regions["is_on"].pose.translation_m
    assert on_a[1] > 0 > on_f[1], "A is on +Y, F on -Y"
    assert on_a[0] - on_next[0] == pytest.approx(0.79), "seat pitch along X, row 01 at the front"
    below = places["seat_06A"].regions["is_below"]
    assert below.pose.translation_m[2] == 0.0
    assert 0.2 <= below.size_m[2] <= 0.3, "under-seat clearance"
    # The place under seat 06A's neighbour in front lies below seat 05A's cushion.
    assert abs(below.pose.translation_m[0] - on_a[0]) < 0.1
    def fits(cls: str) -> bool:  # in some axis-aligned orientation
        return bool(np.all(np.sort(catalog[cls].size_m) <= np.sort(below.size_m)))

    assert not fits("trolley_suitcase"), "a trolley case cannot fit under a seat"
    assert fits("small_suitcase") and fits("backpack") and fits("laptop_bag")
    # Region frames: -Y points to the front of the cabin (+X), +X to the left (+Y).
    for name, place in places.items():
        for region in place.regions.values():
            rotation = region.pose.rotation
            np.testing.assert_allclose(rotation @ [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], atol=1e-12, err_msg=name)
            np.testing.assert_allclose(rotation @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], atol=1e-12, err_msg=name)


# --- USD --------------------------------------------------------------------------------------

@pytest.mark.usd
def test_every_asset_follows_the_conventions():
    from pxr import Usd, UsdGeom, UsdShade

    files = _usd_files()
    assert len(files) >= 24
    for path in files:
        stage = Usd.Stage.Open(str(path))
        assert UsdGeom.GetStageUpAxis(stage) == "Z", path
        assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0, path
        root = stage.GetDefaultPrim()
        assert root, path
        assert Usd.ModelAPI(root).GetKind() in ("component", "assembly"), path
        meshes = 0
        for prim in stage.Traverse():
            if prim.IsA(UsdGeom.Gprim):
                assert prim.IsA(UsdGeom.Mesh), f"{path}:{prim.GetPath()} is a {prim.GetTypeName()}"
                mesh = UsdGeom.Mesh(prim)
                points = np.array(mesh.GetPointsAttr().Get())
                extent = np.array(mesh.GetExtentAttr().Get())
                np.testing.assert_allclose(extent, [points.min(0), points.max(0)], atol=1e-6)
                material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
                assert material, f"{path}:{prim.GetPath()} has no material"
                shader = material.ComputeSurfaceSource()[0]
                assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
                meshes += 1
        assert meshes > 0, path


@pytest.mark.usd
def test_every_asset_passes_usd_validation():
    # UsdUtils.ComplianceChecker is gone from usd-core 26; its rules live on as the
    # UsdValidation validators that usdchecker runs.
    from pxr import Usd, UsdValidation

    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    for path in _usd_files():
        errors = [e for e in context.Validate(Usd.Stage.Open(str(path)))
                  if e.GetType() == UsdValidation.ValidationErrorType.Error]
        assert errors == [], f"{path}: " + "; ".join(e.GetMessage() for e in errors)


@pytest.mark.usd
def test_catalog_extents_match_usd_bounds_of_default_variants(catalog):
    from pxr import Usd

    from usdscene.assetgen.usd_write import bounds_of_stage

    for name in catalog.classes():
        entry = catalog[name]
        stage = Usd.Stage.Open(str(entry.usd_path))
        lo, hi = bounds_of_stage(stage, variants=entry.default_variants)
        np.testing.assert_allclose(entry.extent_min_m, lo, atol=2e-4, err_msg=name)
        np.testing.assert_allclose(entry.extent_max_m, hi, atol=2e-4, err_msg=name)


@pytest.mark.usd
def test_catalog_places_equal_usd_place_prims(catalog):
    from pxr import Usd, UsdGeom

    entry = catalog["aircraft_cabin"]
    stage = Usd.Stage.Open(str(entry.usd_path))
    scope = stage.GetDefaultPrim().GetChild(stage_schema.ASSET_PLACES)
    usd_places = {p.GetName(): p for p in scope.GetChildren()}
    assert set(usd_places) == set(entry.places)
    cache = UsdGeom.XformCache()
    for name, place in entry.places.items():
        prim = usd_places[name]
        assert prim.GetAttribute(stage_schema.ATTR_PLACE_KIND).Get() == place.kind
        regions = {r.GetAttribute(stage_schema.ATTR_PLACE_RELATION).Get(): r for r in prim.GetChildren()}
        assert set(regions) == set(place.regions)
        for relation, region in place.regions.items():
            usd_region = regions[relation]
            assert REGION_RELATIONS[usd_region.GetName()] == relation
            world = np.array(cache.GetLocalToWorldTransform(usd_region)).T  # USD is row-vector
            np.testing.assert_allclose(world, region.pose.as_array(), atol=1e-9, err_msg=f"{name}/{relation}")
            size = usd_region.GetAttribute(stage_schema.ATTR_PLACE_SIZE).Get()
            np.testing.assert_allclose(tuple(size), region.size_m, err_msg=f"{name}/{relation}")


@pytest.mark.usd
def test_rebuild_reproduces_committed_files_byte_for_byte(tmp_path):
    from usdscene.assetgen.library import build_library

    written = build_library(tmp_path)
    rebuilt = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    committed = sorted(p.relative_to(ASSETS) for p in ASSETS.rglob("*")
                       if p.is_file() and p.suffix in (".usda", ".json", ".md") and "imported" not in p.parts)
    assert rebuilt == committed
    assert len(written) == len(rebuilt)
    for rel in rebuilt:
        assert (tmp_path / rel).read_bytes() == (ASSETS / rel).read_bytes(), f"{rel} differs from its generator"


@pytest.mark.usd
def test_variants_and_colour_override_compose(tmp_path, catalog):
    """A variant picks its colour; a stronger opinion on the documented shader input wins."""
    from pxr import Gf, Sdf, Usd

    stage = Usd.Stage.CreateInMemory()
    colour_attr = f"{stage_schema.ASSET_COLOR_SHADER}.{stage_schema.ATTR_ASSET_COLOR}"
    looks = {}
    for name, variant in (("a", "navy"), ("b", "red")):
        prim = stage.DefinePrim(f"/World/{name}", "Xform")
        prim.GetReferences().AddReference(str(catalog["backpack"].usd_path))
        prim.GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE).SetVariantSelection(variant)
        looks[name] = stage.GetAttributeAtPath(f"/World/{name}/{colour_attr}")
    assert tuple(looks["a"].Get()) != tuple(looks["b"].Get())
    override = stage.OverridePrim(f"/World/a/{stage_schema.ASSET_COLOR_SHADER}")
    override.CreateAttribute(stage_schema.ATTR_ASSET_COLOR, Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.9, 0.7, 0.1))
    assert tuple(looks["a"].Get()) == pytest.approx((0.9, 0.7, 0.1))
    # Shape variants change geometry: the open laptop is taller than the closed one.
    laptop = catalog["laptop"].usd_path
    from usdscene.assetgen.usd_write import bounds_of_stage

    closed = bounds_of_stage(Usd.Stage.Open(str(laptop)), variants={"appearance": "closed_silver"})[1][2]
    opened = bounds_of_stage(Usd.Stage.Open(str(laptop)), variants={"appearance": "open_silver"})[1][2]
    assert opened > 0.15 > 0.03 > closed


@pytest.mark.usd
def test_triangle_budgets():
    from pxr import Usd, UsdGeom

    def triangles(stage, root) -> int:
        total = 0
        for prim in Usd.PrimRange(root):
            if prim.IsA(UsdGeom.Mesh):
                total += int(np.sum(np.array(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get()) - 2))
        return total

    cabin = Usd.Stage.Open(str(ASSETS / "environments" / "aircraft_cabin.usda"))
    seat = triangles(cabin, cabin.GetPrimAtPath("/AircraftCabin/Seats/Seat_01A"))
    assert 1000 <= seat <= 3000
    for name in ("passenger", "person"):  # one topology for every body and pose
        people = Usd.Stage.Open(str(ASSETS / "people" / f"{name}.usda"))
        pose_set = people.GetDefaultPrim().GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_POSE)
        for pose in pose_set.GetVariantNames():
            pose_set.SetVariantSelection(pose)
            assert 2000 <= triangles(people, people.GetDefaultPrim()) <= 6000, pose
    for path in sorted((ASSETS / "objects").glob("*.usda")):
        stage = Usd.Stage.Open(str(path))
        vset = stage.GetDefaultPrim().GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE)
        for variant in vset.GetVariantNames():
            vset.SetVariantSelection(variant)
            assert 12 <= triangles(stage, stage.GetDefaultPrim()) <= 2000, f"{path.name} {variant}"


def test_assets_list_prints_every_class(capsys):
    from usdscene.cli import main

    assert main(["assets", "list"]) == 0
    out = capsys.readouterr().out
    for name in ("aircraft_cabin", "trolley_suitcase", "passenger", "headphones"):
        assert name in out


@pytest.mark.usd
def test_assets_build_command_takes_the_row_count(tmp_path, capsys):
    from usdscene.cli import main

    assert main(["assets", "build", "--out", str(tmp_path), "--rows", "3"]) == 0
    small = load_catalog([tmp_path], include_default=False)
    places = small["aircraft_cabin"].places
    assert sorted(n for n in places if n.startswith("seat_")) == [f"seat_{r:02d}{c}" for r in (1, 2, 3) for c in "ABCDEF"]
    assert "bin_03R" in places and "aisle_04" not in places
    assert len(small.classes("object")) >= 22
    assert main(["assets", "build", "--out", str(tmp_path / "x"), "--rows", "0"]) == 1
    assert "rows 0" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
