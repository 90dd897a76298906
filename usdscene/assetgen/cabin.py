"""The ``aircraft_cabin`` environment: a single-aisle 3+3 cabin section with named places.

Cabin frame (Z up, metres, floor at z = 0):

- **X** runs along the cabin towards the front (galley). The aft face of the front partition
  (galley wall) is at x = 0; rows are numbered from the front (row 01 is nearest the
  partition), so the cabin extends towards negative x.
- **Y** points to the left when facing forward; the cabin is centred on the aisle (y = 0).
  Seats A-C are on the +Y side (A at the window), D-F on the -Y side (F at the window).
- Every seat faces +X.

Places (``<defaultPrim>/Places/<place>/<region>``, each region an Xform whose transform maps
the region frame to the cabin frame, plus ``usdscene:place:size`` and
``usdscene:place:relation``):

- ``seat_<row:02d><letter>``: ``on`` (cushion top), ``below`` (floor under the seat in front;
  row 01 has no seat in front, so its ``below`` is the floor under its own seat), ``in_front``
  (the legroom floor in front of the cushion), ``back_pocket`` (the literature pocket on the
  back of the seat in front; row 01 uses the pocket on the partition).
- ``bin_<row:02d><L|R>``: ``in`` (the floor of the overhead bin above that row; L = +Y side).
- ``aisle_<row:02d>``: ``on`` (the aisle floor beside that row).

Region frames: Z up, the support surface at z = 0, usable box x ∈ ±size_x/2, y ∈ ±size_y/2,
z ∈ [0, size_z]; size_z is the real clearance (under a seat ≈ 0.28 m). Every region frame is
the cabin frame turned +90° about Z: its -Y axis points to the front of the cabin (+X) and its
+X axis to the left (+Y). Assets face -Y, so an object or passenger placed without yaw faces
forward like the seats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Kind, Sdf, Usd, UsdGeom

from usdscene.document import stage_schema
from usdscene.assetgen import mesh as m
from usdscene.assetgen.usd_write import (MaterialSpec, author_places, define_material, define_mesh,
                                         in_variant, new_asset_stage, set_transform, set_translate)
from usdscene.scene.catalog import REGION_RELATIONS, Place, PlaceRegion, places_for_catalog
from usdscene.document.model import Pose

SEAT_LETTERS = "ABCDEF"


@dataclass(frozen=True)
class CabinConfig:
    """Dimensions of the generated cabin (metres).

    Attributes:
        rows: number of seat rows (numbered 01..rows from the front).
        seat_pitch_m: distance between the same point of two consecutive rows.
        aisle_width_m: free width between the armrests of seats C and D.
        seat_spacing_m: centre-to-centre distance of two seats of a row (cushion + armrest).
        first_row_gap_m: distance from the partition to the front edge of row 01's cushion.
        cushion_height_m: height of the seat cushion top above the floor.
        under_seat_clearance_m: free height under a seat pan.
    """

    rows: int = 20
    seat_pitch_m: float = 0.79
    aisle_width_m: float = 0.5
    seat_spacing_m: float = 0.48
    first_row_gap_m: float = 0.42
    cushion_height_m: float = 0.45
    under_seat_clearance_m: float = 0.28


ROOT = "AircraftCabin"
PROTOTYPES = "/_Prototypes"

MATERIALS = {
    "SeatFabric": MaterialSpec((0.05, 0.09, 0.22), roughness=0.9),
    "Headrest": MaterialSpec((0.75, 0.75, 0.72), roughness=0.85),
    "SeatShell": MaterialSpec((0.32, 0.33, 0.35), roughness=0.45),
    "SeatFrame": MaterialSpec((0.55, 0.56, 0.58), roughness=0.35, metallic=0.8),
    "Pocket": MaterialSpec((0.03, 0.03, 0.04), roughness=0.8),
    "Carpet": MaterialSpec((0.12, 0.14, 0.20), roughness=0.95),
    "AisleCarpet": MaterialSpec((0.20, 0.08, 0.08), roughness=0.95),
    "Sidewall": MaterialSpec((0.78, 0.77, 0.74), roughness=0.5),
    "Ceiling": MaterialSpec((0.85, 0.85, 0.84), roughness=0.5),
    "WindowReveal": MaterialSpec((0.70, 0.70, 0.70), roughness=0.4),
    "Bin": MaterialSpec((0.80, 0.80, 0.78), roughness=0.45),
    "BinDoor": MaterialSpec((0.88, 0.88, 0.86), roughness=0.35),
    "BinInterior": MaterialSpec((0.35, 0.35, 0.37), roughness=0.8),
    "Partition": MaterialSpec((0.62, 0.58, 0.52), roughness=0.5),
    "Curtain": MaterialSpec((0.08, 0.10, 0.25), roughness=0.9),
    "CoveLight": MaterialSpec((0.9, 0.9, 0.9), roughness=0.5, emissive=(2.0, 1.9, 1.7)),
}

# Cross-section of the left (+Y) inner wall from the floor up to the ceiling centre, (y, z) m.
_WALL_PROFILE = np.array([
    (1.60, 0.00), (1.68, 0.20), (1.74, 0.45), (1.77, 0.78), (1.77, 1.12), (1.74, 1.35),
    (1.66, 1.55), (1.52, 1.80), (1.32, 2.02), (1.05, 2.18), (0.75, 2.25), (0.35, 2.28), (0.0, 2.28),
])
_WALL_TOP_INDEX = 6        # profile rows up to here are sidewall, above are ceiling
_WINDOW_ROWS = (3, 4)      # the window hole spans profile rows 3..4 (z 0.78..1.12)
WINDOW_WIDTH_M = 0.26
BIN_Y_AISLE_M = 1.08       # aisle face of the bins
BIN_Y_BACK_M = 1.62
BIN_Z_FLOOR_M = 1.58
BIN_Z_TOP_M = 1.98


def row_front_x(config: CabinConfig, row: int) -> float:
    """x of the cushion front edge of ``row`` (1-based), metres."""
    return -config.first_row_gap_m - (row - 1) * config.seat_pitch_m


def seat_y(config: CabinConfig, letter: str) -> float:
    """y of the centre of seat ``letter`` (A..F), metres."""
    index = SEAT_LETTERS.index(letter)
    from_aisle = index - 3 if index >= 3 else 2 - index  # 0 for C/D, 2 for A/F
    y = config.aisle_width_m / 2 + config.seat_spacing_m * (from_aisle + 0.5)
    return y if index < 3 else -y


def rear_wall_x(config: CabinConfig) -> float:
    """x of the rear wall of the cabin (behind the last row), metres."""
    return row_front_x(config, config.rows) - 0.48 - 0.62


# --- seat geometry (seat frame: origin on the floor under the cushion front edge centre) ----

_BACK_TILT_DEG = 12.0
_BACK_BASE = np.array([-0.49, 0.0, 0.42])
_BACK_DIR = np.array([-np.sin(np.radians(_BACK_TILT_DEG)), 0.0, np.cos(np.radians(_BACK_TILT_DEG))])
_BACK_FWD = np.array([np.cos(np.radians(_BACK_TILT_DEG)), 0.0, np.sin(np.radians(_BACK_TILT_DEG))])
_BACK_THICKNESS = 0.10


def _on_backrest(s: float, offset_fwd: float) -> np.ndarray:
    """A point ``s`` m up the backrest centre line and ``offset_fwd`` m in front of it."""
    return _BACK_BASE + s * _BACK_DIR + offset_fwd * _BACK_FWD


def backrest_clearance_m(points_seat: np.ndarray, pitch_rows: float = 0.0) -> np.ndarray:
    """Signed distance (N,) of seat-frame points in front of the backrest's front face (of
    the seat ``pitch_rows`` seat pitches further forward, its rear shell face when
    ``pitch_rows`` is 1): positive = in front of it. Used to seat people against the
    backrest and clear of the seat in front."""
    base = _BACK_BASE + np.array([pitch_rows * CabinConfig().seat_pitch_m, 0.0, 0.0])
    rel = np.asarray(points_seat, dtype=np.float64) - base
    d = rel @ _BACK_FWD
    if pitch_rows:
        return -(d + 0.0955)  # behind its pocket (the rearmost part of the shell): positive = clear
    # The headrest (0.22 m tall around 0.55 m up the backrest) stands 0.08 m proud of it.
    up = rel @ _BACK_DIR
    headrest = (up > 0.44) & (up < 0.66) & (np.abs(rel[:, 1]) < 0.19)
    return d - np.where(headrest, 0.08, _BACK_THICKNESS / 2)


ARMREST_SIZE_M = (0.40, 0.04, 0.05)
ARMREST_CENTRE_M = (-0.25, 0.22, 0.62)
"""The left armrest's box (seat frame); the right one is its mirror image across y = 0."""


def armrest_depth_m(points_seat: np.ndarray, config: CabinConfig = CabinConfig()) -> np.ndarray:
    """Depth (N,) of seat-frame points inside an armrest beside the seat: its own two and the
    neighbours' two next to them (``seat_spacing_m`` further out), each as its bounding box (the
    mesh's rounded edges lie inside it); 0 outside. Used to keep seated people's hips and
    thighs out of them."""
    p = np.asarray(points_seat, dtype=np.float64)
    size = np.asarray(ARMREST_SIZE_M)
    depth = np.zeros(len(p))
    for y in (ARMREST_CENTRE_M[1], config.seat_spacing_m - ARMREST_CENTRE_M[1]):
        for side in (1.0, -1.0):
            centre = np.array([ARMREST_CENTRE_M[0], side * y, ARMREST_CENTRE_M[2]])
            d = (size / 2 - np.abs(p - centre)).min(axis=1)  # > 0 inside: to the nearest face
            depth = np.maximum(depth, d)
    return depth


def _tilted(mesh: m.MeshData, centre: np.ndarray) -> m.MeshData:
    return mesh.transformed(m.translation(centre) @ m.rotation_y(-_BACK_TILT_DEG))


def seat_parts(config: CabinConfig) -> dict[str, m.MeshData]:
    """Meshes of one seat by material name (≈1.5k triangles)."""
    top = config.cushion_height_m
    pan = config.under_seat_clearance_m + 0.02
    fabric = [
        m.rounded_box((0.46, 0.43, 0.11), 0.04).translated((-0.235, 0.0, top - 0.055)),
        _tilted(m.rounded_box((_BACK_THICKNESS, 0.43, 0.64), 0.04), _on_backrest(0.32, 0.0)),
    ]
    headrest = [_tilted(m.rounded_box((0.05, 0.38, 0.22), 0.02), _on_backrest(0.55, 0.055))]
    shell = [
        # Hard back shell with the tray table, and the armrests.
        _tilted(m.rounded_box((0.02, 0.41, 0.50), 0.008, 1), _on_backrest(0.34, -0.06)),
        _tilted(m.rounded_box((0.018, 0.36, 0.26), 0.008, 1), _on_backrest(0.45, -0.079)),
        *(m.rounded_box(ARMREST_SIZE_M, 0.015, 1).translated(np.multiply(ARMREST_CENTRE_M, (1.0, side, 1.0)))
          for side in (1.0, -1.0)),
        m.box((0.44, 0.44, 0.04)).translated((-0.24, 0.0, pan + 0.02)),
    ]
    pocket = [_tilted(m.rounded_box((0.025, 0.34, 0.20), 0.008, 1), _on_backrest(0.14, -0.083))]
    frame = [
        m.box((0.035, 0.03, pan)).translated((-0.09, 0.22, pan / 2)),
        m.box((0.035, 0.03, pan)).translated((-0.42, 0.22, pan / 2)),
        m.box((0.40, 0.03, 0.03)).translated((-0.255, 0.22, 0.015)),
        m.box((0.035, 0.03, 0.34)).translated((-0.22, 0.22, pan + 0.17)),
        # The baggage restraint bar in front of the under-seat stowage.
        m.cylinder(0.008, 0.44, 8, caps=False).transformed(
            m.translation((-0.07, 0.22, 0.06)) @ m.rotation_x(90.0)),
    ]
    return {"SeatFabric": m.merge(fabric), "Headrest": m.merge(headrest),
            "SeatShell": m.merge(shell), "Pocket": m.merge(pocket), "SeatFrame": m.merge(frame)}


def _pocket_region_local() -> tuple[np.ndarray, tuple[float, float, float]]:
    """Pocket bottom centre in the frame of the seat that carries it, and the pocket size."""
    bottom = _on_backrest(0.05, -0.083 - 0.02)
    return bottom, (0.04, 0.32, 0.18)


# --- walls, floor, ceiling -----------------------------------------------------------------

def _resample_x(config: CabinConfig) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """x breakpoints of the wall grid (front partition to rear wall, increasing x) and the
    column index ranges that are window holes."""
    windows = sorted((row_front_x(config, r) - 0.30 - WINDOW_WIDTH_M / 2,
                      row_front_x(config, r) - 0.30 + WINDOW_WIDTH_M / 2)
                     for r in range(1, config.rows + 1))
    xs = [rear_wall_x(config)]
    holes = []
    for lo, hi in windows:
        xs.extend([lo, hi])
        holes.append((len(xs) - 2, len(xs) - 1))
    xs.append(0.0)
    return np.asarray(xs), holes


def _wall_surfaces(config: CabinConfig, side: float) -> dict[str, list[m.MeshData]]:
    xs, holes = _resample_x(config)
    profile = _WALL_PROFILE.copy()
    grid = np.zeros((len(xs), len(profile), 3))
    grid[..., 0] = xs[:, None]
    grid[..., 1] = side * profile[None, :, 0]
    grid[..., 2] = profile[None, :, 1]
    full = m.quad_strip(grid)
    quads = full.face_indices.reshape(-1, 4)
    n_rows = len(profile) - 1
    col = np.arange(len(quads)) // n_rows
    row = np.arange(len(quads)) % n_rows
    hole_cols = {c for c, _ in holes}
    is_hole = np.isin(col, list(hole_cols)) & (row == _WINDOW_ROWS[0])
    # Normals must face the aisle (y → 0); quad_strip's orientation depends on the side.
    flip = np.dot(full.normals[len(profile) + 3], [0.0, -side, 0.0]) < 0
    if flip:
        quads = quads[:, ::-1]
        normals = -full.normals
    else:
        normals = full.normals

    def subset(mask: np.ndarray) -> m.MeshData:
        q = quads[mask]
        return m.MeshData(full.points, normals, np.full(len(q), 4, dtype=np.int32),
                          q.reshape(-1).astype(np.int32))

    sidewall = subset(~is_hole & (row < _WALL_TOP_INDEX))
    ceiling = subset(row >= _WALL_TOP_INDEX)
    reveals = []
    y0, z0 = profile[_WINDOW_ROWS[0]]
    y1, z1 = profile[_WINDOW_ROWS[1]]
    depth = 0.09
    for c0, c1 in holes:
        xa, xb = xs[c0], xs[c1]
        inner = [(xa, side * y0, z0), (xb, side * y0, z0), (xb, side * y1, z1), (xa, side * y1, z1)]
        ring = np.asarray(inner)
        outer = ring + [0.0, side * depth, 0.0]
        loop = np.concatenate([ring, ring[:1]])
        loop_out = np.concatenate([outer, outer[:1]])
        tube = m.quad_strip(np.stack([loop, loop_out], axis=0))
        reveals.append(tube)
        reveals.append(_window_bezel((xa + xb) / 2, side * (y0 - 0.004), (z0 + z1) / 2, side,
                                     (xb - xa) / 2, (z1 - z0) / 2))
    return {"Sidewall": [sidewall], "Ceiling": [ceiling], "WindowReveal": reveals}


def _window_bezel(x: float, y: float, z: float, side: float, half_w: float, half_h: float,
                  points: int = 32) -> m.MeshData:
    """A flat frame just inside the wall around a window hole: rectangular outside, rounded
    inside (a squircle inscribed in the rectangular hole), facing the aisle."""
    t = np.linspace(0.0, 2 * np.pi, points, endpoint=False)
    c, s = np.cos(t), np.sin(t)
    # Squircle |u/a|^4 + |v/b|^4 = 1: rounded corners like a real cabin window.
    u = half_w * np.sign(c) * np.abs(c) ** 0.5
    v = half_h * np.sign(s) * np.abs(s) ** 0.5
    outer_w, outer_h = half_w + 0.06, half_h + 0.07
    scale = np.minimum(outer_w / np.maximum(np.abs(u), 1e-9), outer_h / np.maximum(np.abs(v), 1e-9))
    rings = [np.stack([x + u * k, np.full(points, y), z + v * k], axis=1) for k in (np.ones(points), scale)]
    bezel = m.quad_strip(np.stack(rings, axis=0), closed=True)
    if np.dot(bezel.normals[0], [0.0, -side, 0.0]) < 0:
        quads = bezel.face_indices.reshape(-1, 4)[:, ::-1]
        bezel = m.MeshData(bezel.points, -bezel.normals, bezel.face_counts, quads.reshape(-1).astype(np.int32))
    return bezel


def _end_wall(config: CabinConfig, x: float, facing: float, thickness: float) -> m.MeshData:
    """A solid wall filling the cabin cross-section at ``x``; ``facing`` = +1 faces +X."""
    prof = _WALL_PROFILE
    # Fill between the two sides row by row: a (rows, 2) grid per face.
    left = np.stack([np.full(len(prof), x), prof[:, 0], prof[:, 1]], axis=1)
    right = np.stack([np.full(len(prof), x), -prof[:, 0], prof[:, 1]], axis=1)
    face = m.quad_strip(np.stack([left, right], axis=1))
    if np.dot(face.normals[0], [facing, 0.0, 0.0]) < 0:
        q = face.face_indices.reshape(-1, 4)[:, ::-1]
        face = m.MeshData(face.points, -face.normals, face.face_counts, q.reshape(-1).astype(np.int32))
    back = face.translated((-facing * thickness, 0.0, 0.0))
    back = m.MeshData(back.points, -back.normals, back.face_counts,
                      back.face_indices.reshape(-1, 4)[:, ::-1].reshape(-1).astype(np.int32))
    return m.merge([face, back])


def _floor(config: CabinConfig) -> dict[str, list[m.MeshData]]:
    x0, x1 = rear_wall_x(config), 0.0
    half_aisle = config.aisle_width_m / 2
    outer = _WALL_PROFILE[0, 0] + 0.02
    carpet = []
    for sign in (1.0, -1.0):
        width = outer - half_aisle
        carpet.append(m.box((x1 - x0, width, 0.02)).translated(((x0 + x1) / 2, sign * (half_aisle + width / 2), -0.01)))
    aisle = m.box((x1 - x0, 2 * half_aisle, 0.02)).translated(((x0 + x1) / 2, 0.0, -0.01))
    return {"Carpet": carpet, "AisleCarpet": [aisle]}


def _bins(config: CabinConfig) -> tuple[dict[str, list[m.MeshData]], dict[str, dict[str, list[m.MeshData]]]]:
    """Fixed bin shells by material, and the doors per configuration variant."""
    fixed: dict[str, list[m.MeshData]] = {"Bin": [], "BinInterior": [], "CoveLight": []}
    doors = {"bins_open": [], "bins_closed": []}
    x_back, x_front = rear_wall_x(config) + 0.05, -0.02
    length = x_front - x_back
    depth = BIN_Y_BACK_M - BIN_Y_AISLE_M
    height = BIN_Z_TOP_M - BIN_Z_FLOOR_M
    for side in (1.0, -1.0):
        yc = side * (BIN_Y_AISLE_M + depth / 2)
        xc = (x_back + x_front) / 2
        fixed["Bin"].append(m.box((length, depth + 0.02, 0.04)).translated((xc, yc, BIN_Z_FLOOR_M - 0.02)))
        fixed["Bin"].append(m.box((length, depth, 0.03)).translated((xc, yc, BIN_Z_TOP_M + 0.015)))
        fixed["BinInterior"].append(m.box((length, 0.03, height)).translated(
            (xc, side * (BIN_Y_BACK_M - 0.015), BIN_Z_FLOOR_M + height / 2)))
        # Passenger service units (reading lights) under the bins.
        fixed["BinInterior"].append(m.box((length, 0.10, 0.02)).translated(
            (xc, side * (BIN_Y_AISLE_M + 0.12), BIN_Z_FLOOR_M - 0.05)))
        fixed["CoveLight"].append(m.box((length, 0.03, 0.015)).translated(
            (xc, side * (BIN_Y_AISLE_M + 0.05), BIN_Z_TOP_M + 0.04)))
        edges = sorted({row_front_x(config, r) - 0.25 + config.seat_pitch_m / 2 for r in range(1, config.rows + 1)}
                       | {x_back})
        for xe in edges:
            fixed["Bin"].append(m.box((0.02, depth, height)).translated((min(max(xe, x_back + 0.01), x_front - 0.01), yc,
                                                                          BIN_Z_FLOOR_M + height / 2)))
        for r in range(1, config.rows + 1):
            xr = row_front_x(config, r) - 0.25
            door = m.rounded_box((config.seat_pitch_m - 0.02, 0.03, height + 0.02), 0.012, 1)
            closed = door.translated((xr, side * (BIN_Y_AISLE_M - 0.015), BIN_Z_FLOOR_M + height / 2))
            # Open: hinged on the top aisle edge and swung up towards the aisle by 105°.
            angle = 105.0
            hinge = np.array([xr, side * BIN_Y_AISLE_M, BIN_Z_TOP_M + 0.01])
            local = door.translated((0.0, -side * 0.015, -(height + 0.02) / 2))
            rot = m.rotation_x(-side * angle)
            opened = local.transformed(m.translation(hinge) @ rot)
            doors["bins_closed"].append(closed)
            doors["bins_open"].append(opened)
    return fixed, doors


# --- places ----------------------------------------------------------------------------------

# Region frames are the cabin frame turned +90° about Z, so that a region's -Y axis points to
# the front of the cabin (+X), the way the seats face: assets face -Y (Blender's front view),
# so an asset placed with no yaw faces forward like the passengers.
REGION_ROTATION = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _region(relation_region: str, centre: np.ndarray, size_cabin: tuple[float, float, float]) -> tuple[str, PlaceRegion]:
    """A region centred at ``centre`` (cabin frame) whose box spans ``size_cabin`` along the
    cabin's (x, y, z) axes; stored in the rotated region frame (x and y sizes swapped)."""
    pose = Pose.from_rotation_translation(REGION_ROTATION, np.round(np.asarray(centre, dtype=np.float64), 4) + 0.0)
    size = (size_cabin[1], size_cabin[0], size_cabin[2])
    size_r = tuple(round(float(v), 4) for v in size)
    return relation_region, PlaceRegion(relation=REGION_RELATIONS[relation_region], pose=pose, size_m=size_r)  # type: ignore[arg-type]


def cabin_places(config: CabinConfig) -> dict[str, tuple[str, dict[str, PlaceRegion]]]:
    """Place name → (kind, region name → region) in the cabin frame, sorted by name."""
    places: dict[str, tuple[str, dict[str, PlaceRegion]]] = {}
    pocket_local, pocket_size = _pocket_region_local()
    top = config.cushion_height_m
    clearance = config.under_seat_clearance_m
    for r in range(1, config.rows + 1):
        xf = row_front_x(config, r)
        for letter in SEAT_LETTERS:
            y = seat_y(config, letter)
            regions = dict([
                # Headroom above the cushion up to the bins (1.58 m), 1.10 m.
                _region("on", np.array([xf - 0.235, y, top]), (0.42, 0.40, 1.10)),
                # Legroom: from the cushion edge to the front seat's pan, under its backrest.
                _region("in_front", np.array([xf + 0.16, y, 0.0]), (0.28, 0.40, 0.42)),
            ])
            if r == 1:
                below_x = xf - 0.28
                # Row 01's pocket hangs on the partition, bottom 0.55 m above the floor.
                pocket = np.array([-0.03, y, 0.55])
            else:
                front = row_front_x(config, r - 1)
                below_x = front - 0.28
                pocket = pocket_local + [front, y, 0.0]
            regions.update([
                _region("below", np.array([below_x, y, 0.0]), (0.42, 0.40, clearance)),
                _region("back_pocket", pocket, pocket_size),
            ])
            places[f"seat_{r:02d}{letter}"] = ("seat", regions)
        xc = xf - 0.25
        for side_name, side in (("L", 1.0), ("R", -1.0)):
            yc = side * (BIN_Y_AISLE_M + BIN_Y_BACK_M - 0.03) / 2
            places[f"bin_{r:02d}{side_name}"] = ("bin", dict([
                _region("in", np.array([xc, yc, BIN_Z_FLOOR_M]),
                        (config.seat_pitch_m - 0.04, BIN_Y_BACK_M - BIN_Y_AISLE_M - 0.06,
                         BIN_Z_TOP_M - BIN_Z_FLOOR_M - 0.02))]))
        places[f"aisle_{r:02d}"] = ("aisle", dict([
            _region("on", np.array([xc, 0.0, 0.0]), (config.seat_pitch_m - 0.04, config.aisle_width_m - 0.06, 2.0))]))
    return dict(sorted(places.items()))


# --- the asset --------------------------------------------------------------------------------

def build_cabin(config: CabinConfig = CabinConfig()) -> tuple[Usd.Stage, dict[str, Place]]:
    """Author the cabin asset in memory.

    Returns:
        (stage, places): the stage (write it with ``save_stage``) and its places for the
        catalog (cabin frame = asset frame).
    """
    stage, root_prim = new_asset_stage(ROOT, Kind.Tokens.assembly)
    root = str(root_prim.GetPath())
    looks = f"{root}/{stage_schema.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    materials = {name: define_material(stage, f"{looks}/{name}", spec) for name, spec in MATERIALS.items()}

    # One seat prototype (an abstract class prim outside the default prim), referenced by
    # every seat: small files, one set of materials in every importer.
    stage.CreateClassPrim(PROTOTYPES)
    proto = UsdGeom.Xform.Define(stage, f"{PROTOTYPES}/Seat")
    for name, part in seat_parts(config).items():
        define_mesh(stage, f"{proto.GetPath()}/{name}", part, materials[name])

    shell = UsdGeom.Xform.Define(stage, f"{root}/Shell")
    groups: dict[str, list[m.MeshData]] = {}
    for side_name, side in (("L", 1.0), ("R", -1.0)):
        for mat, parts in _wall_surfaces(config, side).items():
            groups.setdefault(f"{mat}{side_name}|{mat}", []).extend(parts)
    for mat, parts in _floor(config).items():
        groups.setdefault(f"{mat}|{mat}", []).extend(parts)
    groups["FrontPartition|Partition"] = [_end_wall(config, 0.0, -1.0, 0.06)]
    groups["RearWall|Partition"] = [_end_wall(config, rear_wall_x(config), 1.0, 0.06)]
    # Galley curtain in the aisle, and the row-01 literature pockets on the partition.
    groups["GalleyCurtain|Curtain"] = [m.box((0.02, 0.70, 1.95)).translated((-0.012, 0.0, 0.975))]
    groups["BulkheadPockets|Pocket"] = [
        m.rounded_box((0.03, 0.34, 0.20), 0.008, 1).translated((-0.015, seat_y(config, letter), 0.65))
        for letter in SEAT_LETTERS]
    fixed_bins, doors = _bins(config)
    for mat, parts in fixed_bins.items():
        groups[f"Bins{mat}|{mat}"] = parts
    for key in sorted(groups):
        prim_name, mat = key.split("|")
        define_mesh(stage, f"{shell.GetPath()}/{prim_name}", m.merge(groups[key]), materials[mat])

    configuration = stage_schema.VARIANT_SET_CONFIGURATION
    for variant in ("bins_open", "bins_closed"):
        with in_variant(root_prim, configuration, variant):
            define_mesh(stage, f"{root}/Shell/BinDoors", m.merge(doors[variant]), materials["BinDoor"])
    root_prim.GetVariantSets().GetVariantSet(configuration).SetVariantSelection("bins_open")

    seats = UsdGeom.Scope.Define(stage, f"{root}/Seats")
    for r in range(1, config.rows + 1):
        for letter in SEAT_LETTERS:
            seat = UsdGeom.Xform.Define(stage, f"{seats.GetPath()}/Seat_{r:02d}{letter}").GetPrim()
            seat.GetReferences().AddInternalReference(proto.GetPath())
            set_translate(seat, (row_front_x(config, r), seat_y(config, letter), 0.0))

    places = cabin_places(config)
    author_places(stage, root, places)
    return stage, places_for_catalog(places)


def describe(config: CabinConfig) -> str:
    """Catalog description: the frame and place conventions in one paragraph."""
    return (
        f"Single-aisle 3+3 cabin section, {config.rows} rows (01 at the front) x seats A-F, "
        f"seat pitch {config.seat_pitch_m} m, aisle {config.aisle_width_m} m. Frame: Z up, metres, "
        "floor at z=0; +X towards the front galley, aft face of the front partition at x=0, rows "
        "towards -X; +Y to the left facing forward, aisle centred on y=0, seats A-C on +Y (A at "
        "the window), D-F on -Y. Places: seat_<row><letter> (on, below = under the seat in front "
        "[row 01: under its own seat], in_front = legroom floor, back_pocket = pocket on the seat "
        "in front [row 01: on the partition]), bin_<row><L|R> (in; L = +Y), aisle_<row> (on). Region frames are the cabin frame "
        "turned +90 deg about Z (region -Y = cabin +X, the way seats face; assets face -Y). "
        "Variant set 'configuration': bins_open | bins_closed.")
