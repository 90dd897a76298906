"""What the people family wears: clothing colours drawn from a distribution where dark and
neutral colours dominate, fabrics (procedural surface kinds) per garment, and shoes.

The colour categories are the eleven of the PETA pedestrian-attribute dataset (Deng et al.,
"Pedestrian attribute recognition at far distance", ACM MM 2014: black, blue, brown, green,
grey, orange, pink, purple, red, white, yellow), split where surveillance crops show a
difference a camera sees (navy and denim blue, dark and light grey, beige). The shares are
this project's estimate in the order those datasets' colour labels report (black the most
frequent colour of tops and trousers, then greys, blues and white; saturated colours a few
per cent each); they are not counts from a labelled dataset, and a user with such counts can
pass them to :func:`draw_outfit`.

Colours are linear RGB albedos of dyed fabric (black cloth reflects 2-3 %, white about 60 %).
Fabrics are kinds of :data:`usdscene.document.surfaces.SURFACES` (object space: the weave
moves with the body). Pure: no pxr, no bpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from usdscene.document.surfaces import surface_recipe
from usdscene.errors import AssetError

CLOTH_COLOURS: dict[str, tuple[float, float, float]] = {  # linear RGB albedo
    "black": (0.022, 0.022, 0.025), "dark_grey": (0.055, 0.055, 0.06), "grey": (0.17, 0.17, 0.175),
    "white": (0.62, 0.62, 0.60), "beige": (0.36, 0.29, 0.18), "navy": (0.018, 0.025, 0.07),
    "blue": (0.05, 0.11, 0.32), "denim_blue": (0.06, 0.09, 0.18), "brown": (0.11, 0.06, 0.03),
    "green": (0.07, 0.10, 0.04), "red": (0.38, 0.035, 0.035), "burgundy": (0.13, 0.02, 0.03),
    "pink": (0.58, 0.24, 0.30), "purple": (0.14, 0.05, 0.19), "yellow": (0.58, 0.42, 0.05),
    "orange": (0.58, 0.19, 0.03),
}

TOP_COLOUR_SHARES: dict[str, float] = {
    "black": 0.26, "dark_grey": 0.12, "grey": 0.10, "white": 0.12, "navy": 0.09, "blue": 0.07,
    "brown": 0.04, "beige": 0.04, "green": 0.04, "red": 0.04, "burgundy": 0.02, "pink": 0.02,
    "purple": 0.015, "yellow": 0.015, "orange": 0.01,
}
BOTTOM_COLOUR_SHARES: dict[str, float] = {
    "black": 0.34, "denim_blue": 0.24, "dark_grey": 0.10, "navy": 0.08, "beige": 0.08, "grey": 0.06,
    "brown": 0.05, "white": 0.02, "green": 0.02, "red": 0.01,
}
SHOE_COLOUR_SHARES: dict[str, float] = {
    "black": 0.45, "white": 0.20, "brown": 0.15, "dark_grey": 0.12, "grey": 0.05, "navy": 0.03,
}
# Fabric of each garment: shares of surface kinds.
TOP_FABRIC_SHARES: dict[str, float] = {"cotton": 0.5, "knit": 0.25, "pattern": 0.15, "denim": 0.10}
BOTTOM_FABRIC_SHARES: dict[str, float] = {"denim": 0.55, "cotton": 0.35, "pattern": 0.10}

SHARE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Outfit:
    """One person's clothes.

    Attributes:
        top_colour, bottom_colour, shoe_colour: keys of :data:`CLOTH_COLOURS`.
        top_fabric, bottom_fabric: surface kinds (``cotton``, ``knit``, ``denim``, ``pattern``).
    """

    top_colour: str
    bottom_colour: str
    shoe_colour: str
    top_fabric: str
    bottom_fabric: str

    @property
    def top_rgb(self) -> tuple[float, float, float]:
        return CLOTH_COLOURS[self.top_colour]

    @property
    def bottom_rgb(self) -> tuple[float, float, float]:
        return CLOTH_COLOURS[self.bottom_colour]

    @property
    def shoe_rgb(self) -> tuple[float, float, float]:
        return CLOTH_COLOURS[self.shoe_colour]


def check_colour_shares(shares: Mapping[str, float], *, field: str) -> None:
    """Refuse a colour distribution that names an unknown colour or does not sum to 1.

    Raises:
        AssetError: naming ``field`` and the bad value.
    """
    _check_shares(shares, field, CLOTH_COLOURS, "colour")


def check_fabric_shares(shares: Mapping[str, float], *, field: str) -> None:
    """Refuse a fabric distribution that names an unknown surface kind or does not sum to 1.

    Raises:
        AssetError: naming ``field`` and the bad value.
    """
    for name in shares:
        surface_recipe(name, where=f"{field}.{name}")
    _check_shares(shares, field, None, "fabric")


def _check_shares(shares: Mapping[str, float], field: str, known: Mapping | None, what: str) -> None:
    for name, share in shares.items():
        if known is not None and name not in known:
            raise AssetError(f"unknown {what} {name!r} (known: {', '.join(sorted(known))})", where=field)
        if not (isinstance(share, (int, float)) and math.isfinite(share) and share >= 0):
            raise AssetError(f"share {share!r} of {name!r} is not a number >= 0", where=field)
    total = float(sum(shares.values()))
    if not shares or abs(total - 1.0) > SHARE_TOLERANCE:
        raise AssetError(f"the shares sum to {total:.6g}, not 1", where=field)


def _draw(rng: np.random.Generator, shares: Mapping[str, float]) -> str:
    names = list(shares)
    p = np.array([shares[n] for n in names], dtype=float)
    return names[int(rng.choice(len(names), p=p / p.sum()))]


def draw_outfit(rng: np.random.Generator, *, top_colours: Mapping[str, float] = TOP_COLOUR_SHARES,
                bottom_colours: Mapping[str, float] = BOTTOM_COLOUR_SHARES,
                shoe_colours: Mapping[str, float] = SHOE_COLOUR_SHARES,
                top_fabrics: Mapping[str, float] = TOP_FABRIC_SHARES,
                bottom_fabrics: Mapping[str, float] = BOTTOM_FABRIC_SHARES) -> Outfit:
    """One outfit drawn from the distributions (five draws from ``rng``, in a fixed order).

    Raises:
        AssetError: a distribution with an unknown name or shares that do not sum to 1.
    """
    for field, shares in (("top_colours", top_colours), ("bottom_colours", bottom_colours),
                          ("shoe_colours", shoe_colours)):
        check_colour_shares(shares, field=field)
    check_fabric_shares(top_fabrics, field="top_fabrics")
    check_fabric_shares(bottom_fabrics, field="bottom_fabrics")
    return Outfit(top_colour=_draw(rng, top_colours), bottom_colour=_draw(rng, bottom_colours),
                  shoe_colour=_draw(rng, shoe_colours), top_fabric=_draw(rng, top_fabrics),
                  bottom_fabric=_draw(rng, bottom_fabrics))
