"""Cross-camera table of a run: for each object and frame, the cameras that see it, how much of
it each one sees, at what pixel density and at which DORI image-detail class. Pure (numpy).

The table is computed from the labels of the run (no second pass over the images), so it is the
same whether the labels were computed while rendering or afterwards:

* a camera *sees* an object in a frame when the object has at least one visible pixel in that
  camera's instance mask (a fully occluded object, which has an amodal box only, is not seen);
* ``visible_fraction`` is the label's (visible / amodal pixels; None when unknown);
* ``px_per_m`` is :func:`usdscene.labels.pixel_density.pixel_density` of the camera, as rendered (its pose
  at that frame, its intrinsics scaled to the image's size), at the object's centre: the centre
  of the axis-aligned bounds of the object's world triangles at that frame;
* ``dori`` is :func:`usdscene.labels.pixel_density.dori_class` of ``px_per_m`` in the DORI table
  (:data:`ANNOTATION_DORI_FILE`, IEC 62676-4:2015 by default); ``""`` below its lowest class.
  The annotations keep the 2015 classes while the camera planner defaults to the 2025 levels:
  switching them would change every annotated output of existing documents, and the 2015 names
  are what those outputs and their readers already use.

Objects present at a frame that no camera sees get a row with no cameras, so that "seen by 0
cameras" can be counted.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping, Protocol, Sequence

import numpy as np

from usdscene.labels.image_labels import Annotations
from usdscene.document.model import Camera, SceneSpec
from usdscene.labels.pixel_density import DORI_FILE

# The detail table of the cross-camera table in annotated outputs (IEC 62676-4:2015).
ANNOTATION_DORI_FILE = DORI_FILE

# (frame, camera, uid) → pixels per metre at the object's centre.
Densities = Mapping[tuple[int, str, str], float]


@dataclass(frozen=True)
class Sighting:
    """One camera's view of one object in one frame.

    Attributes:
        camera: camera (stream) name.
        pixel_count: visible pixels (> 0).
        visible_fraction: visible / amodal pixels, 0..1; None when unknown.
        px_per_m: pixel density at the object's centre (pixels per metre); None when unknown.
        dori: DORI class ``px_per_m`` reaches; ``""`` below the lowest class; None when unknown.
    """

    camera: str
    pixel_count: int
    visible_fraction: float | None = None
    px_per_m: float | None = None
    dori: str | None = None


@dataclass(frozen=True)
class CrossCameraRow:
    """The cameras that see one object in one frame.

    Attributes:
        frame: frame number.
        uid: object uid (the scene's).
        class_name: asset class.
        sightings: one per camera that sees the object, sorted by camera name; empty when none does.
    """

    frame: int
    uid: str
    class_name: str
    sightings: tuple[Sighting, ...] = ()

    @property
    def camera_count(self) -> int:
        """How many cameras see the object."""
        return len(self.sightings)

    def best(self) -> Sighting | None:
        """The sighting with the highest pixel density (first camera by name on ties); None when
        no camera sees the object or no density is known."""
        known = [s for s in self.sightings if s.px_per_m is not None]
        return max(known, key=lambda s: s.px_per_m) if known else None


class TriangleSource(Protocol):
    """What :func:`object_densities` needs from the stage (e.g. :class:`usdscene.scene.stage_geometry.StageGeometry`)."""

    def triangles(self, frame: int, uids=None) -> dict[str, np.ndarray]:
        """uid → (T, 3, 3) world triangles (metres) of the objects visible at ``frame``, restricted to
        ``uids`` when given."""


def _by_frame(annotations: Annotations) -> dict[int, list]:
    """frame → its images, ascending (one pass; ``Annotations.for_frame`` scans every image)."""
    out: dict[int, list] = {}
    for image in annotations.images:
        out.setdefault(image.frame, []).append(image)
    return dict(sorted(out.items()))


def object_centre(triangles_m: np.ndarray) -> np.ndarray:
    """Centre of the axis-aligned bounds of (T, 3, 3) world triangles → (3,) metres."""
    points = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3)
    return (points.min(axis=0) + points.max(axis=0)) / 2.0


def camera_for_image(camera: Camera, frame: int, width_px: int, height_px: int) -> Camera:
    """The camera as it rendered one image: its pose at ``frame`` and its intrinsics scaled to
    the image's size (a render at a resolution scale; pixel centres at integers, so a position
    p maps to ``(p + 0.5) · s - 0.5`` per axis)."""
    return dataclasses.replace(camera, intrinsics=camera.intrinsics.resized(width_px, height_px),
                               pose=camera.pose_at(frame), frame_poses=())


def object_densities(annotations: Annotations, cameras: Mapping[str, Camera],
                     geometry: TriangleSource) -> dict[tuple[int, str, str], float]:
    """Pixel density at the centre of every object a camera sees, per image.

    Args:
        annotations: labels of the run.
        cameras: camera name → the camera as composed in the stage (per-frame poses included;
            :func:`usdscene.render.stage_reader.read_stage_plan`).
        geometry: world triangles per object per frame.

    Returns:
        ``(frame, camera, uid) → px/m`` for every visible label whose camera and geometry are
        known (0.0 where the centre does not project, e.g. behind a camera that sees only a part).
    """
    from usdscene.labels.pixel_density import pixel_density

    out: dict[tuple[int, str, str], float] = {}
    # Static objects come back as the same cached triangle array frame after frame: one centre
    # each. Keeping the array in the cache keeps its id from being reused.
    known: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def centre_of(triangles: np.ndarray) -> np.ndarray:
        if id(triangles) not in known:
            known[id(triangles)] = (triangles, object_centre(triangles))
        return known[id(triangles)][1]

    for frame, frame_images in _by_frame(annotations).items():
        images = [image for image in frame_images if image.camera in cameras]
        uids = {o.uid for image in images for o in image.objects if o.visible}
        if not uids:
            continue
        centres = {uid: centre_of(tris) for uid, tris in geometry.triangles(frame, uids).items() if len(tris)}
        for image in images:
            seen = [o.uid for o in image.objects if o.visible and o.uid in centres]
            if not seen:
                continue
            camera = camera_for_image(cameras[image.camera], frame, image.width_px, image.height_px)
            values = pixel_density(camera, np.stack([centres[uid] for uid in seen]))
            out.update({(frame, image.camera, uid): float(v) for uid, v in zip(seen, values)})
    return out


def cross_camera_table(annotations: Annotations, scene: SceneSpec, *, densities: Densities | None = None,
                       dori_table: Sequence | None = None) -> tuple[CrossCameraRow, ...]:
    """The cross-camera table of a run (see the module docstring).

    Args:
        annotations: labels of the run.
        scene: the scene (objects present at each frame, classes).
        densities: from :func:`object_densities`; None = pixel densities unknown.
        dori_table: ascending DORI classes (:func:`usdscene.labels.pixel_density.load_dori`); None = the
            shipped table.

    Returns:
        One row per (labelled frame, object present at that frame or labelled in it), sorted by
        (frame, uid); pixel densities are rounded to 1e-3 px/m.
    """
    from usdscene.labels.pixel_density import dori_index, load_dori

    table = tuple(load_dori(ANNOTATION_DORI_FILE) if dori_table is None else dori_table)
    names = [c.name for c in table] + [""]  # index -1 (below the lowest class) → ""
    densities = densities or {}
    # Rounded once, classified in one vectorised pass (thousands of labels per frame).
    rounded = {key: round(float(value), 3) for key, value in densities.items()}
    classified = dict(zip(rounded, (names[i] for i in dori_index(np.fromiter(rounded.values(), float,
                                                                                 len(rounded)), table))))
    classes = {o.uid: o.class_name for o in scene.objects}
    rows = []
    for frame, images in _by_frame(annotations).items():
        seen: dict[str, list[Sighting]] = {o.uid: [] for o in scene.objects_present(frame)}
        for image in images:
            for label in image.objects:
                classes.setdefault(label.uid, label.class_name)
                sightings = seen.setdefault(label.uid, [])
                if not label.visible:
                    continue
                key = (frame, image.camera, label.uid)
                fraction = None if label.visible_fraction is None else round(float(label.visible_fraction), 6)
                sightings.append(Sighting(
                    camera=image.camera, pixel_count=int(label.pixel_count), visible_fraction=fraction,
                    px_per_m=rounded.get(key), dori=classified.get(key)))
        rows.extend(CrossCameraRow(frame=frame, uid=uid, class_name=classes.get(uid, ""),
                                   sightings=tuple(sorted(s, key=lambda x: x.camera)))
                    for uid, s in sorted(seen.items()))
    return tuple(rows)
