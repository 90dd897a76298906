"""Blender shader-node trees of the procedural surfaces (``usdscene.document.surfaces``).

The worker calls :func:`apply_surfaces` once after the USD import. Every mesh object whose
custom property ``usdscene_surface`` (from ``userProperties:usdscene_surface`` in the stage)
names a kind gets, in each material slot (or in the slots whose material the value names,
``Body=knit Bottom=denim``), a node tree built from the kind's recipe and the
slot's imported base colour (the UsdPreviewSurface colour, which a document may have
recoloured): one material per (kind, colour), shared by every object that asks for it.

The tree, in the recipe's metres (world position for scenery, object coordinates for things
that move):

* grain: fBm noise at ``grain_m`` blended with one random brightness per Voronoi cell of the
  same size (stones of an aggregate, pores, fibres);
* blotches: low-frequency noise at ``blotch_m`` through a ramp (stains, patches, fading);
* cracks (``crack_cell_m``): Voronoi cell edges of noise-distorted coordinates, a thin dark
  groove; seams (``seam_m``): joint lines along the two axes that lie in the surface
  (the axis along the normal is masked out, so walls and floors both get a grid);
* wear (painted lines): the paint worn off to a dark under-layer where a noise is high;
* stripes (printed fabric): bands across the object's height;
* colour = base colour x brightness of all of them; roughness varies with the blotches and the
  grain; a bump node turns grain, cracks and seams into normals.

Colour detail lies in the albedo and bump detail in the normal, the two guide passes that
OpenImageDenoise (``denoising_input_passes = rgb_albedo_normal``) keeps sharp: the denoiser
smooths noise, not texture.

This module never imports ``bpy``: the worker (the only importer) passes its module in.
"""

from __future__ import annotations

import logging

import re

from usdscene.document.surfaces import SURFACE_PROPERTY, SurfaceRecipe, surface_recipe, surface_slots

log = logging.getLogger(__name__)

# Cracks: the groove's half-width in cell units (a 3.5 m cell gives cracks ~2 cm wide).
CRACK_WIDTH = 0.0025
# Worn paint shows this fraction of its colour (the asphalt under it).
WORN_BRIGHTNESS = 0.2


class _Graph:
    """Shorthand for building one material's node tree."""

    def __init__(self, tree) -> None:
        self.nodes, self.links = tree.nodes, tree.links

    def node(self, kind: str, inputs: dict | None = None, **props):
        n = self.nodes.new(kind)
        for key, value in props.items():
            setattr(n, key, value)
        for key, value in (inputs or {}).items():
            self.set(n.inputs[key], value)
        return n

    def set(self, socket, value) -> None:
        if hasattr(value, "is_output") or hasattr(value, "links"):
            self.links.new(value, socket)
        else:
            socket.default_value = value

    def math(self, op: str, a, b=0.0, clamp: bool = False):
        n = self.node("ShaderNodeMath", operation=op, use_clamp=clamp)
        self.set(n.inputs[0], a)
        self.set(n.inputs[1], b)
        return n.outputs[0]

    def noise(self, coords, size_m: float, detail: float = 4.0, roughness: float = 0.55):
        n = self.node("ShaderNodeTexNoise", {"Scale": 1.0 / size_m, "Detail": detail, "Roughness": roughness})
        self.set(n.inputs["Vector"], coords)
        return n.outputs[0]

    def voronoi(self, coords, size_m: float, feature: str = "F1", output: int = 0):
        n = self.node("ShaderNodeTexVoronoi", {"Scale": 1.0 / size_m}, feature=feature)
        self.set(n.inputs["Vector"], coords)
        return n.outputs[output]


def _coordinates(g: _Graph, recipe: SurfaceRecipe):
    if recipe.space == "object":
        return g.node("ShaderNodeTexCoord").outputs["Object"]
    return g.node("ShaderNodeNewGeometry").outputs["Position"]


def _seams(g: _Graph, coords, seam_m: float, width: float):
    """1 on the joint lines of a grid of ``seam_m`` in the surface's own two axes, else 0."""
    xyz = g.node("ShaderNodeSeparateXYZ")
    g.set(xyz.inputs[0], coords)
    normal = g.node("ShaderNodeSeparateXYZ")
    g.set(normal.inputs[0], g.node("ShaderNodeNewGeometry").outputs["Normal"])
    seam = None
    for axis in range(3):
        # Distance to the nearest joint in joint spacings: |fract(x / s + 0.5) - 0.5|.
        phase = g.math("FRACT", g.math("ADD", g.math("DIVIDE", xyz.outputs[axis], seam_m), 0.5))
        line = g.math("LESS_THAN", g.math("ABSOLUTE", g.math("SUBTRACT", phase, 0.5)), width / 2)
        in_plane = g.math("SUBTRACT", 1.0, g.math("ABSOLUTE", normal.outputs[axis]))
        line = g.math("GREATER_THAN", g.math("MULTIPLY", line, in_plane), 0.5)
        seam = line if seam is None else g.math("MAXIMUM", seam, line)
    return seam


def build_material(bpy, recipe: SurfaceRecipe, base_rgb: tuple[float, float, float], name: str):
    """A new Blender material of ``recipe`` on the linear RGB ``base_rgb``."""
    material = bpy.data.materials.new(name)
    if not getattr(material, "node_tree", None):
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    g = _Graph(tree)
    coords = _coordinates(g, recipe)
    # Grain: noise blended with one random value per cell (stones, pores).
    cells = g.node("ShaderNodeSeparateColor")
    g.set(cells.inputs[0], g.voronoi(coords, recipe.grain_m, output=1))
    grain = g.math("ADD", g.math("MULTIPLY", g.noise(coords, recipe.grain_m * 0.7, detail=3.0), 0.5),
                   g.math("MULTIPLY", cells.outputs[0], 0.5))
    # Mottling between grain and blotches (decimetres for scenery): what a camera 2-40 m away
    # resolves when the grain itself is below a pixel.
    grain = g.math("ADD", g.math("MULTIPLY", grain, 0.5),
                   g.math("MULTIPLY", g.noise(coords, recipe.blotch_m / 10, detail=5.0, roughness=0.65), 0.5))
    # Blotches: 0 clean .. 1 darkest stain.
    ramp = g.node("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[0].color = 0.45, (1, 1, 1, 1)
    ramp.color_ramp.elements[1].position, ramp.color_ramp.elements[1].color = 0.7, (0, 0, 0, 1)
    g.set(ramp.inputs[0], g.noise(coords, recipe.blotch_m, detail=3.0, roughness=0.6))
    stain = g.math("SUBTRACT", 1.0, ramp.outputs[0])
    brightness = g.math("MULTIPLY", g.math("ADD", 1.0 - recipe.grain_contrast / 2,
                                           g.math("MULTIPLY", grain, recipe.grain_contrast)),
                        g.math("SUBTRACT", 1.0, g.math("MULTIPLY", stain, recipe.blotch_contrast)))
    height = g.math("MULTIPLY", grain, 0.5)
    if recipe.crack_cell_m > 0:
        # Cell edges are straight: coordinates warped by a noise of a fifth of the cell make
        # them wander like cracks.
        wobble = g.node("ShaderNodeTexNoise", {"Scale": 5.0 / recipe.crack_cell_m, "Detail": 3.0})
        g.set(wobble.inputs["Vector"], coords)
        offset = g.node("ShaderNodeVectorMath", operation="SCALE")
        g.set(offset.inputs[0], wobble.outputs[1])
        offset.inputs["Scale"].default_value = 0.25 * recipe.crack_cell_m
        warp = g.node("ShaderNodeVectorMath", operation="ADD")
        g.set(warp.inputs[0], coords)
        g.set(warp.inputs[1], offset.outputs[0])
        edge = g.voronoi(warp.outputs[0], recipe.crack_cell_m, feature="DISTANCE_TO_EDGE")
        crack = g.math("LESS_THAN", edge, CRACK_WIDTH)
        # Only some cell edges are cracks: a coarse noise gates them.
        crack = g.math("MULTIPLY", crack, g.math("GREATER_THAN", g.noise(coords, recipe.crack_cell_m, 2.0), 0.5))
        brightness = g.math("MULTIPLY", brightness, g.math("SUBTRACT", 1.0, g.math("MULTIPLY", crack, 0.6)))
        height = g.math("SUBTRACT", height, crack)
    if recipe.seam_m > 0:
        seam = _seams(g, coords, recipe.seam_m, recipe.seam_width)
        brightness = g.math("MULTIPLY", brightness, g.math("SUBTRACT", 1.0, g.math("MULTIPLY", seam, 0.35)))
        height = g.math("SUBTRACT", height, g.math("MULTIPLY", seam, 0.5))
    if recipe.wear > 0:
        worn = g.math("GREATER_THAN", g.noise(coords, 0.08, detail=6.0), 1.0 - recipe.wear * 0.5 - 0.25)
        brightness = g.math("MULTIPLY", brightness,
                            g.math("SUBTRACT", 1.0, g.math("MULTIPLY", worn, 1.0 - WORN_BRIGHTNESS)))
        height = g.math("SUBTRACT", height, g.math("MULTIPLY", worn, 0.3))
    if recipe.stripes_m > 0:
        wave = g.node("ShaderNodeTexWave", {"Scale": 1.0 / (2 * recipe.stripes_m)}, wave_type="BANDS",
                      bands_direction="Z", wave_profile="SIN")
        g.set(wave.inputs["Vector"], coords)
        stripe = g.math("GREATER_THAN", wave.outputs[1], 0.5)  # hard-edged printed bands
        brightness = g.math("MULTIPLY", brightness, g.math("SUBTRACT", 1.0, g.math("MULTIPLY", stripe, 0.55)))
    color = g.node("ShaderNodeVectorMath", operation="SCALE")
    color.inputs[0].default_value = tuple(float(c) for c in base_rgb)
    g.set(color.inputs["Scale"], brightness)
    rough = g.math("ADD", recipe.roughness,
                   g.math("MULTIPLY", g.math("SUBTRACT", stain, 0.5), recipe.roughness_variation), clamp=True)
    rough = g.math("ADD", rough, g.math("MULTIPLY", g.math("SUBTRACT", grain, 0.5), recipe.roughness_variation / 2),
                   clamp=True)
    bsdf = g.node("ShaderNodeBsdfPrincipled", {"Metallic": recipe.metallic})
    g.set(bsdf.inputs["Base Color"], color.outputs[0])
    g.set(bsdf.inputs["Roughness"], rough)
    if recipe.bump_strength > 0:
        bump = g.node("ShaderNodeBump", {"Strength": recipe.bump_strength, "Distance": min(0.02, recipe.grain_m)})
        g.set(bump.inputs["Height"], height)
        g.set(bsdf.inputs["Normal"], bump.outputs[0])
    out = g.node("ShaderNodeOutputMaterial")
    g.set(out.inputs["Surface"], bsdf.outputs[0])
    return material


def _base_color(material) -> tuple[float, float, float]:
    """The imported material's base colour (linear RGB); mid grey when it has none."""
    tree = getattr(material, "node_tree", None) if material is not None else None
    if tree is not None:
        for n in tree.nodes:
            if n.type == "BSDF_PRINCIPLED":
                return tuple(round(float(c), 4) for c in n.inputs["Base Color"].default_value[:3])
    if material is not None:
        return tuple(round(float(c), 4) for c in material.diffuse_color[:3])
    return (0.5, 0.5, 0.5)


def _imported_name(material) -> str | None:
    """The USD material's prim name: Blender adds ``.001`` to the second material of a name."""
    return None if material is None else re.sub(r"\.\d{3,}$", "", material.name)


def surface_of(ob) -> str | None:
    """The surface kind an imported object asks for (on the object or its mesh data)."""
    kind = ob.get(SURFACE_PROPERTY)
    if kind is None and ob.data is not None and hasattr(ob.data, "get"):
        kind = ob.data.get(SURFACE_PROPERTY)
    return str(kind) if kind is not None else None


def apply_surfaces(bpy) -> int:
    """Give every object that names a surface kind its procedural materials.

    Returns:
        How many material slots were replaced.

    Raises:
        AssetError: an object names an unknown kind (the prim and the value).
    """
    made: dict[tuple, object] = {}
    replaced = 0
    for ob in bpy.data.objects:
        if ob.type != "MESH":
            continue
        kind = surface_of(ob)
        if kind is None:
            continue
        where = f"{ob.name}: {SURFACE_PROPERTY}"
        kinds = surface_slots(kind, where=where)
        if not ob.material_slots:
            ob.data.materials.append(None)
        for slot in ob.material_slots:
            slot_kind = kinds.get(None) or kinds.get(_imported_name(slot.material))
            if slot_kind is None:
                continue  # a material the value does not name keeps its imported look
            recipe = surface_recipe(slot_kind, where=where)
            base = _base_color(slot.material)
            key = (slot_kind, base)
            if key not in made:
                made[key] = build_material(bpy, recipe, base, f"usdscene_surface_{slot_kind}_{len(made):03d}")
            slot.material = made[key]
            replaced += 1
    if made:
        log.info("procedural surfaces: %d materials for %d slots", len(made), replaced)
    return replaced
