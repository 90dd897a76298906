"""The shipped assets import into Blender (bpy) with their materials, variant colours and the
documented colour override."""

from __future__ import annotations

from pathlib import Path

import pytest

from usdscene.document import stage_schema
from usdscene.scene.catalog import load_catalog

pytestmark = [pytest.mark.usd, pytest.mark.blender]

OVERRIDE = (0.9, 0.7, 0.1)
PASSENGER_BODY = "m_35_192_average_tone1"


def _stage(folder: Path) -> Path:
    from pxr import Gf, Sdf, Usd, UsdGeom

    catalog = load_catalog()
    stage = Usd.Stage.CreateNew(str(folder / "scene.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    env = UsdGeom.Xform.Define(stage, stage_schema.ENVIRONMENT).GetPrim()
    env.GetReferences().AddReference(str(catalog["aircraft_cabin"].usd_path))

    def add(name: str, cls: str, variants: dict[str, str]) -> Usd.Prim:
        prim = UsdGeom.Xform.Define(stage, f"/World/Objects/{name}").GetPrim()
        prim.GetReferences().AddReference(str(catalog[cls].usd_path))
        for key, value in variants.items():
            prim.GetVariantSets().GetVariantSet(key).SetVariantSelection(value)
        return prim

    add("pax", "passenger", {"pose": "reading", "appearance": PASSENGER_BODY})
    add("bag", "backpack", {"appearance": "red"})
    recoloured = add("case", "trolley_suitcase", {"appearance": "black"})
    shader = stage.OverridePrim(f"{recoloured.GetPath()}/{stage_schema.ASSET_COLOR_SHADER}")
    shader.CreateAttribute(stage_schema.ATTR_ASSET_COLOR, Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*OVERRIDE))
    stage.GetRootLayer().Save()
    return folder / "scene.usda"


def _base_colour(obj) -> tuple[float, float, float]:
    material = obj.material_slots[0].material
    bsdf = next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    return tuple(round(v, 3) for v in bsdf.inputs["Base Color"].default_value[:3])


def _slot_colour(slot) -> tuple[float, float, float]:
    bsdf = next(n for n in slot.material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    return tuple(round(v, 3) for v in bsdf.inputs["Base Color"].default_value[:3])


def _mesh_under(objects, ancestor: str, name_prefix: str):
    for obj in objects:
        if obj.type != "MESH" or not obj.name.startswith(name_prefix):
            continue
        parent = obj.parent
        while parent is not None:
            if parent.name == ancestor:
                return obj
            parent = parent.parent
    raise AssertionError(f"no mesh {name_prefix}* under {ancestor}")


def test_cabin_and_objects_import_with_materials(tmp_path):
    import bpy

    from usdscene.assetgen.objects import OBJECT_CLASSES
    from usdscene.assetgen.people import SKIN_TONES, family

    scene = _stage(tmp_path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.wm.usd_import(filepath=str(scene))
    assert result == {"FINISHED"}
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    # 120 seats x 5 meshes, the shell, and the three objects.
    assert len(meshes) > 600
    assert all(len(o.material_slots) >= 1 and o.material_slots[0].material is not None for o in meshes)
    # Places are guides: pxr reads them, Blender's importer leaves them out.
    assert not any(o.name.startswith(("seat_", "bin_", "aisle_")) for o in bpy.data.objects)
    names = {m.name.split(".")[0] for m in bpy.data.materials}
    assert {"SeatFabric", "Carpet", "Sidewall", "BinDoor", "Body", "Skin"} <= names
    # The passenger is one mesh whose face subsets bind the clothing, skin and hair materials.
    body = next(b for b in family() if b.name == PASSENGER_BODY)
    pax = _mesh_under(meshes, "pax", "Body")
    slots = {slot.material.name.split(".")[0]: slot for slot in pax.material_slots}
    assert {"Body", "Bottom", "Shoes", "Skin", "Hair"} <= set(slots)
    assert _slot_colour(slots["Body"]) == pytest.approx(body.top, abs=1e-3)
    assert _slot_colour(slots["Skin"]) == pytest.approx(SKIN_TONES[body.skin], abs=1e-3)
    used = {pax.material_slots[p.material_index].material.name.split(".")[0] for p in pax.data.polygons}
    assert used == {"Body", "Bottom", "Shoes", "Skin", "Hair"}
    red = next(v for v in next(c for c in OBJECT_CLASSES if c.name == "backpack").variants if v.name == "red")
    assert _base_colour(_mesh_under(meshes, "bag", "Body")) == pytest.approx(red.colors["Body"], abs=1e-3)
    assert _base_colour(_mesh_under(meshes, "case", "Body")) == pytest.approx(OVERRIDE, abs=1e-3)
