"""Targets of a camera plan: sample points in the regions of catalog places
(``seat_*:on,below,in_front``) or in explicit boxes. Pure (numpy).
"""

from __future__ import annotations

import fnmatch
import logging
import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from usdscene.scene.catalog import REGION_RELATIONS, Place
from usdscene.errors import DocumentError, ProblemCollector

log = logging.getLogger(__name__)


# Points of a target lie this far inside its region, so that a point on a support surface is
# not hidden by that surface itself.
SURFACE_LIFT_M = 0.03


@dataclass(frozen=True)
class Target:
    """Something the camera system must see, as sample points.

    Attributes:
        name: ``<place>:<region>`` (``seat_05C:on``) or the box's name.
        place: place name ("" for a box).
        region: region short name (``on``, ``below``, ``in_front``, ...) or "box".
        points_m: (N, 3) float64 world points, metres.
    """

    name: str
    place: str
    region: str
    points_m: np.ndarray

    @property
    def centre_m(self) -> np.ndarray:
        """(3,) mean of the points."""
        return self.points_m.mean(axis=0)


@dataclass(frozen=True)
class TargetSpec:
    """A parsed ``--targets`` argument: places matching ``pattern`` with ``regions``, or a box.

    Attributes:
        pattern: glob on place names (``seat_*``); "" for a box.
        regions: region short names (keys of :data:`usdscene.scene.catalog.REGION_RELATIONS`).
        box_name: name of an explicit box target.
        box_min_m, box_max_m: its corners in world metres.
    """

    pattern: str = ""
    regions: tuple[str, ...] = ()
    box_name: str = ""
    box_min_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    box_max_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


def parse_target_spec(text: str, where: str = "--targets") -> TargetSpec:
    """Parse ``GLOB:REGION,REGION`` (``seat_*:on,below,in_front``) or
    ``box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`` (metres).

    Raises:
        DocumentError: unknown region name, malformed box.
    """
    parts = text.split(":")
    if parts[0] == "box":
        try:
            if len(parts) != 3 or not parts[1]:
                raise ValueError
            values = [float(v) for v in parts[2].split(",")]
            if len(values) != 6 or not all(math.isfinite(v) for v in values):
                raise ValueError
        except ValueError:
            raise DocumentError(f"expected box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (metres), got {text!r}",
                                where=where) from None
        lo, hi = values[:3], values[3:]
        if any(h <= l for l, h in zip(lo, hi)):
            raise DocumentError(f"box {parts[1]!r} has a max corner not above its min corner: {text!r}", where=where)
        return TargetSpec(box_name=parts[1], box_min_m=tuple(lo), box_max_m=tuple(hi))  # type: ignore[arg-type]
    if len(parts) != 2 or not parts[0] or not parts[1]:
        raise DocumentError(f"expected PLACE_GLOB:REGION[,REGION...] (e.g. 'seat_*:on,below') or "
                            f"box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX, got {text!r}", where=where)
    regions = tuple(r.strip() for r in parts[1].split(","))
    bad = [r for r in regions if r not in REGION_RELATIONS]
    if bad:
        raise DocumentError(f"unknown region {bad[0]!r} in {text!r}; regions: {', '.join(REGION_RELATIONS)}",
                            where=where)
    return TargetSpec(pattern=parts[0], regions=regions)


def box_points(size_m: Sequence[float], spacing_m: float) -> np.ndarray:
    """Sample points of a box ``[-sx/2, sx/2] × [-sy/2, sy/2] × [0, sz]`` (a region frame):
    a grid on its support surface (lifted by :data:`SURFACE_LIFT_M`) and, for boxes taller than
    two lifts, a second layer at half height.

    Args:
        size_m: (3,) box size, metres.
        spacing_m: grid spacing; at least 2 points per horizontal axis.

    Returns:
        (N, 3) float64 points in the box frame.
    """
    sx, sy, sz = (float(v) for v in size_m)
    axes = []
    for s in (sx, sy):
        n = max(2, int(math.ceil(s / spacing_m - 1e-9)) + 1)
        inset = min(SURFACE_LIFT_M, s / 4)
        axes.append(np.linspace(-s / 2 + inset, s / 2 - inset, n))
    heights = [min(SURFACE_LIFT_M, sz / 2)]
    if sz > 4 * SURFACE_LIFT_M:
        heights.append(sz / 2)
    gx, gy, gz = np.meshgrid(axes[0], axes[1], heights, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)


def targets_from_places(places: Mapping[str, Place], specs: Sequence[TargetSpec], *,
                        spacing_m: float = 0.2) -> list[Target]:
    """Targets of the places and boxes ``specs`` name, in spec order then place-name order.

    Args:
        places: the environment's places (:meth:`usdscene.scene.catalog.Catalog.places`).
        specs: parsed ``--targets`` arguments.
        spacing_m: spacing of the sample grid in each region (metres).

    Returns:
        One :class:`Target` per (place, region) that exists, and one per box.

    Raises:
        DocumentError: a pattern matches no place, or no matched place has a named region.
    """
    problems = ProblemCollector()
    targets: list[Target] = []
    seen: set[str] = set()
    for spec in specs:
        if spec.box_name:
            lo, hi = np.array(spec.box_min_m), np.array(spec.box_max_m)
            local = box_points(hi - lo, spacing_m)
            pts = local + np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
            targets.append(Target(spec.box_name, "", "box", pts))
            continue
        names = sorted(n for n in places if fnmatch.fnmatchcase(n, spec.pattern))
        if not names:
            problems.add("--targets", f"place pattern {spec.pattern!r} matches no place of the environment "
                                      f"(places look like {', '.join(sorted(places)[:3])}, ...)")
            continue
        found = 0
        for name in names:
            for region in spec.regions:
                r = places[name].regions.get(REGION_RELATIONS[region])
                # 'in' and 'back_pocket' both serve is_in; keep the name the user asked for.
                key = f"{name}:{region}"
                if r is None or key in seen:
                    continue
                seen.add(key)
                found += 1
                pts = r.pose.transform_points(box_points(r.size_m, spacing_m))
                targets.append(Target(key, name, region, pts))
        if not found:
            problems.add("--targets", f"no place matching {spec.pattern!r} has a region "
                                      f"{', '.join(spec.regions)}")
    problems.raise_if_any(DocumentError)
    return targets
