"""Multi-view ground-plane export (the WILDTRACK / MultiviewX layout) of an annotated moving
sequence, in three flavours. Pure (numpy, cv2).

``OUT/exports/multiview/``, with ``<view>`` the camera name (flavour ``free``) or ``C1``, ``C2``, ...
(``wildtrack``, ``multiviewx``: views in camera name order, numbered from 1) and ``<calib>`` the
camera name (``free``), ``CVLab<k>`` (``wildtrack``) or ``Camera<k>`` (``multiviewx``)::

    annotations_positions/<frame:08d>.json   per labelled frame: [{"personID", "positionID",
                                             "views": [{"viewNum", "xmin", "ymin", "xmax", "ymax"}]}]
    calibrations/intrinsic/intr_<calib>.xml  camera_matrix, distortion_coefficients, distortion_model,
                                             image_width, image_height (cv2.FileStorage); wildtrack:
                                             intrinsic_original/ (with the distortion) and
                                             intrinsic_zero/ (zero distortion: what MVDet reads)
    calibrations/extrinsic/extr_<calib>.xml  rvec, tvec (world → camera, OpenCV): cv2.FileStorage
                                             matrices; wildtrack: WILDTRACK's plain text
                                             ``<rvec>a b c</rvec>`` that ElementTree reads
    Image_subsets/<view>/<frame:08d>.png     the rendered images (relative links)
    dataset.json                             the numbers an MVDet-style dataset class needs
                                             (:func:`mvdet_numbers`)
    grid.json                                the ground grid, the views, the ids, the rules below

**Frames.** File frame = document frame - first labelled frame (0, 1, ...: MVDet's frame range
starts at 0); MOT's frame is that plus 1.

**Units.** ``free`` and ``multiviewx``: metres. ``wildtrack``: centimetres (WILDTRACK's own: its
``tvec`` and grid are in cm), so ``tvec`` and the grid numbers of ``dataset.json`` are in cm.

**The ground grid.** Positions are the points of a regular grid on the world ground plane
(z = 0, world metres, Z up): ``origin_m`` = (x0, y0), ``cell_m`` the spacing, ``size`` =
(nx, ny) points. Position id ``p`` is the point ``(x0 + cell_m · (p mod nx), y0 + cell_m ·
(p div nx))`` (WILDTRACK's rule: origin (-3, -9) m, 2.5 cm, 480 × 1440; MultiviewX's: origin
(0, 0), 2.5 cm, 1000 × 640); a world position maps to its nearest grid point, ``p = ix + nx ·
iy`` with ``ix = round((x - x0) / cell_m)``, so id → world → id is exact. A person off the grid
gets ``positionID`` -1. Without a grid given, :func:`default_grid` takes 2.5 cm cells over the
annotated positions plus 1 m, the origin on whole metres.

**Positions** are the objects' per-frame ``ground_position_m`` (where they stand, written by
``usdscene generate tracks``); a fixed object of the document (a person standing at a ticket
machine) stands at the origin of its pose. Objects placed only by relations have no pose in the
document and are left out with a warning naming them. **Ids** are those of every usdscene
export (:func:`usdscene.converters.exports.tracks.track_ids`). **Views** are the cameras in name
order (``viewNum`` 0, 1, ...) whose lens OpenCV models: perspective and OpenCV pinhole
(``distortion_model`` ``pinhole``, the 5 or 8 Brown-Conrady coefficients, ``cv2.projectPoints``),
equidistant fisheye, OpenCV fisheye and VCD kannala (``fisheye``, 4 coefficients,
``cv2.fisheye.projectPoints``), and the equisolid fisheye through the OpenLABEL writer's
OpenCV-fisheye fit (its error over the field of view, :func:`equisolid_fit_error_px`, is logged
and recorded in ``grid.json``); other lenses are left out with a warning naming the lens models
that stay in. A **box** is the person's whole projection clipped to the image (the amodal box)
in views with at least one visible pixel, as pixel edges (pixel i covers [i, i + 1), ``xmax``
exclusive), and -1 for every coordinate in the others. The calibration is in OpenCV's pixel
convention (pixel centres at integers): a projected point (u, v) lies in a box when ``xmin <= u
+ 0.5 <= xmax``.

**MVDet's reading rules** (its ``Wildtrack`` / ``MultiviewX`` dataset classes): the camera index
is ``int(folder[-1]) - 1`` of each ``Image_subsets/`` folder, so at most 9 views are named
(:data:`MAX_NAMED_VIEWS`); calibrations are opened by fixed names; only ``camera_matrix`` of the
intrinsics is used (no distortion: the flavours warn for distorting lenses); a frame is
``int(file name before the dot)``.
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
from usdscene.converters.exports.tracks import ground_positions, require_tracks, track_ids
from usdscene.converters.openlabel.annotations import LabelIndex, image_records
from usdscene.converters.exports.yolo import link_or_copy
from usdscene.errors import DocumentError, OutputError, Problem
from usdscene.files import dumps_json, staged_folder
from usdscene.document.model import Camera, RenderSettings

log = logging.getLogger(__name__)

MULTIVIEW_DIR = "multiview"
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
    has none for its lens (see the module docstring). The equisolid fisheye gets the OpenLABEL
    writer's OpenCV-fisheye fit (:data:`usdscene.lens.fisheye.EQUISOLID_KB_COEFFS`,
    :func:`equisolid_fit_error_px`)."""
    from usdscene.lens import lens_for

    k = camera.intrinsics
    found = lens_for(k).opencv_distortion(k)
    return None if found is None else (found[0], k.camera_matrix(), found[1])


OPENCV_LENSES = ("perspective", "opencv_pinhole", "fisheye_equidistant", "opencv_fisheye", "kannala",
                 "fisheye_equisolid")
"""The lens models the multi-view export keeps (the last one through the OpenCV-fisheye fit)."""


def equisolid_fit_error_px(camera: Camera) -> float:
    """Largest image distance (pixels) between the camera's lens and its OpenCV export over the
    camera's field of view (the equisolid lens's OpenCV-fisheye fit; 0.0 for exact exports)."""
    from usdscene.lens import lens_for

    return lens_for(camera.intrinsics).opencv_fit_error_px(camera.intrinsics)


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

    from usdscene.converters.openlabel.store import scene_document

    body = DocumentBody(scene_document(document)["openlabel"])
    cameras = read_cameras(body, RenderSettings())
    body.problems.raise_if_any(DocumentError)
    return cameras


def _edges(box) -> list[int]:
    cx, cy, w, h = (float(v) for v in box)
    xmin, ymin = int(round(cx - w / 2.0 + 0.5)), int(round(cy - h / 2.0 + 0.5))
    return [xmin, ymin, xmin + int(round(w)), ymin + int(round(h))]


FLAVOURS = ("free", "wildtrack", "multiviewx")
"""``free``: folders and files named by camera; ``wildtrack`` / ``multiviewx``: the layouts MVDet
reads (see the module docstring)."""
MAX_NAMED_VIEWS = 9
"""MVDet takes a camera's index from the last character of its ``Image_subsets/`` folder name."""
FLAVOUR_OPTION = "--multiview-flavour"
DATASET_FILE = "dataset.json"


@dataclass(frozen=True)
class Flavour:
    """How one flavour names its views and writes its calibrations.

    Attributes:
        name: one of :data:`FLAVOURS`.
        unit_m: metres per world unit of its calibrations and grid (WILDTRACK: centimetres).
    """

    name: str
    unit_m: float

    def folder(self, camera: str, k: int) -> str:
        """``Image_subsets/`` folder of view k (0-based)."""
        return camera if self.name == "free" else f"C{k + 1}"

    def stem(self, camera: str, k: int) -> str:
        """Calibration file stem of view k: ``intr_<stem>.xml``, ``extr_<stem>.xml``."""
        if self.name == "wildtrack":
            return f"CVLab{k + 1}"
        if self.name == "multiviewx":
            return f"Camera{k + 1}"
        return camera


def flavour_of(name: str) -> Flavour:
    """The :class:`Flavour` called ``name``.

    Raises:
        OutputError: an unknown name.
    """
    if name not in FLAVOURS:
        raise OutputError([Problem(FLAVOUR_OPTION, f"unknown flavour {name!r}; expected one of {', '.join(FLAVOURS)}")])
    return Flavour(name, 0.01 if name == "wildtrack" else 1.0)


def _views(document: dict, warn: bool = True) -> tuple[list[str], dict[str, tuple]]:
    """Labelled cameras kept (name order) and name → (camera, (model, K, D)); warns for those left out."""
    records = image_records(document)
    labelled = {r["camera"] for r in records}
    calibrations = {}
    left_out = []
    for camera in _cameras(document):
        if camera.name not in labelled:
            continue
        calibration = opencv_calibration(camera)
        if calibration is None:
            left_out.append(f"{camera.name} ({camera.intrinsics.lens.value})")
            continue
        calibrations[camera.name] = (camera, calibration)
    if left_out and warn:
        log.warning("cameras %s have lenses OpenCV cannot model; they are left out of the multi-view export, "
                    "which keeps the lens models %s", ", ".join(left_out), ", ".join(OPENCV_LENSES))
    return sorted(calibrations), calibrations


def check_flavour(document: dict, name: str) -> Flavour:
    """The flavour ``name`` after checking it can name every view of the document.

    Raises:
        OutputError: an unknown flavour, or more views than MVDet's last-digit rule can number.
    """
    flavour = flavour_of(name)
    if flavour.name != "free":
        views, _ = _views(document, warn=False)
        if len(views) > MAX_NAMED_VIEWS:
            raise OutputError([Problem(FLAVOUR_OPTION, f"{name!r} names cameras C1..C{MAX_NAMED_VIEWS}, but the "
                                       f"document has {len(views)} views ({', '.join(views)}): MVDet takes a "
                                       "camera's index from the last digit of its folder name, which breaks past "
                                       f"{MAX_NAMED_VIEWS}; use {FLAVOUR_OPTION} free or fewer cameras")])
    return flavour


def fixed_ground_positions(document: dict, uids: Iterable[str], frames: Iterable[int]) -> tuple[dict, list[str]]:
    """frame → uid → (3,) ground point of tracked objects that have no ``ground_position_m``:
    the origin of their pose (where the asset stands, as for movers), at every frame they are
    present; returns those positions and the uids that have no explicit pose (placed by
    relations), which cannot be placed without the stage."""
    from usdscene.converters.openlabel.load import DocumentBody
    from usdscene.converters.openlabel.objects import read_objects

    wanted = set(uids)
    if not wanted:
        return {}, []
    # Only these objects are read: reading every mover's per-frame poses of a long sequence
    # would cost more than the whole export.
    from usdscene.converters.openlabel.store import scene_document

    root = scene_document(document)["openlabel"]
    frames_in = root.get("frames", {}) or {}
    trimmed = dict(root, objects={u: o for u, o in (root.get("objects", {}) or {}).items() if u in wanted},
                   frames={k: {"objects": {u: e for u, e in ((f or {}).get("objects", {}) or {}).items() if u in wanted}}
                           for k, f in frames_in.items()})
    _, _, objects, _ = read_objects(DocumentBody(trimmed))
    frames = list(frames)
    out: dict[int, dict[str, np.ndarray]] = {}
    unplaced = []
    for obj in objects:
        if obj.uid not in wanted:
            continue
        poses = dict(obj.frame_poses)
        if obj.pose is None and not poses:
            unplaced.append(obj.uid)
            continue
        for frame in frames:
            if obj.frame_intervals and not any(iv.frame_start <= frame <= iv.frame_end for iv in obj.frame_intervals):
                continue
            pose = poses.get(frame, obj.pose)
            if pose is None:
                continue
            out.setdefault(frame, {})[obj.uid] = np.asarray(pose.matrix, dtype=np.float64).reshape(4, 4)[:3, 3]
    return out, sorted(unplaced)


def _write_text_extrinsics(path: Path, rvec: np.ndarray, tvec: np.ndarray) -> None:
    # WILDTRACK's own form: MVDet reads it with ElementTree and splits the text on single spaces.
    text = "".join(f"  <{n}>{' '.join(repr(float(v)) for v in np.asarray(a).reshape(3))}</{n}>\n"
                   for n, a in (("rvec", rvec), ("tvec", tvec)))
    path.write_text(f'<?xml version="1.0"?>\n<opencv_storage>\n{text}</opencv_storage>\n', encoding="utf-8")


def mvdet_numbers(flavour: Flavour, grid: GroundGrid, views: int, image_hw: tuple[int, int], frames: int) -> dict:
    """The numbers an MVDet-style dataset class needs (``dataset.json``), in the flavour's units.

    ``worldgrid_shape`` and ``worldgrid2worldcoord_mat`` follow the flavour's indexing: WILDTRACK's
    ``ij`` (rows along world x: shape ``[nx, ny]``), MultiviewX's ``xy`` (rows along world y:
    shape ``[ny, nx]``); the matrix maps ``[row, col, 1]`` to world units."""
    unit = flavour.unit_m
    cell, x0, y0 = grid.cell_m / unit, grid.origin_m[0] / unit, grid.origin_m[1] / unit
    nx, ny = grid.size
    if flavour.name == "multiviewx":
        shape, indexing, mat = [ny, nx], "xy", [[0.0, cell, x0], [cell, 0.0, y0], [0.0, 0.0, 1.0]]
    else:
        shape, indexing, mat = [nx, ny], "ij", [[cell, 0.0, x0], [0.0, cell, y0], [0.0, 0.0, 1.0]]
    return {"flavour": flavour.name, "num_cam": views, "num_frame": frames, "img_shape": list(image_hw),
            "worldgrid_shape": shape, "indexing": indexing, "grid_size_xy": [nx, ny], "cell_size": cell,
            "origin_xy": [x0, y0], "unit_m": unit, "worldgrid2worldcoord_mat": mat,
            "position_id": f"ix + {nx} * iy (grid_x = pos % {nx}, grid_y = pos // {nx})"}


def export_multiview(document: dict, out_dir: str | os.PathLike, *, grid: GroundGrid | None = None,
                     classes: Iterable[str] | None = None, link_images: bool = True,
                     index: LabelIndex | None = None, flavour: str = "free") -> Path:
    """Write ``<out_dir>/exports/multiview/`` (see the module docstring); returns that folder.

    Args:
        document: annotated document of a moving sequence.
        out_dir: the output folder holding the document and the images.
        grid: the ground grid (world metres); None = :func:`default_grid` of the positions.
        classes: object types exported as persons; None = every object with ground positions.
        link_images: link the images into ``Image_subsets/``.
        index: the document's :class:`LabelIndex` when another export reads it too.
        flavour: one of :data:`FLAVOURS`.

    Raises:
        OutputError: no frame rate (no tracks), no labelled image, no camera OpenCV models, an
            unknown flavour or more views than it can name.
    """
    fps = require_tracks(document, "multi-view")
    records = image_records(document)
    if not records:
        raise OutputError("the document has no labelled image; render and annotate it first",
                          where=str(Path(out_dir) / layout.ANNOTATIONS_FILE))
    style = check_flavour(document, flavour)
    objects = document["openlabel"].get("objects", {}) or {}
    wanted = None if classes is None else set(classes)
    ids = track_ids(document)
    frames = sorted({r["frame"] for r in records})
    positions = {f: {u: p for u, p in by_uid.items()
                     if wanted is None or (objects.get(u) or {}).get("type") in wanted}
                 for f, by_uid in ground_positions(document).items()}
    with_positions = {u for by_uid in positions.values() for u in by_uid}
    fixed = [u for u in ids if u not in with_positions and wanted is not None
             and (objects.get(u) or {}).get("type") in wanted]
    fixed_positions, unplaced = fixed_ground_positions(document, fixed, frames)
    for frame, by_uid in fixed_positions.items():
        positions.setdefault(frame, {}).update(by_uid)
    if unplaced:
        log.warning("objects %s are placed by relations, not by a pose; the multi-view export cannot tell "
                    "where they stand and leaves them out", ", ".join(f"{u} ({objects[u].get('name', '')})"
                                                                   for u in unplaced))
    grid = grid or default_grid(positions)
    views, calibrations = _views(document)
    if not views:
        raise OutputError("no labelled camera has a lens OpenCV models (perspective, OpenCV pinhole, "
                          "fisheye); nothing to export", where="streams")
    view_num = {name: k for k, name in enumerate(views)}
    first = frames[0]
    index = index or LabelIndex(document)
    off_grid = 0
    unit = style.unit_m
    target = Path(out_dir) / layout.EXPORTS_DIR / MULTIVIEW_DIR
    fits = {}
    with staged_folder(target, what="multi-view export folder") as staging:
        (staging / "annotations_positions").mkdir()
        intrinsic_dirs = ["intrinsic_original", "intrinsic_zero"] if style.name == "wildtrack" else ["intrinsic"]
        for sub in (*intrinsic_dirs, "extrinsic"):
            (staging / "calibrations" / sub).mkdir(parents=True)
        for name in views:
            camera, (model, K, D) = calibrations[name]
            stem = style.stem(name, view_num[name])
            rvec, tvec = world_to_camera(camera, first)
            for sub in intrinsic_dirs:
                # intrinsic_zero: WILDTRACK's camera matrix for undistorted images (what MVDet reads)
                zero = sub == "intrinsic_zero"
                _write_storage(staging / "calibrations" / sub / f"intr_{stem}.xml", {
                    "camera_matrix": K, "distortion_coefficients": (np.zeros_like(D) if zero else D).reshape(1, -1),
                    "distortion_model": model, "image_width": int(camera.intrinsics.width_px),
                    "image_height": int(camera.intrinsics.height_px)})
            if style.name == "wildtrack":
                _write_text_extrinsics(staging / "calibrations" / "extrinsic" / f"extr_{stem}.xml", rvec, tvec / unit)
            else:
                _write_storage(staging / "calibrations" / "extrinsic" / f"extr_{stem}.xml",
                               {"rvec": rvec.reshape(3, 1), "tvec": (tvec / unit).reshape(3, 1)})
            fit_error_px = equisolid_fit_error_px(camera)
            if fit_error_px > 0.0:
                fits[name] = fit_error_px
                log.warning("camera %r: its %s lens is written as its OpenCV-fisheye fit (the OpenLABEL "
                            "writer's), within %.2g px of the lens over its field of view", name,
                            camera.intrinsics.lens.value, fits[name])
            if style.name != "free" and (model != "pinhole" or np.any(D)):
                log.warning("camera %r has lens distortion (%s); MVDet projects with the camera matrix only, "
                            "so its ground points miss there (calibrations/%s has the distortion)",
                            name, camera.intrinsics.lens.value, intrinsic_dirs[0])
            moving = any(camera.pose_at(f).matrix != camera.pose_at(first).matrix for f in frames)
            if moving:
                log.warning("camera %r moves; its extrinsics are those of frame %d", name, first)
        if link_images:
            for record in records:
                if record["camera"] in view_num:
                    k = view_num[record["camera"]]
                    link_or_copy((Path(out_dir) / record["uri"]).resolve(),
                                 staging / "Image_subsets" / style.folder(record["camera"], k)
                                 / f"{record['frame'] - first:08d}.png", False)
        for frame in frames:
            here = positions.get(frame, {})
            uids = sorted((u for u in here if u in ids), key=lambda u: ids[u])
            pids = grid.position_ids(np.array([here[u][:2] for u in uids]).reshape(-1, 2)) if uids else []
            boxes: dict[str, dict[str, list[int]]] = {}
            for name in views:
                for label in index.held_labels(frame, name):
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
            (staging / "annotations_positions" / f"{frame - first:08d}.json").write_text(
                json.dumps(entries, separators=(",", ":")) + "\n", encoding="utf-8")
        first_camera = calibrations[views[0]][0].intrinsics
        (staging / DATASET_FILE).write_text(dumps_json(mvdet_numbers(
            style, grid, len(views), (int(first_camera.height_px), int(first_camera.width_px)),
            frames[-1] - first + 1)) + "\n", encoding="utf-8")
        (staging / "grid.json").write_text(dumps_json({
            "grid": grid.as_json(), "fps": fps, "flavour": style.name, "unit_m": unit,
            "first_frame": first, "frame_rule": "file frame = document frame - first_frame (MOT frame - 1)",
            "views": [{"viewNum": view_num[n], "camera": n, "folder": f"Image_subsets/{style.folder(n, view_num[n])}",
                       "intrinsic": f"calibrations/{intrinsic_dirs[0]}/intr_{style.stem(n, view_num[n])}.xml",
                       "extrinsic": f"calibrations/extrinsic/extr_{style.stem(n, view_num[n])}.xml",
                       **({"fit_error_px": fits[n]} if n in fits else {})} for n in views],
            "ids": ids, "fixed": sorted((u for u in fixed if u not in unplaced), key=ids.get),
            "left_out": unplaced,
            "box": "whole projection clipped to the image in views with a visible pixel, pixel edges "
                   "(xmax exclusive); -1 where the view does not see the person",
            "position": "ground_position_m of the object (where it stands; a fixed object: the origin of its "
                        "pose), nearest grid point",
        }) + "\n", encoding="utf-8")
    if off_grid:
        log.warning("%d person-frames lie off the ground grid (positionID -1)", off_grid)
    return target


def write_multiview(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_multiview`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    return export_multiview(job.document, job.out_dir, grid=job.options.grid, classes=job.person_classes(),
                            index=job.label_index(), flavour=job.options.multiview_flavour)


def check_multiview(job) -> None:
    """The registry's check: the flavour can name every view, before anything is written."""
    check_flavour(job.document, job.options.multiview_flavour)
