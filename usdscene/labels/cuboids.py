"""3D boxes (cuboids) of objects in world metres, and their OpenLABEL form. Pure (numpy).

A :class:`Cuboid` is upright (world Z up): the object's yaw about Z orients it, and its size is
measured along the object's own axes: width along its x, length along its y, height along z
(the catalog's movers face -Y, so ``length_m`` runs along a car or a walker). The box is the
tightest such box around the object's posed geometry at that frame: every world triangle of
the object (people: their posed, skinned body; vehicles and other objects: their model at its
pose), so it contains every point of the object and its projection through any lens contains
the object's amodal projection. An object whose origin lies inside that box's ground
footprint (a person's root between its feet, a vehicle's model centre) has the box centred on
its origin horizontally instead, so that the box moves with the object and not with its
stride (see :func:`fit_cuboid`).

The yaw is the object's, not the geometry's: the direction of its local x axis in the world,
``atan2(x_y, x_x)`` (the local y axis when x points straight up), so a walker swinging an arm
keeps its heading and the box grows instead of turning.

OpenLABEL (1.0.0 ``cuboid``): ``val`` = ``[x, y, z, qx, qy, qz, qw, sx, sy, sz]``, the centre,
the rotation as a quaternion (a rotation about Z only) and the size, in the document's world
coordinate system (:data:`CUBOID_NAME` ``box3d``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Collection, Iterable, Mapping, Protocol

import numpy as np

CUBOID_NAME = "box3d"

# The 8 corners of the unit cube [-1/2, 1/2]^3 (x fastest) and its 12 outward triangles.
_UNIT_CORNERS = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
_FACES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6],      # bottom, top
                   [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7],      # -y, +y
                   [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])     # -x, +x


@dataclass(frozen=True)
class Cuboid:
    """An upright 3D box in world metres (Z up).

    Attributes:
        center_m: (3,) centre, world metres.
        size_m: (3,) width (along the object's x), length (along y), height (along z), metres.
        yaw_rad: rotation about world Z from the world's axes to the object's, radians, (-π, π].
    """

    center_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    yaw_rad: float

    @property
    def quaternion_xyzw(self) -> tuple[float, float, float, float]:
        """The rotation as a unit quaternion ``(x, y, z, w)`` (about Z only)."""
        half = self.yaw_rad / 2.0
        return (0.0, 0.0, math.sin(half), math.cos(half))

    def rotation(self) -> np.ndarray:
        """(3, 3) rotation object → world (column vectors)."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def corners(self) -> np.ndarray:
        """(8, 3) world corners, metres; index bit 0 = +x, bit 1 = +y, bit 2 = +z side of the object."""
        local = _UNIT_CORNERS * np.asarray(self.size_m, dtype=np.float64)
        return local @ self.rotation().T + np.asarray(self.center_m, dtype=np.float64)

    def triangles(self) -> np.ndarray:
        """(12, 3, 3) world triangles of the box's surface (outward facing), metres: what the
        amodal projection takes (:func:`usdscene.labels.amodal.amodal_projection`)."""
        return self.corners()[_FACES]

    def openlabel_val(self) -> list[float]:
        """``[x, y, z, qx, qy, qz, qw, sx, sy, sz]`` (OpenLABEL's 10-value cuboid)."""
        return [*map(float, self.center_m), *self.quaternion_xyzw, *map(float, self.size_m)]

    @staticmethod
    def from_openlabel_val(val) -> "Cuboid":
        """The inverse of :meth:`openlabel_val` (a quaternion about Z only, as written here)."""
        values = [float(v) for v in val]
        if len(values) != 10:
            raise ValueError(f"a 10-value cuboid was expected, got {len(values)} values")
        x, y, z, qx, qy, qz, qw, sx, sy, sz = values
        return Cuboid((x, y, z), (sx, sy, sz), _wrap(2.0 * math.atan2(qz, qw)))


def _wrap(angle_rad: float) -> float:
    """Angle into (-π, π]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def object_yaw(local_to_world: np.ndarray) -> float:
    """Yaw of an object from its (4, 4) USD local → world matrix (row vectors: row 0 is the
    local x axis in world coordinates), radians.

    The local x axis projected onto the ground; the local y axis (turned by -90°) when x
    points (nearly) straight up or down.
    """
    m = np.asarray(local_to_world, dtype=np.float64)
    x_axis, y_axis = m[0, :3], m[1, :3]
    if math.hypot(x_axis[0], x_axis[1]) > 1e-6 * max(float(np.linalg.norm(x_axis)), 1e-300):
        return _wrap(math.atan2(x_axis[1], x_axis[0]))
    return _wrap(math.atan2(y_axis[1], y_axis[0]) - math.pi / 2.0)


def fit_cuboid(triangles_m: np.ndarray, yaw_rad: float, origin_m: np.ndarray | None = None) -> Cuboid:
    """The tightest upright box at ``yaw_rad`` around an object's world triangles; with an
    ``origin_m`` inside the box's ground footprint, the tightest such box centred on it
    horizontally.

    A walker's tightest box follows its stride: a leg swung forward moves the centre by 0.1-0.2 m
    between two frames (5 m/s between frames at 30 fps, beyond what the AI City readers
    accept), while its origin moves with its track. Centred on the origin, the box still holds
    every point and its centre moves as the object does; a rigid object whose origin is the
    centre of its model (the catalog's vehicles) keeps its tight box.

    Args:
        triangles_m: (T, 3, 3) (or (N, 3) points) world metres; at least one point.
        yaw_rad: the object's yaw (:func:`object_yaw`), radians.
        origin_m: (3,) the object's origin in the world, metres; None = the tight box.

    Returns:
        The :class:`Cuboid`; its size is 0 along an axis where the geometry is flat.
    """
    points = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3)
    if not len(points):
        raise ValueError("an object without geometry has no 3D box")
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    local = points @ rotation  # world → object axes (R^T p for row vectors)
    low, high = local.min(axis=0), local.max(axis=0)
    if origin_m is not None:
        origin = np.asarray(origin_m, dtype=np.float64) @ rotation
        if np.all((low[:2] <= origin[:2]) & (origin[:2] <= high[:2])):
            reach = np.maximum(origin[:2] - low[:2], high[:2] - origin[:2])
            low[:2], high[:2] = origin[:2] - reach, origin[:2] + reach
    center = rotation @ ((low + high) / 2.0)
    return Cuboid(tuple(float(v) for v in center), tuple(float(v) for v in high - low), _wrap(float(yaw_rad)))


def frame_cuboids(triangles_m: Mapping[str, np.ndarray],
                  local_to_world: Mapping[str, np.ndarray]) -> dict[str, Cuboid]:
    """The 3D box of every object of one frame that has both geometry and a pose.

    Args:
        triangles_m: uid → (T, 3, 3) world triangles, metres
            (:meth:`usdscene.scene.stage_geometry.StageGeometry.triangles`).
        local_to_world: uid → (4, 4) USD local → world matrix of the object
            (:meth:`usdscene.scene.stage_geometry.StageGeometry.transforms`).

    Returns:
        uid → :class:`Cuboid`, in the order of ``triangles_m``.
    """
    return {uid: fit_cuboid(tris, object_yaw(local_to_world[uid]), np.asarray(local_to_world[uid])[3, :3])
            for uid, tris in triangles_m.items() if uid in local_to_world and len(tris)}


def cuboid_data(cuboid: Cuboid, coordinate_system: str) -> dict:
    """The OpenLABEL ``object_data.cuboid`` item of a box (name :data:`CUBOID_NAME`)."""
    return {"name": CUBOID_NAME, "val": cuboid.openlabel_val(), "coordinate_system": coordinate_system}


def document_cuboids(document: dict) -> dict[int, dict[str, Cuboid]]:
    """Every ``box3d`` cuboid of an annotated OpenLABEL document, read in one pass.

    Returns:
        frame → {object key (the document's uid) → :class:`Cuboid`}, frames ascending; frames
        without boxes are absent.
    """
    frames = ((document or {}).get("openlabel") or {}).get("frames") or {}
    result: dict[int, dict[str, Cuboid]] = {}
    for key in sorted(frames, key=lambda k: int(k)):
        boxes = {}
        for uid, entry in ((frames[key] or {}).get("objects") or {}).items():
            for item in ((entry or {}).get("object_data") or {}).get("cuboid", []) or []:
                if item.get("name") == CUBOID_NAME and item.get("val") is not None:
                    boxes[uid] = Cuboid.from_openlabel_val(item["val"])
        if boxes:
            result[int(key)] = boxes
    return result


class PoseSource(Protocol):
    """What :func:`labelled_cuboids` needs from the stage (e.g.
    :class:`usdscene.scene.stage_geometry.StageGeometry`)."""

    def triangles(self, frame: int, uids=None) -> dict[str, np.ndarray]:
        """uid → (T, 3, 3) world triangles (metres) of the objects visible at ``frame``."""

    def transforms(self, frame: int, uids=None) -> dict[str, np.ndarray]:
        """uid → (4, 4) USD local → world matrix of the objects visible at ``frame``."""


def labelled_cuboids(frames: Iterable[int], geometry: PoseSource,
                     uids: Collection[str] | None = None) -> dict[int, dict[str, Cuboid]]:
    """The 3D box of every object with geometry at each of ``frames``.

    Args:
        frames: frame numbers (the labelled ones).
        geometry: the stage's triangles and object poses.
        uids: restrict to these objects (e.g. those of the mask id map); None = all.

    Returns:
        frame → uid → :class:`Cuboid`, frames ascending; objects absent at a frame are absent.
    """
    out = {}
    for frame in sorted(set(int(f) for f in frames)):
        out[frame] = frame_cuboids(geometry.triangles(frame, uids), geometry.transforms(frame, uids))
    return out
