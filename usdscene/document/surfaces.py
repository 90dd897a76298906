"""Procedural surfaces: the materials with detail that a stage names and the renderer builds.

A USD file cannot carry a Blender shader-node tree, and UsdPreviewSurface has one colour and
one roughness per material: every surface would be one flat colour. So a mesh that wants
detail names a *surface kind* in the string attribute ``userProperties:usdscene_surface``
(:data:`usdscene.document.stage_schema`'s user-property convention, which Blender's USD import
keeps as a custom property); its UsdPreviewSurface stays the fallback every other USD
renderer shows, and its colour stays the surface's base colour. The render worker
(``usdscene.render.blender.surface_nodes``) replaces the material of such meshes by the kind's
node tree: colour variation, roughness variation and bump detail, all in world metres (or
object metres for things that move, so clothes do not swim over a walking body).

One mesh with several materials (a person: top, trousers, skin) names a kind per material
instead: ``Body=knit Bottom=denim`` (material name ``=`` kind, separated by spaces); its other
materials keep their UsdPreviewSurface.

In a modelling tool's file the same name is a material called ``surface.<kind>``
(``surface.asphalt``), the way place boxes are called ``place.<place>.<region>``;
``usdscene assets add`` turns it into the attribute.

Every recipe below is plain numbers; sizes are in metres. Pure: no pxr, no bpy.
"""

from __future__ import annotations

from dataclasses import dataclass

from usdscene.errors import AssetError

SURFACE_ATTRIBUTE = "userProperties:usdscene_surface"
SURFACE_PROPERTY = "usdscene_surface"  # the custom property Blender's import makes of it
MATERIAL_PREFIX = "surface."


@dataclass(frozen=True)
class SurfaceRecipe:
    """One surface kind, in world (or object) metres.

    Attributes:
        name: the kind, as a stage or a DCC material names it.
        space: ``"world"`` (scenery: texture fixed to the world) or ``"object"`` (things that
            move: texture fixed to the object).
        grain_m: feature size of the fine grain (aggregate, pores, fibres), metres.
        grain_contrast: relative brightness spread of the grain (0 = none, 0.5 = +-25 %).
        blotch_m: feature size of the large variation (stains, patches, fading), metres.
        blotch_contrast: relative darkening of the darkest blotches.
        roughness: mean roughness, 0 (mirror) .. 1 (matte).
        roughness_variation: roughness spread, +- half of it, following the blotches.
        bump_strength: strength of the bump (0 .. 1) of the grain and the features.
        metallic: 0 dielectric .. 1 metal.
        crack_cell_m: spacing of cracks (0: none); cracks are dark thin lines with a groove.
        seam_m: spacing of seams, tile joints or weave rows (0: none).
        seam_width: joint width as a fraction of ``seam_m``.
        wear: fraction of the surface worn through to a darker under-layer (painted lines).
        stripes_m: width of a printed pattern's stripes (0: none), in object metres.
    """

    name: str
    space: str = "world"
    grain_m: float = 0.01
    grain_contrast: float = 0.3
    blotch_m: float = 2.0
    blotch_contrast: float = 0.3
    roughness: float = 0.8
    roughness_variation: float = 0.2
    bump_strength: float = 0.3
    metallic: float = 0.0
    crack_cell_m: float = 0.0
    seam_m: float = 0.0
    seam_width: float = 0.04
    wear: float = 0.0
    stripes_m: float = 0.0


SURFACES: dict[str, SurfaceRecipe] = {r.name: r for r in (
    # Aggregate of a few millimetres to 2 cm, oil stains and patches of metres, cracks ~3 m apart.
    SurfaceRecipe("asphalt", grain_m=0.012, grain_contrast=0.7, blotch_m=3.0, blotch_contrast=0.45,
                  roughness=0.85, roughness_variation=0.25, bump_strength=0.45, crack_cell_m=3.5),
    # Cast concrete: fine pores, formwork seams every 1.2 m, water stains.
    SurfaceRecipe("concrete", grain_m=0.006, grain_contrast=0.35, blotch_m=1.5, blotch_contrast=0.35,
                  roughness=0.8, roughness_variation=0.2, bump_strength=0.25, seam_m=1.2, seam_width=0.01),
    # Road paint over asphalt, worn through where tyres pass.
    SurfaceRecipe("painted_line", grain_m=0.01, grain_contrast=0.25, blotch_m=0.6, blotch_contrast=0.2,
                  roughness=0.6, roughness_variation=0.2, bump_strength=0.2, wear=0.3),
    # 30 cm floor tiles with grout.
    SurfaceRecipe("tiles", grain_m=0.004, grain_contrast=0.15, blotch_m=2.0, blotch_contrast=0.2,
                  roughness=0.35, roughness_variation=0.25, bump_strength=0.3, seam_m=0.3, seam_width=0.03),
    # Painted or galvanised metal: fine scratches, dull patches.
    SurfaceRecipe("metal", grain_m=0.003, grain_contrast=0.15, blotch_m=0.8, blotch_contrast=0.25,
                  roughness=0.35, roughness_variation=0.3, bump_strength=0.05, metallic=1.0),
    # Glazing: a dark mirror that reflects sky and surroundings; faint dirt.
    SurfaceRecipe("glass", grain_m=0.02, grain_contrast=0.05, blotch_m=1.0, blotch_contrast=0.15,
                  roughness=0.04, roughness_variation=0.06, bump_strength=0.0),
    # Grass and soil: the ground beyond the deck.
    SurfaceRecipe("grass", grain_m=0.02, grain_contrast=0.6, blotch_m=4.0, blotch_contrast=0.5,
                  roughness=0.95, roughness_variation=0.05, bump_strength=0.5),
    # Fabrics, fixed to the body: weave rows in millimetres, fading and folds over decimetres.
    SurfaceRecipe("denim", space="object", grain_m=0.004, grain_contrast=0.35, blotch_m=0.12, blotch_contrast=0.4,
                  roughness=0.9, roughness_variation=0.1, bump_strength=0.35, seam_m=0.003, seam_width=0.3),
    SurfaceRecipe("knit", space="object", grain_m=0.006, grain_contrast=0.4, blotch_m=0.15, blotch_contrast=0.3,
                  roughness=0.95, roughness_variation=0.05, bump_strength=0.5),
    SurfaceRecipe("cotton", space="object", grain_m=0.003, grain_contrast=0.2, blotch_m=0.1, blotch_contrast=0.35,
                  roughness=0.85, roughness_variation=0.1, bump_strength=0.3),
    SurfaceRecipe("pattern", space="object", grain_m=0.004, grain_contrast=0.25, blotch_m=0.1, blotch_contrast=0.3,
                  roughness=0.85, roughness_variation=0.1, bump_strength=0.25, stripes_m=0.04),
)}


def surface_recipe(name: str, *, where: str) -> SurfaceRecipe:
    """The recipe called ``name``.

    Raises:
        AssetError: naming ``where`` (the field or file location) and the unknown value.
    """
    recipe = SURFACES.get(name)
    if recipe is None:
        raise AssetError(f"unknown surface {name!r} (known: {', '.join(sorted(SURFACES))})", where=where)
    return recipe


def surface_from_material_name(material_name: str | None, *, where: str) -> str | None:
    """The surface kind a DCC material name asks for (``surface.asphalt`` → ``asphalt``), or
    None for any other name.

    Raises:
        AssetError: a ``surface.`` name of an unknown kind, naming ``where`` and the value.
    """
    if not material_name or not material_name.startswith(MATERIAL_PREFIX):
        return None
    kind = material_name[len(MATERIAL_PREFIX):]
    surface_recipe(kind, where=where)
    return kind


def surface_slots(value: str, *, where: str) -> dict[str | None, str]:
    """The kinds a ``usdscene_surface`` value asks for: ``"asphalt"`` (every material of the
    mesh) → ``{None: "asphalt"}``; ``"Body=knit Bottom=denim"`` (per material name) →
    ``{"Body": "knit", "Bottom": "denim"}``.

    Raises:
        AssetError: an unknown kind or a malformed pair, naming ``where`` and the value.
    """
    words = str(value).split()
    if len(words) == 1 and "=" not in words[0]:
        surface_recipe(words[0], where=where)
        return {None: words[0]}
    slots: dict[str | None, str] = {}
    for word in words:
        material, sep, kind = word.partition("=")
        if not sep or not material or not kind:
            raise AssetError(f"{word!r} in {value!r} is not <material>=<surface kind>", where=where)
        surface_recipe(kind, where=where)
        slots[material] = kind
    if not slots:
        raise AssetError(f"empty surface value {value!r}", where=where)
    return slots


def surface_slots_value(slots: dict[str, str]) -> str:
    """The ``usdscene_surface`` value of per-material kinds (inverse of :func:`surface_slots`)."""
    return " ".join(f"{material}={kind}" for material, kind in slots.items())
