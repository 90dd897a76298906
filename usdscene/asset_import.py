"""Bring your own asset: convert a mesh file (OBJ, GLB/glTF, PLY, STL) or reference a USD file
and register it as an asset class in a catalog folder.

Mesh files are read with trimesh, rotated to Z up (``up_axis="Y"`` rotates +90° about X),
scaled to metres (``unit_scale_m`` = metres per file unit), and for objects moved so that the
origin is the centre of the bottom face. They are written as ``<catalog>/imported/<class>.usda``
following the library's conventions (one ``UsdGeom.Mesh`` with extent and normals, a ``Body``
UsdPreviewSurface material whose colour a scene can override, an ``appearance`` variant set).

USD files are referenced, not copied: ``<catalog>/imported/<class>.usda`` is a small wrapper
whose default prim references the file's default prim through a transform that applies the
file's own ``upAxis``/``metersPerUnit`` (or the given overrides) and the origin rule.

Every check happens before anything is written; the USD file and then the catalog are written
atomically, so a failed ``add`` leaves the catalog byte-identical.
"""

from __future__ import annotations

import json
import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from usdscene.catalog import ASSET_KINDS, CATALOG_FILE, AssetEntry, _entry_from_json, entry_to_json
from usdscene.errors import AssetError, OutputError
from usdscene.files import dumps_json, resolve_inside, write_text_atomic

log = logging.getLogger(__name__)

MESH_FORMATS = {".obj": "obj", ".glb": "glb", ".gltf": "gltf", ".ply": "ply", ".stl": "stl"}
USD_FORMATS = (".usd", ".usda", ".usdc", ".usdz")
# Conventional up axis of each mesh format when the user does not say: glTF is Y up by its
# specification and most OBJ exporters write Y up; STL and PLY come from CAD/scanners (Z up).
DEFAULT_UP_AXIS = {"obj": "Y", "glb": "Y", "gltf": "Y", "ply": "Z", "stl": "Z"}
DEFAULT_RELATIONS = {"object": ("is_on", "is_below", "is_in", "is_in_front_of"),
                     "passenger": ("is_on",), "environment": ()}
IMPORTED_FOLDER = "imported"
_CLASS_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class ImportOptions:
    """How to read a user's file.

    Attributes:
        kind: catalog kind (``object``, ``passenger`` or ``environment``).
        up_axis: ``"Y"`` or ``"Z"``; None = the format's convention (USD: the file's upAxis).
        unit_scale_m: metres per file unit; None = 1 (USD: the file's metersPerUnit).
        description: catalog description.
        replace: allow replacing a class that the catalog already has.
    """

    kind: str = "object"
    up_axis: str | None = None
    unit_scale_m: float | None = None
    description: str = ""
    replace: bool = False


def up_axis_rotation(up_axis: str) -> np.ndarray:
    """(3, 3) rotation taking a ``up_axis``-up frame to Z up (Y up: +90° about X)."""
    if up_axis == "Z":
        return np.eye(3)
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _check_inputs(source: Path, class_name: str, catalog_dir: Path, options: ImportOptions,
                  allowed_roots: Sequence[Path]) -> tuple[Path, dict]:
    """Validate everything that does not need reading the asset; returns the resolved source
    and the current catalog data (``{}`` for a new catalog)."""
    if not _CLASS_NAME.match(class_name):
        raise AssetError(f"class name {class_name!r} must be lower_snake_case (a-z, 0-9, _), "
                         "starting with a letter", where="--class")
    if options.kind not in ASSET_KINDS:
        raise AssetError(f"kind {options.kind!r} is not one of {ASSET_KINDS}", where="--kind")
    if options.up_axis not in (None, "Y", "Z"):
        raise AssetError(f"up axis {options.up_axis!r} must be 'Y' or 'Z'", where="--up-axis")
    if options.unit_scale_m is not None and not (np.isfinite(options.unit_scale_m) and options.unit_scale_m > 0):
        raise AssetError(f"unit scale {options.unit_scale_m!r} must be a positive number of metres per unit",
                         where="--unit-scale")
    resolved = None
    for root in allowed_roots:
        try:
            resolved = resolve_inside(root, source, what="asset file")
            break
        except OutputError:
            continue
    if resolved is None:
        roots = ", ".join(repr(str(Path(r).resolve())) for r in allowed_roots)
        raise AssetError(f"asset file {str(source)!r} is outside the allowed folders ({roots}); "
                         "copy it into the catalog folder or the working folder", where=str(source))
    if not resolved.is_file():
        raise AssetError(f"asset file {str(source)!r} does not exist or is not a file", where=str(source))
    suffix = resolved.suffix.lower()
    if suffix not in MESH_FORMATS and suffix not in USD_FORMATS:
        known = ", ".join(sorted(MESH_FORMATS) + list(USD_FORMATS))
        raise AssetError(f"unknown asset format {suffix or '(no extension)'!r}; expected one of {known}",
                         where=str(source))
    catalog_path = catalog_dir / CATALOG_FILE
    data: dict = {}
    if catalog_path.exists():
        try:
            data = json.loads(catalog_path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise AssetError(f"cannot read asset catalog: {exc}", where=str(catalog_path)) from exc
        if not isinstance(data, dict) or not isinstance(data.get("classes"), dict):
            raise AssetError("expected an object with a 'classes' object", where=str(catalog_path))
        if class_name in data["classes"] and not options.replace:
            raise AssetError(f"class {class_name!r} already exists in this catalog (use --replace to overwrite)",
                             where=f"{catalog_path}:classes.{class_name}")
    return resolved, data


def _load_mesh(path: Path):
    """The file's geometry as one trimesh.Trimesh (scene transforms applied)."""
    import trimesh

    try:
        loaded = trimesh.load(str(path), file_type=MESH_FORMATS[path.suffix.lower()], force="scene")
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise AssetError(f"cannot read mesh file: {type(exc).__name__}: {exc}", where=str(path)) from exc
    meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces) > 0]
    if not meshes:
        raise AssetError("the file holds no triangle mesh (empty or unreadable geometry)", where=str(path))
    mesh = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
    if not np.all(np.isfinite(mesh.vertices)):
        raise AssetError("the mesh has non-finite vertex coordinates", where=str(path))
    return mesh


def _main_color(mesh) -> tuple[float, float, float]:
    """The mesh's main colour as linear RGB in [0, 1] (grey when it has none)."""
    try:
        visual = mesh.visual
        rgba = visual.material.main_color if hasattr(visual, "material") else visual.main_color
        srgb = np.asarray(rgba[:3], dtype=np.float64) / 255.0
    except Exception:  # no or exotic visuals: fall back to neutral grey
        return (0.5, 0.5, 0.5)
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return tuple(round(float(c), 4) for c in linear)  # type: ignore[return-value]


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N, 3) area-weighted unit vertex normals of a triangle mesh ((F, 3) int faces)."""
    tri = points[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    normals = np.zeros_like(points)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-20), [0.0, 0.0, 1.0])


def _normalised_points(points: np.ndarray, rotation: np.ndarray, scale: float, kind: str) -> np.ndarray:
    pts = (np.asarray(points, dtype=np.float64) @ rotation.T) * scale
    if kind == "object":
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pts = pts - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]
    return pts


def _write_mesh_asset(mesh, class_name: str, options: ImportOptions, up_axis: str, scale: float,
                      target: Path) -> tuple[np.ndarray, np.ndarray]:
    from pxr import Kind, UsdGeom

    from usdscene import stage_schema
    from usdscene.assetgen.mesh import MeshData
    from usdscene.assetgen.usd_write import (MaterialSpec, define_material, define_mesh, in_variant,
                                             new_asset_stage, set_material_color)

    rotation = up_axis_rotation(up_axis)
    points = _normalised_points(mesh.vertices, rotation, scale, options.kind)
    faces = np.asarray(mesh.faces, dtype=np.int32)
    normals = vertex_normals(points, faces)
    data = MeshData(points, normals, np.full(len(faces), 3, dtype=np.int32), faces.reshape(-1))
    usd_kind = Kind.Tokens.assembly if options.kind == "environment" else Kind.Tokens.component
    stage, root = new_asset_stage(stage_schema.prim_name(class_name), usd_kind)
    looks = f"{root.GetPath()}/{stage_schema.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    color = _main_color(mesh)
    material = define_material(stage, f"{looks}/{stage_schema.ASSET_MAIN_MATERIAL}",
                               MaterialSpec(color), color_from_variants=True)
    UsdGeom.Xform.Define(stage, f"{root.GetPath()}/Geom")
    define_mesh(stage, f"{root.GetPath()}/Geom/Mesh", data, material)
    with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, "original"):
        set_material_color(stage, f"{looks}/{stage_schema.ASSET_MAIN_MATERIAL}", color)
    text = stage.GetRootLayer().ExportToString()
    write_text_atomic(target, text)
    rounded = np.round(points, 4)
    return rounded.min(axis=0), rounded.max(axis=0)


def _write_usd_wrapper(source: Path, class_name: str, options: ImportOptions, target: Path,
                       roots: Sequence[Path]) -> tuple[np.ndarray, np.ndarray]:
    from pxr import Gf, Kind, Sdf, Usd, UsdGeom

    from usdscene import stage_schema
    from usdscene.assetgen.usd_write import bounds_of_stage, new_asset_stage
    from usdscene.containment import usd_dependency_problems

    # Every sublayer, reference and payload stays inside the allowed folders, checked before
    # the stage composes (and reads) them.
    problems = usd_dependency_problems(source, [Path(r).resolve() for r in roots])
    if problems:
        raise AssetError(problems)
    try:
        src_stage = Usd.Stage.Open(str(source))
    except Exception as exc:  # pxr raises Tf.ErrorException for unreadable layers
        raise AssetError(f"cannot open USD file: {exc}", where=str(source)) from exc
    if src_stage is None:
        raise AssetError("cannot open USD file", where=str(source))
    default = src_stage.GetDefaultPrim()
    if not default:
        raise AssetError("the USD file has no defaultPrim; set one so it can be referenced", where=str(source))
    up_axis = options.up_axis or str(UsdGeom.GetStageUpAxis(src_stage))
    scale = options.unit_scale_m if options.unit_scale_m is not None else float(UsdGeom.GetStageMetersPerUnit(src_stage))
    usd_kind = Kind.Tokens.assembly if options.kind == "environment" else Kind.Tokens.component
    stage, root = new_asset_stage(stage_schema.prim_name(class_name), usd_kind)
    holder = UsdGeom.Xform.Define(stage, f"{root.GetPath()}/Source")
    # Bounds are computed with an absolute reference (an in-memory layer has no folder to
    # resolve against); the written file then gets the path relative to its own folder.
    holder.GetPrim().GetReferences().AddReference(Sdf.Reference(str(source)))
    m = np.eye(4)
    m[:3, :3] = up_axis_rotation(up_axis) * scale
    op = holder.AddTransformOp()
    op.Set(Gf.Matrix4d(m.T.tolist()))
    lo, hi = bounds_of_stage(stage)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(hi < lo):
        raise AssetError("the USD file's default prim has no geometry with bounds", where=str(source))
    if options.kind == "object":
        offset = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
        m[:3, 3] = offset
        op.Set(Gf.Matrix4d(m.T.tolist()))
        lo, hi = lo + offset, hi + offset
    # Swap in the relative reference on a detached copy of the layer (no stage recomposes
    # it, so nothing tries to resolve the relative path from an in-memory layer).
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(stage.GetRootLayer().ExportToString())
    relative = os.path.relpath(source, target.parent).replace(os.sep, "/")
    layer.GetPrimAtPath(holder.GetPath()).referenceList.prependedItems = [Sdf.Reference(relative)]
    write_text_atomic(target, layer.ExportToString())
    return np.round(lo, 4), np.round(hi, 4)


def import_asset(source: str | os.PathLike, class_name: str, catalog_dir: str | os.PathLike,
                 options: ImportOptions = ImportOptions(),
                 allowed_roots: Sequence[str | os.PathLike] | None = None) -> AssetEntry:
    """Convert or reference ``source`` and register it as ``class_name`` in ``catalog_dir``.

    Args:
        source: mesh file (OBJ, GLB/glTF, PLY, STL) or USD file (usd/usda/usdc/usdz).
        class_name: lower_snake_case class name (the OpenLABEL object type).
        catalog_dir: folder of the catalog (``catalog.json`` created when missing).
        options: kind, up axis, unit scale, description, replace.
        allowed_roots: folders the source must lie in (default: the working folder and
            ``catalog_dir``); a path escaping them is refused.

    Returns:
        The registered catalog entry (extents in metres, asset frame Z up).

    Raises:
        AssetError: unreadable/empty/unknown file, path outside the allowed folders, bad
            options, or the class already exists (without ``replace``). Nothing is written.
    """
    catalog = Path(catalog_dir).resolve()
    from usdscene.containment import consented_folders

    roots = [Path(r) for r in (allowed_roots if allowed_roots is not None
                               else (Path.cwd(), catalog, *consented_folders()))]
    src = Path(source)
    resolved, data = _check_inputs(src if src.is_absolute() else Path.cwd() / src, class_name, catalog,
                                   options, roots)
    target = catalog / IMPORTED_FOLDER / f"{class_name}.usda"
    suffix = resolved.suffix.lower()
    if suffix in MESH_FORMATS:
        mesh = _load_mesh(resolved)
        up_axis = options.up_axis or DEFAULT_UP_AXIS[MESH_FORMATS[suffix]]
        lo, hi = _write_mesh_asset(mesh, class_name, options, up_axis,
                                   options.unit_scale_m if options.unit_scale_m is not None else 1.0, target)
        fmt = MESH_FORMATS[suffix].upper()
    else:
        lo, hi = _write_usd_wrapper(resolved, class_name, options, target, roots)
        fmt = "USD"
    from usdscene import stage_schema

    variants = {stage_schema.VARIANT_SET_APPEARANCE: ("original",)} if suffix in MESH_FORMATS else {}
    entry = AssetEntry(
        class_name=class_name, kind=options.kind, usd_path=target,
        description=options.description or f"Imported from {resolved.name} ({fmt}).",
        variants=variants,
        default_variants={k: v[0] for k, v in variants.items()},
        extent_min_m=tuple(float(v) + 0.0 for v in lo),  # type: ignore[arg-type]
        extent_max_m=tuple(float(v) + 0.0 for v in hi),  # type: ignore[arg-type]
        relations=DEFAULT_RELATIONS[options.kind])
    register_entry(catalog, entry, data)
    log.info("registered %s (%s) in %s", class_name, fmt, catalog)
    return entry


def register_entry(catalog_dir: Path, entry: AssetEntry, data: dict | None = None) -> Path:
    """Add or replace ``entry`` in ``catalog_dir/catalog.json`` (classes kept sorted), atomically."""
    if not data:
        data = {"format": "usdscene-catalog", "version": 1, "classes": {}}
    classes = dict(data["classes"])
    classes[entry.class_name] = entry_to_json(entry, catalog_dir)
    _entry_from_json(entry.class_name, classes[entry.class_name], catalog_dir)  # round-trip check
    data = {**data, "classes": dict(sorted(classes.items()))}
    return write_text_atomic(catalog_dir / CATALOG_FILE, dumps_json(data))
