"""Build the whole procedural asset library and its ``catalog.json``.

``build_library(folder)`` writes every asset below ``folder`` (``environments/``,
``objects/``; ``people/`` is baked separately by ``usdscene.assetgen.people.bake_people`` and
copied from the shipped library when missing) and the catalog, byte-identically for the same code: files are
authored in a fixed order from sorted inputs and written as ``.usda`` text.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Mapping

import numpy as np
from pxr import Kind, UsdGeom

from usdscene.document import stage_schema
from usdscene.assetgen import mesh as m
from usdscene.assetgen.cabin import CabinConfig, build_cabin, describe
from usdscene.assetgen.objects import BODY_ROUGHNESS, OBJECT_CLASSES, SHARED_MATERIALS, ObjectClass
from usdscene.assetgen.usd_write import (MaterialSpec, bounds_of_stage, define_material, define_mesh,
                                         in_variant, new_asset_stage, save_stage, set_material_color)
from usdscene.scene.catalog import CATALOG_FILE, AssetEntry, entry_to_json
from usdscene.files import write_json_atomic

log = logging.getLogger(__name__)

CATALOG_FORMAT = "usdscene-catalog"
CATALOG_VERSION = 1
EXTENT_DECIMALS = 4


def _rounded_extent(lo: np.ndarray, hi: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
    return (tuple(round(float(v), EXTENT_DECIMALS) + 0.0 for v in lo),
            tuple(round(float(v), EXTENT_DECIMALS) + 0.0 for v in hi))


def _centre_on_bottom(parts: Mapping[str, list[m.MeshData]]) -> dict[str, m.MeshData]:
    """Merge each material's meshes, turn the front to -Y and move all so the origin is the
    bottom-face centre."""
    # Builders model the front towards +X; assets face -Y (Blender's front view, the
    # placement convention), so turn everything -90° about Z first.
    turn = m.rotation_z(-90.0)
    merged = {name: m.merge(meshes).transformed(turn) for name, meshes in parts.items()}
    lo = np.min([mesh.points.min(axis=0) for mesh in merged.values()], axis=0)
    hi = np.max([mesh.points.max(axis=0) for mesh in merged.values()], axis=0)
    offset = [-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]]
    return {name: mesh.translated(offset) for name, mesh in merged.items()}


def write_object_asset(cls: ObjectClass, folder: Path) -> AssetEntry:
    """Author one object class as ``folder/objects/<class>.usda``; returns its catalog entry.

    The ``appearance`` variant set holds colour opinions on the materials and, for classes
    whose variants change shape, the geometry itself.
    """
    stage, root = new_asset_stage(stage_schema.prim_name(cls.name), Kind.Tokens.component)
    root_path = str(root.GetPath())
    looks = f"{root_path}/{stage_schema.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    default = cls.variants[0]
    shapes = {v.name: _centre_on_bottom(cls.build({**cls.defaults, **v.params})) for v in cls.variants}
    used = sorted({name for parts in shapes.values() for name in parts} - {stage_schema.ASSET_MAIN_MATERIAL})
    varied = {name for v in cls.variants for name in v.colors}
    materials = {stage_schema.ASSET_MAIN_MATERIAL: define_material(
        stage, f"{looks}/{stage_schema.ASSET_MAIN_MATERIAL}",
        MaterialSpec(default.colors[stage_schema.ASSET_MAIN_MATERIAL], roughness=BODY_ROUGHNESS),
        color_from_variants=True)}
    for name in used:
        materials[name] = define_material(stage, f"{looks}/{name}", SHARED_MATERIALS[name],
                                          color_from_variants=name in varied)
    geom = f"{root_path}/Geom"
    UsdGeom.Xform.Define(stage, geom)
    shared_shape = all(dict(v.params) == dict(default.params) for v in cls.variants)
    if shared_shape:
        for name, mesh in sorted(shapes[default.name].items()):
            define_mesh(stage, f"{geom}/{name}", mesh, materials[name])
    for variant in cls.variants:
        with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, variant.name):
            for mat_name, color in sorted(variant.colors.items()):
                set_material_color(stage, f"{looks}/{mat_name}", color)
            if not shared_shape:
                for name, mesh in sorted(shapes[variant.name].items()):
                    define_mesh(stage, f"{geom}/{name}", mesh, materials[name])
    # The catalog extent is the default variant's: shape variants may be larger or smaller
    # (every mesh's own extent is authored in the USD for per-variant checks).
    root.GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE).SetVariantSelection(default.name)
    lo, hi = _rounded_extent(*bounds_of_stage(stage))
    path = folder / "objects" / f"{cls.name}.usda"
    save_stage(stage, path)
    return AssetEntry(
        class_name=cls.name, kind="object", usd_path=path,
        description=(f"{cls.description} Origin at the bottom-face centre, front towards -Y. Recolour: "
                     f"{stage_schema.ASSET_COLOR_SHADER}.{stage_schema.ATTR_ASSET_COLOR}."),
        variants={stage_schema.VARIANT_SET_APPEARANCE: tuple(v.name for v in cls.variants)},
        default_variants={stage_schema.VARIANT_SET_APPEARANCE: default.name},
        extent_min_m=lo, extent_max_m=hi, relations=cls.relations,  # type: ignore[arg-type]
        orientations=UPRIGHT_OBJECTS.get(cls.name, "any"))


UPRIGHT_OBJECTS = {"coffee_cup": "upright_turned"}
"""Orientation rules of the shipped object classes that may not be laid on a side (a cup
spills); luggage keeps ``any``: people lay bags, even wheeled cases, into bins and under seats."""


def write_cabin_asset(folder: Path, config: CabinConfig = CabinConfig()) -> AssetEntry:
    """Author ``folder/environments/aircraft_cabin.usda``; returns its catalog entry."""
    stage, places = build_cabin(config)
    lo, hi = bounds_of_stage(stage)
    path = folder / "environments" / "aircraft_cabin.usda"
    save_stage(stage, path)
    lo_r, hi_r = _rounded_extent(lo, hi)
    return AssetEntry(
        class_name="aircraft_cabin", kind="environment", usd_path=path, description=describe(config),
        variants={stage_schema.VARIANT_SET_CONFIGURATION: ("bins_open", "bins_closed")},
        default_variants={stage_schema.VARIANT_SET_CONFIGURATION: "bins_open"},
        extent_min_m=lo_r, extent_max_m=hi_r, relations=(), places=places)  # type: ignore[arg-type]


def write_catalog(folder: Path, entries: list[AssetEntry]) -> Path:
    """Write ``folder/catalog.json`` (classes sorted by name) atomically.

    Classes a user registered in this folder with ``usdscene assets add`` (files under
    ``imported/``) are kept, so rebuilding the library does not drop them.
    """
    classes = {e.class_name: entry_to_json(e, folder) for e in entries}
    existing = folder / CATALOG_FILE
    if existing.exists():
        try:
            old = json.loads(existing.read_text(encoding="utf-8")).get("classes", {})
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
            old = {}
        for name, raw in old.items():
            if name not in classes and isinstance(raw, dict) and str(raw.get("usd", "")).startswith("imported/"):
                classes[name] = raw
                log.info("kept imported class %s", name)
    data = {"format": CATALOG_FORMAT, "version": CATALOG_VERSION, "classes": dict(sorted(classes.items()))}
    return write_json_atomic(folder / CATALOG_FILE, data)


def build_library(folder: str | Path, config: CabinConfig = CabinConfig()) -> list[Path]:
    """Generate every procedural asset and the catalog into ``folder``.

    Returns:
        The written files, catalog last.
    """
    from usdscene.assetgen.people import baked_people_entries

    root = Path(folder)
    entries = [write_cabin_asset(root, config)]
    log.info("wrote aircraft_cabin")
    for cls in sorted(OBJECT_CLASSES, key=lambda c: c.name):
        entries.append(write_object_asset(cls, root))
        log.info("wrote %s", cls.name)
    people, people_files = baked_people_entries(root)
    entries.extend(people)
    catalog = write_catalog(root, entries)
    return [e.usd_path for e in entries] + people_files + [catalog]
