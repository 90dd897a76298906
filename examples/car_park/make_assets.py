"""Stand-in for the modelling tool: writes the car park's source files as a DCC tool would.

    python examples/car_park/make_assets.py        # writes examples/car_park/source/

* ``source/car_park.glb``: the environment, Y up and metres as glTF exporters write it. Places
  are boxes named ``place.<place>.<region>``, exactly what a modeller adds in Blender:
  ``place.bay_A3.on`` (a parking bay), ``place.lane_A3.on`` (the driving lane in front of it),
  ``place.walkway_A3.on`` (the footpath behind it). Materials named ``surface.<kind>``
  (``surface.asphalt``, ``surface.concrete``, ``surface.painted_line``, ``surface.tiles``,
  ``surface.metal``, ``surface.glass``, ``surface.grass``) ask for usdscene's procedural
  surfaces; lamp posts, bins, bollards and a sign stand beside the footpaths; nodes named
  ``backdrop.*`` are the surroundings (ground, roads, trees, shrubs, buildings to the horizon).
* ``source/vehicle.usda``: a vehicle, Y up and in centimetres (as many DCC exports are), with
  the variant sets ``model`` (sedan, hatchback, van) and ``paint`` (five colours); its front
  (the bonnet, the cabin set back from it) faces +X, as many exporters leave a car.
* ``source/pedestrian.usda``: a standing person, Z up, metres, variant set ``appearance``.

Nothing here is usdscene-specific except the place names: the files then go through
``usdscene assets add`` like any file from Blender, Maya or Houdini (see README.md).
Deterministic: the same script writes the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent

# Layout in Z-up metres (converted to Y up when the GLB is written).
BAY_X_M = (-5.2, -2.6, 0.0, 2.6, 5.2)   # bay centres along x, two rows
BAY_SIZE_M = (2.4, 5.0)                 # usable width x length of a bay
ROW_Y_M = {"A": 5.5, "B": -5.5}         # bay centres along y (row A north, row B south)
ROOF_Y_M = (-11.0, 0.5)                 # the roof deck covers the south half: the north is open sky
ROOF_Z_M = 3.2
CONCRETE = (150, 150, 148)
PAINT_WHITE = (235, 235, 228)
PAINT_YELLOW = (225, 185, 40)
WALL = (185, 178, 165)
KERB = (120, 120, 118)

Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])


ASPHALT = (70, 70, 72)
DECK_ASPHALT = (98, 98, 100)
GRASS = (62, 82, 40)
FOLIAGE = (48, 72, 34)
BARK = (70, 55, 42)
FACADE = ((176, 170, 160), (140, 128, 112), (196, 192, 184), (120, 116, 112))
GLASS = (40, 48, 58)
POST_GREY = (110, 112, 114)
BIN_GREEN = (30, 58, 40)
BOLLARD_YELLOW = (200, 160, 30)
SIGN_BLUE = (20, 60, 140)


def _paint(mesh: trimesh.Trimesh, colour, surface: str | None) -> trimesh.Trimesh:
    """Colour a part; ``surface`` names the procedural surface its material asks for
    (a material called ``surface.<kind>``, the convention usdscene's import reads)."""
    if surface is None:
        mesh.visual.face_colors = [*colour, 255]
    else:
        mesh.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
            name=f"surface.{surface}", baseColorFactor=[*colour, 255], metallicFactor=0.0, roughnessFactor=0.8))
    return mesh


def _box(size_m, centre_m, colour, surface: str | None = None) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=size_m)
    box.apply_translation(centre_m)
    return _paint(box, colour, surface)


def _cylinder(radius_m, height_m, bottom_m, colour, surface: str | None = None, sections: int = 8):
    cylinder = trimesh.creation.cylinder(radius=radius_m, height=height_m, sections=sections)
    cylinder.apply_translation((bottom_m[0], bottom_m[1], bottom_m[2] + height_m / 2))
    return _paint(cylinder, colour, surface)


def _blob(radius_m, centre_m, squash, colour, surface: str | None = None, subdivisions: int = 1):
    blob = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius_m)
    blob.apply_scale((1.0, 1.0, squash))
    blob.apply_translation(centre_m)
    return _paint(blob, colour, surface)


def clutter_parts() -> list[tuple[str, trimesh.Trimesh]]:
    """What stands about a real car park, outside the walk and drive places: lamp posts
    (north, open deck), bins, bollards and a sign in the strip between the footpaths and the
    parapet / south wall."""
    parts = []
    for i, x in enumerate((-12.0, -4.0, 4.0, 12.0)):  # 6 m lamp posts on the open north side
        parts.append((f"lamp_post_{i}", _cylinder(0.07, 6.0, (x, 11.55, 0.0), POST_GREY, "metal")))
        parts.append((f"lamp_arm_{i}", _box((0.08, 1.2, 0.08), (x, 11.0, 5.95), POST_GREY, "metal")))
        parts.append((f"lamp_head_{i}", _box((0.25, 0.5, 0.12), (x, 10.45, 5.85), POST_GREY, "metal")))
    for side, y in (("n", 11.55), ("s", -11.55)):
        for i, x in enumerate((-8.0, 8.0)):
            parts.append((f"bin_{side}{i}", _cylinder(0.28, 1.0, (x, y, 0.0), BIN_GREEN, "metal", sections=12)))
        for i, x in enumerate((-15.2, -14.4, 14.4, 15.2)):
            parts.append((f"bollard_{side}{i}", _cylinder(0.1, 0.9, (x, y, 0.0), BOLLARD_YELLOW, "metal", sections=6)))
    parts.append(("sign_pole", _cylinder(0.04, 2.2, (0.0, 11.55, 0.0), POST_GREY, "metal")))
    parts.append(("sign_plate", _box((0.6, 0.04, 0.6), (0.0, 11.5, 1.95), SIGN_BLUE, "metal")))
    return parts


def surroundings_parts() -> list[tuple[str, trimesh.Trimesh]]:
    """Ground, roads, trees, shrubs and buildings to the horizon, so no camera looks into a void.

    Every node is named ``backdrop.*``: scenery for the picture, which usdscene keeps out of
    the environment's obstacles, occluders, camera mounts and extent. The ground is 1.2 km square (a camera 6 m up sees it up to 0.6 degrees below the
    horizon); buildings stand 35-110 m away with ribbon windows on the faces towards the deck.
    """
    rng = np.random.default_rng(41)
    parts = [("backdrop.ground", _box((1200.0, 1200.0, 0.1), (0.0, 0.0, -0.08), GRASS, "grass")),
             ("backdrop.road_east", _box((9.0, 1200.0, 0.1), (24.0, 0.0, -0.06), ASPHALT, "asphalt")),
             ("backdrop.road_north", _box((1200.0, 9.0, 0.1), (0.0, 22.0, -0.055), ASPHALT, "asphalt"))]
    for i, x in enumerate(np.arange(-15.0, 16.0, 5.0)):  # a row of trees beyond the parapet
        y = 15.5 + rng.uniform(-0.5, 0.5)
        height = rng.uniform(2.2, 3.0)
        parts.append((f"backdrop.tree_trunk_{i}", _cylinder(0.14, height, (x, y, -0.03), BARK, "concrete")))
        for k in range(2):
            centre = (x + rng.uniform(-0.5, 0.5), y + rng.uniform(-0.5, 0.5), height + 0.6 + 1.0 * k)
            parts.append((f"backdrop.tree_crown_{i}_{k}", _blob(rng.uniform(1.3, 1.8), centre, 0.8, FOLIAGE, "grass")))
    for i, x in enumerate(np.arange(-16.0, 17.0, 2.6)):  # shrubs along the parapet, outside
        parts.append((f"backdrop.shrub_{i}", _blob(0.6, (x, 12.9, 0.2), 0.7, FOLIAGE, "grass", subdivisions=0)))
    for i, y in enumerate((-8.0, -4.0, 4.0, 8.0)):  # lamp posts along the east road
        parts.append((f"backdrop.street_lamp_{i}", _cylinder(0.08, 7.0, (19.2, y, -0.03), POST_GREY, "metal")))
    # Buildings on a ring around the deck: (centre angle, distance, width, depth, floors).
    for i in range(10):
        angle = 2 * np.pi * i / 10 + rng.uniform(-0.15, 0.15)
        distance = rng.uniform(35.0, 110.0)
        width, depth, floors = rng.uniform(14.0, 30.0), rng.uniform(10.0, 16.0), int(rng.integers(2, 7))
        height = 3.2 * floors + 0.6
        cx, cy = distance * np.cos(angle), distance * np.sin(angle)
        facade = FACADE[i % len(FACADE)]
        # Turned so that one long face looks at the deck: axis-aligned boxes turned by the angle.
        turn = trimesh.transformations.rotation_matrix(angle + np.pi / 2, (0, 0, 1), (cx, cy, 0))
        block = _box((width, depth, height), (cx, cy, height / 2 - 0.03), facade, "concrete")
        parts.append((f"backdrop.building_{i}", block.apply_transform(turn)))
        for floor in range(floors):
            z = 3.2 * floor + 1.9
            # Local +y turns to face the deck (the origin).
            band = _box((width - 1.6, 0.1, 1.4), (cx, cy + depth / 2 + 0.02, z), GLASS, "glass")
            parts.append((f"backdrop.building_{i}_window_{floor}", band.apply_transform(turn)))
    return parts


def environment_parts() -> tuple[list[tuple[str, trimesh.Trimesh]], list[tuple[str, tuple, tuple]]]:
    """(scenery, place boxes) in Z-up metres: (name, mesh) and (name, size, bottom centre)."""
    parts = [("floor", _box((34.0, 24.0, 0.2), (0.0, 0.0, -0.1), DECK_ASPHALT, "asphalt")),
             ("roof", _box((34.0, ROOF_Y_M[1] - ROOF_Y_M[0], 0.3),
                           (0.0, sum(ROOF_Y_M) / 2, ROOF_Z_M + 0.15), CONCRETE, "concrete")),
             ("wall_south", _box((34.0, 0.3, ROOF_Z_M), (0.0, -12.0, ROOF_Z_M / 2), WALL, "concrete")),
             ("wall_west", _box((0.3, 24.0, ROOF_Z_M), (-17.0, 0.0, ROOF_Z_M / 2), WALL, "concrete")),
             ("parapet_north", _box((34.0, 0.3, 1.1), (0.0, 12.0, 0.55), WALL, "concrete"))]
    for i, x in enumerate((-9.1, -3.9, 3.9, 9.1)):
        parts.append((f"pillar_{i}", _box((0.5, 0.5, ROOF_Z_M), (x, -8.6, ROOF_Z_M / 2), CONCRETE, "concrete")))
        parts.append((f"pillar_{i}_n", _box((0.5, 0.5, ROOF_Z_M), (x, 0.25, ROOF_Z_M / 2), CONCRETE, "concrete")))
    places = []
    for row, y in ROW_Y_M.items():
        inward = -np.sign(y)  # towards the lane
        edges = [x - 1.3 for x in BAY_X_M] + [BAY_X_M[-1] + 1.3]
        for j, x in enumerate(edges):
            parts.append((f"line_{row}{j}", _box((0.12, BAY_SIZE_M[1], 0.01), (x, y, 0.005), PAINT_WHITE,
                                                 "painted_line")))
        parts.append((f"kerb_{row}", _box((34.0, 0.25, 0.15), (0.0, y - inward * 2.9, 0.075), KERB, "concrete")))
        for k, x in enumerate(BAY_X_M, start=1):
            name = f"{row}{k}"
            places.append((f"place.bay_{name}.on", (*BAY_SIZE_M, 2.2), (x, y, 0.0)))
            places.append((f"place.lane_{name}.on", (2.4, 1.6, 2.2), (x, y + inward * 3.4, 0.0)))
            places.append((f"place.walkway_{name}.on", (2.4, 1.4, 2.2), (x, y - inward * 3.9, 0.15)))
    for k in range(-6, 7):
        parts.append((f"lane_mark_{k}", _box((1.2, 0.12, 0.01), (2.6 * k, 0.0, 0.005), PAINT_YELLOW,
                                             "painted_line")))
    parts.append(("walkway_A", _box((34.0, 2.5, 0.15), (0.0, 9.8, 0.075), KERB, "tiles")))
    parts.append(("walkway_B", _box((34.0, 2.5, 0.15), (0.0, -9.8, 0.075), KERB, "tiles")))
    parts += clutter_parts() + surroundings_parts()
    return parts, places


def write_environment(path: Path) -> Path:
    """The car park as a Y-up glTF binary with its place boxes."""
    parts, places = environment_parts()
    scene = trimesh.Scene()
    for name, mesh in parts:
        scene.add_geometry(mesh.copy().apply_transform(Z_UP_TO_Y_UP), node_name=name, geom_name=name)
    for name, size, bottom in places:
        box = trimesh.creation.box(extents=size)
        box.apply_transform(Z_UP_TO_Y_UP)  # the box's local frame is Y up too
        placed = np.eye(4)
        placed[:3, 3] = (bottom[0], bottom[1], bottom[2] + size[2] / 2)
        scene.add_geometry(box, node_name=name, geom_name=name,
                           transform=Z_UP_TO_Y_UP @ placed @ Z_UP_TO_Y_UP.T)
    path.write_bytes(scene.export(file_type="glb"))
    return path


# --- objects, written with pxr as a DCC's USD exporter would -------------------------------

OUTFITS = {  # jacket, trousers, skin
    "grey_coat": ((0.25, 0.25, 0.27), (0.05, 0.05, 0.08), (0.72, 0.53, 0.42)),
    "red_jacket": ((0.55, 0.06, 0.05), (0.12, 0.12, 0.20), (0.45, 0.30, 0.22)),
    "yellow_vest": ((0.85, 0.70, 0.05), (0.10, 0.10, 0.12), (0.60, 0.42, 0.30)),
    "blue_hoodie": ((0.06, 0.15, 0.45), (0.25, 0.22, 0.18), (0.30, 0.20, 0.14)),
}


def _material(stage, path: str, rgb, roughness: float = 0.5):
    from pxr import Gf, Sdf, UsdShade

    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    color = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    if rgb is not None:
        color.Set(Gf.Vec3f(*rgb))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(roughness)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material, color


def _mesh(stage, path: str, mesh: trimesh.Trimesh, material) -> None:
    from pxr import UsdGeom, UsdShade, Vt

    usd = UsdGeom.Mesh.Define(stage, path)
    points = Vt.Vec3fArray.FromNumpy(np.round(mesh.vertices, 3).astype(np.float32))
    usd.CreatePointsAttr(points)
    usd.CreateFaceVertexCountsAttr([3] * len(mesh.faces))
    usd.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.faces.reshape(-1).astype(np.int32)))
    usd.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(points))
    usd.CreateSubdivisionSchemeAttr("none")
    UsdShade.MaterialBindingAPI.Apply(usd.GetPrim()).Bind(material)


def _in_cm_y_up(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    return mesh.copy().apply_transform(Z_UP_TO_Y_UP)


# Materials of the vehicle's parts: (rgb, roughness, usdscene surface kind or None).
VEHICLE_LOOKS = {
    "glass": ((0.03, 0.04, 0.05), 0.05, "glass"), "tyres": ((0.015, 0.015, 0.015), 0.9, None),
    "rims": ((0.45, 0.46, 0.48), 0.3, "metal"), "headlights": ((0.85, 0.85, 0.80), 0.1, None),
    "taillights": ((0.45, 0.02, 0.02), 0.2, None), "plates": ((0.80, 0.80, 0.74), 0.5, None),
}


# The car park's models and paints: the three models and five paint names its documents were
# generated with (``generate tracks`` draws an appearance per vehicle, so a longer list would
# change every draw after it), each no larger than the block model it replaced.
CAR_PARK_MODELS = ("sedan", "hatchback", "van")
CAR_PARK_PAINTS = ("red", "blue", "silver", "black", "white")


def write_vehicle(path: Path) -> Path:
    """The vehicle: Y up, centimetres, variant sets ``model`` (usdscene's procedural body
    types) and ``paint`` (fleet paints)."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    from usdscene.assetgen.vehicles import PAINT_VARIANTS, vehicle_parts
    from usdscene.document.surfaces import SURFACE_ATTRIBUTE

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/Vehicle").GetPrim()
    stage.SetDefaultPrim(root)
    paint, paint_color = _material(stage, "/Vehicle/Looks/Paint", None, roughness=0.25)
    looks = {name: _material(stage, f"/Vehicle/Looks/{name.capitalize()}", rgb, roughness)[0]
             for name, (rgb, roughness, _) in VEHICLE_LOOKS.items()}
    to_cm = np.diag([100.0, 100.0, 100.0, 1.0])
    models = root.GetVariantSets().AddVariantSet("model")
    for name in CAR_PARK_MODELS:
        models.AddVariant(name)
        models.SetVariantSelection(name)
        with models.GetVariantEditContext():
            for part, mesh in vehicle_parts(name).items():
                prim_path = f"/Vehicle/{part.capitalize()}"
                material = paint if part in ("body", "mirrors") else looks[part]
                _mesh(stage, prim_path, _in_cm_y_up(mesh.copy().apply_transform(to_cm)), material)
                kind = VEHICLE_LOOKS.get(part, (None, None, None))[2]
                if kind is not None:
                    stage.GetPrimAtPath(prim_path).CreateAttribute(
                        SURFACE_ATTRIBUTE, Sdf.ValueTypeNames.String, custom=True).Set(kind)
    models.SetVariantSelection("sedan")
    paints = root.GetVariantSets().AddVariantSet("paint")
    for name in CAR_PARK_PAINTS:
        rgb = PAINT_VARIANTS[name]
        paints.AddVariant(name)
        paints.SetVariantSelection(name)
        with paints.GetVariantEditContext():
            paint_color.Set(Gf.Vec3f(*rgb))
    paints.SetVariantSelection("silver")
    path.write_text(stage.GetRootLayer().ExportToString())
    return path


def write_pedestrian(path: Path) -> Path:
    """A standing adult, 1.75 m, facing -Y: Z up, metres, variant set ``appearance``."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Pedestrian").GetPrim()
    stage.SetDefaultPrim(root)
    jacket, jacket_color = _material(stage, "/Pedestrian/Looks/Jacket", None, roughness=0.8)
    trousers, trousers_color = _material(stage, "/Pedestrian/Looks/Trousers", None, roughness=0.8)
    skin, skin_color = _material(stage, "/Pedestrian/Looks/Skin", None, roughness=0.6)
    legs = []
    for side in (-0.1, 0.1):
        leg = trimesh.creation.capsule(height=0.72, radius=0.075, count=[8, 8])
        leg.apply_translation((side, 0.0, 0.075 + 0.36))
        legs.append(leg)
    torso = trimesh.creation.capsule(height=0.42, radius=0.19, count=[8, 10])
    torso.apply_scale((1.0, 0.62, 1.0))
    torso.apply_translation((0.0, 0.0, 1.12))
    arms = []
    for side in (-0.26, 0.26):
        arm = trimesh.creation.capsule(height=0.52, radius=0.055, count=[6, 8])
        arm.apply_translation((side, 0.0, 1.08))
        arms.append(arm)
    head = trimesh.creation.icosphere(subdivisions=2, radius=0.11)
    head.apply_scale((0.9, 1.0, 1.15))
    head.apply_translation((0.0, 0.0, 1.62))
    _mesh(stage, "/Pedestrian/Legs", trimesh.util.concatenate(legs), trousers)
    _mesh(stage, "/Pedestrian/Torso", trimesh.util.concatenate([torso, *arms]), jacket)
    _mesh(stage, "/Pedestrian/Head", head, skin)
    outfits = root.GetVariantSets().AddVariantSet("appearance")
    for name, (top, bottom, face) in OUTFITS.items():
        outfits.AddVariant(name)
        outfits.SetVariantSelection(name)
        with outfits.GetVariantEditContext():
            jacket_color.Set(Gf.Vec3f(*top))
            trousers_color.Set(Gf.Vec3f(*bottom))
            skin_color.Set(Gf.Vec3f(*face))
    outfits.SetVariantSelection("grey_coat")
    path.write_text(stage.GetRootLayer().ExportToString())
    return path


def main() -> None:
    out = HERE / "source"
    out.mkdir(exist_ok=True)
    for written in (write_environment(out / "car_park.glb"), write_vehicle(out / "vehicle.usda"),
                    write_pedestrian(out / "pedestrian.usda")):
        print(f"wrote {written.relative_to(HERE)} ({written.stat().st_size / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()
