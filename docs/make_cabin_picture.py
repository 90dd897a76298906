"""Render ``docs/img/cabin.png``: the shipped cabin with luggage and passengers, seen by a
corridor camera at the rear of the cabin.

    python docs/make_cabin_picture.py [--out docs/img/cabin.png] [--samples 16] [--width 960]

It builds a small USD stage with pxr (the cabin referenced at /World/Environment, objects and
passengers referenced at catalog places with variant selections and one colour override),
imports it into Blender with ``bpy.ops.wm.usd_import`` and renders it with Cycles on the CPU.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent

# (class, place, relation, variants, yaw_deg, extra local rotation, colour override or None)
PASSENGERS = [
    ("seat_19A", "upright", "f_18_166_slim_tone1"), ("seat_19C", "reading", "f_57_175_average_tone2"),
    ("seat_19E", "leaning", "m_29_195_slim_tone6"), ("seat_18B", "sleeping", "m_69_189_average_tone1"),
    ("seat_18D", "upright", "f_41_150_average_tone5"), ("seat_18F", "reading", "f_80_155_heavy_tone6"),
    ("seat_17A", "leaning", "m_52_165_average_tone4"), ("seat_17C", "upright", "f_24_177_average_tone2"),
    ("seat_17E", "upright", "f_63_164_heavy_tone3"), ("seat_16C", "reading", "m_35_192_average_tone1"),
    ("seat_16D", "sleeping", "m_74_177_heavy_tone2"), ("seat_15A", "upright", "f_46_172_heavy_tone6"),
    ("seat_15B", "reading", "m_18_171_average_tone4"), ("seat_15F", "upright", "m_57_174_heavy_tone5"),
    ("seat_14C", "leaning", "f_29_169_heavy_tone3"), ("seat_14E", "upright", "f_69_153_slim_tone4"),
    ("seat_13D", "reading", "m_41_168_heavy_tone2"), ("seat_12A", "upright", "m_80_162_slim_tone3"),
    ("seat_12C", "upright", "f_52_180_slim_tone1"), ("seat_11F", "sleeping", "m_24_186_heavy_tone5"),
    ("seat_10B", "upright", "m_63_180_slim_tone6"), ("seat_10D", "reading", "f_35_161_slim_tone4"),
    ("seat_09C", "upright", "f_74_158_average_tone5"), ("seat_08E", "leaning", "m_46_183_slim_tone3"),
    ("seat_07A", "upright", "f_18_166_slim_tone1"), ("seat_06D", "upright", "f_57_175_average_tone2"),
]
OBJECTS = [
    ("trolley_suitcase", "aisle_18", "is_on", "black", 90.0, None, (0.9, 0.7, 0.05)),
    ("backpack", "seat_19D", "is_on", "red", 0.0, None, None),
    ("laptop", "seat_18E", "is_on", "open_silver", 0.0, None, None),
    ("handbag", "seat_17B", "is_on", "tan", 20.0, None, None),
    ("jacket", "seat_17F", "is_on", "navy", 0.0, None, None),
    ("duffel_bag", "aisle_15", "is_on", "olive", 80.0, None, None),
    ("small_suitcase", "seat_19B", "is_in_front_of", "teal", 90.0, None, None),
    ("backpack", "seat_18C", "is_in_front_of", "grey", 0.0, None, None),
    ("shopping_bag", "seat_16E", "is_on", "kraft", 0.0, None, None),
    ("pillow", "seat_16F", "is_on", "light_blue", 0.0, None, None),
    ("camera_bag", "seat_14D", "is_on", "black", 0.0, None, None),
    ("coffee_cup", "seat_13E", "is_on", "white_paper", 0.0, None, None),
    ("trolley_suitcase", "bin_18L", "is_in", "silver", 0.0, "lie", None),
    ("duffel_bag", "bin_19R", "is_in", "black", 0.0, None, None),
    ("trolley_suitcase", "bin_17R", "is_in", "red", 0.0, "lie", None),
    ("backpack", "bin_19L", "is_in", "navy", 90.0, None, None),
    ("briefcase", "bin_16L", "is_in", "black", 0.0, "lie", None),
    ("magazine", "seat_15C", "is_on", "red_cover", 0.0, None, None),
    ("blanket", "seat_12B", "is_on", "blue", 0.0, None, None),
]


def _matrix(rotation_deg_z: float, lie: bool, size_m: tuple[float, float, float]) -> np.ndarray:
    """Local transform of an object on its region origin: a yaw, or laid on its back (for
    bins: the tall axis along the region's Y = along the cabin, resting on its depth)."""
    m = np.eye(4)
    if lie:
        # -90° about X: height → +Y, depth → -Z; centre along Y and lift by half the depth.
        m[:3, :3] = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
        m[:3, 3] = [0.0, -size_m[2] / 2, size_m[1] / 2]
        return m
    a = math.radians(rotation_deg_z)
    m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return m


def build_stage(folder: Path) -> Path:
    """Write ``folder/scene.usda`` referencing the shipped library; returns its path."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    from usdscene.document import stage_schema
    from usdscene.scene.catalog import load_catalog

    catalog = load_catalog()
    cabin = catalog["aircraft_cabin"]
    stage = Usd.Stage.CreateNew(str(folder / "scene.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, stage_schema.WORLD).GetPrim()
    stage.SetDefaultPrim(world)
    env = UsdGeom.Xform.Define(stage, stage_schema.ENVIRONMENT).GetPrim()
    env.GetReferences().AddReference(str(cabin.usd_path))
    places = cabin.places

    def place(name: str, cls: str, place_name: str, relation: str, variants: dict[str, str],
              local: np.ndarray, color: tuple[float, float, float] | None) -> None:
        prim = UsdGeom.Xform.Define(stage, f"{stage_schema.OBJECTS}/{name}").GetPrim()
        prim.GetReferences().AddReference(str(catalog[cls].usd_path))
        for set_name, value in variants.items():
            prim.GetVariantSets().GetVariantSet(set_name).SetVariantSelection(value)
        world_m = places[place_name].regions[relation].pose.as_array() @ local
        UsdGeom.Xformable(prim).AddTransformOp().Set(Gf.Matrix4d(world_m.T.tolist()))
        if color is not None:
            shader = stage.OverridePrim(f"{prim.GetPath()}/{stage_schema.ASSET_COLOR_SHADER}")
            shader.CreateAttribute(stage_schema.ATTR_ASSET_COLOR, Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*color))

    UsdGeom.Scope.Define(stage, stage_schema.OBJECTS)
    for i, (seat, pose, look) in enumerate(PASSENGERS):
        place(f"passenger_{i:02d}", "passenger", seat, "is_on",
              {stage_schema.VARIANT_SET_POSE: pose, stage_schema.VARIANT_SET_APPEARANCE: look}, np.eye(4), None)
    for i, (cls, place_name, relation, look, yaw, lie, color) in enumerate(OBJECTS):
        size = catalog[cls].size_m
        place(f"{cls}_{i:02d}", cls, place_name, relation, {stage_schema.VARIANT_SET_APPEARANCE: look},
              _matrix(yaw, lie == "lie", size), color)
    stage.GetRootLayer().Save()
    return folder / "scene.usda"


def render(scene: Path, out: Path, samples: int, width: int) -> float:
    """Import ``scene`` into Blender and render the corridor view; returns seconds taken."""
    import bpy

    start = time.monotonic()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=str(scene))
    sc = bpy.context.scene
    cam_data = bpy.data.cameras.new("corridor")
    cam_data.lens = 14.0
    cam_data.sensor_width = 36.0
    cam = bpy.data.objects.new("corridor", cam_data)
    sc.collection.objects.link(cam)
    # Ceiling-mounted corridor camera at the rear of the cabin looking forward and down.
    cam.location = (-16.25, -0.25, 2.15)
    cam.rotation_euler = (math.radians(68.0), 0.0, math.radians(-90.0))
    sc.camera = cam
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 5.0
    sun.data.angle = math.radians(1.0)
    sun.rotation_euler = (math.radians(55.0), 0.0, math.radians(-30.0))
    sc.collection.objects.link(sun)
    for i in range(6):
        lamp = bpy.data.objects.new(f"ceiling_{i}", bpy.data.lights.new(f"ceiling_{i}", "AREA"))
        lamp.data.shape = "RECTANGLE"
        lamp.data.size, lamp.data.size_y = 0.3, 2.4
        lamp.data.energy = 120.0
        lamp.location = (-1.5 - 2.7 * i, 0.0, 2.24)
        sc.collection.objects.link(lamp)
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs[0].default_value = (0.55, 0.72, 1.0, 1.0)
    background.inputs[1].default_value = 1.5
    sc.world = world
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = samples
    sc.cycles.use_denoising = True
    sc.cycles.max_bounces = 3
    sc.render.resolution_x = width
    sc.render.resolution_y = width * 9 // 16
    sc.render.filepath = str(out)
    sc.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(write_still=True)
    return time.monotonic() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "img" / "cabin.png")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--width", type=int, default=960)
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scene = build_stage(Path(tmp))
        seconds = render(scene, args.out.resolve(), args.samples, args.width)
    print(f"wrote {args.out} in {seconds:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
