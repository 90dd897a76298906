"""A tiny asset catalog built in a temp folder, and scene builders, for the composition tests.

Independent of the shipped asset library so that golden files only change when composition
changes. ``build_test_catalog(folder)`` writes ``catalog.json``, three small object assets
(box with an ``appearance`` variant set and the library's colour shader, cup, bag) and an
environment ``test_cabin`` with places (a row of seats, an aisle and a large hall).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.document import model as m
from usdscene.scene.catalog import load_catalog

OBJECT_CLASSES = {
    # class: (extent min, extent max, appearance variants)
    "box": ((-0.2, -0.15, 0.0), (0.2, 0.15, 0.3), ("plain", "striped")),
    "cup": ((-0.04, -0.04, 0.0), (0.04, 0.04, 0.1), ()),
    "bag": ((-0.15, -0.1, 0.0), (0.15, 0.1, 0.35), ("navy", "red")),
    "pole": ((-0.05, -0.05, 0.0), (0.05, 0.05, 2.5), ()),
    # too tall for under a seat upright; fits lying on its side, turned a quarter
    "tall_bag": ((-0.15, -0.075, 0.0), (0.15, 0.075, 0.42), ()),
    # seated like the library's passengers: origin at the hip contact, feet 0.45 m lower
    "sitter": ((-0.28, -0.25, -0.45), (0.64, 0.25, 0.9), ()),
}


def _yaw_pose(yaw_deg: float, x: float, y: float, z: float) -> m.Pose:
    a = math.radians(yaw_deg)
    rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return m.Pose.from_rotation_translation(rot, (x, y, z))


def make_places() -> dict:
    """place name → {"kind", "regions": {relation: (pose, size_m)}}."""
    places = {}
    for i, letter in enumerate("ABCD"):
        x = 1.0 + 0.5 * i
        places[f"seat_01{letter}"] = {"kind": "seat", "regions": {
            "is_on": (_yaw_pose(90.0, x, 0.0, 0.45), (0.45, 0.45, 1.2)),
            "is_below": (_yaw_pose(90.0, x, 0.05, 0.0), (0.44, 0.40, 0.40)),
            "is_in_front_of": (_yaw_pose(90.0, x, 0.45, 0.0), (0.44, 0.40, 2.0)),
        }}
    places["aisle_01"] = {"kind": "aisle", "regions": {
        "is_on": (_yaw_pose(0.0, 2.0, 1.2, 0.0), (3.0, 0.6, 2.2))}}
    places["hall"] = {"kind": "floor", "regions": {
        "is_on": (_yaw_pose(30.0, 0.0, 6.0, 0.0), (9.0, 7.0, 3.0))}}
    places["bin_01"] = {"kind": "bin", "regions": {
        "is_in": (_yaw_pose(0.0, 2.0, -0.3, 1.6), (1.0, 0.4, 0.35))}}
    return places


def _asset_usda(name: str, lo, hi, variants) -> str:
    # Box corners, index = 4·x + 2·y + z with 0 = low and 1 = high.
    points = ", ".join(str((x, y, z)) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2]))
    variant_block = ""
    meta = ""
    if variants:
        colours = [(0.5, 0.5, 0.5), (0.8, 0.2, 0.2), (0.1, 0.2, 0.6)]
        entries = "\n".join(
            f'        "{v}" {{\n            over "Looks"\n            {{\n                over "Body"\n'
            f'                {{\n                    over "Surface"\n                    {{\n'
            f"                        color3f inputs:diffuseColor = {colours[i % 3]}\n"
            f"                    }}\n                }}\n            }}\n        }}"
            for i, v in enumerate(variants))
        variant_block = f'    variantSet "appearance" = {{\n{entries}\n    }}\n'
        meta = f' (\n    variants = {{ string appearance = "{variants[0]}" }}\n    prepend variantSets = "appearance"\n)'
    # Variant opinions are weaker than local ones (LIVRPS): with variants, only they set the colour.
    local_colour = "" if variants else "                color3f inputs:diffuseColor = (0.5, 0.5, 0.5)\n"
    return f"""#usda 1.0
(
    defaultPrim = "{name}"
    metersPerUnit = 1
    upAxis = "Z"
)

def Xform "{name}"{meta}
{{
    def Mesh "Geom" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {{
        float3[] extent = [{tuple(lo)}, {tuple(hi)}]
        int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
        int[] faceVertexIndices = [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
        rel material:binding = </{name}/Looks/Body>
        point3f[] points = [{points}]
        uniform token subdivisionScheme = "none"
    }}

    def Scope "Looks"
    {{
        def Material "Body"
        {{
            token outputs:surface.connect = </{name}/Looks/Body/Surface.outputs:surface>

            def Shader "Surface"
            {{
                uniform token info:id = "UsdPreviewSurface"
{local_colour}                token outputs:surface
            }}
        }}
    }}
{variant_block}}}
"""


def _environment_usda(places: dict) -> str:
    blocks = []
    for name, place in sorted(places.items()):
        regions = []
        for rel, (pose, size) in place["regions"].items():
            mat = pose.as_array().T  # Gf row-vector layout
            rows = ", ".join("(" + ", ".join(repr(float(v)) for v in row) + ")" for row in mat)
            regions.append(f"""            def Xform "{rel.replace('is_', '')}"
            {{
                uniform token usdscene:place:relation = "{rel}"
                double3 usdscene:place:size = ({size[0]}, {size[1]}, {size[2]})
                matrix4d xformOp:transform = ( {rows} )
                uniform token[] xformOpOrder = ["xformOp:transform"]
            }}""")
        blocks.append(f"""        def Xform "{name}"
        {{
            uniform token usdscene:place:kind = "{place['kind']}"
{chr(10).join(regions)}
        }}""")
    return f"""#usda 1.0
(
    defaultPrim = "test_cabin"
    metersPerUnit = 1
    upAxis = "Z"
)

def Xform "test_cabin"
{{
    def Cube "Floor"
    {{
        double size = 1
        float3 xformOp:scale = (20, 20, 0.02)
        double3 xformOp:translate = (0, 0, -0.01)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
    }}

    def Scope "Places"
    {{
{chr(10).join(blocks)}
    }}
}}
"""


def build_test_catalog(folder: Path) -> Path:
    """Write the test catalog into ``folder``; returns ``folder``."""
    folder = Path(folder)
    (folder / "objects").mkdir(parents=True, exist_ok=True)
    (folder / "environments").mkdir(parents=True, exist_ok=True)
    classes = {}
    for name, (lo, hi, variants) in OBJECT_CLASSES.items():
        (folder / "objects" / f"{name}.usda").write_text(_asset_usda(name, lo, hi, variants))
        classes[name] = {
            "kind": "object", "usd": f"objects/{name}.usda", "description": f"test {name}",
            "variants": {"appearance": list(variants)} if variants else {},
            "default_variants": {"appearance": variants[0]} if variants else {},
            "extent_m": [list(lo), list(hi)],
            "relations": ["is_on", "is_below", "is_in", "is_in_front_of"],
        }
    places = make_places()
    (folder / "environments" / "test_cabin.usda").write_text(_environment_usda(places))
    classes["test_cabin"] = {
        "kind": "environment", "usd": "environments/test_cabin.usda", "description": "test cabin",
        "extent_m": [[-10, -10, 0], [10, 10, 3]],
        "places": {name: {"kind": p["kind"], "regions": {
            rel: {"matrix": list(pose.matrix), "size_m": list(size)}
            for rel, (pose, size) in p["regions"].items()}} for name, p in places.items()},
    }
    (folder / "catalog.json").write_text(json.dumps(
        {"format": "usdscene-catalog", "version": 1, "classes": classes}, indent=2))
    return folder


def load_test_catalog(folder: Path):
    return load_catalog([folder], include_default=False)


def pinhole(width=64, height=48, f=50.0, cx=None, cy=None, distortion=(), lens=m.LensModel.PERSPECTIVE,
            fov_deg=None) -> m.Intrinsics:
    return m.Intrinsics(lens=lens, width_px=width, height_px=height, fx_px=f, fy_px=f,
                        cx_px=(width - 1) / 2 if cx is None else cx,
                        cy_px=(height - 1) / 2 if cy is None else cy,
                        distortion=tuple(distortion), fov_deg=fov_deg, sensor_width_mm=6.4)


def look_at_cv(eye, target) -> m.Pose:
    """OpenCV camera pose at ``eye`` looking at ``target`` with world Z roughly up in the image."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return m.Pose.from_rotation_translation(np.stack([x, y, z], axis=1), eye)


def small_scene(seed: int = 7) -> m.SceneSpec:
    """The golden example: 2 cameras, 3 lights, places, relations, noise, colours, 6 frames."""
    cam_moving = m.Camera(
        name="cam_aisle", intrinsics=pinhole(f=40.0, cx=30.0, cy=25.5, distortion=(-0.1, 0.01, 0.001, 0.0, 0.0),
                                             lens=m.LensModel.OPENCV_PINHOLE),
        pose=look_at_cv((2.0, 3.0, 2.0), (2.0, 0.0, 0.5)),
        frame_poses=((3, look_at_cv((2.5, 3.0, 2.0), (2.0, 0.0, 0.5))),
                     (4, look_at_cv((2.5, 3.0, 2.0), (2.0, 0.0, 0.5)))),
        clip_near_m=0.05, clip_far_m=50.0, model_name="Test Cam 1", description="over the aisle",
        custom={"mount": "ceiling"})
    cam_fish = m.Camera(name="cam_fish", intrinsics=pinhole(f=20.0, lens=m.LensModel.OPENCV_FISHEYE,
                                                            distortion=(0.01, -0.002, 0.0, 0.0), fov_deg=180.0),
                        pose=look_at_cv((1.0, -1.0, 2.2), (1.5, 0.0, 0.0)))
    lights = (
        m.Light(uid="l1", name="cabin_light", kind=m.LightKind.AREA, pose=m.Pose.from_rotation_translation(np.eye(3), (2, 0, 2.3)),
                power_w=150.0, size_m=(1.5, 0.2)),
        m.Light(uid="l2", name="reading_spot", kind=m.LightKind.SPOT,
                pose=m.Pose.from_rotation_translation(np.eye(3), (1.0, 0.0, 2.0)), power_w=20.0,
                spot_angle_deg=40.0, spot_blend=0.3, color_rgb=(1.0, 0.9, 0.8),
                frame_intervals=(m.FrameInterval(2, 4),)),
        m.Light(uid="l3", name="sun", kind=m.LightKind.SUN, power_w=3.0),
    )
    places = (m.PlaceRef("p1", "seat_01A"), m.PlaceRef("p2", "seat_01B"), m.PlaceRef("p3", "aisle_01"))
    noisy = m.Randomization(position_noise_m=0.02, rotation_noise_deg=5.0)
    objects = (
        m.SceneObject(uid="o1", name="bag one", class_name="bag", frame_intervals=(m.FrameInterval(0, 5),),
                      randomization=m.Randomization(position_noise_m=0.02, rotation_noise_deg=5.0,
                                                    random_color=True, random_appearance=True)),
        m.SceneObject(uid="o2", name="box", class_name="box", frame_intervals=(m.FrameInterval(0, 5),),
                      randomization=noisy, appearance="striped"),
        m.SceneObject(uid="o3", name="cup on box", class_name="cup", frame_intervals=(m.FrameInterval(1, 4),),
                      color_rgb=(0.9, 0.1, 0.1)),
        m.SceneObject(uid="o4", name="pinned", class_name="cup", frame_intervals=(m.FrameInterval(0, 2),),
                      pose=_yaw_pose(45.0, 3.0, 2.0, 0.0)),
    )
    relations = (
        m.Relation("r1", "is_below", "o1", "p1", (m.FrameInterval(0, 2),)),
        m.Relation("r2", "is_on", "o1", "p2", (m.FrameInterval(3, 5),)),
        m.Relation("r3", "is_on", "o2", "p3"),
        m.Relation("r4", "is_on", "o3", "o2"),
        m.Relation("r5", "looks_at", "o3", "o1"),
    )
    return m.SceneSpec(
        name="golden", frame_start=0, frame_end=5, cameras=(cam_moving, cam_fish), lights=lights,
        objects=objects, places=places, relations=relations,
        render=m.RenderSettings(samples=2, resolution_px=(64, 48), seed=3), seed=seed,
        environment="test_cabin", exports=("coco",), roi_rules={"is_below": "correct"},
        description="small composition example",
        provenance=m.Provenance(source="golden.openlabel.json", source_sha256="0" * 64))


def test_test_catalog_loads_and_assets_open(tmp_path):
    from pxr import Usd, UsdGeom

    catalog = load_test_catalog(build_test_catalog(tmp_path / "cat"))
    assert catalog.classes("environment") == ("test_cabin",)
    assert set(catalog.places("test_cabin")) >= {"seat_01A", "aisle_01", "hall"}
    for name in OBJECT_CLASSES:
        stage = Usd.Stage.Open(str(catalog[name].usd_path))
        prim = stage.GetDefaultPrim()
        box = UsdGeom.Imageable(prim).ComputeWorldBound(0, "default").ComputeAlignedRange()
        assert np.allclose(box.GetMin(), catalog[name].extent_min_m, atol=1e-6)
        assert np.allclose(box.GetMax(), catalog[name].extent_max_m, atol=1e-6)


test_test_catalog_loads_and_assets_open = pytest.mark.usd(test_test_catalog_loads_and_assets_open)


# --------------------------------------------------------------------------------------------
# Comparing scenes with a tolerance (poses within 1e-6 m / 1e-4 degrees)

POSITION_TOL_M = 1e-6
ANGLE_TOL_DEG = 1e-4


def pose_difference(a: m.Pose, b: m.Pose) -> tuple[float, float]:
    """(translation distance in metres, rotation angle between the two in degrees)."""
    dt = float(np.linalg.norm(a.translation_m - b.translation_m))
    r = a.rotation.T @ b.rotation
    cos = max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0))
    # acos is ill-conditioned near 0: use the skew part for small angles.
    sin = np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    return dt, math.degrees(math.atan2(sin, cos))


def scene_differences(a, b, where: str = "scene", rel: float = 1e-6) -> list[str]:
    """Every difference between two scene-model values (dataclasses, tuples, mappings, poses,
    floats with relative tolerance ``rel``); provenance is ignored."""
    import dataclasses
    import enum

    out: list[str] = []
    if isinstance(a, m.Pose) and isinstance(b, m.Pose):
        dt, da = pose_difference(a, b)
        if dt > POSITION_TOL_M or da > ANGLE_TOL_DEG:
            out.append(f"{where}: poses differ by {dt:.3g} m / {da:.3g} deg")
        return out
    if isinstance(a, m.Provenance):
        return out
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        if type(a) is not type(b):
            return [f"{where}: {type(a).__name__} vs {type(b).__name__}"]
        for f in dataclasses.fields(a):
            out += scene_differences(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}", rel)
        return out
    if isinstance(a, enum.Enum) or isinstance(b, enum.Enum):
        return [] if a == b else [f"{where}: {a!r} != {b!r}"]
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items vs {len(b)}: {a!r} vs {b!r}"[:300]]
        for i, (x, y) in enumerate(zip(a, b)):
            out += scene_differences(x, y, f"{where}[{i}]", rel)
        return out
    if isinstance(a, dict) or hasattr(a, "keys"):
        if not hasattr(b, "keys") or set(a.keys()) != set(b.keys()):
            return [f"{where}: keys {sorted(a)} vs {sorted(b) if hasattr(b, 'keys') else b!r}"]
        for k in a:
            out += scene_differences(a[k], b[k], f"{where}[{k!r}]", rel)
        return out
    if isinstance(a, float) or isinstance(b, float):
        if a is None or b is None or not math.isclose(float(a), float(b), rel_tol=rel, abs_tol=1e-9):
            return [f"{where}: {a!r} != {b!r}"]
        return out
    return [] if a == b else [f"{where}: {a!r} != {b!r}"]


def assert_scenes_close(a, b, rel: float = 1e-6) -> None:
    diffs = scene_differences(a, b, rel=rel)
    assert not diffs, "\n".join(diffs[:20])
