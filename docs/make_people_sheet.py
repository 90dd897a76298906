"""Render ``docs/img/people.png``: the people family side by side: the 24 bodies in two rows
(each in its own default clothes), then one body through every ``person`` pose and the four
``passenger`` poses.

    python docs/make_people_sheet.py [--out docs/img/people.png] [--samples 16] [--width 1600]

A small USD stage references the shipped ``person`` / ``passenger`` assets with variant
selections, imported into Blender with ``bpy.ops.wm.usd_import`` and rendered with Cycles.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SPACING_M = 0.75


def build_stage(folder: Path, library: Path | None) -> Path:
    """Write ``folder/scene.usda``; returns its path."""
    from pxr import Gf, Usd, UsdGeom

    from usdscene.document import stage_schema as ss
    from usdscene.scene.catalog import load_catalog

    catalog = load_catalog([library] if library else ())
    person, passenger = catalog["person"], catalog["passenger"]
    bodies = person.variants[ss.VARIANT_SET_APPEARANCE]
    stage = Usd.Stage.CreateNew(str(folder / "scene.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World").GetPrim()
    stage.SetDefaultPrim(world)

    def add(name: str, entry, appearance: str, pose: str, x: float, y: float, z: float = 0.0,
            yaw_deg: float = 0.0) -> None:
        prim = UsdGeom.Xform.Define(stage, f"/World/{name}").GetPrim()
        prim.GetReferences().AddReference(str(entry.usd_path))
        prim.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE).SetVariantSelection(appearance)
        prim.GetVariantSets().GetVariantSet(ss.VARIANT_SET_POSE).SetVariantSelection(pose)
        UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(x, y, z))
        UsdGeom.Xformable(prim).AddRotateZOp().Set(yaw_deg)

    for i, body in enumerate(bodies):
        row, col = divmod(i, 12)
        add(f"body_{i:02d}", person, body, "standing", (col - 5.5) * SPACING_M, 2.5 * row, 0.0)
    poses = person.variants[ss.VARIANT_SET_POSE]
    for i, pose in enumerate(poses):
        # Turned three quarters to the camera, so strides and arms show.
        add(f"pose_{i:02d}", person, bodies[15], pose, (i - 7.0) * 0.85, -2.6, 0.0, -55.0)
    for i, pose in enumerate(passenger.variants[ss.VARIANT_SET_POSE]):
        add(f"seated_{i:02d}", passenger, bodies[4], pose, (i + 4.5) * 0.85, -2.6, 0.45, -40.0)
    stage.GetRootLayer().Save()
    return folder / "scene.usda"


def render(scene: Path, out: Path, samples: int, width: int) -> float:
    """Import ``scene`` into Blender and render it from the front; returns seconds taken."""
    import bpy

    start = time.monotonic()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=str(scene))
    sc = bpy.context.scene
    cam_data = bpy.data.cameras.new("front")
    cam_data.lens = 30.0
    cam = bpy.data.objects.new("front", cam_data)
    sc.collection.objects.link(cam)
    # From the front and a little to the left, so walking legs and seated thighs show.
    cam.location = (0.0, -14.0, 3.0)
    cam.rotation_euler = (math.radians(82.0), 0.0, math.radians(0.0))
    sc.camera = cam
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.5
    sun.rotation_euler = (math.radians(50.0), 0.0, math.radians(-25.0))
    sc.collection.objects.link(sun)
    bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 2.0, 0.0))
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs[0].default_value = (0.8, 0.85, 0.9, 1.0)
    world.node_tree.nodes["Background"].inputs[1].default_value = 0.8
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
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "img" / "people.png")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--library", type=Path, default=None, help="asset library folder (default: shipped)")
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scene = build_stage(Path(tmp), args.library)
        seconds = render(scene, args.out.resolve(), args.samples, args.width)
    print(f"wrote {args.out} in {seconds:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
