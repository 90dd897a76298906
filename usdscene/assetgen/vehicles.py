"""Procedural vehicles that read as vehicles: body types with the features a detector uses,
and paint from a real fleet's colour distribution.

Each body type (:data:`BODY_TYPES`: hatchback, sedan, SUV, van, pickup) is a side profile
(bumpers, bonnet, windscreen rake, roof, rear window and boot, hatch, box or bed) with wheel
arches cut into its sills, extruded across the width; then the parts a camera sees at 5-40 m:

* ``body``: the painted shell (profile with the arches);
* ``glass``: windscreen, rear window and the side windows, set in body-colour frames (A, B
  and C pillars, the roof rail and the belt line stay paint);
* ``tyres`` and ``rims`` (wheels in the arches; rims a lighter metal disc on each face);
* ``headlights``, ``taillights``, ``mirrors`` (paint) and ``plates`` (front and rear).

Frame: Z up, metres, the front towards +X, the origin on the ground under the middle of the
wheelbase. Everything is built from the numbers below: deterministic, no files.

Paint (:data:`PAINT_SHARES`): Axalta's Global Automotive Color Popularity Report 2021 (69th
edition), the world's new cars: white 35 %, black 19 %, grey 19 %, silver 9 %, blue 8 %,
red 5 %, the rest (beige, brown, green, yellow and gold) 5 %. :data:`PAINT_VARIANTS` spreads
them over 20 named paints of 5 % each (7 whites, 4 blacks, 4 greys, 2 silvers, 1 blue, 1 red,
1 beige), so a uniform draw over the variants (how ``generate tracks`` picks an appearance) is
a draw from the fleet to within 3 points per colour (blue 5 % for 8 %).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from usdscene.errors import AssetError

PAINT_SHARES: dict[str, float] = {
    "white": 0.35, "black": 0.19, "grey": 0.19, "silver": 0.09, "blue": 0.08, "red": 0.05, "other": 0.05,
}
# 20 paints, 5 % of the fleet each (linear RGB): the shares above in steps of 5 %.
PAINT_VARIANTS: dict[str, tuple[float, float, float]] = {
    "white": (0.80, 0.80, 0.78), "white_pearl": (0.76, 0.75, 0.70), "white_ivory": (0.72, 0.70, 0.62),
    "white_arctic": (0.78, 0.80, 0.82), "white_solid": (0.70, 0.70, 0.69), "white_cream": (0.74, 0.71, 0.64),
    "white_frost": (0.66, 0.68, 0.70),
    "black": (0.02, 0.02, 0.025), "black_metallic": (0.035, 0.035, 0.04), "black_blue": (0.02, 0.025, 0.04),
    "black_onyx": (0.015, 0.015, 0.015),
    "grey": (0.16, 0.16, 0.17), "grey_dark": (0.07, 0.075, 0.08), "grey_graphite": (0.10, 0.10, 0.105),
    "grey_light": (0.30, 0.31, 0.32),
    "silver": (0.55, 0.56, 0.58), "silver_dark": (0.38, 0.39, 0.41),
    "blue": (0.04, 0.10, 0.45), "red": (0.55, 0.04, 0.03), "beige": (0.42, 0.37, 0.27),
}
PAINT_FAMILY = {name: ("other" if name == "beige" else name.split("_")[0]) for name in PAINT_VARIANTS}


@dataclass(frozen=True)
class BodyType:
    """One body type's numbers (metres, degrees).

    Attributes:
        length_m, width_m, height_m: overall size (height to the roof).
        clearance_m: sill height above the ground.
        belt_m: height of the belt line (bonnet top, window bottoms).
        bonnet_m: bonnet length from the front bumper to the windscreen's foot.
        windscreen_rake_deg: windscreen angle from the vertical.
        rear: ``notch`` (sedan boot), ``hatch`` (sloped tailgate), ``box`` (near-vertical
            tailgate: SUV, van) or ``bed`` (pickup: a cab, then an open bed at ``bed_rail_m``).
        rear_window_rake_deg: rear window angle from the vertical.
        boot_m: length of the boot lid (notch) or of the bed (pickup) behind the cabin.
        wheel_radius_m, wheelbase_m: the wheels.
    """

    name: str
    length_m: float
    width_m: float
    height_m: float
    clearance_m: float
    belt_m: float
    bonnet_m: float
    windscreen_rake_deg: float
    rear: str
    rear_window_rake_deg: float
    boot_m: float
    wheel_radius_m: float
    wheelbase_m: float
    bed_rail_m: float = 0.0


BODY_TYPES: dict[str, BodyType] = {b.name: b for b in (
    BodyType("hatchback", 3.97, 1.62, 1.46, 0.17, 0.90, 0.85, 60.0, "hatch", 35.0, 0.0, 0.31, 2.55),
    BodyType("sedan", 4.57, 1.66, 1.44, 0.15, 0.86, 1.05, 58.0, "notch", 50.0, 0.95, 0.32, 2.80),
    BodyType("suv", 4.45, 1.74, 1.70, 0.22, 1.05, 1.00, 58.0, "box", 20.0, 0.0, 0.36, 2.75),
    BodyType("van", 4.80, 1.82, 1.95, 0.18, 1.00, 0.60, 35.0, "box", 5.0, 0.0, 0.33, 3.20),
    BodyType("pickup", 4.70, 1.74, 1.80, 0.25, 1.05, 1.00, 58.0, "bed", 10.0, 1.45, 0.37, 2.95, 1.10),
)}

ROOF_ROUND_M = 0.06       # the roof's edges and the bumpers' corners are cut by this much
FRAME_M = 0.06            # window frames (pillars, rails) left in paint around the glass
GLASS_PROUD_M = 0.004     # glass stands this far off the paint, so it never z-fights
TYRE_WIDTH_M = 0.21
RIM_RADIUS_FRACTION = 0.62


def check_paint_shares(shares: Mapping[str, float], *, field: str) -> None:
    """Refuse a paint distribution with a negative share or shares that do not sum to 1.

    Raises:
        AssetError: naming ``field`` and the value.
    """
    for name, share in shares.items():
        if not (isinstance(share, (int, float)) and math.isfinite(share) and share >= 0):
            raise AssetError(f"share {share!r} of {name!r} is not a number >= 0", where=field)
    total = float(sum(shares.values()))
    if abs(total - 1.0) > 1e-6:
        raise AssetError(f"the shares sum to {total:.6g}, not 1", where=field)


def body_type(name: str, *, where: str) -> BodyType:
    """The body type called ``name``.

    Raises:
        AssetError: an unknown name, naming ``where`` and the value.
    """
    if name not in BODY_TYPES:
        raise AssetError(f"unknown vehicle body type {name!r} (known: {', '.join(BODY_TYPES)})", where=where)
    return BODY_TYPES[name]


def side_profile(b: BodyType) -> tuple[np.ndarray, np.ndarray]:
    """(outline, greenhouse): the body's side profile as (N, 2) (x, z) points counter-clockwise
    seen from +Y (without the wheel arches), and the glazed area above the belt as (M, 2)."""
    front, back = b.length_m / 2, -b.length_m / 2
    r = ROOF_ROUND_M
    ws_foot = front - b.bonnet_m
    ws_run = (b.height_m - b.belt_m) * math.tan(math.radians(b.windscreen_rake_deg))
    roof_front = ws_foot - ws_run
    rear_run = (b.height_m - b.belt_m) * math.tan(math.radians(b.rear_window_rake_deg))
    nose = b.clearance_m + 0.75 * (b.belt_m - b.clearance_m)  # the bumper's top, under the bonnet's lip
    points = [(front, b.clearance_m + 0.05), (front, nose), (front - 0.15, b.belt_m - 0.02), (ws_foot, b.belt_m)]
    if b.rear == "notch":
        boot_top = b.belt_m + 0.05
        rw_foot = back + b.boot_m
        roof_back = rw_foot + rear_run
        points += [(roof_front, b.height_m - r), (roof_front - r, b.height_m), (roof_back + r, b.height_m),
                   (roof_back, b.height_m - r), (rw_foot, boot_top), (back + 0.1, boot_top),
                   (back, boot_top - 0.15)]
        glass_back = (roof_back, rw_foot)
    elif b.rear == "bed":
        cab_back = back + b.boot_m
        points += [(roof_front, b.height_m - r), (roof_front - r, b.height_m), (cab_back + r, b.height_m),
                   (cab_back, b.height_m - r), (cab_back, b.bed_rail_m), (back, b.bed_rail_m)]
        glass_back = (cab_back, cab_back)
    else:  # hatch, box: the roof runs back to a tailgate of the rear window's rake
        tail_foot = back + (0.0 if b.rear == "box" else 0.12)
        roof_back = tail_foot + rear_run
        points += [(roof_front, b.height_m - r), (roof_front - r, b.height_m), (roof_back + r, b.height_m),
                   (roof_back, b.height_m - r), (tail_foot, b.belt_m), (back, b.belt_m - 0.1)]
        glass_back = (roof_back, tail_foot)
    points += [(back, b.clearance_m + 0.05), (back + 0.05, b.clearance_m), (front - 0.05, b.clearance_m)]
    outline = np.array(points[::-1], dtype=float)  # listed clockwise above: reverse
    top = b.height_m - FRAME_M
    low = b.belt_m + FRAME_M / 2
    k_front = (top - low) / (b.height_m - b.belt_m)
    greenhouse = np.array([
        (ws_foot - FRAME_M - (low - b.belt_m) * math.tan(math.radians(b.windscreen_rake_deg)), low),
        (roof_front - FRAME_M, top), (glass_back[0] + FRAME_M, top),
        (glass_back[1] + FRAME_M + (glass_back[0] - glass_back[1]) * (1 - k_front), low)], dtype=float)
    return outline, greenhouse


def _with_arches(outline: np.ndarray, b: BodyType) -> np.ndarray:
    """The outline with a round wheel arch cut into the sill over each axle."""
    arch = b.wheel_radius_m + 0.05
    # The arch meets the sill where the circle round the wheel's centre crosses it.
    theta_max = math.acos((b.clearance_m - b.wheel_radius_m) / arch)
    out = []
    n = len(outline)
    for i in range(n):
        p, q = outline[i], outline[(i + 1) % n]
        out.append(tuple(p))
        if abs(p[1] - b.clearance_m) > 1e-9 or abs(q[1] - b.clearance_m) > 1e-9:
            continue
        d = 1.0 if q[0] > p[0] else -1.0
        for x in sorted((b.wheelbase_m / 2, -b.wheelbase_m / 2), key=lambda a: d * a):
            if min(p[0], q[0]) + arch < x < max(p[0], q[0]) - arch:
                for theta in np.linspace(-d * theta_max, d * theta_max, 15):
                    out.append((x + arch * math.sin(theta), b.wheel_radius_m + arch * math.cos(theta)))
    return np.array(out, dtype=float)


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def triangulate(poly: np.ndarray) -> np.ndarray:
    """(T, 3) triangles of a simple polygon ``(N, 2)`` (counter-clockwise), by ear clipping."""
    idx = list(range(len(poly)))
    tris = []

    def inside(p, a, b, c) -> bool:
        d1 = (p[0] - b[0]) * (a[1] - b[1]) - (a[0] - b[0]) * (p[1] - b[1])
        d2 = (p[0] - c[0]) * (b[1] - c[1]) - (b[0] - c[0]) * (p[1] - c[1])
        d3 = (p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])
        return not ((d1 < 0 or d2 < 0 or d3 < 0) and (d1 > 0 or d2 > 0 or d3 > 0))

    guard = 0
    while len(idx) > 3 and guard < 10000:
        guard += 1
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) <= 1e-12:
                continue  # reflex or degenerate corner
            if any(inside(poly[j], a, b, c) for j in idx if j not in (i0, i1, i2)):
                continue
            tris.append((i0, i1, i2))
            del idx[k]
            break
        else:
            break  # no ear: a degenerate remainder; what is left is dropped
    if len(idx) == 3:
        tris.append(tuple(idx))
    return np.array(tris, dtype=np.int64)


def extrude(poly_xz: np.ndarray, y0: float, y1: float):
    """A closed prism (trimesh) of the (x, z) polygon between y = ``y0`` and ``y1``."""
    import trimesh

    poly = poly_xz if _area(poly_xz) > 0 else poly_xz[::-1]
    n = len(poly)
    near = np.column_stack([poly[:, 0], np.full(n, y0), poly[:, 1]])
    far = np.column_stack([poly[:, 0], np.full(n, y1), poly[:, 1]])
    caps = triangulate(poly)
    # A counter-clockwise (x, z) triangle faces -Y: the near cap as it is, the far one reversed;
    # the walls wind so that their normals point to the right of the outline's travel (out).
    faces = [caps, caps[:, ::-1] + n]
    for i in range(n):
        j = (i + 1) % n
        faces.append(np.array([[i, j + n, j], [i, i + n, j + n]]))
    return trimesh.Trimesh(np.vstack([near, far]), np.vstack(faces), process=True)


def _outwards(mesh):
    """A convex mesh with every face wound outwards (normal away from its centre)."""
    centre = mesh.vertices.mean(axis=0)
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    inward = np.einsum("ij,ij->i", normals, tri.mean(axis=1) - centre) < 0
    faces = mesh.faces.copy()
    faces[inward] = faces[inward][:, ::-1]
    mesh.faces = faces
    return mesh


def _panel(corners: np.ndarray, thickness: float):
    """A thin slab (trimesh) over a planar quad ``(4, 3)``, ``thickness`` along its normal."""
    import trimesh

    normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    normal /= np.linalg.norm(normal)
    pts = np.vstack([corners, corners + thickness * normal])
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2],
                      [2, 6, 7], [2, 7, 3], [3, 7, 4], [3, 4, 0]])
    return _outwards(trimesh.Trimesh(pts, faces, process=True))


def _box(size, centre):
    import trimesh

    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(centre)
    return mesh


def vehicle_parts(name: str) -> dict[str, object]:
    """The parts of body type ``name`` as trimesh meshes (Z up, metres, front +X): ``body``,
    ``glass``, ``tyres``, ``rims``, ``headlights``, ``taillights``, ``mirrors``, ``plates``.

    Raises:
        AssetError: an unknown body type.
    """
    import trimesh

    b = body_type(name, where="vehicle body type")
    outline, greenhouse = side_profile(b)
    half = b.width_m / 2
    body = extrude(_with_arches(outline, b), -half, half)
    # Glass: the side windows in two (a B-pillar of FRAME_M between them), windscreen, rear.
    glass = []
    gx = greenhouse
    split = 0.5 * (gx[0, 0] + gx[3, 0]) if b.rear != "bed" else None
    for side in (-1.0, 1.0):
        y = side * (half + GLASS_PROUD_M)
        quads = []
        if split is None:
            quads.append(gx)
        else:
            # Front and rear panes: the greenhouse cut at the B pillar.
            lo, hi = gx[0, 1], gx[1, 1]
            quads.append(np.array([gx[0], gx[1], (split + FRAME_M / 2, hi), (split + FRAME_M / 2, lo)]))
            quads.append(np.array([(split - FRAME_M / 2, lo), (split - FRAME_M / 2, hi), gx[2], gx[3]]))
        for q in quads:
            corners = np.column_stack([q[:, 0], np.full(4, y), q[:, 1]])
            glass.append(_panel(corners, side * 0.003))
    ws_foot = b.length_m / 2 - b.bonnet_m
    top = b.height_m - 0.01
    run = (top - b.belt_m) * math.tan(math.radians(b.windscreen_rake_deg))
    w = half - FRAME_M
    screen = np.array([(ws_foot - 0.02, -w, b.belt_m + 0.03), (ws_foot - 0.02, w, b.belt_m + 0.03),
                       (ws_foot - run + 0.02, w, top - 0.03), (ws_foot - run + 0.02, -w, top - 0.03)])
    glass.append(_panel(screen + np.array([0.01, 0, 0.01]), -0.003))
    # The rear window, on the tailgate's (or the cab's back wall's) slope.
    rear = np.array([(gx[3, 0] - FRAME_M - 0.012, w, gx[3, 1]), (gx[3, 0] - FRAME_M - 0.012, -w, gx[3, 1]),
                     (gx[2, 0] - FRAME_M - 0.012, -w, gx[2, 1]), (gx[2, 0] - FRAME_M - 0.012, w, gx[2, 1])])
    glass.append(_panel(rear, 0.003))
    tyres, rims = [], []
    for x in (b.wheelbase_m / 2, -b.wheelbase_m / 2):
        for side in (-1.0, 1.0):
            y = side * (half - TYRE_WIDTH_M / 2 - 0.01)
            tyre = trimesh.creation.cylinder(radius=b.wheel_radius_m, height=TYRE_WIDTH_M, sections=20)
            tyre.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, (1, 0, 0)))
            tyre.apply_translation((x, y, b.wheel_radius_m))
            tyres.append(tyre)
            rim = trimesh.creation.cylinder(radius=RIM_RADIUS_FRACTION * b.wheel_radius_m,
                                            height=TYRE_WIDTH_M + 0.02, sections=16)
            rim.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, (1, 0, 0)))
            rim.apply_translation((x, y, b.wheel_radius_m))
            rims.append(rim)
    front, back = b.length_m / 2, -b.length_m / 2
    nose = b.clearance_m + 0.75 * (b.belt_m - b.clearance_m)
    lamp_z = nose - 0.06
    headlights = [_box((0.04, 0.30, 0.10), (front + 0.005, s * (half - 0.22), lamp_z)) for s in (-1, 1)]
    tail_z = (b.bed_rail_m if b.rear == "bed" else b.belt_m) - 0.12
    taillights = [_box((0.04, 0.22, 0.12), (back - 0.005, s * (half - 0.16), tail_z)) for s in (-1, 1)]
    mirror_x = ws_foot - 0.1
    # Mirrors stand 6 cm proud of the body: within the 1.8-2.0 m that the car park's generator
    # and bays were laid out for.
    mirrors = [_box((0.10, 0.10, 0.09), (mirror_x, s * (half + 0.01), b.belt_m + 0.08)) for s in (-1, 1)]
    plates = [_box((0.02, 0.52, 0.11), (front + 0.005, 0.0, b.clearance_m + 0.18)),
              _box((0.02, 0.52, 0.11), (back - 0.005, 0.0, tail_z - 0.2))]
    cat = trimesh.util.concatenate
    return {"body": body, "glass": cat(glass), "tyres": cat(tyres), "rims": cat(rims),
            "headlights": cat(headlights), "taillights": cat(taillights), "mirrors": cat(mirrors),
            "plates": cat(plates)}
