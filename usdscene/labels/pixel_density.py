"""Pixel density at a point seen by a camera, and the image-detail classes it reaches (DORI).

Pixel density (px/m) of a point is the image-space length, in pixels, of one metre laid at the
point perpendicular to the viewing ray, taken in the worse of the two perpendicular directions
(the local Jacobian of the exact lens model from :mod:`usdscene.labels.projection`), so a
fisheye's squeezed radial direction at the edge of its image is what counts.

The detail classes are a table of minimum densities, shipped for two editions of IEC 62676-4
(:data:`STANDARD_FILES`): the 2015 DORI classes (``usdscene/data/dori.json``: monitor ... inspect)
and the 2025 levels (``usdscene/data/dori_2025.json``: overview ... scrutinize, in the object-size
groups LPDO and HPDO); a user file replaces either. The camera planner (:mod:`usdscene.design`)
uses the 2025 table unless told otherwise; the cross-camera table of annotated runs
(:mod:`usdscene.labels.cross_camera`) keeps the 2015 table, so that annotated outputs stay as
they were. Pure (numpy).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import Camera
from usdscene.labels.projection import project_points
from usdscene.shipped import shipped_data_file

log = logging.getLogger(__name__)


DORI_FILE = shipped_data_file("dori.json")
# Shipped detail tables by edition of IEC 62676-4 (``plan-cameras --standard``).
STANDARD_FILES = {"2015": DORI_FILE, "2025": shipped_data_file("dori_2025.json")}


def read_json_object(path: Path, problems: ProblemCollector) -> dict | None:
    """The JSON object in ``path``; None (and a problem naming the file) when it cannot be read
    or is not an object."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        problems.add(str(path), f"cannot read: {exc}")
        return None
    if not isinstance(data, dict):
        problems.add(str(path), "expected a JSON object")
        return None
    return data


@dataclass(frozen=True)
class DoriClass:
    """An image-detail class: name, the pixel density it needs at the target (px/m), and its
    object-size group (``LPDO`` / ``HPDO`` in IEC 62676-4:2025; "" where the table has none)."""

    name: str
    px_per_m: float
    group: str = ""


def load_dori(path: str | os.PathLike | None = None) -> tuple[DoriClass, ...]:
    """The DORI table, ascending in pixel density.

    Args:
        path: a JSON file replacing the shipped IEC 62676-4:2015 table
            (``{"classes": [{"name": ..., "px_per_m": ...}, ...]}``).

    Raises:
        DocumentError: unreadable file, malformed entries, repeated names.
    """
    file = Path(path) if path is not None else DORI_FILE
    problems = ProblemCollector()
    data = read_json_object(file, problems)
    classes: list[DoriClass] = []
    if data is not None:
        raw = data.get("classes")
        if not isinstance(raw, list) or not raw:
            problems.add(f"{file}:classes", "expected a non-empty list of {name, px_per_m}")
            raw = []
        for i, item in enumerate(raw):
            where = f"{file}:classes[{i}]"
            if not isinstance(item, dict) or not isinstance(item.get("name"), str):
                problems.add(where, f"expected an object with a 'name' string, got {item!r}")
                continue
            value = item.get("px_per_m")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                problems.add(f"{where}.px_per_m", f"expected a positive number, got {value!r}")
                continue
            classes.append(DoriClass(item["name"], float(value), str(item.get("group", ""))))
        names = [c.name for c in classes]
        for name in sorted({n for n in names if names.count(n) > 1}):
            problems.add(f"{file}:classes", f"class name {name!r} appears more than once")
    problems.raise_if_any(DocumentError)
    return tuple(sorted(classes, key=lambda c: c.px_per_m))


def standard_file(standard: str) -> Path:
    """The shipped detail table of an edition of IEC 62676-4 (``2015`` or ``2025``).

    Raises:
        DocumentError: an edition that is not shipped.
    """
    if standard not in STANDARD_FILES:
        raise DocumentError(f"unknown standard {standard!r}; shipped: {', '.join(STANDARD_FILES)}",
                            where="--standard")
    return STANDARD_FILES[standard]


def table_standard(path: str | os.PathLike | None = None) -> str:
    """The name of the standard a detail table follows: its ``standard`` field
    (``IEC 62676-4:2025``), or ``custom table <file name>`` when it names none."""
    file = Path(path) if path is not None else DORI_FILE
    problems = ProblemCollector()
    data = read_json_object(file, problems)
    problems.raise_if_any(DocumentError)
    name = data.get("standard") if data is not None else None
    return name if isinstance(name, str) and name else f"custom table {file.name}"


def dori_index(px_per_m: np.ndarray, table: Sequence[DoriClass]) -> np.ndarray:
    """Index into ``table`` of the best class each density reaches; -1 = below the lowest.

    Args:
        px_per_m: any-shaped array of pixel densities.
        table: ascending classes (:func:`load_dori`).

    Returns:
        int array of the same shape.
    """
    thresholds = np.array([c.px_per_m for c in table])
    values = np.nan_to_num(np.asarray(px_per_m, dtype=np.float64), nan=0.0)
    return np.searchsorted(thresholds, values, side="right") - 1


def dori_class(px_per_m: float, table: Sequence[DoriClass]) -> str | None:
    """Name of the best class ``px_per_m`` reaches, None below the lowest."""
    i = int(dori_index(np.array([px_per_m]), table)[0])
    return table[i].name if i >= 0 else None


def class_index(name: str, table: Sequence[DoriClass], where: str = "dori") -> int:
    """Index of a class by name; DocumentError naming the known classes otherwise."""
    for i, c in enumerate(table):
        if c.name == name:
            return i
    raise DocumentError(f"unknown image-detail class {name!r}; the table has {', '.join(c.name for c in table)}",
                        where=where)


def pixel_density(camera: Camera, points_m: np.ndarray, step_m: float = 0.01) -> np.ndarray:
    """Pixels per metre at each point, across the viewing ray, in the worse direction.

    Two small steps perpendicular to the viewing ray are projected with the camera's exact
    lens model; the smaller of their image lengths per metre is returned.

    Args:
        camera: the camera.
        points_m: (N, 3) world points, metres.
        step_m: finite-difference step (metres).

    Returns:
        (N,) float64 px/m; 0 where the point or its neighbours do not project.
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    if not len(pts):
        return np.zeros(0)
    pose = camera.pose.as_array()
    r, t = pose[:3, :3], pose[:3, 3]
    ray = pts - t
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    # Perpendicular directions: the camera's x axis and y axis made orthogonal to each ray.
    densities = []
    uv0, ok0 = project_points(camera, pts)
    for axis in (r[:, 0], r[:, 1]):
        e = axis - (ray @ axis)[:, None] * ray
        e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
        uv1, ok1 = project_points(camera, pts + step_m * e)
        d = np.linalg.norm(uv1 - uv0, axis=1) / step_m
        densities.append(np.where(ok0 & ok1, d, 0.0))
    return np.minimum(densities[0], densities[1])
