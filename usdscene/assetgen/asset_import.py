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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.scene.catalog import ASSET_KINDS, CATALOG_FILE, DEFAULT_COLOR_SHADER, ORIENTATION_RULES, AssetEntry, _entry_from_json, entry_to_json
from usdscene.errors import AssetError, OutputError, Problem
from usdscene.files import dumps_json, resolve_inside, write_text_atomic
from usdscene.scene.place_discovery import file_to_world, up_axis_rotation

log = logging.getLogger(__name__)

MESH_FORMATS = {".obj": "obj", ".glb": "glb", ".gltf": "gltf", ".ply": "ply", ".stl": "stl"}
USD_FORMATS = (".usd", ".usda", ".usdc", ".usdz")
# Blender projects are exported to USD by a Blender worker process, then imported as USD.
BLEND_FORMAT = ".blend"
# Conventional up axis of each mesh format when the user does not say: glTF is Y up by its
# specification and most OBJ exporters write Y up; STL and PLY come from CAD/scanners (Z up).
DEFAULT_UP_AXIS = {"obj": "Y", "glb": "Y", "gltf": "Y", "ply": "Z", "stl": "Z"}
DEFAULT_RELATIONS = {"object": ("is_on", "is_below", "is_in", "is_in_front_of"),
                     "passenger": ("is_on",), "environment": ()}
IMPORTED_FOLDER = "imported"
FORWARD_AXES = ("-Y", "+Y", "+X", "-X")
"""Where an asset's front may face (after the turn to Z up); the library's convention is -Y."""
# Quarter turns about Z that take each forward axis to -Y.
_FORWARD_YAW_DEG = {"-Y": 0, "+Y": 180, "+X": -90, "-X": 90}


def forward_turn(forward_axis: str) -> np.ndarray:
    """(4, 4) turn about Z taking an asset whose front faces ``forward_axis`` (Z up) to the
    library's convention (front at -Y); exact quarter turns, no float noise."""
    yaw = _FORWARD_YAW_DEG[forward_axis]
    c, s = {0: (1, 0), 90: (0, 1), 180: (-1, 0), -90: (0, -1)}[yaw]
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out
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
        forward_axis: where the file's front faces once Z up (``-Y``, ``+Y``, ``+X``, ``-X``);
            the asset is turned about Z so that it faces -Y, the library's convention.
        orientations: how placement may lay the class (see :data:`usdscene.scene.catalog.ORIENTATION_RULES`).
        color_material: path of a material (or its surface shader) under the file's default
            prim whose ``diffuseColor`` a scene's colour sets (referenced USD files); None = the
            library's ``Looks/Body/Surface`` when the file has it, else the class is not recoloured.
    """

    kind: str = "object"
    up_axis: str | None = None
    unit_scale_m: float | None = None
    description: str = ""
    replace: bool = False
    forward_axis: str = "-Y"
    orientations: str = "upright_turned"
    color_material: str | None = None


PLAUSIBLE_SIZE_M = {"object": (0.02, 25.0), "passenger": (0.3, 3.0), "environment": (2.0, 5000.0)}
"""Largest dimension (metres) an asset of each kind plausibly has; outside it the file's unit
is most likely misread (a car in centimetres read as metres is 467 m long)."""
# Common file units (metres per unit, name), most likely first: metres, then the usual mix-ups,
# centimetres (many DCC tools and the USD default), millimetres (CAD), inches, decimetres,
# feet, kilometres.
_UNITS_M = ((1.0, "metres"), (0.01, "centimetres"), (0.001, "millimetres"), (0.0254, "inches"),
            (0.1, "decimetres"), (0.3048, "feet"), (1000.0, "kilometres"))


def size_warnings(size_m, kind: str, unit_scale_m: float) -> list[str]:
    """Warnings for an asset whose size is implausible for its kind, naming the likely
    ``--unit-scale`` (the most often mixed-up unit that makes the size plausible).

    Args:
        size_m: (3,) size of the asset in metres, as converted.
        kind: catalog kind.
        unit_scale_m: the metres per file unit the conversion used.
    """
    largest = float(np.max(size_m))
    low, high = PLAUSIBLE_SIZE_M[kind]
    if low <= largest <= high or largest <= 0:
        return []
    units = largest / unit_scale_m  # the size in file units
    likely = [(u, name) for u, name in _UNITS_M if low <= units * u <= high and u != unit_scale_m]
    hint = (f": if it is in {likely[0][1]}, give --unit-scale {likely[0][0]:g}" if likely
            else "; check --unit-scale")
    article = "an" if kind[0] in "aeiou" else "a"
    return [f"{article} {kind} {largest:.4g} m across is implausible (expected {low:g} to {high:g} m); the file "
            f"is probably not in the unit assumed ({unit_scale_m:g} m per unit){hint}"]


def _check_inputs(source: Path, class_name: str, catalog_dir: Path, options: ImportOptions,
                  allowed_roots: Sequence[Path]) -> tuple[Path, dict]:
    """Validate everything that does not need reading the asset; returns the resolved source
    and the current catalog data (``{}`` for a new catalog)."""
    if not _CLASS_NAME.match(class_name):
        raise AssetError(f"class name {class_name!r} must be lower_snake_case (a-z, 0-9, _), "
                         "starting with a letter", where="--class")
    if options.kind not in ASSET_KINDS + (PERSON_KIND,):
        raise AssetError(f"kind {options.kind!r} is not one of {ASSET_KINDS + (PERSON_KIND,)}", where="--kind")
    if options.up_axis not in (None, "Y", "Z"):
        raise AssetError(f"up axis {options.up_axis!r} must be 'Y' or 'Z'", where="--up-axis")
    if options.forward_axis not in FORWARD_AXES:
        raise AssetError(f"forward axis {options.forward_axis!r} must be one of {', '.join(FORWARD_AXES)}",
                         where="--forward-axis")
    if options.kind == "environment" and options.forward_axis != "-Y":
        raise AssetError("an environment keeps its own axes (its places are where they are modelled); "
                         "--forward-axis is for objects and passengers", where="--forward-axis")
    if options.orientations not in ORIENTATION_RULES:
        raise AssetError(f"orientation rule {options.orientations!r} must be one of {', '.join(ORIENTATION_RULES)}",
                         where="--orientations")
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
    if suffix not in MESH_FORMATS and suffix not in USD_FORMATS and suffix != BLEND_FORMAT:
        known = ", ".join(sorted(MESH_FORMATS) + list(USD_FORMATS) + [BLEND_FORMAT])
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


def _load_parts(path: Path, discover_places: bool) -> tuple[list, list]:
    """The file's geometry as (node name, trimesh.Trimesh in file-world coordinates) parts,
    and its place boxes (:class:`usdscene.scene.place_discovery.PlaceBox`) when ``discover_places``
    (their geometry is then not part of the asset)."""
    import trimesh

    from usdscene.scene.place_discovery import EMPTY_BOUNDS, PlaceBox, parse_place_name

    fmt = MESH_FORMATS[path.suffix.lower()]
    # OBJ objects (``o``) are nodes of their own only when split; other formats keep nodes.
    extra = {"split_objects": True, "group_material": False} if fmt == "obj" else {}
    try:
        loaded = trimesh.load(str(path), file_type=fmt, force="scene", **extra)
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise AssetError(f"cannot read mesh file: {type(exc).__name__}: {exc}", where=str(path)) from exc
    parts, boxes, problems = [], [], []
    graph = loaded.graph
    for node in sorted(graph.nodes, key=str):
        if node == graph.base_frame:
            continue
        matrix, geom_name = graph[node]
        geom = loaded.geometry.get(geom_name) if geom_name is not None else None
        # OBJ objects become geometries named after the object under a generated node name.
        label = str(geom_name) if fmt == "obj" and geom_name is not None else str(node)
        try:
            named = parse_place_name(label, where=f"{path}:{label}") if discover_places else None
        except AssetError as exc:  # every malformed place name is reported at once
            problems.extend(exc.problems)
            continue
        if named is not None:
            if isinstance(geom, trimesh.Trimesh) and len(geom.vertices):
                lo, hi = geom.vertices.min(axis=0), geom.vertices.max(axis=0)
            else:
                lo, hi = EMPTY_BOUNDS
            boxes.append(PlaceBox(node=label, place=named[0], region=named[1], matrix=np.asarray(matrix),
                                  local_min=np.asarray(lo, float), local_max=np.asarray(hi, float)))
        elif isinstance(geom, trimesh.Trimesh) and len(geom.faces) > 0:
            parts.append((label, geom.copy().apply_transform(matrix)))
    if problems:
        raise AssetError(problems)
    if not parts:
        raise AssetError("the file holds no triangle mesh (empty or unreadable geometry)", where=str(path))
    for label, mesh in parts:
        if not np.all(np.isfinite(mesh.vertices)):
            raise AssetError("the mesh has non-finite vertex coordinates", where=f"{path}:{label}")
    return parts, boxes


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


# Nodes named ``backdrop.<name>`` are scenery for the picture only (ground and buildings to the
# horizon): USD purpose "render", which the renderer draws and the environment's obstacles,
# occluders, mounts and extent leave out (usdscene.scene.stage_geometry.environment_meshes).
BACKDROP_PREFIX = "backdrop."


def _surface_kind(mesh, label: str) -> str:
    """The procedural surface a part's material names (``surface.asphalt``), else ``""``.

    Raises:
        AssetError: a ``surface.`` material of an unknown kind (the part and the value).
    """
    from usdscene.document.surfaces import surface_from_material_name

    material = getattr(getattr(mesh, "visual", None), "material", None)
    name = getattr(material, "name", None)
    return surface_from_material_name(name, where=f"{label}: material") or ""


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N, 3) area-weighted unit vertex normals of a triangle mesh ((F, 3) int faces)."""
    tri = points[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 * area
    normals = np.zeros_like(points)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-20), [0.0, 0.0, 1.0])


def _write_mesh_asset(parts: list, class_name: str, options: ImportOptions, up_axis: str, scale: float,
                      target: Path, places: Mapping | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Write the converted asset; an object is one recolourable mesh, an environment keeps one
    mesh per colour of the file (floor, markings, walls) and gets its ``Places``."""
    import trimesh
    from pxr import Kind, Sdf, UsdGeom

    from usdscene.document import stage_schema
    from usdscene.document.surfaces import SURFACE_ATTRIBUTE
    from usdscene.assetgen.mesh import MeshData
    from usdscene.assetgen.usd_write import (MaterialSpec, author_places, define_material, define_mesh,
                                             in_variant, new_asset_stage, set_material_color)

    rotation = forward_turn(options.forward_axis)[:3, :3] @ up_axis_rotation(up_axis)
    meshes = [mesh for _, mesh in parts]
    if options.kind == "environment":
        # One mesh per (backdrop, procedural surface, colour): a ``surface.<kind>`` material
        # keeps its kind, ``backdrop.*`` nodes stay apart (render purpose, below).
        by_look: dict[tuple[bool, str, tuple[float, float, float]], list] = {}
        for label, mesh in parts:
            key = (label.lower().startswith(BACKDROP_PREFIX), _surface_kind(mesh, label), _main_color(mesh))
            by_look.setdefault(key, []).append(mesh)
        # By colour, as before surfaces and backdrops existed: old files keep their bytes.
        ordered = sorted(by_look.items(), key=lambda kv: (kv[0][0], kv[0][2], kv[0][1]))
        groups = [(color, group) for (_, _, color), group in ordered]
        surfaces = [kind for (_, kind, _), _ in ordered]
        backdrops = [backdrop for (backdrop, _, _), _ in ordered]
    else:
        whole = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
        groups = [(_main_color(whole), [whole])]
        surfaces, backdrops = [""], [False]
    usd_kind = Kind.Tokens.assembly if options.kind == "environment" else Kind.Tokens.component
    stage, root = new_asset_stage(stage_schema.prim_name(class_name), usd_kind)
    looks = f"{root.GetPath()}/{stage_schema.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    UsdGeom.Xform.Define(stage, f"{root.GetPath()}/Geom")
    all_points, flat = [], []
    for index, (color, group) in enumerate(groups):
        mesh = trimesh.util.concatenate(group) if len(group) > 1 else group[0]
        if options.kind == "environment":
            # Scenery is walls, pillars and kerbs: hard edges. Shared corner vertices would
            # smooth a box into a cylinder, so every face gets its own vertices (flat normals).
            mesh = trimesh.Trimesh(mesh.vertices[mesh.faces].reshape(-1, 3),
                                   np.arange(3 * len(mesh.faces)).reshape(-1, 3), process=False)
        points = (np.asarray(mesh.vertices, dtype=np.float64) @ rotation.T) * scale  # Z up, metres
        all_points.append(points)
        flat.append(mesh)
    # The extent is the environment's own: a backdrop to the horizon would make it kilometres.
    measured = [p for p, backdrop in zip(all_points, backdrops) if not backdrop] or all_points
    lo_all = np.min([p.min(axis=0) for p in measured], axis=0)
    hi_all = np.max([p.max(axis=0) for p in measured], axis=0)
    offset = np.zeros(3)
    if options.kind == "object":
        offset = -np.array([(lo_all[0] + hi_all[0]) / 2, (lo_all[1] + hi_all[1]) / 2, lo_all[2]])
    for index, ((color, group), points) in enumerate(zip(groups, all_points)):
        mesh = flat[index]
        points = points + offset
        faces = np.asarray(mesh.faces, dtype=np.int32)
        data = MeshData(points, vertex_normals(points, faces), np.full(len(faces), 3, dtype=np.int32),
                        faces.reshape(-1))
        # The first (for objects: only) material is the recolourable "Body".
        name = stage_schema.ASSET_MAIN_MATERIAL if index == 0 else f"Surface_{index:02d}"
        material = define_material(stage, f"{looks}/{name}", MaterialSpec(color), color_from_variants=index == 0)
        usd_mesh = define_mesh(stage, f"{root.GetPath()}/Geom/{'Mesh' if index == 0 else f'Mesh_{index:02d}'}",
                               data, material)
        if surfaces[index]:
            usd_mesh.GetPrim().CreateAttribute(SURFACE_ATTRIBUTE, Sdf.ValueTypeNames.String, custom=True).Set(
                surfaces[index])
        if backdrops[index]:
            usd_mesh.CreatePurposeAttr(UsdGeom.Tokens.render)
    with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, "original"):
        set_material_color(stage, f"{looks}/{stage_schema.ASSET_MAIN_MATERIAL}", groups[0][0])
    if places:
        author_places(stage, str(root.GetPath()), places)
    text = stage.GetRootLayer().ExportToString()
    write_text_atomic(target, text)
    return np.round(lo_all + offset, 4), np.round(hi_all + offset, 4)


@dataclass(frozen=True)
class _Written:
    """What writing an asset produced: bounds (metres, asset frame), places, variants."""

    lo: np.ndarray
    hi: np.ndarray
    places: Mapping = field(default_factory=dict)
    variants: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    default_variants: Mapping[str, str] = field(default_factory=dict)
    variant_extents: Mapping[str, Mapping[str, tuple]] = field(default_factory=dict)
    color_shader: str = DEFAULT_COLOR_SHADER
    unit_scale_m: float = 1.0


def _bottom_centre_offset(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(3,) translation that puts the origin at the centre of the bottom face of [lo, hi]."""
    return np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])


def _per_variant_origins(stage, root, holder, op, m: np.ndarray, variants: Mapping, defaults: Mapping,
                         source: Path) -> dict:
    """Give every ``appearance`` variant its own origin when the variants differ in size or
    offset (a van is taller than a sedan; a file's variants rarely share one bottom centre).

    Each variant then authors the holder's transform with its own bottom-centre offset (a
    variant opinion loses to a direct one, so the direct value is cleared), and the catalog
    records each variant's extent. Variants that all share the default's bounds keep the one
    direct transform and record nothing.

    Returns:
        ``{"appearance": {variant: ((3,) min, (3,) max)}}`` in metres, or ``{}``.
    """
    from pxr import Gf

    from usdscene.document import stage_schema
    from usdscene.assetgen.usd_write import bounds_of_stage, in_variant

    names = variants.get(stage_schema.VARIANT_SET_APPEARANCE, ())
    if len(names) < 2:
        return {}
    raw = m.copy()
    raw[:3, 3] = 0.0
    op.Set(Gf.Matrix4d(raw.T.tolist()))
    vset = root.GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE)
    bounds = {}
    for name in names:
        vset.SetVariantSelection(name)
        lo, hi = bounds_of_stage(stage)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(hi < lo):
            raise AssetError(f"variant {name!r} of the USD file's default prim has no geometry with bounds",
                             where=str(source))
        bounds[name] = (lo, hi)
    vset.SetVariantSelection(defaults[stage_schema.VARIANT_SET_APPEARANCE])
    first = bounds[names[0]]
    if all(np.allclose(b[0], first[0], atol=1e-6) and np.allclose(b[1], first[1], atol=1e-6)
           for b in bounds.values()):
        op.Set(Gf.Matrix4d(m.T.tolist()))
        return {}
    op.GetAttr().Clear()
    extents = {}
    for name in names:
        lo, hi = bounds[name]
        offset = _bottom_centre_offset(lo, hi)
        placed = raw.copy()
        placed[:3, 3] = offset
        with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, name):
            op.Set(Gf.Matrix4d(placed.T.tolist()))
        extents[name] = (tuple(float(v) + 0.0 for v in np.round(lo + offset, 4)),
                         tuple(float(v) + 0.0 for v in np.round(hi + offset, 4)))
    vset.SetVariantSelection(defaults[stage_schema.VARIANT_SET_APPEARANCE])
    return {stage_schema.VARIANT_SET_APPEARANCE: extents}


MAX_LIFTED_VARIANTS = 512
"""Most combinations of a USD file's variant sets that become ``appearance`` variants."""


def _usd_place_boxes(stage, default, source: Path) -> list:
    """Place boxes under the default prim of a USD file (file units, matrices relative to the
    default prim's parent, which is what a reference brings in)."""
    from pxr import Usd, UsdGeom

    from usdscene.scene.place_discovery import EMPTY_BOUNDS, PLACE_PROPERTY, PlaceBox, parse_place_name

    xforms = UsdGeom.XformCache()
    bboxes = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render,
                                                         UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide],
                               useExtentsHint=False)
    parent = np.array(xforms.GetLocalToWorldTransform(default.GetParent())).T if default.GetParent() else np.eye(4)
    boxes, problems = [], []
    prims = iter(Usd.PrimRange(default))
    for prim in prims:
        value = None
        for attr_name in (f"userProperties:{PLACE_PROPERTY}", "usdscene:place"):
            attr = prim.GetAttribute(attr_name)
            if attr and attr.HasAuthoredValue():
                value = attr.Get()
        try:
            named = parse_place_name(prim.GetName(), value, where=f"{source}:{prim.GetPath()}")
        except AssetError as exc:  # every malformed place marker is reported at once
            problems.extend(exc.problems)
            continue
        if named is None:
            continue
        prims.PruneChildren()  # a box's own children belong to the box
        box = bboxes.ComputeUntransformedBound(prim).ComputeAlignedRange()
        if box.IsEmpty():
            lo, hi = EMPTY_BOUNDS
        else:
            lo, hi = np.array(box.GetMin(), float), np.array(box.GetMax(), float)
        world = np.linalg.inv(parent) @ np.array(xforms.GetLocalToWorldTransform(prim)).T
        boxes.append(PlaceBox(node=str(prim.GetPath()), place=named[0], region=named[1], matrix=world,
                              local_min=lo, local_max=hi))
    if problems:
        raise AssetError(problems)
    return boxes


def _lift_variants(src_default, root, holder, source: Path) -> tuple[dict, dict]:
    """Expose the variant sets of the file's default prim as the asset's ``appearance`` set.

    A reference keeps the file's variant sets on the referencing child, where a document cannot
    reach them; the asset root gets one ``appearance`` variant per combination (one set: its
    variant names; several: names joined by ``-`` in the sets' order) that selects it on the
    child, so ``appearance`` and ``random_appearance`` work as for the library's assets.
    """
    import itertools

    from usdscene.document import stage_schema
    from usdscene.assetgen.usd_write import in_variant

    sets = src_default.GetVariantSets()
    names = [n for n in sets.GetNames() if sets.GetVariantSet(n).GetVariantNames()]
    if not names:
        return {}, {}
    choices = [tuple(sets.GetVariantSet(n).GetVariantNames()) for n in names]
    combos = list(itertools.product(*choices))
    if len(combos) > MAX_LIFTED_VARIANTS:
        raise AssetError(f"the default prim's variant sets {names} make {len(combos)} combinations "
                         f"(at most {MAX_LIFTED_VARIANTS} become appearance variants)", where=str(source))
    current = tuple(sets.GetVariantSet(n).GetVariantSelection() or c[0] for n, c in zip(names, choices))
    label = {combo: "-".join(combo) for combo in combos}
    for combo in combos:
        with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, label[combo]):
            for set_name, value in zip(names, combo):
                holder.GetVariantSets().SetSelection(set_name, value)
    root.GetVariantSets().GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE).SetVariantSelection(label[current])
    variants = {stage_schema.VARIANT_SET_APPEARANCE: tuple(label[c] for c in combos)}
    return variants, {stage_schema.VARIANT_SET_APPEARANCE: label[current]}


def _warn_unreachable_variants(default, source: Path) -> list[str]:
    """Warn about variant sets below the default prim: only the default prim's sets become
    ``appearance`` variants, so a document cannot reach these (the kit's ``wheels`` on each
    wheel). Returns ``<prim>:<set>`` for each."""
    from pxr import Usd

    found = []
    for prim in Usd.PrimRange(default):
        if prim == default:
            continue
        sets = prim.GetVariantSets()
        found += [f"{prim.GetPath().MakeRelativePath(default.GetPath())}:{name}" for name in sets.GetNames()
                  if len(sets.GetVariantSet(name).GetVariantNames()) > 1]
    if found:
        shown = ", ".join(found[:6]) + (f" and {len(found) - 6} more" if len(found) > 6 else "")
        log.warning("%s: variant sets below the default prim stay at their selection (documents can only choose "
                    "the default prim's sets): %s", source.name, shown)
    return found


def _color_slot(default, color_material: str | None, source: Path) -> str:
    """The shader (path relative to the file's default prim) whose ``inputs:diffuseColor`` a
    scene's colour sets, or ``""`` when the class cannot be recoloured.

    ``color_material`` names a material (its surface shader is used) or a shader; without it,
    the library's ``Looks/Body/Surface`` is used when the file has one. A colour written
    anywhere else would be recorded in the labels but never rendered.

    Raises:
        AssetError: ``color_material`` is missing, not a material or shader, has no
            ``diffuseColor`` input, or that input is driven by a texture (an authored value
            would not show).
    """
    from pxr import Sdf, UsdShade

    where = f"{source}:{default.GetPath()}"
    if color_material is None:
        shader = UsdShade.Shader(default.GetStage().GetPrimAtPath(default.GetPath().AppendPath(DEFAULT_COLOR_SHADER)))
        if shader and shader.GetInput("diffuseColor"):
            return DEFAULT_COLOR_SHADER
        log.warning("%s has no %s shader: scenes cannot recolour class objects (no colour is recorded); "
                    "name the paint material with --color-material", source.name, DEFAULT_COLOR_SHADER)
        return ""
    relative = color_material.strip("/")
    try:
        path = default.GetPath().AppendPath(relative)
    except Exception:  # Sdf raises on malformed paths
        path = Sdf.Path()
    prim = default.GetStage().GetPrimAtPath(path) if not path.isEmpty else None
    if not prim:
        raise AssetError(f"--color-material {color_material!r}: no prim {relative!r} under the default prim",
                         where=where)
    shader = UsdShade.Shader(prim) if prim.IsA(UsdShade.Shader) else None
    if prim.IsA(UsdShade.Material):
        source_shader = UsdShade.Material(prim).ComputeSurfaceSource()[0]
        shader = source_shader if source_shader else None
    if shader is None:
        raise AssetError(f"--color-material {color_material!r} is neither a material with a surface shader "
                         "nor a shader", where=where)
    color = shader.GetInput("diffuseColor")
    if not color:
        raise AssetError(f"--color-material {color_material!r}: shader {str(shader.GetPath())!r} has no "
                         "diffuseColor input", where=where)
    if color.HasConnectedSource():
        raise AssetError(f"--color-material {color_material!r}: the diffuseColor of {str(shader.GetPath())!r} "
                         "comes from a texture, so a colour value would not show", where=where)
    return str(shader.GetPath().MakeRelativePath(default.GetPath()))


def _write_usd_wrapper(source: Path, class_name: str, options: ImportOptions, target: Path,
                       roots: Sequence[Path]) -> _Written:
    from pxr import Gf, Kind, Sdf, Usd, UsdGeom

    from usdscene.document import stage_schema
    from usdscene.assetgen.usd_write import author_places, bounds_of_stage, new_asset_stage
    from usdscene.document.containment import usd_dependency_problems
    from usdscene.scene.place_discovery import places_from_boxes

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
    boxes = _usd_place_boxes(src_stage, default, source) if options.kind == "environment" else []
    authored, places = places_from_boxes(boxes, up_axis, scale, source=str(source))
    usd_kind = Kind.Tokens.assembly if options.kind == "environment" else Kind.Tokens.component
    stage, root = new_asset_stage(stage_schema.prim_name(class_name), usd_kind)
    holder = UsdGeom.Xform.Define(stage, f"{root.GetPath()}/Source")
    # Bounds are computed with an absolute reference (an in-memory layer has no folder to
    # resolve against); the written file then gets the path relative to its own folder.
    holder.GetPrim().GetReferences().AddReference(Sdf.Reference(str(source)))
    # Place boxes are annotations of the modeller, not scenery: hidden from renders and bounds.
    for box in boxes:
        relative = Sdf.Path(box.node).MakeRelativePath(default.GetPath())
        stage.OverridePrim(holder.GetPath().AppendPath(relative)).SetActive(False)
    variants, defaults = _lift_variants(default, root, holder.GetPrim(), source)
    color_shader = _color_slot(default, options.color_material, source) if options.kind != "environment" else ""
    _warn_unreachable_variants(default, source)
    m = forward_turn(options.forward_axis) @ file_to_world(up_axis, scale)
    op = holder.AddTransformOp()
    op.Set(Gf.Matrix4d(m.T.tolist()))
    lo, hi = bounds_of_stage(stage)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(hi < lo):
        raise AssetError("the USD file's default prim has no geometry with bounds", where=str(source))
    variant_extents: dict = {}
    if options.kind == "object":
        offset = _bottom_centre_offset(lo, hi)
        m[:3, 3] = offset
        op.Set(Gf.Matrix4d(m.T.tolist()))
        lo, hi = lo + offset, hi + offset
        variant_extents = _per_variant_origins(stage, root, holder, op, m, variants, defaults, source)
    if authored:
        author_places(stage, str(root.GetPath()), authored)
    # Swap in the relative reference on a detached copy of the layer (no stage recomposes
    # it, so nothing tries to resolve the relative path from an in-memory layer).
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(stage.GetRootLayer().ExportToString())
    relative = os.path.relpath(source, target.parent).replace(os.sep, "/")
    layer.GetPrimAtPath(holder.GetPath()).referenceList.prependedItems = [Sdf.Reference(relative)]
    write_text_atomic(target, layer.ExportToString())
    return _Written(np.round(lo, 4), np.round(hi, 4), places, variants, defaults, variant_extents,
                    f"{holder.GetPath().name}/{color_shader}" if color_shader else "", scale)


def _export_blend(blend: Path, usd_path: Path) -> Path:
    """Export a .blend to ``usd_path`` (kept beside the wrapper, which references it) through
    a Blender worker process; written under a temporary name and renamed when complete.

    Raises:
        AssetError: Blender could not open or export the file.
    """
    from usdscene.errors import RenderError
    from usdscene.render.driver import run_job
    from usdscene.render.job import BlendToUsdJob

    usd_path.parent.mkdir(parents=True, exist_ok=True)
    partial = usd_path.with_name(usd_path.name + ".partial.usda")
    try:
        run_job(BlendToUsdJob(blend=str(blend), usd=str(partial)), "USD export of a .blend")
        os.replace(partial, usd_path)
    except RenderError as exc:
        raise AssetError([Problem(str(blend), p.message) for p in exc.problems]) from None
    finally:
        partial.unlink(missing_ok=True)
    return usd_path


PERSON_KIND = "person"
"""``--kind person``: a rigged person; checked by :mod:`usdscene.assetgen.person_rig`."""


def _refuse_person(path: Path) -> None:
    """A person file is never registered rigid: every reason it cannot be posed, or (a
    posable rig) that posing one's own rig is not supported yet, as one error naming the file."""
    from usdscene.assetgen.person_rig import NOT_YET, person_rig_problems
    from usdscene.errors import Problem

    try:
        reasons = person_rig_problems(path)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise AssetError(f"cannot read the person file: {exc}", where=str(path)) from None
    raise AssetError([Problem(str(path), reason) for reason in (reasons or [NOT_YET])])


def import_asset(source: str | os.PathLike, class_name: str, catalog_dir: str | os.PathLike,
                 options: ImportOptions = ImportOptions(),
                 allowed_roots: Sequence[str | os.PathLike] | None = None) -> AssetEntry:
    """Convert or reference ``source`` and register it as ``class_name`` in ``catalog_dir``.

    Args:
        source: mesh file (OBJ, GLB/glTF, PLY, STL), USD file (usd/usda/usdc/usdz) or Blender
            project (.blend, exported to USD beside the catalog entry by a Blender worker).
        class_name: lower_snake_case class name (the OpenLABEL object type).
        catalog_dir: folder of the catalog (``catalog.json`` created when missing).
        options: kind, up axis, unit scale, description, replace.
        allowed_roots: folders the source must lie in (default: the working folder,
            ``catalog_dir``, the allowed asset folders and the source's own folder: naming a
            file is consent to read it); a path escaping them is refused.

    Returns:
        The registered catalog entry (extents in metres, asset frame Z up).

    Raises:
        AssetError: unreadable/empty/unknown file, path outside the allowed folders, bad
            options, or the class already exists (without ``replace``). Nothing is written.
    """
    catalog = Path(catalog_dir).resolve()
    from usdscene.document.containment import consented_folders

    src = Path(source)
    src_abs = src if src.is_absolute() else Path.cwd() / src
    # A file named on the command line is the user's consent to read it (and what it refers
    # to beside it); containment guards the paths found inside documents and catalogs.
    usual = (Path.cwd(), catalog, *consented_folders())
    roots = [Path(r) for r in (allowed_roots if allowed_roots is not None
                               else (*usual, src_abs.resolve().parent))]
    resolved, data = _check_inputs(src_abs, class_name, catalog, options, roots)
    from usdscene.document.containment import is_inside

    if resolved.suffix.lower() in USD_FORMATS and not is_inside(resolved, [Path(r).resolve() for r in usual]):
        # The wrapper references the file where it is: scenes must be allowed to read there.
        log.warning("%s lies outside the working and catalog folders and is referenced where it is; scenes "
                    "using class %r need --asset-path %s (or $USDSCENE_ASSET_PATH)", resolved, class_name,
                    resolved.parent)
    if options.kind == PERSON_KIND:
        _refuse_person(resolved)
    target = catalog / IMPORTED_FOLDER / f"{class_name}.usda"
    suffix = resolved.suffix.lower()
    if suffix in MESH_FORMATS:
        written = _import_mesh(resolved, class_name, options, target)
        fmt = MESH_FORMATS[suffix].upper()
    elif suffix == BLEND_FORMAT:
        exported = _export_blend(resolved, target.with_name(f"{class_name}.blend.usda"))
        written = _write_usd_wrapper(exported, class_name, options, target, [*roots, exported.parent])
        fmt = "Blender"
    else:
        written = _write_usd_wrapper(resolved, class_name, options, target, roots)
        fmt = "USD"
    if options.kind == "environment":
        log.info("%s: %d places found (%s)", resolved.name, len(written.places),
                 ", ".join(sorted(written.places)[:8]) + (" ..." if len(written.places) > 8 else ""))
    for warning in size_warnings(np.asarray(written.hi) - np.asarray(written.lo), options.kind, written.unit_scale_m):
        log.warning("%s: %s", resolved.name, warning)
    entry = AssetEntry(
        class_name=class_name, kind=options.kind, usd_path=target,
        description=options.description or f"Imported from {resolved.name} ({fmt}).",
        variants=written.variants,
        default_variants=dict(written.default_variants),
        extent_min_m=tuple(float(v) + 0.0 for v in written.lo),  # type: ignore[arg-type]
        extent_max_m=tuple(float(v) + 0.0 for v in written.hi),  # type: ignore[arg-type]
        relations=DEFAULT_RELATIONS[options.kind],
        places=written.places,
        variant_extents=written.variant_extents,
        orientations=options.orientations if options.kind != "environment" else "any",
        color_shader=written.color_shader,
        forward_axis=options.forward_axis)
    register_entry(catalog, entry, data)
    log.info("registered %s (%s) in %s", class_name, fmt, catalog)
    return entry


def _import_mesh(resolved: Path, class_name: str, options: ImportOptions, target: Path) -> "_Written":
    """Convert a mesh file (OBJ, GLB/glTF, PLY, STL) into the asset layer ``target``, its places
    found from marker boxes for an environment.

    Raises:
        AssetError: ``--color-material`` was given (a converted mesh has one colour material).
    """
    from usdscene.document import stage_schema
    from usdscene.scene.place_discovery import places_from_boxes

    if options.color_material is not None:
        raise AssetError("--color-material names a material of a USD file; a converted mesh is "
                         f"recoloured through its {DEFAULT_COLOR_SHADER} material", where="--color-material")

    parts, boxes = _load_parts(resolved, discover_places=options.kind == "environment")
    up_axis = options.up_axis or DEFAULT_UP_AXIS[MESH_FORMATS[resolved.suffix.lower()]]
    scale = options.unit_scale_m if options.unit_scale_m is not None else 1.0
    authored, places = places_from_boxes(boxes, up_axis, scale, source=str(resolved))
    lo, hi = _write_mesh_asset(parts, class_name, options, up_axis, scale, target, authored)
    variants = {stage_schema.VARIANT_SET_APPEARANCE: ("original",)}
    return _Written(lo, hi, places, variants, {k: v[0] for k, v in variants.items()}, unit_scale_m=scale)


def register_entry(catalog_dir: Path, entry: AssetEntry, data: dict | None = None) -> Path:
    """Add or replace ``entry`` in ``catalog_dir/catalog.json`` (classes kept sorted), atomically."""
    if not data:
        data = {"format": "usdscene-catalog", "version": 1, "classes": {}}
    classes = dict(data["classes"])
    classes[entry.class_name] = entry_to_json(entry, catalog_dir)
    _entry_from_json(entry.class_name, classes[entry.class_name], catalog_dir)  # round-trip check
    data = {**data, "classes": dict(sorted(classes.items()))}
    return write_text_atomic(catalog_dir / CATALOG_FILE, dumps_json(data))


def remove_entry(catalog_dir: str | os.PathLike, class_name: str, *, imported_only: bool = False) -> list[Path]:
    """Unregister ``class_name`` from ``catalog_dir/catalog.json`` (atomically) and delete the
    files ``assets add`` wrote for it under ``imported/`` (``<class>.usda``, ``<class>.blend.usda``).

    Args:
        catalog_dir: the catalog folder.
        class_name: the class to remove.
        imported_only: refuse classes whose file is not under ``imported/`` (the generated
            library's classes, which ``assets build`` would write back).

    Returns:
        The files deleted.

    Raises:
        AssetError: no such catalog or class, or a generated class with ``imported_only``.
    """
    folder = Path(catalog_dir).resolve()
    path = folder / CATALOG_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise AssetError(f"cannot read asset catalog: {exc}", where=str(path)) from exc
    classes = data.get("classes") if isinstance(data, dict) else None
    if not isinstance(classes, dict) or class_name not in classes:
        known = ", ".join(sorted(classes)) if isinstance(classes, dict) else "none"
        raise AssetError(f"class {class_name!r} is not in this catalog (classes: {known})", where=str(path))
    usd = str(classes[class_name].get("usd", ""))
    imported = usd.startswith(f"{IMPORTED_FOLDER}/")
    if imported_only and not imported:
        raise AssetError(f"class {class_name!r} belongs to the generated library ({usd}); only classes added "
                         "with 'assets add' can be removed from it", where=f"{path}:classes.{class_name}")
    remaining = {k: v for k, v in classes.items() if k != class_name}
    write_text_atomic(path, dumps_json({**data, "classes": remaining}))
    deleted = []
    if imported:
        for name in (f"{class_name}.usda", f"{class_name}.blend.usda"):
            candidate = folder / IMPORTED_FOLDER / name
            if candidate.is_file():
                candidate.unlink()
                deleted.append(candidate)
    return deleted
