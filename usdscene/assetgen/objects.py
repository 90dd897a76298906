"""The dynamic object classes: cabin luggage and personal items, each with variants.

Every class is a :class:`ObjectClass`: a builder turning shape parameters into meshes per
material, and a list of :class:`ObjectVariant` (colour and shape). Asset frame: Z up, metres,
origin at the centre of the bottom face (the writer re-centres every variant). Builders model
the object's front (pocket, screen, latches) towards +X; the writer turns every object -90°
about Z so that the shipped assets face -Y (Blender's front view, the placement convention).

The recolourable material of every class is ``Body`` (see ``stage_schema.ASSET_COLOR_SHADER``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from usdscene.assetgen import mesh as m
from usdscene.assetgen.usd_write import MaterialSpec

Parts = dict[str, list[m.MeshData]]
RGB = tuple[float, float, float]

# Materials other than Body, shared by all classes (a class uses the ones its builder names).
SHARED_MATERIALS: dict[str, MaterialSpec] = {
    "Trim": MaterialSpec((0.03, 0.03, 0.035), roughness=0.6),
    "Metal": MaterialSpec((0.75, 0.75, 0.77), roughness=0.3, metallic=1.0),
    "Screen": MaterialSpec((0.01, 0.015, 0.03), roughness=0.1),
    "Paper": MaterialSpec((0.85, 0.84, 0.80), roughness=0.9),
    "Accent": MaterialSpec((0.8, 0.8, 0.8), roughness=0.5),
}
BODY_ROUGHNESS = 0.55

ALL_RELATIONS = ("is_on", "is_below", "is_in", "is_in_front_of")


@dataclass(frozen=True)
class ObjectVariant:
    """One entry of the ``appearance`` variant set.

    Attributes:
        name: variant name.
        colors: material name → linear RGB (``Body`` at least).
        params: shape parameters passed to the class builder (merged over the defaults).
    """

    name: str
    colors: Mapping[str, RGB]
    params: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class ObjectClass:
    """A procedural object class.

    Attributes:
        name: class name (OpenLABEL object type).
        description: one sentence with the real size.
        build: shape parameters → meshes per material name.
        defaults: default shape parameters.
        variants: appearance variants; the first is the default.
        relations: placement relations the class supports as a subject.
    """

    name: str
    description: str
    build: Callable[[Mapping[str, float]], Parts]
    defaults: Mapping[str, float]
    variants: tuple[ObjectVariant, ...]
    relations: tuple[str, ...] = ALL_RELATIONS


def _arc_handle(width: float, rise: float, z: float, radius: float, plane: str = "yz",
                offset: float = 0.0) -> m.MeshData:
    """A half-ellipse handle standing on z with its ends ``width`` apart."""
    t = np.linspace(0.0, np.pi, 11)
    a, b = (width / 2) * np.cos(t), z + rise * np.sin(t)
    off = np.full_like(t, offset)
    pts = np.stack([off, a, b], axis=1) if plane == "yz" else np.stack([a, off, b], axis=1)
    return m.sweep(pts, radius, 8)


def _wheels(sx: float, sy: float, radius: float) -> list[m.MeshData]:
    out = []
    for x in (-sx / 2 + 0.03, sx / 2 - 0.03):
        for y in (-sy / 2 + 0.03, sy / 2 - 0.03):
            wheel = m.cylinder(radius, 0.02, 10).transformed(m.translation((x, y - 0.01, radius)) @ m.rotation_x(-90.0))
            out.append(wheel)
    return out


# --- builders ----------------------------------------------------------------------------------

def _backpack(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((d, w, h), 0.06).translated((0, 0, h / 2))
    pocket = m.rounded_box((0.05, w * 0.75, h * 0.45), 0.02).translated((d / 2 + 0.01, 0, h * 0.3))
    straps = [m.sweep([(-d / 2 - 0.005, y, h * 0.85), (-d / 2 - 0.025, y, h * 0.5), (-d / 2 - 0.01, y, h * 0.12)], 0.012, 6)
              for y in (-w * 0.28, w * 0.28)]
    handle = _arc_handle(0.08, 0.025, h - 0.005, 0.008, plane="yz", offset=-d * 0.2)
    return {"Body": [body, pocket], "Trim": straps + [handle]}


def _trolley(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    wheel_r = 0.025
    body = m.rounded_box((d, w, h), 0.035).translated((0, 0, wheel_r * 2 + h / 2))
    ribs = [m.rounded_box((d + 0.006, 0.012, h * 0.9), 0.004, 1).translated((0, y, wheel_r * 2 + h / 2))
            for y in (-w * 0.25, 0.0, w * 0.25)]
    top = wheel_r * 2 + h
    rods = [m.cylinder(0.008, 0.02, 8).translated((-d / 2 + 0.025, y, top)) for y in (-w * 0.3, w * 0.3)]
    grip = m.rounded_box((0.03, w * 0.66, 0.025), 0.01, 1).translated((-d / 2 + 0.025, 0, top + 0.025))
    side_handle = _arc_handle(0.12, 0.025, top - 0.002, 0.008, plane="xz", offset=0.0).transformed(m.rotation_z(90.0))
    return {"Body": [body] + ribs, "Trim": _wheels(d, w, wheel_r) + [grip, side_handle], "Metal": rods}


def _briefcase(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((d, w, h), 0.015).translated((0, 0, h / 2))
    handle = _arc_handle(0.12, 0.035, h + 0.005, 0.01)
    latches = [m.box((d + 0.006, 0.03, 0.02)).translated((0, y, h - 0.03)) for y in (-w * 0.3, w * 0.3)]
    feet = [m.cylinder(0.006, 0.004, 8).translated((0, y, 0)) for y in (-w * 0.4, w * 0.4)]
    return {"Body": [body], "Trim": [handle], "Metal": latches + feet}


def _handbag(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((d, w, h), min(d, h) * 0.35).translated((0, 0, h / 2))
    straps = [_arc_handle(w * 0.55, h * 0.6, h - 0.01, 0.007, offset=x) for x in (-d * 0.25, d * 0.25)]
    clasp = m.box((0.006, 0.04, 0.025)).translated((d / 2, 0, h * 0.8))
    return {"Body": [body] + straps, "Metal": [clasp]}


def _laptop(p: Mapping[str, float]) -> Parts:
    w, d, t = p["width"], p["depth"], 0.009
    base = m.rounded_box((d, w, t), 0.003, 1).translated((0, 0, t / 2))
    keys = m.box((d * 0.45, w * 0.85, 0.001)).translated((d * 0.08, 0, t + 0.0005))
    if p["open"] > 0.5:
        # Lid hinged on the rear edge (-X), opened 110° from closed.
        hinge = m.translation((-d / 2, 0, t)) @ m.rotation_y(-(180.0 - 110.0))
        lid = m.rounded_box((d, w, 0.006), 0.003, 1).translated((d / 2, 0, 0.003)).transformed(hinge)
        screen = m.box((d * 0.88, w * 0.92, 0.001)).translated((d / 2, 0, -0.0005)).transformed(hinge)
        return {"Body": [base, lid], "Trim": [keys], "Screen": [screen]}
    lid = m.rounded_box((d, w, 0.006), 0.003, 1).translated((0, 0, t + 0.0035))
    return {"Body": [base, lid], "Trim": [keys]}


def _laptop_bag(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((d, w, h), 0.02).translated((0, 0, h / 2))
    flap = m.rounded_box((0.01, w * 0.96, h * 0.55), 0.004, 1).translated((d / 2 + 0.004, 0, h * 0.7))
    handles = [_arc_handle(0.14, 0.06, h - 0.005, 0.009, offset=x) for x in (-d * 0.2, d * 0.2)]
    return {"Body": [body, flap], "Trim": handles}


def _slab_device(p: Mapping[str, float]) -> Parts:
    """Tablet or phone lying screen up."""
    w, d, t = p["width"], p["depth"], p["thickness"]
    body = m.rounded_box((d, w, t), min(t / 2, 0.01), 2).translated((0, 0, t / 2))
    screen = m.box((d * 0.92, w * 0.9, 0.0008)).translated((0, 0, t + 0.0004))
    parts: Parts = {"Body": [body], "Screen": [screen]}
    if p.get("case", 0.0) > 0.5:
        parts["Body"] = [m.rounded_box((d + 0.01, w + 0.01, t + 0.004), 0.006, 2).translated((0, 0, (t + 0.004) / 2))]
        parts["Screen"] = [m.box((d * 0.92, w * 0.9, 0.0008)).translated((0, 0, t + 0.0044))]
    return parts


def _magazine(p: Mapping[str, float]) -> Parts:
    w, d, t = p["width"], p["depth"], p["thickness"]
    if p["open"] > 0.5:
        pages = [m.rounded_box((d, w, t / 2), 0.001, 1).translated((0, y, t / 4)) for y in (-w / 2, w / 2)]
        cover = m.box((d * 0.9, w * 0.85, 0.0005)).translated((0, -w / 2, t / 2 + 0.0002))
        return {"Paper": pages, "Body": [cover]}
    cover = m.rounded_box((d, w, t), 0.001, 1).translated((0, 0, t / 2))
    return {"Body": [cover]}


def _newspaper(p: Mapping[str, float]) -> Parts:
    w, d, t = p["width"], p["depth"], p["thickness"]
    sheet = m.rounded_box((d, w, t), t * 0.45, 1).translated((0, 0, t / 2))
    headline = m.box((d * 0.15, w * 0.8, 0.0004)).translated((d * 0.35, 0, t + 0.0002))
    return {"Body": [sheet], "Trim": [headline]}


def _book(p: Mapping[str, float]) -> Parts:
    w, d, t = p["width"], p["depth"], p["thickness"]
    cover = 0.003 if p["hard"] > 0.5 else 0.001
    boards = [m.box((d, w, cover)).translated((0, 0, z)) for z in (cover / 2, t - cover / 2)]
    spine = m.box((d, cover, t)).translated((0, -w / 2 + cover / 2, t / 2))
    pages = m.box((d - 0.006, w - 0.006, t - 2 * cover)).translated((0, 0.002, t / 2))
    return {"Body": boards + [spine], "Paper": [pages]}


def _bottle(p: Mapping[str, float]) -> Parts:
    r, h = p["radius"], p["height"]
    profile = [(0.0, 0.0), (r * 0.9, 0.0), (r, 0.01), (r, h * 0.7), (r * 0.85, h * 0.8),
               (r * 0.45, h * 0.9), (r * 0.42, h * 0.93), (0.0, h * 0.93)]
    body = m.lathe(profile, 16)
    cap = m.cylinder(r * 0.48, h * 0.07, 12).translated((0, 0, h * 0.93))
    return {"Body": [body], "Trim": [cap]}


def _cup(p: Mapping[str, float]) -> Parts:
    r0, r1, h = p["radius_bottom"], p["radius_top"], p["height"]
    body = m.lathe([(0.0, 0.0), (r0, 0.0), (r1, h * 0.92), (0.0, h * 0.92)], 16)
    if p["mug"] > 0.5:
        handle = m.sweep(m.arc_points(h * 0.3, -90, 90, 9, plane="xz", centre_m=(r1, 0, h * 0.5)), 0.006, 6)
        rim = m.lathe([(r1 * 0.98, h * 0.92), (r1, h)], 16)
        return {"Body": [body, handle, rim]}
    lid = m.lathe([(0.0, h * 0.92), (r1 + 0.003, h * 0.92), (r1 + 0.003, h * 0.96), (r1 * 0.8, h), (0.0, h)], 16)
    sleeve = m.lathe([(r0 + (r1 - r0) * 0.3 + 0.002, h * 0.3), (r0 + (r1 - r0) * 0.7 + 0.002, h * 0.7)], 16)
    return {"Body": [body], "Trim": [lid], "Accent": [sleeve]}


def _soft_fold(p: Mapping[str, float]) -> Parts:
    """Folded textile (jacket, blanket): a soft slab with a fold roll."""
    w, d, h = p["width"], p["depth"], p["height"]
    slab = m.rounded_box((d, w, h), h * 0.45).translated((0, 0, h / 2))
    roll = m.capsule((d / 2 - h * 0.3, -w / 2 + h * 0.4, h * 0.5), (d / 2 - h * 0.3, w / 2 - h * 0.4, h * 0.5), h * 0.5, rings=3, sectors=10)
    parts: Parts = {"Body": [slab, roll]}
    if p.get("collar", 0.0) > 0.5:
        parts["Body"].append(m.rounded_box((0.08, w * 0.5, h * 0.5), h * 0.2).translated((-d / 2 + 0.05, 0, h)))
        parts["Trim"] = [m.cylinder(0.006, 0.003, 8).translated((d * 0.1 * k, 0, h - 0.001)) for k in (-2, 0, 2)]
    return parts


def _pillow(p: Mapping[str, float]) -> Parts:
    if p["neck"] > 0.5:
        arc = m.arc_points(0.11, -135, 135, 13, plane="xy", centre_m=(0, 0, 0.05))
        return {"Body": [m.sweep(arc, 0.05, 10)]}
    w, d, h = p["width"], p["depth"], p["height"]
    return {"Body": [m.rounded_box((d, w, h), h * 0.48, 3).translated((0, 0, h / 2))]}


def _duffel(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((w, d, h), min(d, h) * 0.45, 3).translated((0, 0, h / 2))
    ends = [m.ellipsoid((0.01, d * 0.42, h * 0.42), 6, 12).translated((x, 0, h / 2)) for x in (-w / 2, w / 2)]
    handles = [_arc_handle(0.2, 0.09, h - 0.01, 0.01, plane="xz", offset=y) for y in (-d * 0.2, d * 0.2)]
    zip_line = m.box((w * 0.8, 0.012, 0.004)).translated((0, 0, h - 0.001))
    return {"Body": [body], "Trim": ends + handles + [zip_line]}


def _shopping_bag(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    walls = [m.box((0.002, w, h)).translated((x, 0, h / 2)) for x in (-d / 2, d / 2)]
    walls += [m.box((d, 0.002, h)).translated((0, y, h / 2)) for y in (-w / 2, w / 2)]
    walls.append(m.box((d, w, 0.002)).translated((0, 0, 0.001)))
    handles = [_arc_handle(w * 0.4, 0.08, h - 0.03, 0.004, offset=x) for x in (-d / 2 + 0.003, d / 2 - 0.003)]
    contents = m.rounded_box((d * 0.8, w * 0.85, h * 0.2), 0.02).translated((0, 0, h * 0.85))
    return {"Body": walls, "Trim": handles, "Paper": [contents]}


def _camera_bag(p: Mapping[str, float]) -> Parts:
    w, d, h = p["width"], p["depth"], p["height"]
    body = m.rounded_box((d, w, h), 0.03).translated((0, 0, h / 2))
    lid = m.rounded_box((d + 0.01, w + 0.01, 0.03), 0.012).translated((0, 0, h - 0.01))
    strap = _arc_handle(w * 0.95, 0.18, h * 0.6, 0.006, offset=0.0)
    return {"Body": [body], "Trim": [lid, strap]}


def _umbrella(p: Mapping[str, float]) -> Parts:
    length = p["length"]
    r = p["radius"]
    canopy = m.capsule((-length / 2 + 0.12, 0, r), (length / 2 - 0.05, 0, r), r, r * 0.35, rings=3, sectors=10)
    tip = m.cylinder(0.004, 0.04, 6).transformed(m.translation((length / 2 - 0.05, 0, r)) @ m.rotation_y(90.0))
    shaft = m.cylinder(0.005, 0.08, 6).transformed(m.translation((-length / 2 + 0.04, 0, r)) @ m.rotation_y(90.0))
    hook = m.sweep(m.arc_points(0.035, 90, 270, 9, plane="xz", centre_m=(-length / 2 + 0.04, 0, r + 0.0)), 0.011, 8) \
        if p["hook"] > 0.5 else m.capsule((-length / 2 + 0.01, 0, r), (-length / 2 + 0.12, 0, r), 0.014, rings=2, sectors=8)
    return {"Body": [canopy], "Trim": [hook], "Metal": [tip, shaft]}


def _headphones(p: Mapping[str, float]) -> Parts:
    span = p["span"]
    cup_r = p["cup_radius"]
    band = m.sweep(m.arc_points(span / 2, 0, 180, 15, plane="yz", centre_m=(0, 0, cup_r * 1.2)), 0.008, 8)
    cups = [m.cylinder(cup_r, 0.035, 16).transformed(m.translation((0, s * (span / 2 - 0.01), cup_r * 1.2)) @ m.rotation_x(s * 90.0))
            for s in (-1.0, 1.0)]
    pads = [m.cylinder(cup_r * 0.85, 0.015, 16).transformed(m.translation((0, s * (span / 2 - 0.01), cup_r * 1.2)) @ m.rotation_x(-s * 90.0))
            for s in (-1.0, 1.0)]
    return {"Body": cups + [band], "Trim": pads}


# --- the classes -------------------------------------------------------------------------------

def _v(name: str, body: RGB, params: Mapping[str, float] | None = None, **colors: RGB) -> ObjectVariant:
    return ObjectVariant(name, {"Body": body, **colors}, dict(params or {}))


NAVY, RED, BLACK, GREY = (0.02, 0.04, 0.12), (0.45, 0.03, 0.03), (0.02, 0.02, 0.02), (0.25, 0.25, 0.26)
SILVER, BLUE, GREEN, TAN = (0.6, 0.6, 0.62), (0.04, 0.12, 0.45), (0.05, 0.25, 0.08), (0.45, 0.28, 0.14)

OBJECT_CLASSES: tuple[ObjectClass, ...] = (
    ObjectClass("backpack", "Daypack backpack, about 0.30 x 0.26 x 0.41 m with pocket, straps and handle.", _backpack,
                {"width": 0.30, "depth": 0.18, "height": 0.38},
                (_v("navy", NAVY), _v("red", RED), _v("black_large", BLACK, {"width": 0.33, "depth": 0.23, "height": 0.52}),
                 _v("grey", GREY))),
    ObjectClass("trolley_suitcase", "Cabin-size trolley suitcase, 0.40 x 0.23 x 0.55 m body on wheels.", _trolley,
                {"width": 0.40, "depth": 0.23, "height": 0.55},
                (_v("black", BLACK), _v("silver", SILVER), _v("red", RED),
                 _v("blue_oversize", BLUE, {"width": 0.45, "depth": 0.27, "height": 0.65}))),
    ObjectClass("small_suitcase", "Under-seat wheeled bag, 0.35 x 0.20 x 0.38 m with wheels.", _trolley,
                {"width": 0.35, "depth": 0.20, "height": 0.31},
                (_v("teal", (0.02, 0.25, 0.25)), _v("black", BLACK), _v("pink", (0.6, 0.15, 0.25)))),
    ObjectClass("briefcase", "Hard briefcase, 0.42 x 0.11 x 0.32 m.", _briefcase,
                {"width": 0.42, "depth": 0.11, "height": 0.32},
                (_v("brown_leather", (0.18, 0.07, 0.03)), _v("black", BLACK), _v("aluminium", SILVER))),
    ObjectClass("handbag", "Handbag with two straps, 0.30 x 0.12 x 0.22 m body.", _handbag,
                {"width": 0.30, "depth": 0.12, "height": 0.22},
                (_v("tan", TAN), _v("black", BLACK), _v("red_small", RED, {"width": 0.24, "depth": 0.10, "height": 0.17}))),
    ObjectClass("laptop", "14-inch laptop, 0.32 x 0.22 m, 18 mm closed.", _laptop,
                {"width": 0.32, "depth": 0.22, "open": 0.0},
                (_v("closed_silver", SILVER), _v("open_silver", SILVER, {"open": 1.0}),
                 _v("closed_black", (0.05, 0.05, 0.06)), _v("open_black", (0.05, 0.05, 0.06), {"open": 1.0}))),
    ObjectClass("laptop_bag", "Laptop messenger bag, 0.40 x 0.08 x 0.30 m.", _laptop_bag,
                {"width": 0.40, "depth": 0.08, "height": 0.30},
                (_v("black", BLACK), _v("grey", GREY), _v("brown", (0.2, 0.1, 0.04)))),
    ObjectClass("tablet", "10-inch tablet, 0.25 x 0.17 x 0.008 m.", _slab_device,
                {"width": 0.25, "depth": 0.17, "thickness": 0.008, "case": 0.0},
                (_v("space_grey", (0.12, 0.12, 0.13)), _v("silver", SILVER),
                 _v("red_case", RED, {"case": 1.0}))),
    ObjectClass("phone", "Smartphone, 0.15 x 0.075 x 0.008 m.", _slab_device,
                {"width": 0.075, "depth": 0.15, "thickness": 0.008, "case": 0.0},
                (_v("black", BLACK), _v("white", (0.8, 0.8, 0.8)), _v("blue_case", BLUE, {"case": 1.0}))),
    ObjectClass("magazine", "Inflight magazine, 0.28 x 0.21 x 0.006 m.", _magazine,
                {"width": 0.21, "depth": 0.28, "thickness": 0.006, "open": 0.0},
                (_v("red_cover", RED), _v("blue_cover", BLUE), _v("open", (0.5, 0.3, 0.1), {"open": 1.0}))),
    ObjectClass("newspaper", "Newspaper, folded 0.30 x 0.40 m or opened 0.60 x 0.40 m.", _newspaper,
                {"width": 0.40, "depth": 0.30, "thickness": 0.012},
                (_v("folded", (0.8, 0.8, 0.78)), _v("folded_salmon", (0.85, 0.6, 0.5)),
                 _v("open", (0.8, 0.8, 0.78), {"width": 0.60, "depth": 0.40, "thickness": 0.004}))),
    ObjectClass("book", "Book, 0.24 x 0.16 x 0.03 m.", _book,
                {"width": 0.16, "depth": 0.24, "thickness": 0.03, "hard": 1.0},
                (_v("green_hardcover", GREEN), _v("red_hardcover", RED),
                 _v("blue_paperback", BLUE, {"width": 0.11, "depth": 0.18, "thickness": 0.022, "hard": 0.0}))),
    ObjectClass("water_bottle", "Water bottle, 0.07 m diameter, 0.24 m tall.", _bottle,
                {"radius": 0.035, "height": 0.24},
                (_v("blue_plastic", (0.3, 0.5, 0.8)), _v("steel", SILVER),
                 _v("small_green", (0.2, 0.5, 0.3), {"radius": 0.03, "height": 0.18}))),
    ObjectClass("coffee_cup", "Take-away coffee cup, 0.09 m diameter, 0.12 m tall.", _cup,
                {"radius_bottom": 0.028, "radius_top": 0.042, "height": 0.12, "mug": 0.0},
                (_v("white_paper", (0.85, 0.85, 0.83)), _v("kraft", (0.45, 0.3, 0.18)),
                 _v("ceramic_mug", (0.7, 0.15, 0.1), {"radius_bottom": 0.04, "radius_top": 0.042, "height": 0.095, "mug": 1.0}))),
    ObjectClass("jacket", "Folded jacket, 0.45 x 0.35 x 0.09 m.", _soft_fold,
                {"width": 0.45, "depth": 0.35, "height": 0.09, "collar": 1.0},
                (_v("navy", NAVY), _v("beige", (0.5, 0.42, 0.3)), _v("black_long", BLACK, {"width": 0.6, "depth": 0.4, "height": 0.07}))),
    ObjectClass("blanket", "Airline blanket, folded 0.35 x 0.30 x 0.07 m.", _soft_fold,
                {"width": 0.35, "depth": 0.30, "height": 0.07, "collar": 0.0},
                (_v("blue", (0.1, 0.15, 0.4)), _v("grey", GREY),
                 _v("spread_red", (0.45, 0.08, 0.08), {"width": 0.6, "depth": 0.9, "height": 0.025}))),
    ObjectClass("pillow", "Cabin pillow, 0.40 x 0.30 x 0.10 m.", _pillow,
                {"width": 0.40, "depth": 0.30, "height": 0.10, "neck": 0.0},
                (_v("white", (0.85, 0.85, 0.85)), _v("light_blue", (0.4, 0.55, 0.8)),
                 _v("neck_grey", GREY, {"neck": 1.0}))),
    ObjectClass("duffel_bag", "Duffel bag, 0.55 x 0.28 x 0.28 m.", _duffel,
                {"width": 0.55, "depth": 0.28, "height": 0.28},
                (_v("olive", (0.15, 0.17, 0.06)), _v("black", BLACK),
                 _v("red_small", RED, {"width": 0.45, "depth": 0.24, "height": 0.24}))),
    ObjectClass("shopping_bag", "Paper shopping bag with purchases, 0.32 x 0.12 x 0.32 m.", _shopping_bag,
                {"width": 0.32, "depth": 0.12, "height": 0.32},
                (_v("kraft", (0.45, 0.3, 0.17)), _v("white", (0.85, 0.85, 0.85)), _v("black_duty_free", BLACK))),
    ObjectClass("camera_bag", "Camera bag with shoulder strap, 0.25 x 0.15 x 0.18 m.", _camera_bag,
                {"width": 0.25, "depth": 0.15, "height": 0.18},
                (_v("black", BLACK), _v("grey", GREY), _v("khaki", (0.35, 0.3, 0.18)))),
    ObjectClass("umbrella", "Folded umbrella lying down, 0.60 m long.", _umbrella,
                {"length": 0.60, "radius": 0.03, "hook": 1.0},
                (_v("black", BLACK), _v("red", RED), _v("compact_blue", BLUE, {"length": 0.28, "radius": 0.025, "hook": 0.0}))),
    ObjectClass("headphones", "Over-ear headphones standing, 0.18 x 0.08 x 0.20 m.", _headphones,
                {"span": 0.17, "cup_radius": 0.045},
                (_v("black", BLACK), _v("white", (0.85, 0.85, 0.85)), _v("blue", BLUE))),
)
