"""Write mask-derived labels into an OpenLABEL document. Pure (no pxr, no bpy).

:func:`add_annotations` takes the scene's OpenLABEL document (the input, or what
``write_openlabel`` made of the SceneSpec) and returns a new document with the cameras in their
exact calibrated form (``streams[<camera>].stream_properties`` intrinsics and
``coordinate_systems[<camera>].pose_wrt_parent`` as the writer writes them, per-frame transforms
for moving cameras; a friendly-form camera block becomes calibrated intrinsics) and, per frame:

* ``frames[f].frame_properties.streams[<camera>].uri``: the image, relative to the output folder
  (``images/<camera>/<frame:06d>.png``; the document lives in that folder);
* ``frames[f].frame_properties.usdscene.streams[<camera>]``: ``{"mask_uri", "width_px",
  "height_px"}``, the 16-bit instance mask (``masks/<camera>/<frame:06d>.png``, 0 = background,
  ids in the ``mask_id`` attributes) and the image size. The schema's ``stream`` object admits
  no extra key, ``frame_properties`` does, hence this place. For a camera with a sensor also
  ``sensor`` (the sensor's values at that frame and the noise generator's entropy, see
  :func:`sensor_record`; for a camera with auto exposure also ``exposure``, the stops it applied
  and its meter's reading) and, with ``--keep-clean``, ``clean_uri`` (the image before them).
* ``frames[f].objects[<uid>].object_data``, per camera that sees the object:

  - ``bbox`` named ``<camera>_bbox``: tight box of the visible pixels, ``[cx, cy, w, h]`` in
    pixels with pixel centres at integer coordinates (the box spans whole pixels, so
    ``w = x_max - x_min + 1``), ``coordinate_system`` = camera. Attributes: ``num``
    ``visible_fraction`` (visible / amodal pixels, 0..1; absent when unknown), ``num``
    ``pixel_count`` (visible pixels), ``boolean`` ``truncated``, ``vec`` ``amodal_bbox``
    ([cx, cy, w, h] of the whole projection clipped to the image; absent when unknown),
    ``num`` ``mask_id``.
  - ``bbox`` named ``<camera>_amodal_bbox``: the whole projection clipped to the image, written
    whenever it is known, *also for fully occluded objects* (which have no ``<camera>_bbox``).
    Attributes: ``visible_fraction``, ``pixel_count``, ``amodal_pixel_count``, ``truncated``,
    ``mask_id``.
  - people (objects whose asset carries keypoints): 17 ``point2d`` named
    ``<camera>_kp_<keypoint>`` (COCO-17 names, e.g. ``cam0_kp_left_wrist``), ``val`` ``[x, y]``
    pixels (``[0, 0]`` when not in the image), ``coordinate_system`` = camera, attribute ``num``
    ``visibility``: 2 on the person's own mask pixels (within 1 px), 1 hidden, 0 outside the
    image or behind the camera. Projected through the camera's lens model like the amodal box.
  - ``poly2d`` named ``<camera>_poly2d_<k>`` (k = 0, 1, ...): closed polygons
    (``MODE_POLY2D_ABSOLUTE``, ``[x0, y0, x1, y1, ...]`` pixel centres of boundary pixels) of
    the visible region; ``hierarchy`` = OpenCV's ``[next, previous, first_child, parent]`` with
    indices k among the same camera's polygons (holes are children of their outer contour);
    attribute ``boolean`` ``is_hole``.

Per labelled frame, every object present in that frame (or labelled in it) gets the cross-camera
table of :mod:`usdscene.labels.cross_camera`: ``vec`` object data named ``usdscene_cameras`` whose value
is the names of the cameras that see it (at least one visible pixel), sorted, ``[]`` when none
does. Attributes: ``num`` ``camera_count``; ``vec`` ``visible_fractions``, ``px_per_m`` (pixel
density at the object's centre) and ``dori`` (IEC 62676-4 image-detail class, ``""`` below the
lowest), parallel to the camera names and present only when known for every camera; ``num``
``best_px_per_m`` and ``text`` ``best_dori`` of the densest camera, present when known. The
DORI table used is recorded in ``metadata.usdscene_annotations.dori_classes``.

Per labelled frame, objects placed through relations also get ``text`` object data
``resolved_place`` (place name) and ``resolved_relation`` (e.g. ``is_below``): the place their
chain of relations ends at (:func:`resolve_places`), so ``bag is_on suitcase is_below
seat_03A`` reads as below seat_03A.

Per labelled frame, every object with geometry present in it gets its 3D box
(:mod:`usdscene.labels.cuboids`): ``cuboid`` object data named ``box3d``, ``val`` ``[x, y, z,
qx, qy, qz, qw, sx, sy, sz]`` in the world coordinate system (the root ``scene_cs``), metres;
:func:`usdscene.labels.cuboids.document_cuboids` reads them back.

Every object gets ``object_data_pointers`` for these names (type, frame intervals,
``attribute_pointers``), its ``frame_intervals`` are widened to the labelled frames, and the
root ``frame_intervals`` is the union of all frames. ``metadata.usdscene_annotations`` records
the conventions and the polygon tolerance. Relations are kept as given.
"""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from usdscene.document import output_layout as layout
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.labels.pixel_density import DoriClass, load_dori
from usdscene.labels.cuboids import CUBOID_NAME, Cuboid, cuboid_data
from usdscene.labels.cross_camera import CrossCameraRow, Densities, cross_camera_table
from usdscene.labels.image_labels import Annotations, ObjectLabel
from usdscene.document.model import FrameInterval, RelationType, SceneSpec, union_intervals

ANNOTATION_METADATA_KEY = "usdscene_annotations"
FRAME_PROPERTIES_KEY = "usdscene"
BBOX_SUFFIX = "_bbox"
AMODAL_BBOX_SUFFIX = "_amodal_bbox"
POLY2D_INFIX = "_poly2d_"
POLY2D_MODE = "MODE_POLY2D_ABSOLUTE"
KEYPOINT_INFIX = "_kp_"
RESOLVED_PLACE = "resolved_place"
RESOLVED_RELATION = "resolved_relation"
CAMERAS_DATA = "usdscene_cameras"

_BBOX_ATTRIBUTES = {"visible_fraction": "num", "pixel_count": "num", "truncated": "boolean",
                    "amodal_bbox": "vec", "mask_id": "num"}
_AMODAL_ATTRIBUTES = {"visible_fraction": "num", "pixel_count": "num", "amodal_pixel_count": "num",
                      "truncated": "boolean", "mask_id": "num"}
_POLY_ATTRIBUTES = {"is_hole": "boolean"}
_CAMERAS_ATTRIBUTES = {"camera_count": "num", "visible_fractions": "vec", "px_per_m": "vec", "dori": "vec",
                       "best_px_per_m": "num", "best_dori": "text"}


def _relative_uri(path: Path, out_dir: str | os.PathLike) -> str:
    return Path(os.path.relpath(path, out_dir)).as_posix()


def bbox_name(camera: str) -> str:
    """Name of the visible 2D box of ``camera``."""
    return f"{camera}{BBOX_SUFFIX}"


def amodal_bbox_name(camera: str) -> str:
    """Name of the amodal (full-extent) 2D box of ``camera``."""
    return f"{camera}{AMODAL_BBOX_SUFFIX}"


def poly2d_name(camera: str, index: int) -> str:
    """Name of polygon ``index`` of ``camera``."""
    return f"{camera}{POLY2D_INFIX}{index}"


def _attributes(values: dict[str, Any], kinds: dict[str, str]) -> dict:
    out: dict[str, list] = {}
    for name, kind in kinds.items():
        value = values.get(name)
        if value is None:
            continue
        out.setdefault(kind, []).append({"name": name, "val": value})
    return out


def _object_data(camera: str, label: ObjectLabel) -> dict[str, list]:
    """OpenLABEL object data of one object in one camera (see the module docstring)."""
    data: dict[str, list] = {}
    amodal = list(label.amodal_box.center_size()) if label.amodal_box is not None else None
    fraction = None if label.visible_fraction is None else round(float(label.visible_fraction), 6)
    if label.box is not None:
        values = {"visible_fraction": fraction, "pixel_count": int(label.pixel_count),
                  "truncated": bool(label.truncated), "amodal_bbox": amodal, "mask_id": int(label.mask_id)}
        data.setdefault("bbox", []).append({
            "name": bbox_name(camera), "val": list(label.box.center_size()),
            "coordinate_system": camera, "attributes": _attributes(values, _BBOX_ATTRIBUTES)})
    if label.amodal_box is not None:
        values = {"visible_fraction": fraction, "pixel_count": int(label.pixel_count),
                  "amodal_pixel_count": label.amodal_pixel_count,
                  "truncated": bool(label.truncated), "mask_id": int(label.mask_id)}
        data.setdefault("bbox", []).append({
            "name": amodal_bbox_name(camera), "val": amodal,
            "coordinate_system": camera, "attributes": _attributes(values, _AMODAL_ATTRIBUTES)})
    contours = label.contours
    for k, contour in enumerate(contours):
        children = [j for j, c in enumerate(contours) if c.is_hole and c.parent == k]
        same_level = [j for j, c in enumerate(contours) if c.is_hole == contour.is_hole
                      and (not contour.is_hole or c.parent == contour.parent)]
        pos = same_level.index(k)
        nxt = same_level[pos + 1] if pos + 1 < len(same_level) else -1
        prev = same_level[pos - 1] if pos > 0 else -1
        data.setdefault("poly2d", []).append({
            "name": poly2d_name(camera, k), "val": contour.flat(), "mode": POLY2D_MODE,
            "closed": True, "coordinate_system": camera,
            "hierarchy": [nxt, prev, children[0] if children else -1, int(contour.parent)],
            "attributes": {"boolean": [{"name": "is_hole", "val": bool(contour.is_hole)}]}})
    if label.keypoints is not None:
        from usdscene.labels.keypoints import COCO_KEYPOINTS

        for name, (x, y, v) in zip(COCO_KEYPOINTS, label.keypoints):
            data.setdefault("point2d", []).append({
                "name": keypoint_name(camera, name), "val": [float(x), float(y)], "coordinate_system": camera,
                "attributes": {"num": [{"name": "visibility", "val": int(v)}]}})
    return data


def _cameras_data(row: CrossCameraRow) -> dict:
    """``usdscene_cameras`` vec of one cross-camera row (see the module docstring)."""
    sightings = row.sightings

    def parallel(values: list) -> list | None:
        return None if any(v is None for v in values) else values

    best = row.best()
    values = {"camera_count": row.camera_count,
              "visible_fractions": parallel([s.visible_fraction for s in sightings]),
              "px_per_m": parallel([s.px_per_m for s in sightings]),
              "dori": parallel([s.dori for s in sightings]),
              "best_px_per_m": None if best is None else best.px_per_m,
              "best_dori": None if best is None else best.dori}
    return {"name": CAMERAS_DATA, "val": [s.camera for s in sightings],
            "attributes": _attributes(values, _CAMERAS_ATTRIBUTES)}


def keypoint_name(camera: str, keypoint: str) -> str:
    """``point2d`` name of one COCO keypoint seen by one camera: ``<camera>_kp_<keypoint>``."""
    return f"{camera}{KEYPOINT_INFIX}{keypoint}"


def _pointer_type_attrs(name: str, kind: str) -> dict[str, str]:
    if name == CAMERAS_DATA:
        return _CAMERAS_ATTRIBUTES
    if kind in ("text", "cuboid"):
        return {}
    if kind == "point2d":
        return {"visibility": "num"}
    if kind == "poly2d":
        return _POLY_ATTRIBUTES
    return _AMODAL_ATTRIBUTES if name.endswith(AMODAL_BBOX_SUFFIX) else _BBOX_ATTRIBUTES


def _intervals_json(frames: Iterable[int]) -> list[dict]:
    return [{"frame_start": iv.frame_start, "frame_end": iv.frame_end}
            for iv in union_intervals(FrameInterval(f, f) for f in frames)]


def _intervals_of(raw: Any) -> list[FrameInterval]:
    out = []
    for item in raw or ():
        if isinstance(item, dict) and "frame_start" in item and "frame_end" in item:
            out.append(FrameInterval(int(item["frame_start"]), int(item["frame_end"])))
    return out


def _document_key(uid: str, objects: dict, scene: SceneSpec) -> str | None:
    """The document's key of a scene object: the uid itself, or, for scenes built in code whose
    uids the writer renumbered (OpenLABEL keys are integers or UUIDs), the object of the same
    name and class."""
    if uid in objects:
        return uid
    obj = scene.object_by_uid().get(uid)
    if obj is None:
        return None
    matches = [k for k, e in objects.items()
               if isinstance(e, dict) and e.get("name") == obj.name and e.get("type") == obj.class_name]
    return matches[0] if len(matches) == 1 else None


def resolve_places(scene: SceneSpec, frame: int) -> dict[str, tuple[str, str]]:
    """Where each present object is at ``frame``, followed through chains of relations.

    ``bag is_on suitcase`` and ``suitcase is_below seat_03A`` resolve the bag to
    ``(seat_03A's uid, "is_below")``: an object placed relative to another object inherits that
    object's place and relation. Only placement relations (is_on, is_below, is_in,
    is_in_front_of) active at ``frame`` count (a relation without frame intervals holds while its
    subject is present); cycles and dangling chains resolve to nothing.

    Returns:
        uid → (place uid, relation type) for every object that resolves to a place.
    """
    return resolve_places_over(scene, (frame,))[frame]


def resolve_places_over(scene: SceneSpec, frames: Iterable[int]) -> dict[int, dict[str, tuple[str, str]]]:
    """:func:`resolve_places` for many frames in one pass over the relations (a generated
    sequence holds thousands of one-frame relations).

    Returns:
        frame → (uid → (place uid, relation type)), for every frame of ``frames``.
    """
    wanted = sorted(set(frames))
    out: dict[int, dict[str, tuple[str, str]]] = {f: {} for f in wanted}
    if not wanted:
        return out
    lo, hi = wanted[0], wanted[-1]
    every = frozenset(wanted)

    def within(intervals) -> set[int] | frozenset[int]:
        return {f for iv in intervals for f in range(max(iv.frame_start, lo), min(iv.frame_end, hi) + 1)
                if f in every}

    present = {o.uid: (within(o.frame_intervals) if o.frame_intervals else every) for o in scene.objects}
    placement = {r.value for r in RelationType}
    places = {p.uid for p in scene.places}
    support: dict[int, dict[str, tuple[str, str]]] = {f: {} for f in wanted}
    for rel in scene.relations:
        subject_frames = present.get(rel.subject_uid)
        if rel.type not in placement or not subject_frames:
            continue
        active = subject_frames if not rel.frame_intervals else within(rel.frame_intervals) & subject_frames
        for f in active:
            support[f].setdefault(rel.subject_uid, (rel.object_uid, rel.type))
    for f in wanted:
        links, resolved = support[f], out[f]
        for uid in links:
            seen, current = {uid}, links[uid]
            while current[0] not in places:
                nxt = links.get(current[0])
                if nxt is None or current[0] in seen:
                    break
                seen.add(current[0])
                current = nxt
            if current[0] in places:
                resolved[uid] = current
    return out


def _canonical_cameras(root: dict, scene: SceneSpec) -> None:
    """Write every camera of ``scene`` in the writer's exact form: ``streams[<camera>]`` with
    the intrinsics the images were rendered with (a friendly-form block becomes
    ``intrinsics_pinhole``/``intrinsics_fisheye``), ``coordinate_systems[<camera>]`` with the
    exact camera → world pose under the document's root coordinate system, and per-frame
    transforms for moving cameras. Stream ``uri``/``description`` of the input are kept; a camera
    whose coordinate system hangs below another (non-root) system is left as given."""
    from usdscene.converters.openlabel.write import write_openlabel

    written = write_openlabel(SceneSpec(name=scene.name, frame_start=scene.frame_start,
                                        frame_end=scene.frame_end, cameras=scene.cameras))["openlabel"]
    systems = root.setdefault("coordinate_systems", {})
    root_cs = next((name for name, cs in systems.items()
                    if isinstance(cs, dict) and not cs.get("parent") and cs.get("type") == "scene_cs"), None)
    if root_cs is None:
        root_cs = next(name for name, cs in written["coordinate_systems"].items() if not cs.get("parent"))
        systems[root_cs] = {"type": "scene_cs", "parent": "", "children": []}
    streams = root.setdefault("streams", {})
    frames = root.setdefault("frames", {})
    for cam in scene.cameras:
        stream = copy.deepcopy(written["streams"][cam.name])
        old = streams.get(cam.name) or {}
        for key in ("uri", "description"):
            if old.get(key):
                stream[key] = old[key]
        streams[cam.name] = stream
        old_cs = systems.get(cam.name)
        if isinstance(old_cs, dict) and old_cs.get("parent") not in (None, "", root_cs):
            continue
        systems[cam.name] = {
            "type": "sensor_cs", "parent": root_cs,
            "children": list(old_cs.get("children", [])) if isinstance(old_cs, dict) else [],
            "pose_wrt_parent": copy.deepcopy(written["coordinate_systems"][cam.name]["pose_wrt_parent"])}
        children = systems[root_cs].setdefault("children", [])
        if cam.name not in children:
            children.append(cam.name)
        for key, frame in written.get("frames", {}).items():
            for transform in (frame.get("frame_properties", {}).get("transforms", {}) or {}).values():
                if transform.get("src") != cam.name:
                    continue
                target = frames.setdefault(str(key), {}).setdefault("frame_properties", {}).setdefault("transforms", {})
                for name in [n for n, t in target.items()
                             if isinstance(t, dict) and t.get("src") == cam.name and t.get("dst") == root_cs]:
                    del target[name]  # the same pose under another key: keep one
                target[f"{cam.name}_to_{root_cs}"] = dict(copy.deepcopy(transform), dst=root_cs)


def sensor_record(sensor, seed: int, camera: str, frame: int) -> dict:
    """What the camera's sensor did to one image: its fields at this frame (defaults left out;
    an empty object for a sensor of defaults) and the entropy of the noise generator."""
    from usdscene.document.imaging import image_seed, spec_to_json

    return {**spec_to_json(sensor.at_frame(frame)), "seed": image_seed(seed, camera, frame)}


def add_annotations(document: dict, scene: SceneSpec, annotations: Annotations,
                    out_dir: str | os.PathLike, *, densities: Densities | None = None,
                    dori_table: Sequence[DoriClass] | None = None,
                    cuboids: Mapping[int, Mapping[str, Cuboid]] | None = None) -> dict:
    """The document plus per-frame image/mask uris, per-camera labels and the cross-camera
    table (a new dict).

    Args:
        document: ``{"openlabel": {...}}`` of the scene (not modified).
        scene: the SceneSpec it describes (camera names, object classes).
        annotations: labels of every labelled (frame, camera).
        out_dir: the output folder; uris are relative to it (the document is written there).
        densities: pixel densities of the cross-camera table
            (:func:`usdscene.labels.cross_camera.object_densities`); None = unknown (no ``px_per_m``
            and ``dori`` attributes).
        dori_table: ascending DORI classes; None = the shipped IEC 62676-4:2015 table.
        cuboids: frame → uid → 3D box (:func:`usdscene.labels.cuboids.labelled_cuboids`),
            written as ``cuboid`` object data named ``box3d``; None = no 3D boxes.

    Returns:
        A new ``{"openlabel": {...}}`` dict; see the module docstring for where things go.

    Raises:
        DocumentError: a label names a camera or object uid the document does not have.
    """
    result = copy.deepcopy(document)
    root = result.get("openlabel")
    if not isinstance(root, dict):
        raise DocumentError("expected an object with an 'openlabel' object", where="openlabel")
    _canonical_cameras(root, scene)
    objects = root.setdefault("objects", {})
    frames = root.setdefault("frames", {})
    cameras = {c.name for c in scene.cameras}
    sensors = {c.name: c.sensor for c in scene.cameras if c.sensor is not None}
    problems = ProblemCollector()
    # name → (type, frames) per object, for the data pointers.
    pointer_frames: dict[str, dict[str, tuple[str, set[int]]]] = {}
    for image in annotations.images:
        if image.camera not in cameras:
            problems.add(f"annotations.{image.camera}", f"camera {image.camera!r} is not a camera of the scene")
            continue
        frame = frames.setdefault(str(int(image.frame)), {})
        props = frame.setdefault("frame_properties", {})
        streams = props.setdefault("streams", {})
        streams.setdefault(image.camera, {})["uri"] = _relative_uri(
            layout.image_path(out_dir, image.camera, image.frame), out_dir)
        ours = props.setdefault(FRAME_PROPERTIES_KEY, {}).setdefault("streams", {})
        ours[image.camera] = {"mask_uri": _relative_uri(layout.mask_path(out_dir, image.camera, image.frame), out_dir),
                              "width_px": int(image.width_px), "height_px": int(image.height_px)}
        sensor = sensors.get(image.camera)
        if sensor is not None:
            ours[image.camera]["sensor"] = sensor_record(sensor, scene.seed, image.camera, int(image.frame))
            exposure = layout.exposure_path(out_dir, image.camera, image.frame)
            if exposure.is_file():
                # what the auto exposure chose for this image (written beside it by the worker)
                ours[image.camera]["sensor"]["exposure"] = json.loads(exposure.read_text(encoding="utf-8"))
            clean = layout.clean_image_path(out_dir, image.camera, image.frame)
            if clean.is_file():
                ours[image.camera]["clean_uri"] = _relative_uri(clean, out_dir)
        for label in image.objects:
            key = _document_key(label.uid, objects, scene)
            if key is None:
                problems.add(f"openlabel.objects.{label.uid}",
                             f"labelled object uid {label.uid!r} is not an object of the document")
                continue
            data = _object_data(image.camera, label)
            if not data:
                continue
            frame_objects = frame.setdefault("objects", {})
            object_data = frame_objects.setdefault(key, {}).setdefault("object_data", {})
            pointers = pointer_frames.setdefault(key, {})
            for kind, items in data.items():
                existing = object_data.setdefault(kind, [])
                replaced = {item["name"] for item in items}
                existing[:] = [e for e in existing if e.get("name") not in replaced] + items
                for item in items:
                    pointers.setdefault(item["name"], (kind, set()))[1].add(int(image.frame))
    problems.raise_if_any(DocumentError)
    if scene.fps is not None:  # a document read with a rate: every labelled frame has its instant
        for frame_number in annotations.frames():
            props = frames.setdefault(str(int(frame_number)), {}).setdefault("frame_properties", {})
            props.setdefault("timestamp", float(frame_number) / float(scene.fps))

    place_names = {p.uid: p.name for p in scene.places}
    for frame_number, where in resolve_places_over(scene, annotations.frames()).items():
        for uid, (place_uid, relation) in sorted(where.items()):
            key = _document_key(uid, objects, scene)
            if key is None:
                continue
            frame_objects = frames.setdefault(str(frame_number), {}).setdefault("objects", {})
            texts = frame_objects.setdefault(key, {}).setdefault("object_data", {}).setdefault("text", [])
            values = {RESOLVED_PLACE: place_names[place_uid], RESOLVED_RELATION: relation}
            texts[:] = [t for t in texts if t.get("name") not in values]
            texts.extend({"name": name, "val": value} for name, value in values.items())
            for name in values:
                pointer_frames.setdefault(key, {}).setdefault(name, ("text", set()))[1].add(frame_number)

    dori_table = load_dori() if dori_table is None else tuple(dori_table)
    for row in cross_camera_table(annotations, scene, densities=densities, dori_table=dori_table):
        key = _document_key(row.uid, objects, scene)
        if key is None:
            continue
        frame_objects = frames.setdefault(str(row.frame), {}).setdefault("objects", {})
        vecs = frame_objects.setdefault(key, {}).setdefault("object_data", {}).setdefault("vec", [])
        vecs[:] = [v for v in vecs if v.get("name") != CAMERAS_DATA] + [_cameras_data(row)]
        pointer_frames.setdefault(key, {}).setdefault(CAMERAS_DATA, ("vec", set()))[1].add(row.frame)

    world = next((name for name, system in (root.get("coordinate_systems") or {}).items()
                  if isinstance(system, dict) and not system.get("parent")), "world")
    for frame_number, boxes in sorted((cuboids or {}).items()):
        for uid, cuboid in boxes.items():
            key = _document_key(uid, objects, scene)
            if key is None:
                continue
            frame_objects = frames.setdefault(str(int(frame_number)), {}).setdefault("objects", {})
            items = frame_objects.setdefault(key, {}).setdefault("object_data", {}).setdefault("cuboid", [])
            items[:] = [c for c in items if c.get("name") != CUBOID_NAME] + [cuboid_data(cuboid, world)]
            pointer_frames.setdefault(key, {}).setdefault(CUBOID_NAME, ("cuboid", set()))[1].add(int(frame_number))

    for uid, names in pointer_frames.items():
        element = objects[uid]
        ptrs = element.setdefault("object_data_pointers", {})
        all_frames: set[int] = set()
        for name, (kind, data_frames) in sorted(names.items()):
            all_frames |= data_frames
            ptrs[name] = {"type": kind, "frame_intervals": _intervals_json(data_frames),
                          "attribute_pointers": dict(_pointer_type_attrs(name, kind))}
        widened = union_intervals([*_intervals_of(element.get("frame_intervals")),
                                   *(FrameInterval(f, f) for f in all_frames)])
        element["frame_intervals"] = [{"frame_start": iv.frame_start, "frame_end": iv.frame_end}
                                      for iv in widened]

    frame_numbers = [int(k) for k in frames if str(k).lstrip("-").isdigit()]
    root["frame_intervals"] = [
        {"frame_start": iv.frame_start, "frame_end": iv.frame_end}
        for iv in union_intervals([*_intervals_of(root.get("frame_intervals")),
                                   *(FrameInterval(f, f) for f in frame_numbers)])]
    metadata = root.setdefault("metadata", {"schema_version": "1.0.0"})
    metadata.setdefault("schema_version", "1.0.0")
    metadata[ANNOTATION_METADATA_KEY] = {
        "pixel_convention": "pixel centres at integer coordinates, x right, y down",
        "bbox": "[cx, cy, w, h] in pixels; the box spans whole pixels (w = x_max - x_min + 1)",
        "poly2d": "closed polygons through boundary pixel centres; hierarchy = OpenCV "
                  "[next, previous, first_child, parent] among the camera's polygons",
        "polygon_epsilon_px": float(annotations.epsilon_px),
        "min_visible_fraction": float(annotations.min_visible_fraction),
        "mask_uris": f"frames.<f>.frame_properties.{FRAME_PROPERTIES_KEY}.streams.<camera>.mask_uri",
        "cross_camera": f"frames.<f>.objects.<uid>.object_data.vec[name={CAMERAS_DATA}]: cameras with a "
                        "visible pixel; px_per_m at the object's bounds centre; dori per dori_classes",
        "dori_classes": [{"name": c.name, "px_per_m": float(c.px_per_m)} for c in dori_table],
    }
    if cuboids:
        metadata[ANNOTATION_METADATA_KEY]["cuboid"] = (
            f"frames.<f>.objects.<uid>.object_data.cuboid[name={CUBOID_NAME}]: [x, y, z, qx, qy, qz, qw, "
            f"sx, sy, sz] in {world!r} metres (Z up): centre, rotation about Z (the object's yaw), width "
            "along the object's x, length along y, height along z; the tightest such box around "
            "the object's posed geometry")
    return result


# --------------------------------------------------------------------------------------------
# Reading the labels back (used by the exporters, which work from the document only)


def image_records(document: dict) -> list[dict]:
    """Every labelled image of an annotated document, sorted by (frame, camera).

    Returns:
        Dicts ``{"frame": int, "camera": str, "uri": str, "mask_uri": str | None,
        "width_px": int, "height_px": int}``.

    Raises:
        DocumentError: an image record has no size (neither in ``frame_properties.usdscene``
            nor in the stream's intrinsics).
    """
    root = document.get("openlabel", {})
    streams = root.get("streams", {})
    problems = ProblemCollector()
    records = []
    for key, frame in root.get("frames", {}).items():
        props = frame.get("frame_properties", {}) or {}
        ours = (props.get(FRAME_PROPERTIES_KEY) or {}).get("streams", {})
        for camera, stream in (props.get("streams") or {}).items():
            if "uri" not in stream:
                continue
            extra = ours.get(camera, {})
            width, height = extra.get("width_px"), extra.get("height_px")
            if width is None or height is None:
                width, height = _stream_size(streams.get(camera, {}))
            if width is None or height is None:
                problems.add(f"openlabel.frames.{key}.frame_properties.streams.{camera}",
                             f"image {stream['uri']!r} has no known size")
                continue
            records.append({"frame": int(key), "camera": camera, "uri": stream["uri"],
                            "mask_uri": extra.get("mask_uri"), "width_px": int(width),
                            "height_px": int(height)})
    problems.raise_if_any(DocumentError)
    return sorted(records, key=lambda r: (r["frame"], r["camera"]))


def _stream_size(stream: dict) -> tuple[int | None, int | None]:
    props = stream.get("stream_properties", {}) or {}
    for key in ("intrinsics_pinhole", "intrinsics_fisheye", "intrinsics_custom"):
        intr = props.get(key)
        if isinstance(intr, dict) and "width_px" in intr and "height_px" in intr:
            return int(intr["width_px"]), int(intr["height_px"])
    return None, None


def labels_in(document: dict, frame: int, camera: str) -> list[dict]:
    """Labels of one image read back from an annotated document, sorted by mask id then uid.

    Returns:
        Dicts ``{"uid", "type", "name", "bbox": [cx, cy, w, h] | None, "amodal_bbox": ... | None,
        "polygons": [{"points": [x0, y0, ...], "is_hole": bool, "parent": int}],
        "attributes": {name: value}}``; ``attributes`` merges those of the visible and amodal boxes.
    """
    return LabelIndex(document).labels(frame, camera)


class LabelIndex:
    """:func:`labels_in` for many images of one document: each frame's objects are read once
    for all its cameras (reading them per image costs cameras × cameras passes over a frame).
    Keeps the ``max_frames`` frames read last (the exports read frame after frame, so a run of
    any length holds a few frames' labels; a document from the annotation store reads its
    frames shard by shard); the document must not change meanwhile.

    Attributes:
        most_frames_held: the most frames held at once so far.
        frames_read: frames read from the document so far (each read counts; a frame let go
            and asked for again is read again).
    """

    MAX_FRAMES = 16

    def __init__(self, document: dict, max_frames: int = MAX_FRAMES) -> None:
        root = document.get("openlabel", {})
        self._objects = root.get("objects", {})
        self._frames = root.get("frames", {})
        self._max_frames = max(1, int(max_frames))
        self._read: dict[int, dict[str, list[dict]]] = {}  # frame → camera → labels, oldest first
        self.most_frames_held = 0
        self.frames_read = 0

    def labels(self, frame: int, camera: str) -> list[dict]:
        """As :func:`labels_in` (fresh dicts on every call)."""
        return [dict(label, attributes=dict(label["attributes"]), polygons=[dict(p) for p in label["polygons"]],
                     keypoints=None if label["keypoints"] is None else list(label["keypoints"]))
                for label in self.held_labels(frame, camera)]

    def held_labels(self, frame: int, camera: str) -> list[dict]:
        """As :meth:`labels`, but the index's own dicts, not copies (for readers that only read
        them, in the exports' loops over every image): do not modify them."""
        frame = int(frame)
        if frame not in self._read:
            while len(self._read) >= self._max_frames:
                del self._read[next(iter(self._read))]
            self._read[frame] = self._read_frame(frame)
            self.frames_read += 1
            self.most_frames_held = max(self.most_frames_held, len(self._read))
        return self._read[frame].get(camera, [])

    def _read_frame(self, frame: int) -> dict[str, list[dict]]:
        frame_objects = (self._frames.get(str(frame), {}) or {}).get("objects", {}) or {}
        by_camera: dict[str, list[dict]] = {}
        for uid, entry in frame_objects.items():
            data = (entry or {}).get("object_data", {}) or {}
            found: dict[str, dict] = {}  # camera → {"bbox", "amodal_bbox", "attributes", "polygons"}

            def of(camera: str) -> dict:
                label = found.get(camera)
                if label is None:
                    label = found[camera] = {"bbox": None, "amodal_bbox": None, "attributes": {},
                                             "polygons": [], "keypoints": {}}
                return label

            for item in data.get("bbox", ()):
                name = item.get("name", "")
                if not name.endswith(BBOX_SUFFIX):
                    continue
                # A name can be the visible box of one camera and the amodal box of another
                # (cameras "c" and "c_amodal"): both readings count, as they would per camera.
                readings = ((("amodal_bbox", name[:-len(AMODAL_BBOX_SUFFIX)]),) if name.endswith(AMODAL_BBOX_SUFFIX)
                            else ()) + (("bbox", name[:-len(BBOX_SUFFIX)]),)
                for key, camera in readings:
                    label = of(camera)
                    label[key] = list(item["val"])
                    attributes = label["attributes"]
                    # the first value of each name wins (inline: this loop sees every label of every frame)
                    for kind_items in (item.get("attributes") or {}).values():
                        for attr in kind_items:
                            if attr["name"] not in attributes:
                                attributes[attr["name"]] = attr["val"]
            for item in data.get("poly2d", []):
                name = item.get("name", "")
                cut = name.rfind(POLY2D_INFIX)
                index = name[cut + len(POLY2D_INFIX):]
                if cut < 0 or not index.isdigit():
                    continue
                hierarchy = item.get("hierarchy") or [-1, -1, -1, -1]
                of(name[:cut])["polygons"].append((int(index), {
                    "points": [float(v) for v in item["val"]], "parent": int(hierarchy[3]),
                    "is_hole": int(hierarchy[3]) >= 0}))
            for item in data.get("point2d", []):
                name = item.get("name", "")
                cut = name.rfind(KEYPOINT_INFIX)
                if cut < 0:
                    continue
                v = next((a.get("val") for a in (item.get("attributes") or {}).get("num", [])
                          if a.get("name") == "visibility"), 0)
                x, y = item["val"]
                of(name[:cut])["keypoints"][name[cut + len(KEYPOINT_INFIX):]] = (float(x), float(y), int(v))
            element = self._objects.get(uid, {})
            for camera, label in found.items():
                if label["bbox"] is None and label["amodal_bbox"] is None and not label["polygons"]:
                    continue
                by_camera.setdefault(camera, []).append({
                    "uid": uid, "type": element.get("type", ""), "name": element.get("name", ""),
                    "bbox": label["bbox"], "amodal_bbox": label["amodal_bbox"],
                    "polygons": [p for _, p in sorted(label["polygons"], key=lambda kp: kp[0])],
                    "attributes": label["attributes"],
                    "keypoints": _coco_order(label["keypoints"])})
        for labels in by_camera.values():
            labels.sort(key=lambda o: (o["attributes"].get("mask_id", 0), o["uid"]))
        return by_camera


def _coco_order(found: dict) -> list[tuple[float, float, int]] | None:
    """The 17 keypoints in COCO order, or None when the label has none (missing ones: v = 0)."""
    if not found:
        return None
    from usdscene.labels.keypoints import COCO_KEYPOINTS

    return [found.get(name, (0.0, 0.0, 0)) for name in COCO_KEYPOINTS]


def label_classes(document: dict, classes: Iterable[str] | None = None) -> list[str]:
    """Class names of an export, sorted (their order gives COCO ids 1.. and YOLO ids 0..).

    Args:
        document: annotated document.
        classes: the catalog's labelled classes (object and passenger kinds); None = the
            types of the document's objects that carry at least one label.
    """
    if classes is not None:
        return sorted(set(classes))
    root = document.get("openlabel", {})
    found = set()
    for uid, element in root.get("objects", {}).items():
        pointers = element.get("object_data_pointers") or {}
        if any(name.endswith(BBOX_SUFFIX) or POLY2D_INFIX in name for name in pointers):
            found.add(element.get("type", ""))
    return sorted(found)


def cross_camera_rows(document: dict) -> list[dict]:
    """The cross-camera table read back from an annotated document, sorted by (frame, uid).

    Returns:
        Dicts ``{"frame": int, "uid": str, "type": str, "cameras": [str], "visible_fractions":
        [float] | None, "px_per_m": [float] | None, "dori": [str] | None, "best_px_per_m":
        float | None, "best_dori": str | None}`` (lists parallel to ``cameras``; None = unknown).
    """
    root = document.get("openlabel", {})
    objects = root.get("objects", {}) or {}
    rows = []
    for key, frame in (root.get("frames", {}) or {}).items():
        for uid, entry in ((frame or {}).get("objects", {}) or {}).items():
            item = next((v for v in ((entry or {}).get("object_data", {}) or {}).get("vec", [])
                         if v.get("name") == CAMERAS_DATA), None)
            if item is None:
                continue
            attributes = {a["name"]: a["val"] for kind_items in (item.get("attributes") or {}).values()
                          for a in kind_items}
            rows.append({"frame": int(key), "uid": uid, "type": (objects.get(uid) or {}).get("type", ""),
                         "cameras": [str(c) for c in item.get("val", [])],
                         **{name: attributes.get(name) for name in
                            ("visible_fractions", "px_per_m", "dori", "best_px_per_m", "best_dori")}})
    return sorted(rows, key=lambda r: (r["frame"], r["uid"]))
