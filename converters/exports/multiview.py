"""Multi-view ground-plane export (the WILDTRACK / MultiviewX layout) of an annotated moving
sequence. Pure (numpy, cv2).

``OUT/exports/multiview/``::

    annotations_positions/<frame:08d>.json   per labelled frame: [{"personID", "positionID",
                                             "views": [{"viewNum", "xmin", "ymin", "xmax", "ymax"}]}]
    calibrations/intrinsic/intr_<camera>.xml camera_matrix, distortion_coefficients,
                                             distortion_model, image_width, image_height
    calibrations/extrinsic/extr_<camera>.xml rvec, tvec (world → camera, OpenCV)
    Image_subsets/<camera>/<frame:08d>.png   the rendered images (relative links)
    grid.json                                the ground grid, the views, the rules below

**The ground grid.** Positions are the points of a regular grid on the world ground plane
(z = 0, world metres, Z up): ``origin_m`` = (x0, y0), ``cell_m`` the spacing, ``size`` =
(nx, ny) points. Position id ``p`` is the point ``(x0 + cell_m · (p mod nx), y0 + cell_m ·
(p div nx))`` (WILDTRACK's rule: origin (-3, -9) m, 2.5 cm, 480 × 1440); a world position maps
to its nearest grid point, ``p = ix + nx · iy`` with ``ix = round((x - x0) / cell_m)``, so
id → world → id is exact. A person off the grid gets ``positionID`` -1. Without a grid given,
:func:`default_grid` takes 2.5 cm cells over the annotated positions plus 1 m, the origin on
whole metres.

**Positions** are the objects' per-frame ``ground_position_m`` (where they stand, written by
``usdscene generate tracks``); objects without one are not exported. **Ids** are those of every
usdscene export (:func:`usdscene.converters.exports.tracks.track_ids`). **Views** are the cameras in name
order (``viewNum`` 0, 1, ...) whose lens OpenCV models: perspective and OpenCV pinhole
(``distortion_model`` ``pinhole``, the 5 or 8 Brown-Conrady coefficients, ``cv2.projectPoints``),
equidistant fisheye, OpenCV fisheye and VCD kannala (``fisheye``, 4 coefficients,
``cv2.fisheye.projectPoints``); other lenses are left out with a warning. A **box** is the
person's whole projection clipped to the image (the amodal box) in views with at least one
visible pixel, as pixel edges (pixel i covers [i, i + 1), ``xmax`` exclusive), and -1 for every
coordinate in the others. The calibration is in OpenCV's pixel convention (pixel centres at
integers): a projected point (u, v) lies in a box when ``xmin <= u + 0.5 <= xmax``.
"""

from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from usdscene.document import output_layout as layout
from usdscene.converters.exports.tracks import require_tracks, track_ids
from usdscene.converters.openlabel.annotations import LabelIndex, image_records
from usdscene.converters.exports.yolo import link_or_copy
from usdscene.errors import DocumentError, OutputError
from usdscene.files import dumps_json, staged_folder
from usdscene.document.model import Camera, RenderSettings

log = logging.getLogger(__name__)

MULTIVIEW_DIR = "multiview"
GROUND_POSITION = "ground_position_m"
DEFAULT_CELL_M = 0.025
MAX_GRID_POINTS = 2**31 - 1


@dataclass(frozen=True)
class GroundGrid:
    """A regular grid of ground positions (see the module docstring).

    Attributes:
        origin_m: (x0, y0) world metres of position 0.
        cell_m: spacing in metres.
        size: (nx, ny) grid points.
    """

    origin_m: tuple[float, float]
    cell_m: float
    size: tuple[int, int]

    def __post_init__(self) -> None:
        problems = []
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            problems.append(f"cell size {self.cell_m!r} m is not a positive number")
        if not all(math.isfinite(v) for v in self.origin_m):
            problems.append(f"origin {self.origin_m!r} is not finite")
        if min(self.size) < 1 or self.size[0] * self.size[1] > MAX_GRID_POINTS:
            problems.append(f"size {self.size!r} must be at least 1 x 1 and at most {MAX_GRID_POINTS} points")
        if problems:
            raise DocumentError("; ".join(problems), where="ground grid")

    def position_ids(self, xy: np.ndarray) -> np.ndarray:
        """(N,) int64 position ids of (N, 2) world points (nearest grid point; -1 off the grid)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        ij = np.rint((xy - np.asarray(self.origin_m)) / self.cell_m).astype(np.int64)
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < self.size[0]) & (ij[:, 1] >= 0) & (ij[:, 1] < self.size[1])
        return np.where(inside, ij[:, 0] + self.size[0] * ij[:, 1], -1)

    def world(self, position_ids: np.ndarray) -> np.ndarray:
        """(N, 2) world metres of (N,) position ids."""
        p = np.asarray(position_ids, dtype=np.int64).reshape(-1)
        return np.stack([self.origin_m[0] + self.cell_m * (p % self.size[0]),
                         self.origin_m[1] + self.cell_m * (p // self.size[0])], axis=1)

    def as_json(self) -> dict:
        """The grid as recorded in the output, with the rule mapping position ids to world metres."""
        return {"origin_m": [float(v) for v in self.origin_m], "cell_m": float(self.cell_m),
                "size": [int(v) for v in self.size],
                "position_id": "ix + nx * iy; world = origin_m + cell_m * (ix, iy); "
                               "world -> id: nearest grid point, -1 off the grid"}


def ground_positions(document: dict) -> dict[int, dict[str, np.ndarray]]:
    """frame → uid → (3,) ground position (world metres) from the per-frame object data."""
    out: dict[int, dict[str, np.ndarray]] = {}
    for key, frame in (document.get("openlabel", {}).get("frames", {}) or {}).items():
        for uid, entry in ((frame or {}).get("objects", {}) or {}).items():
            for item in ((entry or {}).get("object_data", {}) or {}).get("vec", []):
                if item.get("name") == GROUND_POSITION:
                    out.setdefault(int(key), {})[uid] = np.asarray(item["val"], dtype=np.float64)
    return out


def default_grid(positions: dict[int, dict[str, np.ndarray]]) -> GroundGrid:
    """2.5 cm cells over the positions plus 1 m, the origin on whole metres (see the module doc)."""
    points = np.array([p[:2] for by_uid in positions.values() for p in by_uid.values()]).reshape(-1, 2)
    if not len(points):
        return GroundGrid((0.0, 0.0), DEFAULT_CELL_M, (1, 1))
    lo = np.floor(points.min(axis=0) - 1.0)
    hi = np.ceil(points.max(axis=0) + 1.0)
    size = np.rint((hi - lo) / DEFAULT_CELL_M).astype(int) + 1
    return GroundGrid((float(lo[0]), float(lo[1])), DEFAULT_CELL_M, (int(size[0]), int(size[1])))


def opencv_calibration(camera: Camera) -> tuple[str, np.ndarray, np.ndarray] | None:
    """``(distortion_model, K (3, 3), D)`` of a camera in OpenCV's models, None when OpenCV
    has none for its lens (see the module docstring)."""
    from usdscene.lens import lens_for

    k = camera.intrinsics
    found = lens_for(k).opencv_distortion(k)
    return None if found is None else (found[0], k.camera_matrix(), found[1])


def world_to_camera(camera: Camera, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """``(rvec (3,), tvec (3,))`` of the world → camera transform (OpenCV axes) at a frame."""
    import cv2

    m = camera.pose_at(frame).as_array()
    r = m[:3, :3].T
    rvec, _ = cv2.Rodrigues(r)
    return rvec.reshape(3), -r @ m[:3, 3]


def project_with_calibration(model: str, K: np.ndarray, D: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
                             points: np.ndarray) -> np.ndarray:
    """(N, 2) pixels of (N, 3) world points through an OpenCV calibration (as written)."""
    import cv2

    # Contiguous: cv2.fisheye.projectPoints reads a strided view (the first 3 columns of an
    # (N, 4) array) as if it were packed and returns wrong pixels without an error.
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 1, 3))
    if model == "fisheye":
        uv, _ = cv2.fisheye.projectPoints(pts, rvec.reshape(3, 1), tvec.reshape(3, 1), K, D.reshape(4))
    else:
        uv, _ = cv2.projectPoints(pts, rvec.reshape(3, 1), tvec.reshape(3, 1), K, D)
    return uv.reshape(-1, 2)


def _write_storage(path: Path, values: dict) -> None:
    import cv2

    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    try:
        for name, value in values.items():
            storage.write(name, value)
    finally:
        storage.release()


def _cameras(document: dict) -> list[Camera]:
    from usdscene.converters.openlabel.cameras import read_cameras
    from usdscene.converters.openlabel.load import DocumentBody

    body = DocumentBody(document["openlabel"])
    cameras = read_cameras(body, RenderSettings())
    body.problems.raise_if_any(DocumentError)
    return cameras


def _edges(box) -> list[int]:
    cx, cy, w, h = (float(v) for v in box)
    xmin, ymin = int(round(cx - w / 2.0 + 0.5)), int(round(cy - h / 2.0 + 0.5))
    return [xmin, ymin, xmin + int(round(w)), ymin + int(round(h))]


def export_multiview(document: dict, out_dir: str | os.PathLike, *, grid: GroundGrid | None = None,
                     classes: Iterable[str] | None = None, link_images: bool = True,
                     index: LabelIndex | None = None) -> Path:
    """Write ``<out_dir>/exports/multiview/`` (see the module docstring); returns that folder.

    Args:
        document: annotated document of a moving sequence.
        out_dir: the output folder holding the document and the images.
        grid: the ground grid; None = :func:`default_grid` of the positions.
        classes: object types exported as persons; None = every object with ground positions.
        link_images: link the images into ``Image_subsets/``.
        index: the document's :class:`LabelIndex` when another export reads it too.

    Raises:
        OutputError: no frame rate (no tracks), no labelled image, or no camera OpenCV models.
    """
    fps = require_tracks(document, "multi-view")
    records = image_records(document)
    if not records:
        raise OutputError("the document has no labelled image; render and annotate it first",
                          where=str(Path(out_dir) / layout.ANNOTATIONS_FILE))
    objects = document["openlabel"].get("objects", {}) or {}
    wanted = None if classes is None else set(classes)
    positions = {f: {u: p for u, p in by_uid.items()
                     if wanted is None or (objects.get(u) or {}).get("type") in wanted}
                 for f, by_uid in ground_positions(document).items()}
    grid = grid or default_grid(positions)
    ids = track_ids(document)
    labelled_cameras = sorted({r["camera"] for r in records})
    views, calibrations = [], {}
    for camera in _cameras(document):
        if camera.name not in labelled_cameras:
            continue
        calibration = opencv_calibration(camera)
        if calibration is None:
            log.warning("camera %r: OpenCV has no model of its %s lens; it is left out of the multi-view "
                        "export", camera.name, camera.intrinsics.lens.value)
            continue
        calibrations[camera.name] = (camera, calibration)
    views = sorted(calibrations)
    if not views:
        raise OutputError("no labelled camera has a lens OpenCV models (perspective, OpenCV pinhole, "
                          "fisheye); nothing to export", where="streams")
    view_num = {name: k for k, name in enumerate(views)}
    frames = sorted({r["frame"] for r in records})
    index = index or LabelIndex(document)
    off_grid = 0
    target = Path(out_dir) / layout.EXPORTS_DIR / MULTIVIEW_DIR
    with staged_folder(target, what="multi-view export folder") as staging:
        (staging / "annotations_positions").mkdir()
        for sub in ("intrinsic", "extrinsic"):
            (staging / "calibrations" / sub).mkdir(parents=True)
        first = frames[0]
        for name in views:
            camera, (model, K, D) = calibrations[name]
            rvec, tvec = world_to_camera(camera, first)
            _write_storage(staging / "calibrations" / "intrinsic" / f"intr_{name}.xml", {
                "camera_matrix": K, "distortion_coefficients": D.reshape(1, -1), "distortion_model": model,
                "image_width": int(camera.intrinsics.width_px), "image_height": int(camera.intrinsics.height_px)})
            _write_storage(staging / "calibrations" / "extrinsic" / f"extr_{name}.xml",
                           {"rvec": rvec.reshape(3, 1), "tvec": tvec.reshape(3, 1)})
            moving = any(camera.pose_at(f).matrix != camera.pose_at(first).matrix for f in frames)
            if moving:
                log.warning("camera %r moves; its extrinsics are those of frame %d", name, first)
        if link_images:
            for record in records:
                if record["camera"] in view_num:
                    link_or_copy((Path(out_dir) / record["uri"]).resolve(),
                                 staging / "Image_subsets" / record["camera"] / f"{record['frame']:08d}.png", False)
        for frame in frames:
            here = positions.get(frame, {})
            uids = sorted((u for u in here if u in ids), key=lambda u: ids[u])
            pids = grid.position_ids(np.array([here[u][:2] for u in uids]).reshape(-1, 2)) if uids else []
            boxes: dict[str, dict[str, list[int]]] = {}
            for name in views:
                for label in index.labels(frame, name):
                    if label["bbox"] is not None and label["uid"] in here:
                        boxes.setdefault(label["uid"], {})[name] = _edges(label["amodal_bbox"] or label["bbox"])
            entries = []
            for uid, pid in zip(uids, pids):
                off_grid += int(pid < 0)
                entries.append({"personID": ids[uid], "positionID": int(pid), "views": [
                    dict(zip(("viewNum", "xmin", "ymin", "xmax", "ymax"),
                             [view_num[name], *boxes.get(uid, {}).get(name, [-1, -1, -1, -1])]))
                    for name in views]})
            # compact, as WILDTRACK's own files: thousands of frames, read by programs
            (staging / "annotations_positions" / f"{frame:08d}.json").write_text(
                json.dumps(entries, separators=(",", ":")) + "\n", encoding="utf-8")
        (staging / "grid.json").write_text(dumps_json({
            "grid": grid.as_json(), "fps": fps,
            "views": [{"viewNum": view_num[n], "camera": n,
                       "intrinsic": f"calibrations/intrinsic/intr_{n}.xml",
                       "extrinsic": f"calibrations/extrinsic/extr_{n}.xml"} for n in views],
            "ids": ids,
            "box": "whole projection clipped to the image in views with a visible pixel, pixel edges "
                   "(xmax exclusive); -1 where the view does not see the person",
            "position": "ground_position_m of the object (where it stands), nearest grid point",
        }) + "\n", encoding="utf-8")
    if off_grid:
        log.warning("%d person-frames lie off the ground grid (positionID -1)", off_grid)
    return target


def write_multiview(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_multiview`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    return export_multiview(job.document, job.out_dir, grid=job.options.grid, classes=job.person_classes(),
                            index=job.label_index())
