"""Authoring helpers shared by every procedural asset: stage metadata, meshes, materials.

Conventions written here (and checked by the tests): Z up, ``metersPerUnit = 1``, a
``defaultPrim`` with ``kind`` metadata, every geometry a ``UsdGeom.Mesh`` with an authored
``extent`` and vertex normals, materials as ``UsdPreviewSurface`` bound through
``MaterialBindingAPI``. Files are written as ``.usda`` text from an in-memory layer, so the
same authoring order gives byte-identical files (no timestamps, no absolute paths).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from usdscene.document import stage_schema
from usdscene.assetgen.mesh import MeshData
from usdscene.scene.catalog import PlaceRegion
from usdscene.files import write_text_atomic

# Vertex positions are rounded to a tenth of a millimetre: invisible, and it keeps the text
# files small and free of float noise that would differ between numpy builds.
POINT_DECIMALS = 4
NORMAL_DECIMALS = 3


@dataclass(frozen=True)
class MaterialSpec:
    """A UsdPreviewSurface material.

    Attributes:
        color: linear RGB diffuse colour, each in [0, 1].
        roughness: 0 (mirror) .. 1 (matte).
        metallic: 0 (dielectric) .. 1 (metal).
        opacity: 1 opaque .. 0 invisible.
        emissive: linear RGB emitted radiance (None = no emission).
    """

    color: tuple[float, float, float]
    roughness: float = 0.6
    metallic: float = 0.0
    opacity: float = 1.0
    emissive: tuple[float, float, float] | None = None


def new_asset_stage(root_name: str, kind: str) -> tuple[Usd.Stage, Usd.Prim]:
    """An in-memory stage with the library's metadata and an Xform default prim of ``kind``
    (``Kind.Tokens.component`` or ``assembly``)."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, f"/{root_name}").GetPrim()
    stage.SetDefaultPrim(root)
    Usd.ModelAPI(root).SetKind(kind)
    return stage, root


def define_material(stage: Usd.Stage, path: str, spec: MaterialSpec, *,
                    color_from_variants: bool = False) -> UsdShade.Material:
    """A Material at ``path`` with a UsdPreviewSurface shader named ``Surface``.

    The shader's ``inputs:diffuseColor`` holds the colour directly (no primvar reader):
    Blender's USD importer reads a directly authored value in any composed layer, so a
    stronger layer can recolour an object by overriding that one attribute.

    Args:
        color_from_variants: leave ``diffuseColor`` unauthored here because variants author
            it; a local opinion in the same layer would be stronger than any variant (LIVRPS).
    """
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/{stage_schema.ASSET_SURFACE_SHADER}")
    shader.CreateIdAttr("UsdPreviewSurface")
    color = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    if not color_from_variants:
        color.Set(Gf.Vec3f(*spec.color))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(spec.roughness))
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(spec.metallic))
    if spec.opacity < 1.0:
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(spec.opacity))
    if spec.emissive is not None:
        shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*spec.emissive))
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def set_material_color(stage: Usd.Stage, material_path: str, color: Sequence[float]) -> None:
    """Author the diffuse colour of a material made by :func:`define_material` (in the
    current edit target, e.g. inside a variant)."""
    prim = stage.OverridePrim(f"{material_path}/{stage_schema.ASSET_SURFACE_SHADER}")
    attr = prim.CreateAttribute("inputs:diffuseColor", Sdf.ValueTypeNames.Color3f)
    attr.Set(Gf.Vec3f(*(float(c) for c in color)))


def _vec3f_array(values: np.ndarray, decimals: int) -> Vt.Vec3fArray:
    rounded = np.round(np.asarray(values, dtype=np.float64), decimals) + 0.0  # +0.0: no "-0"
    return Vt.Vec3fArray.FromNumpy(rounded.astype(np.float32))


def define_mesh(stage: Usd.Stage, path: str, mesh: MeshData,
                material: UsdShade.Material | None = None,
                display_color: Sequence[float] | None = None) -> UsdGeom.Mesh:
    """A ``UsdGeom.Mesh`` with points, vertex normals, authored extent and a material binding.

    ``subdivisionScheme = none`` because the normals already make the surface smooth and the
    tessellation is final (renderers must not subdivide again).
    """
    usd_mesh = UsdGeom.Mesh.Define(stage, path)
    points = _vec3f_array(mesh.points, POINT_DECIMALS)
    usd_mesh.CreatePointsAttr(points)
    usd_mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(mesh.face_counts.astype(np.int32)))
    usd_mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.face_indices.astype(np.int32)))
    usd_mesh.CreateNormalsAttr(_vec3f_array(mesh.normals, NORMAL_DECIMALS))
    usd_mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    usd_mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    usd_mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(points))
    if display_color is not None:
        usd_mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
            Vt.Vec3fArray([Gf.Vec3f(*(float(c) for c in display_color))]))
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(usd_mesh.GetPrim()).Bind(material)
    return usd_mesh


def set_transform(prim: Usd.Prim, matrix_row_major: np.ndarray) -> None:
    """Author one ``xformOp:transform`` from a (4, 4) column-vector (row-major maths) matrix.

    USD stores row-vector matrices, i.e. the transpose of the catalog's convention.
    """
    m = np.round(np.asarray(matrix_row_major, dtype=np.float64), 6) + 0.0
    xform = UsdGeom.Xformable(prim)
    xform.ClearXformOpOrder()
    xform.AddTransformOp().Set(Gf.Matrix4d(m.T.tolist()))


def set_translate(prim: Usd.Prim, offset_m: Sequence[float]) -> None:
    """Add a translate op of ``offset_m`` (x, y, z metres, rounded to 6 decimals) to ``prim``."""
    xform = UsdGeom.Xformable(prim)
    xform.AddTranslateOp().Set(Gf.Vec3d(*(round(float(v), 6) + 0.0 for v in offset_m)))


@contextlib.contextmanager
def in_variant(prim: Usd.Prim, set_name: str, variant: str) -> Iterator[None]:
    """Author everything inside the ``with`` block into ``{set_name=variant}`` of ``prim``."""
    vset = prim.GetVariantSets().AddVariantSet(set_name)
    vset.AddVariant(variant)
    vset.SetVariantSelection(variant)
    with vset.GetVariantEditContext():
        yield


def add_variant_names(prim: Usd.Prim, set_name: str, names: Sequence[str], default: str) -> None:
    """Declare a variant set's names (in order) and its default selection."""
    vset = prim.GetVariantSets().AddVariantSet(set_name)
    for name in names:
        vset.AddVariant(name)
    vset.SetVariantSelection(default)


def author_places(stage: Usd.Stage, root: str, places: Mapping[str, tuple[str, Mapping[str, PlaceRegion]]]) -> None:
    """Author an environment's places as ``<root>/Places/<place>/<region>`` Xforms.

    Args:
        stage: the asset stage.
        root: path of the asset's default prim.
        places: place name → (kind, region prim name (``on``, ``below``, ...) → region whose
            pose is in the asset frame).
    """
    scope = UsdGeom.Scope.Define(stage, f"{root}/{stage_schema.ASSET_PLACES}")
    # Places are annotations, not scenery: purpose "guide" keeps them out of renders and out
    # of Blender's import (its importer skips guides by default), while pxr still reads them.
    scope.CreatePurposeAttr(UsdGeom.Tokens.guide)
    for name, (kind, regions) in places.items():
        place = UsdGeom.Xform.Define(stage, f"{root}/{stage_schema.ASSET_PLACES}/{name}").GetPrim()
        place.CreateAttribute(stage_schema.ATTR_PLACE_KIND, Sdf.ValueTypeNames.Token).Set(kind)
        for region_name, region in sorted(regions.items()):
            prim = UsdGeom.Xform.Define(stage, f"{place.GetPath()}/{region_name}").GetPrim()
            set_transform(prim, region.pose.as_array())
            prim.CreateAttribute(stage_schema.ATTR_PLACE_RELATION, Sdf.ValueTypeNames.Token).Set(region.relation)
            prim.CreateAttribute(stage_schema.ATTR_PLACE_SIZE, Sdf.ValueTypeNames.Double3).Set(tuple(region.size_m))


def save_stage(stage: Usd.Stage, path: Path) -> Path:
    """Write the root layer as ``.usda`` text, atomically."""
    return write_text_atomic(path, stage.GetRootLayer().ExportToString())


def bounds_of_stage(stage: Usd.Stage, prim_path: str | None = None,
                    variants: Mapping[str, str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (min (3,), max (3,), metres) of the default prim (or ``prim_path``)
    in its own frame, with ``variants`` selected; computed from the meshes' points."""
    prim = stage.GetPrimAtPath(prim_path) if prim_path else stage.GetDefaultPrim()
    if variants:
        for set_name, name in variants.items():
            prim.GetVariantSets().GetVariantSet(set_name).SetVariantSelection(name)
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_], useExtentsHint=False)
    box = cache.ComputeUntransformedBound(prim).ComputeAlignedRange()
    return np.asarray(box.GetMin(), dtype=np.float64), np.asarray(box.GetMax(), dtype=np.float64)
