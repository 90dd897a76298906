"""The ``passenger`` class: a seated, articulated adult figure with pose and appearance variants.

Asset frame: Z up, metres, origin at the seated hip contact point (the middle of the cushion
area the passenger sits on), facing -Y like every library asset (the joint tables below are
written facing +X and turned -90° about Z when written). Placing the passenger ``is_on`` a
seat (origin on the cushion region's origin, no yaw) seats it facing forward with its back
against the backrest and its feet on the floor 0.45 m below. The figure is built from capsules and ellipsoids per body segment (pelvis,
abdomen, chest, neck, head, upper arms, forearms, hands, thighs, shins, feet).

Variant sets on the default prim: ``pose`` (geometry) and ``appearance`` (colours: skin,
clothing, trousers, hair). ``Body`` is the top/shirt material, the one a per-object colour
overrides.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Kind, UsdGeom

from usdscene.document import stage_schema
from usdscene.assetgen import mesh as m
from usdscene.assetgen.usd_write import (MaterialSpec, bounds_of_stage, define_material, define_mesh,
                                         in_variant, new_asset_stage, save_stage, set_material_color)
from usdscene.scene.catalog import AssetEntry, Place, PlaceRegion
from usdscene.document.model import Pose as PoseMatrix

FLOOR_BELOW_HIP_M = 0.45


@dataclass(frozen=True)
class Pose:
    """Joint layout of one seated pose (passenger frame, metres / degrees).

    Attributes:
        recline_deg: spine tilt backwards from vertical.
        lean_deg: spine tilt sideways (positive towards +Y).
        head_pitch_deg: head tilt forward relative to the spine.
        head_roll_deg: head tilt sideways (positive towards +Y).
        elbows: ((x, y, z), (x, y, z)) left (+Y), right elbow positions.
        wrists: left, right wrist positions.
        knee_spread_m: extra sideways knee distance.
    """

    recline_deg: float
    lean_deg: float
    head_pitch_deg: float
    head_roll_deg: float
    elbows: tuple[tuple[float, float, float], tuple[float, float, float]]
    wrists: tuple[tuple[float, float, float], tuple[float, float, float]]
    knee_spread_m: float = 0.0


POSES: dict[str, Pose] = {
    "upright": Pose(8.0, 0.0, 5.0, 0.0, ((-0.07, 0.25, 0.25), (-0.07, -0.25, 0.25)),
                    ((0.16, 0.16, 0.20), (0.16, -0.16, 0.20))),
    "leaning": Pose(10.0, 9.0, 8.0, 14.0, ((-0.08, 0.28, 0.30), (-0.05, -0.23, 0.25)),
                    ((0.14, 0.27, 0.27), (0.16, -0.10, 0.19)), 0.03),
    "reading": Pose(2.0, 0.0, 22.0, 0.0, ((-0.02, 0.24, 0.28), (-0.02, -0.24, 0.28)),
                    ((0.24, 0.10, 0.38), (0.24, -0.10, 0.38))),
    "sleeping": Pose(20.0, -4.0, 25.0, -20.0, ((-0.04, 0.24, 0.22), (-0.04, -0.24, 0.22)),
                     ((0.14, -0.05, 0.22), (0.14, 0.05, 0.25)), 0.05),
}

SKIN = {"light": (0.75, 0.52, 0.40), "medium": (0.52, 0.33, 0.20), "dark": (0.22, 0.12, 0.07)}
HAIR = {"blond": (0.55, 0.40, 0.18), "brown": (0.12, 0.06, 0.03), "black": (0.02, 0.02, 0.02),
        "grey": (0.45, 0.45, 0.45)}
# name → (skin, top colour, trousers colour, hair)
APPEARANCES: dict[str, tuple[str, tuple[float, float, float], tuple[float, float, float], str]] = {
    "light_blue_shirt": ("light", (0.15, 0.30, 0.60), (0.05, 0.05, 0.08), "blond"),
    "light_red_sweater": ("light", (0.50, 0.05, 0.05), (0.20, 0.18, 0.15), "grey"),
    "medium_green_jacket": ("medium", (0.08, 0.25, 0.12), (0.04, 0.05, 0.12), "black"),
    "medium_white_shirt": ("medium", (0.80, 0.80, 0.78), (0.25, 0.22, 0.18), "brown"),
    "dark_yellow_top": ("dark", (0.70, 0.55, 0.10), (0.05, 0.05, 0.05), "black"),
    "dark_grey_hoodie": ("dark", (0.25, 0.25, 0.27), (0.10, 0.12, 0.25), "black"),
}
DEFAULT_POSE = "upright"
DEFAULT_APPEARANCE = "light_blue_shirt"


def _ellipsoid_along(centre: np.ndarray, axis: np.ndarray, radii: tuple[float, float, float],
                     rings: int = 8, sectors: int = 12) -> m.MeshData:
    """An ellipsoid whose z radius lies along ``axis`` (x radius kept roughly along +X)."""
    z = axis / np.linalg.norm(axis)
    x = np.array([1.0, 0.0, 0.0]) - z * z[0]
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    t = np.eye(4)
    t[:3, :3] = np.stack([x, y, z], axis=1)
    t[:3, 3] = centre
    return m.ellipsoid(radii, rings, sectors).transformed(t)


def _rotate(v: np.ndarray, axis: str, angle_deg: float) -> np.ndarray:
    rot = {"x": m.rotation_x, "y": m.rotation_y}[axis](angle_deg)[:3, :3]
    return rot @ v


def figure_segments(pose: Pose) -> dict[str, tuple[str, m.MeshData]]:
    """Named body segments of the figure in ``pose``: segment → (material, mesh), passenger
    frame facing +X (metres). Segments: pelvis, abdomen, chest, neck, head, hair,
    upper_arm_/forearm_/hand_/thigh_/shin_/shoe_ + left (+Y) or right."""
    up = np.array([0.0, 0.0, 1.0])
    spine = _rotate(_rotate(up, "y", -pose.recline_deg), "x", -pose.lean_deg)
    base = np.array([-0.09, 0.0, 0.13])
    chest = base + 0.30 * spine
    neck_base = base + 0.49 * spine
    head_dir = _rotate(_rotate(spine, "y", pose.head_pitch_deg), "x", -pose.head_roll_deg)
    head = neck_base + 0.16 * head_dir
    side = np.cross(spine, np.array([1.0, 0.0, 0.0]))
    side = -side / np.linalg.norm(side)  # +Y-ish
    shoulders = [neck_base - 0.04 * spine + s * 0.19 * side for s in (1.0, -1.0)]

    out: dict[str, tuple[str, m.MeshData]] = {
        "abdomen": ("Body", _ellipsoid_along(base + 0.13 * spine, spine, (0.11, 0.16, 0.15), 10, 16)),
        "chest": ("Body", _ellipsoid_along(chest + 0.02 * spine, spine, (0.12, 0.19, 0.19), 10, 16)),
        "neck": ("Skin", m.capsule(neck_base - 0.03 * spine, neck_base + 0.07 * spine, 0.052, 0.048, 3, 10)),
        "head": ("Skin", _ellipsoid_along(head, head_dir, (0.095, 0.078, 0.115))),
        "hair": ("Hair", _ellipsoid_along(head + 0.035 * head_dir - 0.015 * np.array([1.0, 0.0, 0.0]), head_dir,
                                          (0.098, 0.083, 0.09), 6, 12)),
    }
    for side_name, shoulder, elbow, wrist in zip(("left", "right"), shoulders, pose.elbows, pose.wrists):
        elbow, wrist = np.asarray(elbow), np.asarray(wrist)
        out[f"upper_arm_{side_name}"] = ("Body", m.capsule(shoulder, elbow, 0.050, 0.042, 3, 10))
        out[f"forearm_{side_name}"] = ("Skin", m.capsule(elbow, wrist, 0.036, 0.028, 3, 10))
        direction = (wrist - elbow) / np.linalg.norm(wrist - elbow)
        out[f"hand_{side_name}"] = ("Skin", _ellipsoid_along(wrist + 0.06 * direction, direction,
                                                             (0.022, 0.045, 0.07), 5, 10))
    out["pelvis"] = ("Trousers", _ellipsoid_along(np.array([-0.05, 0.0, 0.10]), up, (0.13, 0.17, 0.09)))
    for side_name, s in (("left", 1.0), ("right", -1.0)):
        hip = np.array([-0.03, s * 0.09, 0.09])
        knee = np.array([0.40, s * (0.11 + pose.knee_spread_m), 0.12])
        ankle = np.array([0.44, s * (0.11 + pose.knee_spread_m), -FLOOR_BELOW_HIP_M + 0.08])
        out[f"thigh_{side_name}"] = ("Trousers", m.capsule(hip, knee, 0.078, 0.056, 3, 12))
        out[f"shin_{side_name}"] = ("Trousers", m.capsule(knee, ankle, 0.052, 0.038, 3, 10))
        out[f"shoe_{side_name}"] = ("Shoes", m.rounded_box((0.26, 0.095, 0.075), 0.03, 2).translated(
            (ankle[0] + 0.07, ankle[1], -FLOOR_BELOW_HIP_M + 0.0375)))
    return out


def figure_parts(pose: Pose) -> dict[str, list[m.MeshData]]:
    """Meshes of the figure in ``pose`` by material (Body, Skin, Trousers, Shoes, Hair)."""
    parts: dict[str, list[m.MeshData]] = {"Body": [], "Skin": [], "Trousers": [], "Shoes": [], "Hair": []}
    for material, mesh in figure_segments(pose).values():
        parts[material].append(mesh)
    return parts


LAP_PLACE = "lap"
LAP_MIN_CLEARANCE_M = 0.03
"""Free height above the thighs a lap needs (a magazine, a phone, a closed laptop)."""
LAP_CELL_M = 0.01
"""Grid of the free-space search over the thighs."""
LAP_MARGIN_M = 0.015
"""Limb meshes have a vertex every 1-3 cm: each vertex blocks the cells this close."""
LAP_MAX_CLEARANCE_M = 0.25
"""Height a lap holds at most: flat things and small bags, not luggage that would hide the
face (nothing above the lap but open air otherwise bounds it)."""
LAP_SAG_M = 0.01
"""The thighs' top line: thigh points this close below the highest one (knees included)."""
_LAP_SUPPORT = ("thigh_left", "thigh_right")
_LAP_FLOOR = ("pelvis", "abdomen")                 # where the lap begins: the belly ends
_LAP_IGNORED = ("shin_left", "shin_right", "shoe_left", "shoe_right")  # below the lap


def lap_region(pose: Pose) -> PlaceRegion | None:
    """The lap of the figure in ``pose``: the largest box resting on the thighs that no other
    body part (hands, forearms, belly) reaches into.

    The support surface is the top of the thighs (their highest point); the footprint runs
    from where the belly ends to the knees, between the thighs' outer sides, on a
    :data:`LAP_CELL_M` grid; every other segment's vertices block their cells (grown by
    :data:`LAP_MARGIN_M`) from their lowest point up. The largest rectangle whose free height
    is at least :data:`LAP_MIN_CLEARANCE_M` wins (ties: more clearance); its height is the
    free height, at most :data:`LAP_MAX_CLEARANCE_M`.

    Returns:
        The ``is_on`` region in the asset frame (facing -Y: the figure is modelled facing +X
        and turned -90° about Z), or None when no such rectangle exists (hands in the lap).
    """
    segments = figure_segments(pose)
    thighs = np.vstack([segments[n][1].points for n in _LAP_SUPPORT])
    surface = float(thighs[:, 2].max())
    belly = np.vstack([segments[n][1].points for n in _LAP_FLOOR])
    x0 = float(belly[belly[:, 2] >= surface, 0].max())
    top = thighs[thighs[:, 2] >= surface - LAP_SAG_M]
    x1 = float(top[:, 0].max())
    y0, y1 = float(thighs[:, 1].min()), float(thighs[:, 1].max())
    nx, ny = int((x1 - x0) // LAP_CELL_M), int((y1 - y0) // LAP_CELL_M)
    free = np.full((nx, ny), np.inf)  # free height above the surface per cell, metres
    others = [mesh.points for name, (_, mesh) in segments.items()
              if name not in _LAP_SUPPORT + _LAP_IGNORED]
    for p in np.vstack(others):
        i0 = int(np.floor((p[0] - LAP_MARGIN_M - x0) / LAP_CELL_M))
        i1 = int(np.floor((p[0] + LAP_MARGIN_M - x0) / LAP_CELL_M))
        j0 = int(np.floor((p[1] - LAP_MARGIN_M - y0) / LAP_CELL_M))
        j1 = int(np.floor((p[1] + LAP_MARGIN_M - y0) / LAP_CELL_M))
        if i1 < 0 or j1 < 0 or i0 >= nx or j0 >= ny:
            continue
        cells = free[max(i0, 0):i1 + 1, max(j0, 0):j1 + 1]
        np.minimum(cells, p[2] - surface, out=cells)
    best = None  # (area cells, clearance, i0, i1, j0, j1)
    for j0 in range(ny):
        column = np.full(nx, np.inf)
        for j1 in range(j0, ny):
            column = np.minimum(column, free[:, j1])
            ok = column >= LAP_MIN_CLEARANCE_M
            i = 0
            while i < nx:
                if not ok[i]:
                    i += 1
                    continue
                k = i
                while k < nx and ok[k]:
                    k += 1
                area = (k - i) * (j1 - j0 + 1)
                clearance = float(column[i:k].min())
                if best is None or (area, clearance) > best[:2]:
                    best = (area, clearance, i, k, j0, j1 + 1)
                i = k
    if best is None:
        return None
    _, clearance, i0, i1, j0, j1 = best
    cx, cy = x0 + (i0 + i1) / 2.0 * LAP_CELL_M, y0 + (j0 + j1) / 2.0 * LAP_CELL_M
    length, width = (i1 - i0) * LAP_CELL_M, (j1 - j0) * LAP_CELL_M
    clearance = min(clearance, LAP_MAX_CLEARANCE_M)
    # Modelled facing +X; the asset faces -Y: (x, y) → (y, -x), sizes swap.
    matrix = np.eye(4)
    matrix[:3, 3] = [round(cy, 4) + 0.0, round(-cx, 4) + 0.0, round(surface, 4) + 0.0]
    return PlaceRegion(relation="is_on", pose=PoseMatrix.from_matrix(matrix.reshape(16).tolist()),
                       size_m=(round(width, 4), round(length, 4), round(clearance, 4)))


def lap_places() -> dict[str, dict[str, Place]]:
    """``variant_places`` of the pose variant set: pose → {``lap``: Place} (empty when the
    pose has no lap)."""
    out: dict[str, dict[str, Place]] = {}
    for name, pose in POSES.items():
        region = lap_region(pose)
        out[name] = {LAP_PLACE: Place(LAP_PLACE, LAP_PLACE, {"is_on": region})} if region is not None else {}
    return out


def write_passenger_asset(folder: Path) -> AssetEntry:
    """Author ``folder/passengers/passenger.usda``; returns its catalog entry."""
    stage, root = new_asset_stage("passenger", Kind.Tokens.component)
    root_path = str(root.GetPath())
    looks = f"{root_path}/{stage_schema.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    skin, top, trousers, hair = APPEARANCES[DEFAULT_APPEARANCE]
    specs = {
        "Body": MaterialSpec(top, roughness=0.8),
        "Skin": MaterialSpec(SKIN[skin], roughness=0.5),
        "Trousers": MaterialSpec(trousers, roughness=0.85),
        "Shoes": MaterialSpec((0.03, 0.02, 0.02), roughness=0.4),
        "Hair": MaterialSpec(HAIR[hair], roughness=0.7),
    }
    materials = {name: define_material(stage, f"{looks}/{name}", spec,
                                       color_from_variants=name != "Shoes")
                 for name, spec in specs.items()}
    UsdGeom.Xform.Define(stage, f"{root_path}/Geom")
    for pose_name, pose in POSES.items():
        with in_variant(root, stage_schema.VARIANT_SET_POSE, pose_name):
            for name, meshes in sorted(figure_parts(pose).items()):
                # Modelled facing +X; the asset faces -Y like every library asset.
                mesh = m.merge(meshes).transformed(m.rotation_z(-90.0))
                define_mesh(stage, f"{root_path}/Geom/{name}", mesh, materials[name])
    for name, (skin, top, trousers, hair) in APPEARANCES.items():
        with in_variant(root, stage_schema.VARIANT_SET_APPEARANCE, name):
            set_material_color(stage, f"{looks}/Body", top)
            set_material_color(stage, f"{looks}/Skin", SKIN[skin])
            set_material_color(stage, f"{looks}/Trousers", trousers)
            set_material_color(stage, f"{looks}/Hair", HAIR[hair])
    sets = root.GetVariantSets()
    sets.GetVariantSet(stage_schema.VARIANT_SET_POSE).SetVariantSelection(DEFAULT_POSE)
    sets.GetVariantSet(stage_schema.VARIANT_SET_APPEARANCE).SetVariantSelection(DEFAULT_APPEARANCE)
    lo_m, hi_m = bounds_of_stage(stage)  # default pose, like every catalog extent
    path = folder / "passengers" / "passenger.usda"
    save_stage(stage, path)
    lo = tuple(round(float(v), 4) + 0.0 for v in lo_m)
    hi = tuple(round(float(v), 4) + 0.0 for v in hi_m)
    return AssetEntry(
        class_name="passenger", kind="passenger", usd_path=path,
        description=("Seated adult passenger. Origin at the seated hip contact point on the cushion, "
                     f"facing -Y, feet on the floor {FLOOR_BELOW_HIP_M} m below. Recolour the top: "
                     f"{stage_schema.ASSET_COLOR_SHADER}.{stage_schema.ATTR_ASSET_COLOR}."),
        variants={stage_schema.VARIANT_SET_POSE: tuple(POSES),
                  stage_schema.VARIANT_SET_APPEARANCE: tuple(APPEARANCES)},
        default_variants={stage_schema.VARIANT_SET_POSE: DEFAULT_POSE,
                          stage_schema.VARIANT_SET_APPEARANCE: DEFAULT_APPEARANCE},
        extent_min_m=lo, extent_max_m=hi, relations=("is_on",),  # type: ignore[arg-type]
        variant_places={stage_schema.VARIANT_SET_POSE: lap_places()},
        orientations="upright_turned")  # people sit; nobody is laid on a seat
