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
metres are converted: region frames come out Z up, in metres, with the box's own up axis
(local +Y of a Y-up file) as the region's +Z.

Pure module (numpy): the format readers in :mod:`usdscene.assetgen.asset_import` hand it node names,
matrices and local bounds.
"""

from __future__ import annotations

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


def region_from_box(box: PlaceBox, up_axis: str, unit_scale_m: float) -> PlaceRegion:
    """The catalog region (Z up, metres) of one box of a file.

    Args:
        box: the box as read from the file.
        up_axis: ``"Y"`` or ``"Z"``, the file's up axis.
        unit_scale_m: metres per file unit.

    Raises:
        AssetError: the box is sheared, mirrored or flat (no usable size).
    """
    to_world = file_to_world(up_axis, unit_scale_m)
    up = np.eye(4)
    up[:3, :3] = up_axis_rotation(up_axis)
    # The box's local frame is a file frame too: express it Z up so that the box's own up
    # axis becomes the region's +Z.
    world = to_world @ np.asarray(box.matrix, dtype=np.float64) @ up.T
    corners = np.array([[x, y, z] for x in (box.local_min[0], box.local_max[0])
                        for y in (box.local_min[1], box.local_max[1])
                        for z in (box.local_min[2], box.local_max[2])]) @ up[:3, :3].T
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    linear = world[:3, :3]
    scale = np.linalg.norm(linear, axis=0)
    size = np.round((hi - lo) * scale, 4)
    if np.any(scale < 1e-12) or np.any(size <= 0):
        raise AssetError(f"place box {box.node!r} has no volume (size {size.tolist()} m)", where=box.node)
    rotation = linear / scale
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-5) or np.linalg.det(rotation) < 0:
        raise AssetError(f"place box {box.node!r} is sheared or mirrored; apply its transform's "
                         "rotation and scale without negative or non-uniform skew", where=box.node)
    bottom = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2], 1.0])
    origin = (world @ bottom)[:3]
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

