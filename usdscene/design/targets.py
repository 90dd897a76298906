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
# Regions longer than this (in X or Y of their frame) become a grid of equal cells no longer
# than this: a walkway is many targets, each a share of the floor, not one target that counts
# as seen when a quarter of it is.
DEFAULT_CELL_M = 5.0


@dataclass(frozen=True)
class Target:
    """Something the camera system must see, as sample points.

    Attributes:
        name: ``<place>:<region>`` (``seat_05C:on``) or the box's name.
        place: place name ("" for a box).
        region: region short name (``on``, ``below``, ``in_front``, ...) or "box".
        points_m: (N, 3) float64 world points, metres.
        area_m2: floor area the target stands for (its region's or cell's X × Y size), m².
    """

    name: str
    place: str
    region: str
    points_m: np.ndarray
    area_m2: float = 0.0

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


def region_cells(size_m: Sequence[float], cell_m: float) -> list[tuple[tuple[int, int], np.ndarray, np.ndarray]]:
    """A region ``[-sx/2, sx/2] × [-sy/2, sy/2] × [0, sz]`` split into ``nx × ny`` equal cells
    no longer than ``cell_m`` in X and Y (one cell when it already is).

    Returns:
        Per cell, in X-major order: ((i, j), (3,) cell size m, (3,) cell-frame origin in the
        region frame m (the centre of its base)).
    """
    sx, sy, sz = (float(v) for v in size_m)
    nx = max(1, int(math.ceil(sx / cell_m - 1e-9)))
    ny = max(1, int(math.ceil(sy / cell_m - 1e-9)))
    size = np.array([sx / nx, sy / ny, sz])
    return [((i, j), size, np.array([-sx / 2 + (i + 0.5) * size[0], -sy / 2 + (j + 0.5) * size[1], 0.0]))
            for i in range(nx) for j in range(ny)]


def targets_from_places(places: Mapping[str, Place], specs: Sequence[TargetSpec], *,
                        spacing_m: float = 0.2, cell_m: float = DEFAULT_CELL_M) -> list[Target]:
    """Targets of the places and boxes ``specs`` name, in spec order then place-name order.

    Args:
        places: the environment's places (:meth:`usdscene.scene.catalog.Catalog.places`).
        specs: parsed ``--targets`` arguments.
        spacing_m: spacing of the sample grid in each region (metres).
        cell_m: a region or box longer than this in X or Y becomes cells (:func:`region_cells`),
            named ``<place>#<i>_<j>:<region>`` (``<box>#<i>_<j>``).

    Returns:
        One :class:`Target` per (place, region) that exists (per cell of it), and per box.

    Raises:
        DocumentError: a pattern matches no place, or no matched place has a named region.
    """
    problems = ProblemCollector()
    targets: list[Target] = []
    seen: set[str] = set()
    for spec in specs:
        if spec.box_name:
            lo, hi = np.array(spec.box_min_m), np.array(spec.box_max_m)
            cells = region_cells(hi - lo, cell_m)
            for (i, j), size, origin in cells:
                pts = box_points(size, spacing_m) + origin + np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
                name = spec.box_name if len(cells) == 1 else f"{spec.box_name}#{i:03d}_{j:03d}"
                targets.append(Target(name, "", "box", pts, float(size[0] * size[1])))
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
                cells = region_cells(r.size_m, cell_m)
                for (i, j), size, origin in cells:
                    pts = r.pose.transform_points(box_points(size, spacing_m) + origin)
                    cell_key = key if len(cells) == 1 else f"{name}#{i:03d}_{j:03d}:{region}"
                    targets.append(Target(cell_key, name, region, pts, float(size[0] * size[1])))
        if not found:
            problems.add("--targets", f"no place matching {spec.pattern!r} has a region "
                                      f"{', '.join(spec.regions)}")
    problems.raise_if_any(DocumentError)
    return targets
