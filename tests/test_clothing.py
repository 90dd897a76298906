"""What the people wear: the clothing distributions, their checks, the per-material surface
value, the baked assets' fabrics and the renderer's per-slot materials."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.assetgen import clothing
from usdscene.assetgen.people import family
from usdscene.document.surfaces import SURFACES, surface_slots, surface_slots_value
from usdscene.errors import AssetError

DARK_OR_NEUTRAL = {"black", "dark_grey", "grey", "white", "beige", "navy", "denim_blue", "brown"}


def test_distributions_sum_to_one_and_dark_and_neutral_dominate():
    for field, shares in (("top", clothing.TOP_COLOUR_SHARES), ("bottom", clothing.BOTTOM_COLOUR_SHARES),
                          ("shoe", clothing.SHOE_COLOUR_SHARES)):
        clothing.check_colour_shares(shares, field=field)
        assert sum(v for k, v in shares.items() if k in DARK_OR_NEUTRAL) >= 0.75
        assert max(shares, key=shares.get) == "black"
    clothing.check_fabric_shares(clothing.TOP_FABRIC_SHARES, field="top")
    clothing.check_fabric_shares(clothing.BOTTOM_FABRIC_SHARES, field="bottom")
    # Dark means dark: every dark or neutral colour but white and beige reflects under 20 %.
    for name in DARK_OR_NEUTRAL - {"white", "beige"}:
        assert max(clothing.CLOTH_COLOURS[name]) < 0.2


def test_a_distribution_that_does_not_sum_to_one_names_the_field_and_the_sum():
    with pytest.raises(AssetError) as err:
        clothing.draw_outfit(np.random.default_rng(0), top_colours={"black": 0.5, "grey": 0.4})
    assert len(err.value.problems) == 1
    assert err.value.problems[0].where == "top_colours" and "0.9" in str(err.value)


def test_unknown_colour_or_fabric_names_the_field_and_value():
    with pytest.raises(AssetError) as err:
        clothing.check_colour_shares({"black": 0.5, "magenta": 0.5}, field="bottom_colours")
    assert "bottom_colours" in str(err.value) and "'magenta'" in str(err.value)
    with pytest.raises(AssetError) as err:
        clothing.draw_outfit(np.random.default_rng(0), bottom_fabrics={"denim": 0.5, "silk": 0.5})
    assert "bottom_fabrics.silk" in str(err.value) and "'silk'" in str(err.value)


def test_draws_follow_the_shares_and_the_seed():
    rng = np.random.default_rng(7)
    outfits = [clothing.draw_outfit(rng) for _ in range(4000)]
    black_tops = sum(o.top_colour == "black" for o in outfits) / len(outfits)
    assert abs(black_tops - clothing.TOP_COLOUR_SHARES["black"]) < 0.03
    assert {o.bottom_fabric for o in outfits} == set(clothing.BOTTOM_FABRIC_SHARES)
    again = [clothing.draw_outfit(np.random.default_rng(7)) for _ in range(1)]
    assert again[0] == outfits[0]


def test_the_family_wears_the_distribution():
    bodies = family()
    colours = set(clothing.CLOTH_COLOURS.values())
    assert all(b.top in colours and b.bottom in colours and b.shoes in colours for b in bodies)
    assert all(b.top_fabric in SURFACES and b.bottom_fabric in SURFACES for b in bodies)
    dark = {clothing.CLOTH_COLOURS[n] for n in DARK_OR_NEUTRAL}
    assert sum(b.top in dark for b in bodies) >= len(bodies) // 2
    assert len({b.top_fabric for b in bodies}) >= 3 and family() == bodies


def test_surface_value_per_material():
    assert surface_slots("asphalt", where="x") == {None: "asphalt"}
    slots = {"Body": "knit", "Bottom": "denim"}
    assert surface_slots(surface_slots_value(slots), where="x") == slots
    with pytest.raises(AssetError, match="'silk'"):
        surface_slots("Body=silk", where="person: usdscene_surface")
    with pytest.raises(AssetError, match="'Body'"):
        surface_slots("Body Bottom=denim", where="person: usdscene_surface")


@pytest.mark.usd
def test_baked_people_carry_their_fabrics_per_appearance():
    from pxr import Usd

    from usdscene.document import stage_schema as ss
    from usdscene.document.surfaces import SURFACE_ATTRIBUTE
    from usdscene.scene.catalog import load_catalog

    specs = {b.name: b for b in family()}
    for class_name in ("person", "passenger"):
        stage = Usd.Stage.Open(str(load_catalog()[class_name].usd_path))
        root = stage.GetDefaultPrim()
        mesh = stage.GetPrimAtPath(f"{root.GetPath()}/Geom/Body")
        appearance = root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE)
        for name in list(specs)[::7]:
            appearance.SetVariantSelection(name)
            value = mesh.GetAttribute(SURFACE_ATTRIBUTE).Get()
            assert surface_slots(value, where=name) == {"Body": specs[name].top_fabric,
                                                        "Bottom": specs[name].bottom_fabric}


@pytest.mark.usd
@pytest.mark.blender
def test_renderer_gives_the_top_and_trousers_their_fabrics_and_leaves_the_skin(tmp_path):
    import bpy
    from pxr import Usd, UsdGeom

    from usdscene.document import stage_schema as ss
    from usdscene.render.blender.surface_nodes import apply_surfaces
    from usdscene.scene.catalog import load_catalog

    bodies = family()[:2]
    stage = Usd.Stage.CreateNew(str(tmp_path / "two.usda"))
    for k, body in enumerate(bodies):
        prim = stage.DefinePrim(f"/World/p{k}", "Xform")
        UsdGeom.Xformable(prim).AddTranslateOp().Set((2.0 * k, 0.0, 0.0))
        prim.GetReferences().AddReference(str(load_catalog()["person"].usd_path))
        prim.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE).SetVariantSelection(body.name)
    stage.Save()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert "FINISHED" in bpy.ops.wm.usd_import(filepath=str(tmp_path / "two.usda"), property_import_mode="USER")
    meshes = sorted((o for o in bpy.data.objects if o.type == "MESH"), key=lambda o: o.matrix_world.translation.x)
    assert len(meshes) == 2
    before = {ob.name: [s.material.name.split(".")[0] for s in ob.material_slots] for ob in meshes}
    assert apply_surfaces(bpy) == 4  # the top and the trousers of each
    for ob, body in zip(meshes, bodies):
        names = dict(zip(before[ob.name], (s.material.name for s in ob.material_slots)))
        assert not any(names[m].startswith("usdscene_surface_") for m in ("Skin", "Hair", "Shoes"))
        assert names["Body"].startswith(f"usdscene_surface_{body.top_fabric}_")
        assert names["Bottom"].startswith(f"usdscene_surface_{body.bottom_fabric}_")
    made = {s.material.name for ob in meshes for s in ob.material_slots if s.material.name.startswith("usdscene_")}
    wanted = {(b.top_fabric, b.top) for b in bodies} | {(b.bottom_fabric, b.bottom) for b in bodies}
    assert len(made) == len(wanted)
