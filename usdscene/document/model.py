"""SceneSpec: the one intermediate representation every format converts to and from.

Plain frozen dataclasses, stdlib + numpy only (no pxr, no bpy). Conventions, fixed here and
nowhere else re-derived:

* World: right-handed, Z up, metres.
* A :class:`Pose` maps *child* coordinates to *parent* (world) coordinates, like OpenLABEL's
  ``pose_wrt_parent``: ``p_world = pose.matrix @ p_child`` for homogeneous column vectors.
* Camera frames are OpenCV (x right, y down, z forward). USD/Blender cameras look down -Z with
  +Y up; :func:`cv_to_usd_camera_rotation` / :func:`usd_to_cv_camera_rotation` convert
  (``R_usd = R_cv · diag(1, -1, -1)``).
* Lights shine along their local -Z axis (USD/Blender convention).
* Frame numbers are integers and equal the USD time code. Frame intervals are closed.
* Colours are linear RGB in [0, 1].
"""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, field, replace
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

# --------------------------------------------------------------------------------------------
# Geometry


@dataclass(frozen=True)
class Pose:
    """A rigid transform child → parent.

    Attributes:
        matrix: 16 floats, row-major 4x4 homogeneous matrix (last row ``0 0 0 1``); the upper
            3x3 block is a rotation, the last column the translation in metres.
    """

    matrix: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
                                 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)

    @staticmethod
    def identity() -> "Pose":
        """The identity pose (no rotation, no translation)."""
        return Pose()

    @staticmethod
    def from_matrix(matrix: np.ndarray | Sequence[Sequence[float]] | Sequence[float]) -> "Pose":
        """Build from a (4, 4) array or 16 row-major numbers."""
        m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
        return Pose(tuple(float(v) for v in m.reshape(16)))

    @staticmethod
    def from_rotation_translation(rotation: np.ndarray, translation_m: Sequence[float]) -> "Pose":
        """Build from a (3, 3) rotation matrix and a translation (3,) in metres."""
        m = np.eye(4)
        m[:3, :3] = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        m[:3, 3] = np.asarray(translation_m, dtype=np.float64).reshape(3)
        return Pose.from_matrix(m)

    @staticmethod
    def from_quaternion(quaternion_xyzw: Sequence[float], translation_m: Sequence[float]) -> "Pose":
        """Build from a quaternion ``(x, y, z, w)`` (normalised here) and a translation (m)."""
        return Pose.from_rotation_translation(quaternion_to_rotation(quaternion_xyzw), translation_m)

    def as_array(self) -> np.ndarray:
        """The (4, 4) float64 matrix."""
        return np.asarray(self.matrix, dtype=np.float64).reshape(4, 4)

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) rotation matrix."""
        return self.as_array()[:3, :3]

    @property
    def translation_m(self) -> np.ndarray:
        """(3,) translation in metres."""
        return self.as_array()[:3, 3]

    def inverse(self) -> "Pose":
        """The inverse rigid transform: ``self.inverse().compose(self)`` is the identity."""
        m = self.as_array()
        r = m[:3, :3].T
        return Pose.from_rotation_translation(r, -r @ m[:3, 3])

    def compose(self, other: "Pose") -> "Pose":
        """``self ∘ other``: apply ``other`` first, then ``self``."""
        return Pose.from_matrix(self.as_array() @ other.as_array())

    def transform_points(self, points: np.ndarray) -> np.ndarray:
        """Transform (N, 3) points (metres) from child to parent coordinates → (N, 3)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        m = self.as_array()
        return pts @ m[:3, :3].T + m[:3, 3]


def quaternion_to_rotation(quaternion_xyzw: Sequence[float]) -> np.ndarray:
    """(3, 3) rotation matrix of a quaternion given as ``(x, y, z, w)``; normalised first."""
    x, y, z, w = (float(v) for v in quaternion_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n == 0.0:
        raise ValueError("quaternion has zero length")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rotation_to_quaternion(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion ``(x, y, z, w)`` with ``w >= 0`` of a (3, 3) rotation matrix."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x, y, z = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        w, x, y, z = (m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    return (float(x), float(y), float(z), float(w))


def euler_zyx_to_rotation(rz_rad: float, ry_rad: float, rx_rad: float) -> np.ndarray:
    """(3, 3) rotation ``Rz(rz) · Ry(ry) · Rx(rx)`` (OpenLABEL ``sequence`` "ZYX", angles
    given as ``[rz, ry, rx]`` in radians)."""
    cz, sz = math.cos(rz_rad), math.sin(rz_rad)
    cy, sy = math.cos(ry_rad), math.sin(ry_rad)
    cx, sx = math.cos(rx_rad), math.sin(rx_rad)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    return rz @ ry @ rx


def rotation_to_euler_zyx(rotation: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`euler_zyx_to_rotation`: ``(rz, ry, rx)`` in radians."""
    m = np.asarray(rotation, dtype=np.float64)
    ry = math.asin(max(-1.0, min(1.0, -m[2, 0])))
    if abs(m[2, 0]) < 1.0 - 1e-12:
        rz = math.atan2(m[1, 0], m[0, 0])
        rx = math.atan2(m[2, 1], m[2, 2])
    else:  # gimbal lock: rx folded into rz
        rz = math.atan2(-m[0, 1], m[1, 1])
        rx = 0.0
    return (rz, ry, rx)


# OpenCV camera axes (x right, y down, z forward) → USD camera axes (x right, y up, -z forward).
CV_TO_USD_CAMERA_AXES = np.diag([1.0, -1.0, -1.0])


def cv_to_usd_camera_rotation(rotation_cv: np.ndarray) -> np.ndarray:
    """Camera-to-world rotation in OpenCV axes → the same camera in USD/Blender axes."""
    return np.asarray(rotation_cv, dtype=np.float64) @ CV_TO_USD_CAMERA_AXES


def usd_to_cv_camera_rotation(rotation_usd: np.ndarray) -> np.ndarray:
    """Inverse of :func:`cv_to_usd_camera_rotation` (the axis flip is its own inverse)."""
    return np.asarray(rotation_usd, dtype=np.float64) @ CV_TO_USD_CAMERA_AXES


def cv_pose_to_usd_pose(pose_cv: Pose) -> Pose:
    """Camera pose (camera→world) with OpenCV camera axes → USD camera axes."""
    return Pose.from_rotation_translation(cv_to_usd_camera_rotation(pose_cv.rotation), pose_cv.translation_m)


def usd_pose_to_cv_pose(pose_usd: Pose) -> Pose:
    """Camera pose (camera→world) with USD camera axes → OpenCV camera axes."""
    return Pose.from_rotation_translation(usd_to_cv_camera_rotation(pose_usd.rotation), pose_usd.translation_m)


# --------------------------------------------------------------------------------------------
# Time


@dataclass(frozen=True, order=True)
class FrameInterval:
    """A closed interval of frame numbers ``[frame_start, frame_end]``."""

    frame_start: int
    frame_end: int

    def __contains__(self, frame: int) -> bool:
        return self.frame_start <= frame <= self.frame_end

    def frames(self) -> range:
        """The frames of the interval, both ends included."""
        return range(self.frame_start, self.frame_end + 1)


def union_intervals(intervals: Iterable[FrameInterval]) -> tuple[FrameInterval, ...]:
    """Sorted, merged union of closed intervals (adjacent intervals are merged too)."""
    merged: list[FrameInterval] = []
    for iv in sorted(intervals):
        if merged and iv.frame_start <= merged[-1].frame_end + 1:
            last = merged[-1]
            merged[-1] = FrameInterval(last.frame_start, max(last.frame_end, iv.frame_end))
        else:
            merged.append(iv)
    return tuple(merged)


def clip_intervals(intervals: Iterable[FrameInterval], frame_start: int, frame_end: int) -> tuple[FrameInterval, ...]:
    """The merged union of ``intervals`` cut to the closed range ``frame_start..frame_end``
    (empty when none reaches into it)."""
    return union_intervals(FrameInterval(max(iv.frame_start, frame_start), min(iv.frame_end, frame_end))
                           for iv in intervals if iv.frame_end >= frame_start and iv.frame_start <= frame_end)


def in_intervals(frame: int, intervals: Iterable[FrameInterval]) -> bool:
    """Whether ``frame`` lies in any of the closed ``intervals``."""
    return any(frame in iv for iv in intervals)


# --------------------------------------------------------------------------------------------
# Cameras


class LensModel(str, enum.Enum):
    """Projection models. ``r`` is the image radius in pixels, ``θ`` the angle off the axis."""

    PERSPECTIVE = "perspective"                # ideal pinhole: r = f tan θ
    ORTHOGRAPHIC = "orthographic"              # parallel projection
    FISHEYE_EQUIDISTANT = "fisheye_equidistant"  # r = f θ
    FISHEYE_EQUISOLID = "fisheye_equisolid"    # r = 2 f sin(θ/2)
    OPENCV_PINHOLE = "opencv_pinhole"          # pinhole + Brown-Conrady k1 k2 p1 p2 [k3 [k4 k5 k6]]
    OPENCV_FISHEYE = "opencv_fisheye"          # Kannala-Brandt: r = f θ (1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)
    # VCD's kannala, r = f_vcd (k1θ + k2θ³ + k3θ⁵ + k4θ⁷ + k5θ⁹), normalised: f = f_vcd k1 and
    # d_i = k_(i+1) / k1, so r = f θ (1 + d1θ² + d2θ⁴ + d3θ⁶ + d4θ⁸) (OpenCV's formula, any θ)
    KANNALA = "kannala"
    # VCD's radial_poly, r = f_vcd (c1θ + c2θ² + c3θ³ + c4θ⁴ [+ c5θ⁵]), normalised: f = f_vcd c1
    # and d_i = c_(i+1) / c1, so r = f θ (1 + d1θ + d2θ² + d3θ³ [+ d4θ⁴])
    RADIAL_POLY = "radial_poly"


@dataclass(frozen=True)
class Intrinsics:
    """How a camera maps directions to pixels.

    Pixel coordinates follow OpenCV: x right, y down, pixel *centres* at integer coordinates
    (pixel column u covers [u - 0.5, u + 0.5]). A Blender camera without lens shift therefore
    has its principal point at ``((width_px - 1) / 2, (height_px - 1) / 2)``.

    Attributes:
        lens: projection model.
        width_px, height_px: image size in pixels.
        fx_px, fy_px: focal lengths in pixels (for ORTHOGRAPHIC: pixels per metre).
        cx_px, cy_px: principal point in pixels.
        distortion: OpenCV coefficients: (k1, k2, p1, p2[, k3[, k4, k5, k6]]) for
            OPENCV_PINHOLE, (k1, k2, k3, k4) for OPENCV_FISHEYE; the normalised (d1, d2, d3,
            d4) for KANNALA and (d1, d2, d3[, d4]) for RADIAL_POLY (see :class:`LensModel`);
            empty otherwise.
        fov_deg: for fisheye lenses, the full field of view of the image circle (degrees);
            rays beyond ``fov_deg / 2`` off the axis are black. None = unlimited.
        sensor_width_mm: physical sensor width, used to express focal lengths in millimetres
            for USD/Blender (``focal_length_mm = fx_px * sensor_width_mm / width_px``).
    """

    lens: LensModel
    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion: tuple[float, ...] = ()
    fov_deg: float | None = None
    sensor_width_mm: float = 36.0

    @property
    def focal_length_mm(self) -> float:
        """Focal length in millimetres, from ``fx_px`` and the sensor width."""
        return self.fx_px * self.sensor_width_mm / self.width_px

    @property
    def sensor_height_mm(self) -> float:
        """Sensor height matching the pixel aspect: square pixels when fx == fy."""
        return self.sensor_width_mm * self.height_px / self.width_px * (self.fx_px / self.fy_px)

    def resized(self, width_px: int, height_px: int) -> "Intrinsics":
        """The same lens imaging onto ``width_px`` × ``height_px`` pixels (a render at another
        resolution). Pixel centres sit at integers, so a position p maps to ``(p + 0.5) · s - 0.5``
        with s the per-axis size ratio."""
        if (width_px, height_px) == (self.width_px, self.height_px):
            return self
        sx, sy = width_px / self.width_px, height_px / self.height_px
        return replace(self, width_px=width_px, height_px=height_px, fx_px=self.fx_px * sx,
                       fy_px=self.fy_px * sy, cx_px=(self.cx_px + 0.5) * sx - 0.5,
                       cy_px=(self.cy_px + 0.5) * sy - 0.5)

    def camera_matrix(self) -> np.ndarray:
        """(3, 3) OpenCV camera matrix K."""
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])


# Lenses that map the angle off the axis to an image radius; they have an image circle
# (``Intrinsics.fov_deg``) and are written as ``intrinsics_fisheye`` calibrations.
FISHEYE_LENSES = frozenset({LensModel.OPENCV_FISHEYE, LensModel.KANNALA, LensModel.RADIAL_POLY,
                            LensModel.FISHEYE_EQUIDISTANT, LensModel.FISHEYE_EQUISOLID})


@dataclass(frozen=True)
class Camera:
    """A camera stream with its calibration.

    Attributes:
        name: stream name (= coordinate system name) in OpenLABEL, prim name in USD.
        intrinsics: projection model and parameters.
        pose: camera → world, OpenCV camera axes (x right, y down, z forward), for every frame
            not listed in ``frame_poses``.
        frame_poses: per-frame overrides ``(frame, pose)`` sorted by frame.
        clip_near_m, clip_far_m: clipping range in metres.
        model_name: the hardware model label (e.g. "Axis M3068-P"), informational.
        description: free text.
        custom: extra parameters of the friendly form, kept verbatim.
        extra: the stream's content usdscene does not model (other keys of the stream and of
            its ``stream_properties``), as :func:`canonical_json` text; "" = none. Written
            back unchanged.
        sensor: what the camera's sensor and encoder do to its image
            (:class:`usdscene.document.imaging.Sensor`); None = a clean image.
    """

    name: str
    intrinsics: Intrinsics
    pose: Pose = field(default_factory=Pose)
    frame_poses: tuple[tuple[int, Pose], ...] = ()
    clip_near_m: float = 0.01
    clip_far_m: float = 1000.0
    model_name: str = ""
    description: str = ""
    custom: Mapping[str, Any] = field(default_factory=dict)
    extra: str = ""
    sensor: Any = None

    def pose_at(self, frame: int) -> Pose:
        """Camera-to-world pose at ``frame``: its per-frame pose when it has one, else :attr:`pose`."""
        for f, p in self.frame_poses:
            if f == frame:
                return p
        return self.pose


# --------------------------------------------------------------------------------------------
# Lights


class LightKind(str, enum.Enum):
    """Light types, as spelled in the document."""

    POINT = "point"
    SPOT = "spot"
    SUN = "sun"
    AREA = "area"


@dataclass(frozen=True)
class Light:
    """A light source (OpenLABEL object of type ``light``).

    Attributes:
        uid: OpenLABEL object uid.
        name: object name (prim name in USD).
        kind: point / spot / sun / area.
        pose: light → world; the light shines along its local -Z axis.
        power_w: radiant power in watts for point, spot and area lights (Blender's "Power");
            for sun, the irradiance in W/m² (Blender's sun "Strength"). The document reader
            gives a sun without a stated power ``usdscene.document.imaging.DEFAULT_SUN_IRRADIANCE_W_M2``.
        color_rgb: linear RGB in [0, 1].
        radius_m: emitter radius (point, spot) in metres; softens shadows.
        spot_angle_deg: full cone angle of a spot light in degrees.
        spot_blend: softness of the spot edge in [0, 1].
        size_m: (width, height) of an area light in metres.
        sun_angle_deg: angular diameter of the sun disc in degrees.
        frame_intervals: presence; empty = every frame.
    """

    uid: str
    name: str
    kind: LightKind
    pose: Pose = field(default_factory=Pose)
    power_w: float = 100.0
    color_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)
    radius_m: float = 0.05
    spot_angle_deg: float = 45.0
    spot_blend: float = 0.15
    size_m: tuple[float, float] = (0.5, 0.5)
    sun_angle_deg: float = 0.526
    frame_intervals: tuple[FrameInterval, ...] = ()


# --------------------------------------------------------------------------------------------
# Objects, places, relations


# What Blender accepts (the hard limits of its settings, Blender 5.0): a document beyond them
# would pass validation and then fail, overflow or be clamped when it is composed or rendered.
MAX_IMAGE_SIDE_PX = 65536  # RenderSettings.resolution_x / resolution_y
MAX_FRAME = 1048574  # Scene.frame_start / frame_end (Blender's MAXFRAME)
MAX_SAMPLES = 16777216  # Cycles samples
MAX_BOUNCES = 1024  # Cycles max_bounces
MAX_TILE_SIZE_PX = 8192  # Cycles tile_size
MAX_RENDER_SEED = 2**31 - 1  # Cycles seed
MAX_FPS = 1000.0  # frames per second; beyond this a document most likely gives a rate in another unit


class RelationType(str, enum.Enum):
    """Spatial relations that place an object; their object is a place or another object."""

    IS_ON = "is_on"
    IS_BELOW = "is_below"
    IS_IN = "is_in"
    IS_IN_FRONT_OF = "is_in_front_of"


# The relation type names that place an object (``is_on`` ...), in declaration order.
PLACEMENT_RELATIONS = tuple(r.value for r in RelationType)


@dataclass(frozen=True)
class Randomization:
    """Per-object randomization knobs, drawn from the document's seeded generator.

    Attributes:
        position_noise_m: standard deviation of the horizontal position noise, metres.
        rotation_noise_deg: standard deviation of the yaw noise (about world Z), degrees.
        random_color: draw a random base colour for the object.
        random_appearance: draw one of the asset's appearance variants.
    """

    position_noise_m: float = 0.0
    rotation_noise_deg: float = 0.0
    random_color: bool = False
    random_appearance: bool = False


@dataclass(frozen=True)
class DeclaredRegion:
    """A region of a place declared in the document itself (an OpenLABEL ``cuboid`` of the place
    object), for environments whose asset has no such place: a bare mesh needs no round trip
    through a modelling tool.

    Attributes:
        relation: placement relation the region serves (``is_on``, ``is_below``, ...).
        pose: region frame → world: origin at the centre of the box's bottom face (the support
            surface), +Z up out of it.
        size_m: (x, y, z) size of the box in metres.
    """

    relation: str
    pose: Pose
    size_m: tuple[float, float, float]

    @staticmethod
    def from_cuboid(relation: str, value: Sequence[float]) -> "DeclaredRegion":
        """From an OpenLABEL ``cuboid`` value ``[x, y, z, qx, qy, qz, qw, sx, sy, sz]`` (centre in
        world metres, unit rotation quaternion, full sizes in metres)."""
        rotation = quaternion_to_rotation(value[3:7])
        size = tuple(float(v) for v in value[7:10])
        bottom = np.asarray(value[0:3], dtype=np.float64) - rotation @ np.array([0.0, 0.0, size[2] / 2.0])
        return DeclaredRegion(relation, Pose.from_rotation_translation(rotation, bottom), size)

    def to_cuboid(self) -> list[float]:
        """The OpenLABEL ``cuboid`` value of :meth:`from_cuboid`."""
        m = self.pose.as_array()
        centre = m[:3, 3] + m[:3, :3] @ np.array([0.0, 0.0, self.size_m[2] / 2.0])
        return [*(float(v) for v in centre), *(float(v) for v in rotation_to_quaternion(m[:3, :3])),
                *(float(v) for v in self.size_m)]


@dataclass(frozen=True)
class PlaceRef:
    """A place of the environment that the document names (an OpenLABEL object of type
    ``place``). Its geometry lives in the environment asset, or, for places the asset lacks, in
    the document as declared regions.

    Attributes:
        uid: OpenLABEL object uid.
        name: place name in the environment, e.g. ``seat_03A``, ``bin_02L``, ``aisle_04``.
        regions: regions declared in the document (they add to or replace the asset's).
        extra: the element's content usdscene does not read (other object data, other keys),
            canonical JSON ("" when none), written back unchanged.
    """

    uid: str
    name: str
    regions: tuple[DeclaredRegion, ...] = ()
    extra: str = ""


@dataclass(frozen=True)
class SceneObject:
    """A dynamic object of an asset class (OpenLABEL object whose type is a catalog class).

    Attributes:
        uid: OpenLABEL object uid.
        name: object name.
        class_name: asset class in the catalog (e.g. ``backpack``, ``passenger``).
        frame_intervals: presence (closed intervals).
        pose: explicit object → world pose; wins over relations. None = placed by relations.
        frame_poses: explicit per-frame poses ``(frame, pose)`` sorted by frame.
        appearance: requested appearance variant name; None = the asset's default (or random
            when ``randomization.random_appearance``).
        color_rgb: explicit base colour override (linear RGB); None = asset's own.
        randomization: noise and colour knobs.
        extra: the element's content usdscene does not model (object data of other names such
            as bboxes, cuboids, poly2d or a vec ``Position``, their pointers, other keys), as
            :func:`canonical_json` text of a partial OpenLABEL object; "" = none.
        frame_extra: the same per frame ``(frame, text)`` for ``frames[f].objects[uid]``,
            sorted by frame.
        pose_variant: requested variant of the asset's ``pose`` variant set (a passenger's
            ``reading``); None = the asset's default. It decides the support places the object
            offers (a passenger's lap).
    """

    uid: str
    name: str
    class_name: str
    frame_intervals: tuple[FrameInterval, ...] = ()
    pose: Pose | None = None
    frame_poses: tuple[tuple[int, Pose], ...] = ()
    appearance: str | None = None
    color_rgb: tuple[float, float, float] | None = None
    randomization: Randomization = field(default_factory=Randomization)
    extra: str = ""
    frame_extra: tuple[tuple[int, str], ...] = ()
    pose_variant: str | None = None


@dataclass(frozen=True)
class Relation:
    """``subject <type> object``, e.g. ``backpack is_below seat_03A``.

    Attributes:
        uid: OpenLABEL relation uid.
        type: relation name (a :class:`RelationType` value for placement relations; other
            names are kept and written back but do not place anything).
        subject_uid: uid of the object being placed (``rdf_subjects``).
        object_uid: uid of the place or object it relates to (``rdf_objects``).
        frame_intervals: when it holds; empty = whenever the subject is present.
        extra: the element's content usdscene does not read (its ``name`` when not empty,
            ``ontology_uid``, ``resource_uid``, other keys), as :func:`canonical_json` text;
            "" = none. Written back unchanged.
    """

    uid: str
    type: str
    subject_uid: str
    object_uid: str
    frame_intervals: tuple[FrameInterval, ...] = ()
    extra: str = ""


# --------------------------------------------------------------------------------------------
# Carried data


def canonical_json(value: Mapping[str, Any] | None) -> str:
    """Canonical JSON text of a JSON object (sorted keys, no spaces, UTF-8 characters kept);
    "" for None or an empty object.

    This is the form of the ``extra`` fields: text keeps the frozen dataclasses hashable, and
    two carried values are equal exactly when their canonical texts are byte-equal.
    """
    if not value:
        return ""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def extra_data(text: str) -> dict[str, Any]:
    """The JSON object of an ``extra`` field (a fresh copy; ``{}`` for "")."""
    return json.loads(text) if text else {}


# --------------------------------------------------------------------------------------------
# Rendering and provenance


@dataclass(frozen=True)
class RenderSettings:
    """Blender render settings (``metadata.usdscene.render`` in the document).

    Attributes:
        engine: ``cycles`` (default), ``eevee`` or ``workbench``.
        device: ``cpu`` or ``gpu``.
        samples: path-tracing samples per pixel.
        adaptive_threshold: Cycles adaptive-sampling noise threshold; 0 disables it.
        adaptive_min_samples: samples every pixel takes before adaptive sampling may stop it;
            0 lets Cycles choose (used only with ``adaptive_threshold`` > 0).
        denoise: run a denoiser on the beauty pass.
        denoiser: ``openimagedenoise`` or ``optix``.
        denoising_quality: OIDN quality, ``high``, ``balanced`` or ``fast``.
        denoising_prefilter: OIDN prefilter of the albedo/normal guides, ``accurate``,
            ``fast`` or ``none``.
        denoising_input_passes: guides given to the denoiser: ``rgb_albedo_normal``,
            ``rgb_albedo`` or ``rgb``.
        light_tree: Cycles' light tree (many-light sampling by importance); off samples the
            lights by power alone.
        path_guiding: learned path guiding of surface bounces (CPU only).
        sampling_pattern: Cycles' sample sequence: ``tabulated_sobol`` (what a fresh Blender
            scene uses) or ``blue_noise`` (the error of neighbouring pixels decorrelated into
            high frequencies, which the denoiser removes more easily).
        clamp_indirect: largest value of one indirect sample (linear radiance); 0 disables
            clamping. Lower values trade bias for fewer fireflies.
        fast_gi: Cycles' fast GI approximation: after ``fast_gi_ao_bounces`` bounces a path
            stops at the next surface and the light it would have gathered is replaced by
            ambient occlusion tinted by the world (biased; dark in a closed room under a black
            world).
        fast_gi_method: ``replace`` (the bounces after ``fast_gi_ao_bounces`` become ambient
            occlusion) or ``add`` (full global illumination plus ambient occlusion on top).
        fast_gi_ao_bounces: bounces after which fast GI approximates (Cycles' render value,
            ``ao_bounces_render``); 0 turns the approximation off even with ``fast_gi``.
        fast_gi_distance_m: the world's ambient-occlusion distance in metres: how far away a
            surface still occludes (Blender's world ``light_settings.distance``).
        scrambling_distance: Cycles' scrambling distance in [0, 1]: below 1 neighbouring
            pixels share correlated sample sequences (faster on GPUs through coherent rays,
            at the cost of blotchy artefacts); 1 is full per-pixel scrambling. Only with the
            ``tabulated_sobol`` sampling pattern; Cycles ignores it for ``blue_noise``.
        auto_scrambling_distance: let Cycles scale ``scrambling_distance`` by
            ``4 / sqrt(samples)`` (with adaptive sampling, its minimum samples); at 16 spp or
            fewer that factor is >= 1 and nothing changes.
        max_bounces: total light bounces.
        caustics: enable reflective and refractive caustics.
        tile_size_px: Cycles tile size in pixels.
        resolution_px: default (width, height) for cameras that do not give one.
        seed: Cycles sampling seed.
        depth: also write a depth image per rendered image (distance to the image plane,
            :mod:`usdscene.render.depth`): ``png16`` (millimetres) or ``exr`` (metres); None = none.
    """

    engine: str = "cycles"
    device: str = "cpu"
    samples: int = 8
    adaptive_threshold: float = 0.0
    adaptive_min_samples: int = 0
    denoise: bool = True
    denoiser: str = "openimagedenoise"
    # 8 spp + OIDN high/accurate: the fastest row of benchmarks/README.md that reaches 30 dB
    # PSNR against a 1024-sample reference of the cabin (about 9 s per 640x480 image on 2 cores).
    denoising_quality: str = "high"
    denoising_prefilter: str = "accurate"
    # The knobs below keep Cycles' own defaults: measured side by side on four cabin cameras
    # (benchmarks/README.md, "Quality per second"), none of them, alone or combined with fewer
    # samples or a cheaper denoiser, halves the seconds per image within 0.3 dB PSNR.
    denoising_input_passes: str = "rgb_albedo_normal"
    light_tree: bool = True
    path_guiding: bool = False
    clamp_indirect: float = 10.0
    sampling_pattern: str = "tabulated_sobol"
    # Fast GI and scrambling distance keep Cycles' own defaults (off, 1.0): measured side by
    # side on the cabin, neither reaches half the seconds per image within 0.3 dB PSNR.
    fast_gi: bool = False
    fast_gi_method: str = "replace"
    fast_gi_ao_bounces: int = 1
    fast_gi_distance_m: float = 10.0
    scrambling_distance: float = 1.0
    auto_scrambling_distance: bool = False
    max_bounces: int = 1
    caustics: bool = False
    tile_size_px: int = 2048
    resolution_px: tuple[int, int] = (640, 480)
    seed: int = 0
    depth: str | None = None


@dataclass(frozen=True)
class Provenance:
    """Where a scene came from.

    Attributes:
        source: path or URI of the source document ("" if built in memory).
        source_sha256: hex digest of the source bytes ("" if unknown).
        source_format: ``openlabel`` / ``vcd`` / ``usd`` / ``blend``.
        toolkit_version: usdscene version that read it.
    """

    source: str = ""
    source_sha256: str = ""
    source_format: str = "openlabel"
    toolkit_version: str = ""


@dataclass(frozen=True)
class SceneSpec:
    """A whole scene: everything needed to compose, render and label it.

    Attributes:
        name: scene name.
        frame_start, frame_end: closed frame range (USD start/end time codes).
        cameras, lights, objects, places, relations: elements, in document order.
        render: render settings.
        seed: seed of the one ``numpy.random.Generator`` that drives all randomization.
        environment: asset class of the environment (e.g. ``aircraft_cabin``).
        asset_paths: extra asset folders (catalogs) named by the document, as given.
        exports: dataset formats to export after a run (``coco``, ``yolo``, ``rois``).
        roi_rules: relation type → label for ROI crops (e.g. ``{"is_below": "correct"}``).
        roi_ignore: object classes or catalog kinds the ROI rules do not judge
            (``metadata.usdscene.roi_ignore``, e.g. ``("passenger",)``): their objects do not make
            a place region occupied; what rests on them still does.
        split_rule: the training split rule the document carries (``usdscene.document.splits`` syntax,
            e.g. ``train=0.8,val=0.2``), used by ``usdscene export`` when no ``--split`` is
            given; "" = none.
        split_seed: seed of a ``fractions`` split rule.
        fps: frame rate in frames per second (``metadata.usdscene.fps``): frame f is the instant
            ``f / fps`` s, written as the OpenLABEL frame ``timestamp`` and as the stage's
            ``timeCodesPerSecond``; labels are defined at that instant (a motion-blurred image's
            shutter centre). None = the document states no rate.
        world: background, sky or HDRI, exposure and view transform
            (:class:`usdscene.document.imaging.World`); None = the black world of the Standard view.
        description: free text.
        provenance: where it came from.
        extra: the document's content usdscene does not model, as :func:`canonical_json` text
            of a partial OpenLABEL body: unknown ``metadata`` keys, non-camera streams (and
            camera streams without usable intrinsics), actions, events, contexts, ontologies,
            resources, tags, relations that involve them, and per-frame content
            (``frame_properties`` other than transforms, per-frame stream properties,
            actions, events, contexts, relation markers); "" = none. Written back unchanged,
            so a converted document keeps other people's data.
    """

    name: str = "scene"
    frame_start: int = 0
    frame_end: int = 0
    cameras: tuple[Camera, ...] = ()
    lights: tuple[Light, ...] = ()
    objects: tuple[SceneObject, ...] = ()
    places: tuple[PlaceRef, ...] = ()
    relations: tuple[Relation, ...] = ()
    render: RenderSettings = field(default_factory=RenderSettings)
    seed: int = 0
    environment: str | None = None
    asset_paths: tuple[str, ...] = ()
    exports: tuple[str, ...] = ()
    roi_rules: Mapping[str, str] = field(default_factory=dict)
    roi_ignore: tuple[str, ...] = ()
    description: str = ""
    provenance: Provenance = field(default_factory=Provenance)
    extra: str = ""
    split_rule: str = ""
    split_seed: int = 0
    fps: float | None = None
    world: Any = None

    @property
    def frames(self) -> range:
        """The frames of the scene, ``frame_start`` to ``frame_end`` included."""
        return range(self.frame_start, self.frame_end + 1)

    def camera(self, name: str) -> Camera:
        """The camera called ``name``; raises KeyError when there is none."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        raise KeyError(name)

    def object_by_uid(self) -> dict[str, SceneObject]:
        """uid → object, in document order."""
        return {o.uid: o for o in self.objects}

    def place_by_uid(self) -> dict[str, PlaceRef]:
        """uid → place reference, in document order."""
        return {p.uid: p for p in self.places}

    def objects_present(self, frame: int) -> tuple[SceneObject, ...]:
        """Objects whose frame intervals contain ``frame`` (no intervals = always present)."""
        return tuple(o for o in self.objects
                     if not o.frame_intervals or in_intervals(frame, o.frame_intervals))
