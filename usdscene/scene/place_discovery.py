"""Places authored in a DCC tool: named boxes and empties → catalog place regions.

An environment modelled in Blender, Maya, 3ds Max or Houdini marks each place with a box (or
an empty) whose name follows ``place.<place>.<region>``: ``place.bay_03.on``,
``place.bench_2.below``, ``place.counter_1.in_front``. ``.`` and ``_`` are both accepted as
separators, because USD prim names cannot hold a dot and exporters turn ``place.bay_03.on``
into ``place_bay_03_on``. Instead of the name, a custom property ``usdscene_place`` with the
value ``<place>.<region>`` marks any node (Blender exports custom properties to USD as
``userProperties:usdscene_place``; ``usdscene:place`` is read too).

``<region>`` is one of :data:`usdscene.scene.catalog.REGION_RELATIONS` (``on``, ``below``,
``in_front``, ``in``, ``back_pocket``) and decides the placement relation it serves. The
place's kind is its name without the trailing number (``bay_03`` → ``bay``).

The box gives the region: its bottom face is the support surface (the region frame's z = 0
plane, origin at the face's centre), its axes are the region's axes and its size is the
usable size. A box is a mesh node (its own bounding box in its local frame, times the node's
scale); an empty stands for the cube from -1 to 1 on each axis of its frame (Blender's cube
empty of display size 1), so scale the empty to the region. Files that are Y up or not in
metres are converted: region frames come out Z up, in metres, with the box axis that points up
after the conversion as the region's +Z (wherever the file put the Z-up → Y-up turn: in the
vertices, in the nodes' transforms or in a rotated root); a box with no vertical axis is
refused.

Pure module (numpy): the format readers in :mod:`usdscene.assetgen.asset_import` hand it node names,
matrices and local bounds.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from usdscene.scene.catalog import REGION_RELATIONS, Place, PlaceRegion, place_kind, places_for_catalog
from usdscene.errors import AssetError, ProblemCollector
from usdscene.document.model import Pose

PLACE_PROPERTY = "usdscene_place"
"""Custom property naming a place region (value ``<place>.<region>``)."""

# Longest region names first, so ``place_x_in_front`` is region ``in_front``, not ``front``.
_REGIONS = "|".join(sorted(REGION_RELATIONS, key=len, reverse=True))
_PLACE_NAME = re.compile(rf"^place[._](?P<place>[A-Za-z0-9_]+?)[._](?P<region>{_REGIONS})$")
_PROPERTY_VALUE = re.compile(rf"^(?P<place>[A-Za-z0-9_]+)\.(?P<region>{_REGIONS})$")
# An empty's region: the cube from -1 to 1 (Blender's cube empty, display size 1).
EMPTY_BOUNDS = (np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]))


@dataclass(frozen=True)
class PlaceBox:
    """A node of a DCC file that marks a place region.

    Attributes:
        node: node or prim name/path in the file (for messages and to hide the box).
        place: place name (``bay_03``).
        region: region name (``on``, ``below``, ``in_front``, ``in``, ``back_pocket``).
        matrix: (4, 4) node → file-world matrix, column-vector convention, file units.
        local_min, local_max: (3,) bounds of the box in the node's own frame (file units).
    """

    node: str
    place: str
    region: str
    matrix: np.ndarray
    local_min: np.ndarray
    local_max: np.ndarray


def parse_place_name(name: str, property_value: str | None = None, *, where: str = "") -> tuple[str, str] | None:
    """(place, region) named by a node, or None when the node marks no place.

    Args:
        name: the node's name (``place.bay_03.on``, ``place_bay_03_on``).
        property_value: the node's ``usdscene_place`` property, if any (wins over the name).
        where: file and node, for the error.

    Raises:
        AssetError: the property is malformed, or the name starts with ``place.`` but does not
            follow the convention (a misspelt region would silently lose the place).
    """
    if property_value is not None:
        match = _PROPERTY_VALUE.match(str(property_value).strip())
        if match is None:
            raise AssetError(f"{PLACE_PROPERTY} {property_value!r} must be '<place>.<region>' with region "
                             f"one of {sorted(REGION_RELATIONS)}", where=where)
        return match["place"], match["region"]
    match = _PLACE_NAME.match(name)
    if match is not None:
        return match["place"], match["region"]
    if name.startswith("place."):
        raise AssetError(f"node {name!r} looks like a place but is not 'place.<place>.<region>' with region "
                         f"one of {sorted(REGION_RELATIONS)}", where=where)
    return None


def up_axis_rotation(up_axis: str) -> np.ndarray:
    """(3, 3) rotation taking a ``up_axis``-up frame to Z up (Y up: +90° about X)."""
    if up_axis == "Z":
        return np.eye(3)
    return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def file_to_world(up_axis: str, unit_scale_m: float) -> np.ndarray:
    """(4, 4) matrix taking file coordinates to the library's frame (Z up, metres)."""
    m = np.eye(4)
    m[:3, :3] = up_axis_rotation(up_axis) * unit_scale_m
    return m


VERTICAL_TOLERANCE_DEG = 1.0
"""Most a place box's up axis may lean from the vertical after conversion (degrees): a region
is a support surface, and a tilted one would leave objects floating at one end."""


def region_from_box(box: PlaceBox, up_axis: str, unit_scale_m: float) -> PlaceRegion:
    """The catalog region (Z up, metres) of one box of a file.

    The box's matrix and bounds are taken to the library's frame first; the box axis that
    then points up (whichever local axis it is: a Y-up file may carry the Z-up → Y-up turn in
    its vertices, in its nodes' transforms or in a rotated root) becomes the region's +Z, the
    first of the two other axes (in x, y, z order, its positive direction) the region's +X.
    So every valid way of writing one scene gives the same regions.

    Args:
        box: the box as read from the file.
        up_axis: ``"Y"`` or ``"Z"``, the file's up axis.
        unit_scale_m: metres per file unit.

    Raises:
        AssetError: the box is sheared, mirrored, flat (no usable size), or none of its axes
            is vertical (within :data:`VERTICAL_TOLERANCE_DEG`), naming the node.
    """
    world = file_to_world(up_axis, unit_scale_m) @ np.asarray(box.matrix, dtype=np.float64)
    linear = world[:3, :3]
    scale = np.linalg.norm(linear, axis=0)
    local_size = (np.asarray(box.local_max, float) - np.asarray(box.local_min, float)) * scale
    if np.any(scale < 1e-12) or np.any(np.round(local_size, 4) <= 0):
        raise AssetError(f"place box {box.node!r} has no volume (size {np.round(local_size, 4).tolist()} m)",
                         where=box.node)
    axes = linear / scale  # columns: the box's local axes in the library's frame
    if not np.allclose(axes.T @ axes, np.eye(3), atol=1e-5) or np.linalg.det(axes) < 0:
        raise AssetError(f"place box {box.node!r} is sheared or mirrored; apply its transform's "
                         "rotation and scale without negative or non-uniform skew", where=box.node)
    up_index = int(np.argmax(np.abs(axes[2])))
    if abs(axes[2, up_index]) < math.cos(math.radians(VERTICAL_TOLERANCE_DEG)):
        tilt = math.degrees(math.acos(min(1.0, abs(axes[2, up_index]))))
        raise AssetError(f"place box {box.node!r} has no vertical axis after conversion to Z up (the "
                         f"closest leans {tilt:.1f}°); a region's bottom face must be level "
                         "(check the file's up axis, --up-axis)", where=box.node)
    up_sign = 1.0 if axes[2, up_index] > 0 else -1.0
    x_index = min(i for i in range(3) if i != up_index)
    y_index = 3 - up_index - x_index
    # Region axes as signed local axes: +Z = the upward local axis, +X = the first other one,
    # +Y = Z × X (a rotation, never a mirror).
    z_axis = up_sign * axes[:, up_index]
    x_axis = axes[:, x_index]
    y_axis = np.cross(z_axis, x_axis)
    y_sign = 1.0 if float(np.dot(y_axis, axes[:, y_index])) > 0 else -1.0
    rotation = np.column_stack([x_axis, y_sign * axes[:, y_index], z_axis])
    size = np.round(np.array([local_size[x_index], local_size[y_index], local_size[up_index]]), 4)
    # The bottom face's centre, in the box's own coordinates.
    lo, hi = np.asarray(box.local_min, float), np.asarray(box.local_max, float)
    bottom = (lo + hi) / 2.0
    bottom[up_index] = lo[up_index] if up_sign > 0 else hi[up_index]
    origin = (world @ np.append(bottom, 1.0))[:3]
    # Rounding keeps catalog.json readable and free of float noise from the file's matrices.
    pose = Pose.from_rotation_translation(np.round(rotation, 9) + 0.0, np.round(origin, 6) + 0.0)
    relation = REGION_RELATIONS[box.region]
    return PlaceRegion(relation=relation, pose=pose, size_m=tuple(float(v) for v in size))  # type: ignore[arg-type]


def places_from_boxes(boxes: Iterable[PlaceBox], up_axis: str, unit_scale_m: float, *,
                      source: str) -> tuple[dict[str, tuple[str, dict[str, PlaceRegion]]], dict[str, Place]]:
    """Places of a file from its boxes.

    Args:
        boxes: every box found in the file.
        up_axis, unit_scale_m: the file's up axis and metres per unit.
        source: the file (for messages).

    Returns:
        (authored, catalog): place → (kind, region name → region) for
        :func:`usdscene.assetgen.usd_write.author_places`, and the catalog form (regions keyed
        by relation), both sorted by place name.

    Raises:
        AssetError: every bad box at once, and places with two boxes for one relation.
    """
    problems = ProblemCollector()
    authored: dict[str, tuple[str, dict[str, PlaceRegion]]] = {}
    seen: dict[tuple[str, str], str] = {}
    for box in boxes:
        where = f"{source}:{box.node}"
        try:
            region = region_from_box(box, up_axis, unit_scale_m)
        except AssetError as exc:
            for problem in exc.problems:
                problems.add(where, problem.message)
            continue
        key = (box.place, region.relation)
        if key in seen:
            problems.add(where, f"place {box.place!r} already has a {region.relation} region from {seen[key]!r}")
            continue
        seen[key] = box.node
        authored.setdefault(box.place, (place_kind(box.place), {}))[1][box.region] = region
    problems.raise_if_any(AssetError)
    authored = dict(sorted(authored.items()))
    return authored, places_for_catalog(authored)

