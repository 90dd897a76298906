"""AI City Challenge Track 1 (multi-camera people tracking) export of an annotated moving
sequence. Pure (numpy, cv2; h5py lazily for depth).

``OUT/exports/aicity/<scene>/`` for ``edition="2025"`` (the default)::

    calibration.json      "cartesian" calibration: version, osmURL, calibrationType, sensors[]
    ground_truth.json     frame (string key) -> objects, written frame by frame (streamed)
    track1.txt            the ground truth in the submission format (a GT twin for self-scoring)
    map.png               the top-down map (written by the caller: an orthographic render)
    depth_maps/Camera_0000.h5   one dataset per frame, distance_to_image_plane_%05d.png: PNG bytes
    videos/Camera_0000.mp4      (written by the caller from the rendered images)
    usdscene_aicity.json  camera id <-> usdscene camera, class mapping, frame and id rules

and for ``edition="2024"``: ``<scene>/camera_0000/calibration.json`` (``camera projection
matrix``, ``homography matrix``) and ``<scene>/ground_truth.txt`` (``camera_id obj_id frame_id
xmin ymin width height xworld yworld``, one line per object and camera that sees it).

**Cameras** are the labelled cameras in name order, ``Camera_0000``, ``Camera_0001`` ...
(``camera_%04d`` folders and integer ids in 2024); ``usdscene_aicity.json`` records the
mapping. AIC's calibration has no distortion: only ideal pinhole cameras (``perspective``, and
``opencv_pinhole`` with every coefficient zero) are exported; any other lens is refused.

**Frames**: AIC frame = document frame - first labelled frame (0-based, as the published
ground truth and videos count). **Object ids**: :func:`usdscene.converters.exports.tracks.track_ids`.

**Calibration** (per camera, OpenCV axes and pixel centres at integer coordinates):
``intrinsicMatrix`` K, ``extrinsicMatrix`` [R|t] (world -> camera), ``cameraMatrix`` K [R|t]
(world metres -> pixels), ``homography`` K [r1 r2 t]: the world ground plane z = 0, (x, y, 1),
-> image pixels; this is the direction NVIDIA's calibration visualiser applies it in (some other
writers store the inverse). ``coordinates`` is the camera's position (x, y world metres);
``scaleFactor`` (map pixels per metre) and ``translationToGlobalCoordinates`` (metres) are the
map's and equal for every camera: map pixel ``px = (x + tx) s``, ``py = H_map - (y + ty) s``.
``imageCoordinates`` / ``globalCoordinates`` are ground points (z = 0) seen by the camera and
their pixels. ``attributes``: ``fps``, ``direction`` (heading of the optical axis in degrees,
counter-clockwise from world +x), ``direction3d`` (the optical axis, ``"x,y,z"`` world unit
vector), ``frameWidth``, ``frameHeight`` (all as strings), and ``homographyDirection``.

**Ground truth**, per object and frame: ``object type`` (the AIC class), ``object id``,
``object name`` (the usdscene object name), ``3d location`` (the 3D box centre, world metres),
``3d bounding box scale`` [w, l, h] (object x, y, z extents, metres), ``3d bounding box
rotation`` [pitch, roll, yaw] (radians, Z-Y-X), ``2d bounding box`` (the whole projection
clipped to the image, per camera id) and ``2d bounding box visible`` (the visible pixels' box,
only cameras that see a pixel), both ``[xmin, ymin, xmax, ymax]`` pixel edges (xmax exclusive).
The 3D box is the object's ``box3d`` cuboid when the document has one, else the catalog
extent of its class placed by its per-frame pose.

**Classes**: a usdscene class → AIC class mapping (:data:`AIC_CLASSES`); objects of unmapped
classes are left out. **Speed**: the published readers assert at most 5 m/s between frames;
an object moving faster is refused, naming it and the frame.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from usdscene.converters.exports.tracks import ID_RULE, require_tracks, track_ids
from usdscene.document.model import Camera, RenderSettings
from usdscene.errors import DocumentError, OutputError, Problem

log = logging.getLogger(__name__)

AICITY_DIR = "aicity"
EDITIONS = ("2025", "2024")
AIC_CLASSES = {"Person": 0, "Forklift": 1, "NovaCarter": 2, "Transporter": 3, "FourierGR1T2": 4,
               "AgilityDigit": 5}
"""The 2025 Track 1 classes and their ids (the ``class_id`` of ``track1.txt``)."""
MAX_SPEED_M_S = 5.0
CUBOID_NAME = "box3d"
POSE_NAME = "pose_matrix4x4"
GROUND_NAME = "ground_position_m"
HOMOGRAPHY_DIRECTION = "world ground plane z=0 (x, y, 1) -> image pixel (x, y, 1)"
DEPTH_DATASET = "distance_to_image_plane_{:05d}.png"


@dataclass(frozen=True)
class AicOptions:
    """How a moving sequence becomes an AI City Challenge scene.

    Attributes:
        edition: ``"2025"`` or ``"2024"`` (:data:`EDITIONS`).
        class_map: usdscene class → AIC class name (a key of :data:`AIC_CLASSES`); other
            classes are left out.
        scene: name of the scene folder.
        scene_id: the ``<scene_id>`` of ``track1.txt``.
        map_m_per_px: metres per map pixel (``scaleFactor`` = 1 / it).
        map_bounds_m: (x0, y0, x1, y1) world metres the map covers; None = the environment, the
            cameras and the positions plus 2 m.
    """

    edition: str = "2025"
    class_map: Mapping[str, str] = field(default_factory=dict)
    scene: str = "Scene_000"
    scene_id: int = 0
    map_m_per_px: float = 0.05
    map_bounds_m: tuple[float, float, float, float] | None = None


def check_class_map(class_map: Mapping[str, str]) -> None:
    """Raise :class:`DocumentError` naming every mapping to a class AIC does not have."""
    problems = [Problem(f"--aic-class {name}={aic}", f"{aic!r} is no AI City Challenge class; expected one of "
                                                     f"{', '.join(AIC_CLASSES)}")
                for name, aic in class_map.items() if aic not in AIC_CLASSES]
    if problems:
        raise DocumentError(problems)


def _cameras(document: dict) -> list[Camera]:
    from usdscene.converters.openlabel.cameras import read_cameras
    from usdscene.converters.openlabel.load import DocumentBody

    from usdscene.converters.openlabel.store import scene_document

    body = DocumentBody(scene_document(document)["openlabel"])
    cameras = read_cameras(body, RenderSettings())
    body.problems.raise_if_any(DocumentError)
    return cameras


def pinhole_problem(camera: Camera) -> str | None:
    """Why AIC's calibration cannot express a camera's lens (None when it can)."""
    from usdscene.lens import lens_for

    k = camera.intrinsics
    export = lens_for(k).opencv_distortion(k)  # an ideal pinhole: OpenCV's pinhole model, no distortion
    if export is not None and export[0] == "pinhole" and not np.any(export[1]):
        return None
    return (f"its {k.lens.value} lens cannot be written: the AI City Challenge calibration has no distortion "
            "model (an ideal pinhole K [R|t] only); leave the camera out with --cameras")


@dataclass(frozen=True)
class AicCamera:
    """One exported camera: its AIC id, the usdscene camera and its calibration at the first frame.

    Attributes:
        aic_id: ``Camera_0000`` ...
        name: usdscene camera name.
        width_px, height_px: image size.
        K: (3, 3) intrinsic matrix. Rt: (3, 4) world → camera (OpenCV axes).
        position_m: (3,) camera centre, world metres.
    """

    aic_id: str
    name: str
    width_px: int
    height_px: int
    K: np.ndarray
    Rt: np.ndarray
    position_m: np.ndarray

    @property
    def camera_matrix(self) -> np.ndarray:
        """(3, 4) K [R|t]: world metres → homogeneous pixels."""
        return self.K @ self.Rt

    @property
    def homography(self) -> np.ndarray:
        """(3, 3) K [r1 r2 t]: world ground plane (x, y, 1) → homogeneous pixels, H[2, 2] = 1."""
        h = self.K @ self.Rt[:, [0, 1, 3]]
        return h / h[2, 2]


def aic_cameras(document: dict, names: Sequence[str], frame: int) -> list[AicCamera]:
    """The exported cameras (``names`` in name order), or a :class:`DocumentError` naming every
    camera AIC's calibration cannot express."""
    by_name = {c.name: c for c in _cameras(document)}
    problems, out = [], []
    for k, name in enumerate(sorted(names)):
        camera = by_name[name]
        problem = pinhole_problem(camera)
        if problem:
            problems.append(Problem(f"camera {name!r}", problem))
            continue
        m = camera.pose_at(frame).as_array()
        r = m[:3, :3].T
        out.append(AicCamera(f"Camera_{k:04d}", name, int(camera.intrinsics.width_px),
                             int(camera.intrinsics.height_px), camera.intrinsics.camera_matrix(),
                             np.c_[r, -r @ m[:3, 3]], m[:3, 3].copy()))
    if problems:
        raise DocumentError(problems)
    return out


@dataclass(frozen=True)
class MapFrame:
    """Where world metres lie on ``map.png``: ``px = (x + tx) s``, ``py = height_px - (y + ty) s``.

    Attributes:
        scale_px_per_m: s (``scaleFactor``).
        translation_m: (tx, ty) (``translationToGlobalCoordinates``).
        width_px, height_px: the map's size.
    """

    scale_px_per_m: float
    translation_m: tuple[float, float]
    width_px: int
    height_px: int

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) map pixels (continuous, pixel edges) of (N, 2) world points."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([(xy[:, 0] + self.translation_m[0]) * self.scale_px_per_m,
                         self.height_px - (xy[:, 1] + self.translation_m[1]) * self.scale_px_per_m], axis=1)

    @property
    def bounds_m(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) world metres of the map's edges."""
        x0, y0 = -self.translation_m[0], -self.translation_m[1]
        return x0, y0, x0 + self.width_px / self.scale_px_per_m, y0 + self.height_px / self.scale_px_per_m


def map_frame(bounds_m: tuple[float, float, float, float], m_per_px: float) -> MapFrame:
    """The map over ``bounds_m`` (x0, y0, x1, y1) at ``m_per_px``, its size rounded up to whole pixels."""
    if not (math.isfinite(m_per_px) and m_per_px > 0):
        raise DocumentError(f"{m_per_px!r} is not a positive number of metres per pixel", where="--map-m-per-px")
    x0, y0, x1, y1 = bounds_m
    width, height = int(math.ceil((x1 - x0) / m_per_px)), int(math.ceil((y1 - y0) / m_per_px))
    if width < 1 or height < 1 or width * height > 100_000_000:
        raise DocumentError(f"a map of {width} x {height} pixels over {bounds_m} m; choose a coarser scale",
                            where="--map-m-per-px")
    return MapFrame(1.0 / m_per_px, (-float(x0), -float(y0)), width, height)


def _ground_points(camera: AicCamera, count: int = 3) -> tuple[list[dict], list[dict]]:
    """Image/ground correspondences: pixels of a grid over the lower image whose rays meet z = 0
    ahead of the camera, and those ground points."""
    h_inv = np.linalg.inv(camera.homography)
    image, world = [], []
    for fy in np.linspace(0.55, 0.95, count):
        for fx in np.linspace(0.1, 0.9, count):
            u, v = fx * (camera.width_px - 1), fy * (camera.height_px - 1)
            g = h_inv @ np.array([u, v, 1.0])
            if abs(g[2]) < 1e-12:
                continue
            x, y = g[0] / g[2], g[1] / g[2]
            depth = (camera.Rt @ np.array([x, y, 0.0, 1.0]))[2]
            if depth > 0:
                image.append({"x": round(float(u), 3), "y": round(float(v), 3)})
                world.append({"x": float(x), "y": float(y)})
    return image, world


def calibration_json(cameras: Sequence[AicCamera], fps: float, frame_map: MapFrame, place: str) -> dict:
    """The 2025 ``calibration.json`` (see the module docstring)."""
    sensors = []
    for camera in cameras:
        axis = camera.Rt[2, :3]  # the optical axis (camera +z) in world coordinates
        image, world = _ground_points(camera)
        attributes = {"fps": f"{fps:g}", "direction": f"{math.degrees(math.atan2(axis[1], axis[0])):.6f}",
                      "direction3d": ",".join(f"{v:.6f}" for v in axis), "frameWidth": str(camera.width_px),
                      "frameHeight": str(camera.height_px), "homographyDirection": HOMOGRAPHY_DIRECTION,
                      "source": "usdscene"}
        sensors.append({
            "type": "camera", "id": camera.aic_id,
            "origin": {"lng": 0.0, "lat": 0.0}, "geoLocation": {"lng": 0.0, "lat": 0.0},
            "coordinates": {"x": float(camera.position_m[0]), "y": float(camera.position_m[1])},
            "scaleFactor": float(frame_map.scale_px_per_m),
            "translationToGlobalCoordinates": {"x": float(frame_map.translation_m[0]),
                                               "y": float(frame_map.translation_m[1])},
            "attributes": [{"name": k, "value": v} for k, v in attributes.items()],
            "place": [{"name": "building", "value": place}, {"name": "camera", "value": camera.name}],
            "imageCoordinates": image, "globalCoordinates": world,
            "intrinsicMatrix": camera.K.tolist(), "extrinsicMatrix": camera.Rt.tolist(),
            "cameraMatrix": camera.camera_matrix.tolist(), "homography": camera.homography.tolist(),
        })
    return {"version": "1.0", "osmURL": "", "calibrationType": "cartesian", "sensors": sensors}


# --------------------------------------------------------------------------------------------
# Ground truth, frame by frame


@dataclass(frozen=True)
class AicObject:
    """One object in one frame, in AIC's terms.

    Attributes:
        uid: usdscene uid. object_id: integer track id. name: object name.
        aic_class: AIC class name.
        location_m: (3,) box centre. scale_m: (3,) [w, l, h]. rotation_rad: (3,) [pitch, roll, yaw].
        ground_m: (3,) where it stands (``ground_position_m``), else the box's bottom centre.
        boxes: AIC camera id → [xmin, ymin, xmax, ymax] whole projection (pixel edges).
        visible: AIC camera id → [xmin, ymin, xmax, ymax] visible pixels.
    """

    uid: str
    object_id: int
    name: str
    aic_class: str
    location_m: np.ndarray
    scale_m: np.ndarray
    rotation_rad: np.ndarray
    ground_m: np.ndarray
    boxes: dict[str, list[int]]
    visible: dict[str, list[int]]

    def as_json(self) -> dict:
        """The object's entry in ``ground_truth.json``."""
        return {"object type": self.aic_class, "object id": self.object_id, "object name": self.name,
                "3d location": [float(v) for v in self.location_m],
                "3d bounding box scale": [float(v) for v in self.scale_m],
                "3d bounding box rotation": [float(v) for v in self.rotation_rad],
                "2d bounding box": self.boxes, "2d bounding box visible": self.visible}


def pitch_roll_yaw(rotation: np.ndarray) -> np.ndarray:
    """(3,) [pitch, roll, yaw] radians of a (3, 3) rotation R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r = np.asarray(rotation, dtype=np.float64)
    return np.array([math.asin(max(-1.0, min(1.0, -r[2, 0]))), math.atan2(r[2, 1], r[2, 2]),
                     math.atan2(r[1, 0], r[0, 0])])


def _quaternion_matrix(q: Sequence[float]) -> np.ndarray:
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _edges(cx: float, cy: float, w: float, h: float) -> list[int]:
    """OpenLABEL ``[cx, cy, w, h]`` (pixel centres at integers) → whole-pixel edges, xmax exclusive
    (the rule of :func:`usdscene.converters.exports.multiview._edges`, inlined: 2 million boxes a scene)."""
    xmin, ymin = int(round(cx - w / 2.0 + 0.5)), int(round(cy - h / 2.0 + 0.5))
    return [xmin, ymin, xmin + int(round(w)), ymin + int(round(h))]


def _boxes(entry: dict, boxes_by_name: Mapping[str, tuple[str, bool]]) -> tuple[dict, dict]:
    """(whole, visible): AIC camera id → edges of one object in one frame. Only the boxes are read
    (not the polygons, keypoints and attributes :class:`LabelIndex` reads), as AIC needs no more;
    the whole box is the amodal one, else the visible one."""
    whole: dict[str, list[int]] = {}
    visible: dict[str, list[int]] = {}
    for item in ((entry or {}).get("object_data", {}) or {}).get("bbox", []):
        found = boxes_by_name.get(item.get("name", ""))
        if found is None:
            continue
        aic_id, amodal = found
        cx, cy, w, h = item["val"]
        edges = _edges(cx, cy, w, h)
        if amodal:
            whole[aic_id] = edges
        else:
            visible[aic_id] = edges
            whole.setdefault(aic_id, edges)
    return whole, visible


def _object_data(entry: dict, kind: str, name: str):
    for item in ((entry or {}).get("object_data", {}) or {}).get(kind, []):
        if item.get("name") == name:
            return item.get("val")
    return None


def frame_objects(objects: Mapping[str, dict], frame_key: str, frame: dict, *, ids: Mapping[str, int],
                  class_map: Mapping[str, str], camera_ids: Mapping[str, str],
                  extents: Mapping[str, tuple[Sequence[float], Sequence[float]]]) -> list[AicObject]:
    """The AIC objects of one OpenLABEL frame (``{"objects": ...}`` of an annotated document).

    Args:
        objects: the document's ``objects`` (uid → element).
        frame_key, frame: the frame's key and body.
        ids: uid → object id. class_map: usdscene class → AIC class. camera_ids: usdscene camera → AIC id.
        extents: class → (min (3,), max (3,)) metres in the object frame, for objects without a
            ``box3d`` cuboid.
    """
    from usdscene.converters.openlabel.annotations import amodal_bbox_name, bbox_name

    by_name = {bbox_name(c): (a, False) for c, a in camera_ids.items()}
    by_name.update({amodal_bbox_name(c): (a, True) for c, a in camera_ids.items()})
    out = []
    for uid, entry in ((frame or {}).get("objects", {}) or {}).items():
        element = objects.get(uid) or {}
        aic_class = class_map.get(element.get("type", ""))
        if aic_class is None or uid not in ids:
            continue
        cuboid = _object_data(entry, "cuboid", CUBOID_NAME)
        pose = _object_data(entry, "vec", POSE_NAME)
        ground = _object_data(entry, "vec", GROUND_NAME)
        if cuboid is not None:
            location = np.asarray(cuboid[:3], dtype=np.float64)
            scale = np.asarray(cuboid[7:10], dtype=np.float64)
            rotation = _quaternion_matrix(cuboid[3:7])
        elif pose is not None and element.get("type") in extents:
            m = np.asarray(pose, dtype=np.float64).reshape(4, 4)
            lo, hi = (np.asarray(v, dtype=np.float64) for v in extents[element["type"]])
            rotation = m[:3, :3]
            location = m[:3, :3] @ ((lo + hi) / 2.0) + m[:3, 3]
            scale = hi - lo
        else:
            continue
        bottom = location - rotation @ np.array([0.0, 0.0, scale[2] / 2.0])
        whole, visible = _boxes(entry, by_name)
        out.append(AicObject(uid, int(ids[uid]), element.get("name", uid), aic_class, location, scale,
                             pitch_roll_yaw(rotation),
                             np.asarray(ground, dtype=np.float64) if ground is not None else bottom,
                             whole, visible))
    out.sort(key=lambda o: o.object_id)
    return out


class SpeedCheck:
    """The published readers' rule: at most :data:`MAX_SPEED_M_S` between an object's frames."""

    def __init__(self, fps: float) -> None:
        self.fps = fps
        self._last: dict[str, tuple[int, np.ndarray]] = {}

    def check(self, frame: int, objects: Iterable[AicObject]) -> None:
        """Raise :class:`DocumentError` naming an object faster than the limit and the frame."""
        for obj in objects:
            last = self._last.get(obj.uid)
            if last is not None and frame > last[0]:
                speed = float(np.linalg.norm(obj.location_m - last[1])) * self.fps / (frame - last[0])
                if speed > MAX_SPEED_M_S + 1e-9:
                    raise DocumentError(
                        f"moves {speed:.2f} m/s between frames {last[0]} and {frame}; the AI City Challenge "
                        f"readers assert at most {MAX_SPEED_M_S:g} m/s", where=f"object {obj.uid} ({obj.name!r})")
            self._last[obj.uid] = (frame, obj.location_m)


def write_ground_truth(frames: Iterable[tuple[int, list[AicObject]]], folder: Path, *, edition: str,
                       scene_id: int, fps: float, camera_numbers: Mapping[str, int]) -> dict:
    """Write the ground truth frame by frame: ``ground_truth.json`` and ``track1.txt`` (2025) or
    ``ground_truth.txt`` (2024) into ``folder``; only one frame's objects are in memory.

    Args:
        frames: (AIC frame, objects) in frame order.
        camera_numbers: AIC camera id → integer (2024's ``camera_id``).

    Returns:
        counts: ``{"frames", "objects", "boxes"}``.

    Raises:
        DocumentError: an object faster than :data:`MAX_SPEED_M_S` (the caller's staged folder
            then leaves nothing behind).
    """
    speed = SpeedCheck(fps)
    counts = {"frames": 0, "objects": 0, "boxes": 0}
    if edition == "2025":
        with open(folder / "ground_truth.json", "w", encoding="utf-8") as gt, \
                open(folder / "track1.txt", "w", encoding="utf-8") as twin:
            gt.write("{")
            for frame, objects in frames:
                speed.check(frame, objects)
                gt.write(("," if counts["frames"] else "") + f"\n{json.dumps(str(frame))}: ")
                gt.write(json.dumps([o.as_json() for o in objects], separators=(",", ":")))
                for o in objects:
                    twin.write(f"{scene_id} {AIC_CLASSES[o.aic_class]} {o.object_id} {frame} "
                               f"{_num(o.location_m[0])} {_num(o.location_m[1])} {_num(o.location_m[2])} "
                               f"{_num(o.scale_m[0])} {_num(o.scale_m[1])} {_num(o.scale_m[2])} "
                               f"{_num(o.rotation_rad[2])}\n")
                    counts["boxes"] += len(o.boxes)
                counts["frames"] += 1
                counts["objects"] += len(objects)
            gt.write("\n}\n")
    else:
        with open(folder / "ground_truth.txt", "w", encoding="utf-8") as gt:
            for frame, objects in frames:
                speed.check(frame, objects)
                for o in objects:
                    for aic_id, (x0, y0, x1, y1) in sorted(o.visible.items()):
                        gt.write(f"{camera_numbers[aic_id]} {o.object_id} {frame} {x0} {y0} {x1 - x0} {y1 - y0} "
                                 f"{_num(o.ground_m[0])} {_num(o.ground_m[1])}\n")
                        counts["boxes"] += 1
                counts["frames"] += 1
                counts["objects"] += len(objects)
    return counts


def _num(value: float) -> str:
    text = f"{float(value):.6f}".rstrip("0").rstrip(".")
    return text if text not in ("-0", "") else "0"


def document_frames(document: dict, first: int, last: int, **context) -> Iterator[tuple[int, list[AicObject]]]:
    """(AIC frame, objects) of every frame ``first..last`` of an annotated document, one at a time
    (``context``: the keyword arguments of :func:`frame_objects` but ``objects``)."""
    root = document["openlabel"]
    objects = root.get("objects", {}) or {}
    frames = root.get("frames", {}) or {}
    for frame in range(first, last + 1):
        body = frames.get(str(frame))
        yield frame - first, ([] if body is None else frame_objects(objects, str(frame), body, **context))


# --------------------------------------------------------------------------------------------
# Depth


def write_depth_h5(path: Path, pngs: Iterable[tuple[int, Path]]) -> int:
    """One HDF5 file of a camera's depth: a dataset ``distance_to_image_plane_%05d.png`` per AIC
    frame holding that PNG file's bytes (uint8, 1-D); returns the number of frames."""
    import h5py

    count = 0
    with h5py.File(path, "w") as h5:
        for frame, png in pngs:
            h5.create_dataset(DEPTH_DATASET.format(frame), data=np.frombuffer(Path(png).read_bytes(), dtype=np.uint8))
            count += 1
    return count


# --------------------------------------------------------------------------------------------
# The whole scene


def export_aicity(document: dict, out_dir: str | os.PathLike, options: AicOptions, *,
                  extents: Mapping[str, tuple[Sequence[float], Sequence[float]]] = {},
                  place: str = "", environment_bounds_m: tuple[float, float, float, float] | None = None,
                  write_map: Callable[[Path, MapFrame], None] | None = None,
                  write_videos: Callable[[Path, Mapping[str, list[Path]]], None] | None = None) -> Path:
    """Write ``<out_dir>/exports/aicity/<scene>/`` (see the module docstring); returns that folder.

    Everything is checked before anything is written; the folder is built beside the old one and
    swapped in at the end, so a refused export leaves nothing.

    Args:
        document: annotated document of a moving sequence.
        out_dir: the output folder holding the document, images and (if rendered) depth.
        options: edition, classes, scene name, map scale (:class:`AicOptions`).
        extents: class → object-frame bounds for objects without a ``box3d`` cuboid.
        place: the environment's name (the sensors' ``place``).
        environment_bounds_m: (x0, y0, x1, y1) of the environment, which the default map covers too.
        write_map: writes ``map.png`` for a :class:`MapFrame` (2025); None = no map.
        write_videos: writes ``videos/<id>.mp4`` from AIC camera id → images in frame order; None = none.

    Raises:
        OutputError: no frame rate, no labelled image. DocumentError: an unknown AIC class, a lens
            AIC cannot express, an object faster than 5 m/s.
    """
    from usdscene.converters.openlabel.annotations import image_records
    from usdscene.document import output_layout as layout
    from usdscene.files import dumps_json, staged_folder

    if options.edition not in EDITIONS:
        raise DocumentError(f"{options.edition!r} is not an edition; expected one of {', '.join(EDITIONS)}",
                            where="--edition")
    check_class_map(options.class_map)
    if not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]*", options.scene):
        raise DocumentError(f"{options.scene!r} is not a folder name (letters, digits, '_', '-', '.')",
                            where="--aic-scene")
    fps = require_tracks(document, "AI City Challenge")
    records = image_records(document)
    if not records:
        raise OutputError("the document has no labelled image; render and annotate it first",
                          where=str(Path(out_dir) / layout.ANNOTATIONS_FILE))
    first, last = min(r["frame"] for r in records), max(r["frame"] for r in records)
    cameras = aic_cameras(document, sorted({r["camera"] for r in records}), first)
    camera_ids = {c.name: c.aic_id for c in cameras}
    ids = track_ids(document)
    objects = document["openlabel"].get("objects", {}) or {}
    exported = sorted({e.get("type", "") for e in objects.values()} & set(options.class_map))
    left_out = sorted({e.get("type", "") for u, e in objects.items() if u in ids} - set(options.class_map))
    if left_out:
        log.warning("classes %s have no AI City Challenge class; their objects are left out (map them with "
                    "--aic-class CLASS=AIC_CLASS)", left_out)
    context = dict(ids=ids, class_map=options.class_map, camera_ids=camera_ids, extents=extents)
    # The speed rule is checked in a first pass that writes nothing (one frame in memory at a time).
    speed = SpeedCheck(fps)
    positions = []
    for frame, frame_objs in document_frames(document, first, last, **context):
        speed.check(frame + first, frame_objs)
        positions.extend(o.ground_m[:2] for o in frame_objs)
    if options.map_bounds_m is not None:
        bounds = options.map_bounds_m
    else:
        points = np.array([*positions, *(c.position_m[:2] for c in cameras)]).reshape(-1, 2)
        lo, hi = np.floor(points.min(axis=0) - 2.0), np.ceil(points.max(axis=0) + 2.0)
        if environment_bounds_m is not None:
            lo = np.minimum(lo, np.floor(environment_bounds_m[:2]))
            hi = np.maximum(hi, np.ceil(environment_bounds_m[2:]))
        bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    frame_map = map_frame(bounds, options.map_m_per_px)
    target = Path(out_dir) / layout.EXPORTS_DIR / AICITY_DIR / options.scene
    images: dict[str, list[Path]] = {}
    for record in records:
        if record["camera"] in camera_ids:
            images.setdefault(camera_ids[record["camera"]], []).append(Path(out_dir) / record["uri"])
    with staged_folder(target, what="AI City Challenge scene folder") as staging:
        numbers = {c.aic_id: k for k, c in enumerate(cameras)}
        if options.edition == "2025":
            (staging / "calibration.json").write_text(
                dumps_json(calibration_json(cameras, fps, frame_map, place)) + "\n", encoding="utf-8")
            counts = write_ground_truth(document_frames(document, first, last, **context), staging,
                                        edition="2025", scene_id=options.scene_id, fps=fps, camera_numbers=numbers)
            depth_written = {}
            for camera in cameras:
                pngs = [(f - first, Path(out_dir) / "depth" / camera.name / f"{f:06d}.png")
                        for f in sorted({r["frame"] for r in records if r["camera"] == camera.name})]
                if pngs and all(p.is_file() for _, p in pngs):
                    (staging / "depth_maps").mkdir(exist_ok=True)
                    depth_written[camera.aic_id] = write_depth_h5(staging / "depth_maps" / f"{camera.aic_id}.h5", pngs)
            if write_map is not None:
                write_map(staging / "map.png", frame_map)
            if write_videos is not None:
                (staging / "videos").mkdir()
                write_videos(staging / "videos", images)
        else:
            for camera in cameras:
                folder = staging / f"camera_{numbers[camera.aic_id]:04d}"
                folder.mkdir()
                (folder / "calibration.json").write_text(dumps_json({
                    "camera projection matrix": camera.camera_matrix.tolist(),
                    "homography matrix": camera.homography.tolist()}) + "\n", encoding="utf-8")
            counts = write_ground_truth(document_frames(document, first, last, **context), staging,
                                        edition="2024", scene_id=options.scene_id, fps=fps, camera_numbers=numbers)
            depth_written = {}
            if write_videos is not None:
                write_videos(staging, {f"camera_{numbers[k]:04d}/video": v for k, v in images.items()})
        (staging / "usdscene_aicity.json").write_text(dumps_json({
            "edition": options.edition, "fps": fps, "first_frame": first,
            "frame_rule": "AIC frame = document frame - first_frame",
            "cameras": [{"id": c.aic_id, "number": numbers[c.aic_id], "usdscene_camera": c.name} for c in cameras],
            "classes": {name: options.class_map[name] for name in exported},
            "aic_class_ids": AIC_CLASSES, "left_out_classes": left_out,
            "id_rule": ID_RULE, "ids": ids,
            "homography": HOMOGRAPHY_DIRECTION,
            "map": {"scaleFactor": frame_map.scale_px_per_m, "translationToGlobalCoordinates":
                    list(frame_map.translation_m), "size_px": [frame_map.width_px, frame_map.height_px],
                    "bounds_m": list(frame_map.bounds_m),
                    "pixel": "px = (x + tx) * s, py = height - (y + ty) * s (pixel edges)"},
            "depth_frames": depth_written, "counts": counts,
            "box_3d": "box3d cuboid of the document, else the catalog extent of the class placed by the pose",
        }) + "\n", encoding="utf-8")
    return target
