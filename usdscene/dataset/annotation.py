"""Labels of a rendered output folder: instance masks → ``OUT/annotations.openlabel.json``.

For every mask ``OUT/masks/<camera>/<frame:06d>.png`` (ids explained by ``OUT/masks/ids.json``):
tight boxes, polygons and pixel counts from the mask; amodal boxes, truncation and visible
fractions from the objects' triangles in the composed stage (``OUT/stage/scene.usda``)
projected through the exact camera the renderer used; per labelled frame, each object's 3D
box around the same triangles (:mod:`usdscene.labels.cuboids`). The labels are added to the scene
document, which is, in this order: the ``document_path`` given; the source document recorded in
the stage when it still exists unchanged (same sha256); or the scene read back from the stage.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from usdscene.errors import OutputError
from usdscene.validation import DEFAULT_SCHEMA


SINGLE_DOCUMENT_MAX_BYTES = 256 * 1024 * 1024
"""``write_annotations`` also writes ``OUT/annotations.openlabel.json`` when the store's frames
are at most this many bytes (compact JSON; the indented document is about 3 times that: 2.9 MB
of store, 9.1 MB of document for the six-camera car park example); larger runs get it from
``usdscene export-openlabel OUT -o FILE``."""


@dataclass(frozen=True)
class AnnotationSummary:
    """What :func:`write_annotations` labelled, without holding the labels: iterating it
    reads each image's labels back from ``OUT/labels/`` one at a time.

    Attributes:
        out_dir: the output folder.
        pairs: the labelled ``(frame, camera)`` images, sorted.
        visible_per_class: class → visible labels (at least one pixel).
        hidden: fully occluded labels (amodal only).
        store: the store folder (``OUT/annotations``).
        single_document: ``OUT/annotations.openlabel.json`` when it was written, else None.
    """

    out_dir: Path
    pairs: tuple[tuple[int, str], ...]
    visible_per_class: dict
    hidden: int
    store: Path
    single_document: Path | None

    @property
    def images(self) -> tuple[tuple[int, str], ...]:
        """The labelled images (as ``pairs``)."""
        return self.pairs

    def __len__(self) -> int:
        return len(self.pairs)

    def __iter__(self):
        """Each image's :class:`usdscene.labels.image_labels.ImageLabels`, by (frame, camera)."""
        import json

        from usdscene.document import output_layout as layout
        from usdscene.labels.image_labels import image_labels_from_json

        for frame, camera in self.pairs:
            kept = json.loads(layout.labels_path(self.out_dir, camera, frame).read_text(encoding="utf-8"))
            yield image_labels_from_json(kept["labels"])


def write_annotations(out_dir: str | os.PathLike, *, document_path: str | os.PathLike | None = None,
                      epsilon_px: float | None = None, min_visible_fraction: float = 0.0,
                      amodal: bool = True, progress: bool = False,
                      schema: str | os.PathLike | None | Literal["default"] = DEFAULT_SCHEMA,
                      labeller: ImageLabeller | None = None, frames_per_shard: int | None = None,
                      single_document_max_bytes: int = SINGLE_DOCUMENT_MAX_BYTES):
    """Label every mask of a rendered output folder into the annotation store
    ``OUT/annotations/`` (:mod:`usdscene.converters.openlabel.store`), one frame range at a time,
    never a shard that the official schema rejects; for small runs also the single document
    ``OUT/annotations.openlabel.json``, streamed from the store.

    Each range's labels are added to the range's part of the document alone
    (:func:`usdscene.converters.openlabel.annotations.add_annotations`) and written as one
    shard; only the objects' data pointers and frame intervals are merged across ranges, so
    memory holds one range's labels, and the store reads as the document that labelling the
    whole run at once gives. A killed run rewrites the same bytes (each image's labels are
    kept in ``OUT/labels/``; see :class:`ImageLabeller`).

    Args:
        out_dir: output folder of a render.
        document_path, epsilon_px, min_visible_fraction, amodal, progress, labeller: as in
            :func:`annotate_output`.
        schema: official schema every written part must pass (see
            :func:`usdscene.validation.validate_document`); None: no schema check.
        frames_per_shard: frames per shard (None: the store's
            :data:`usdscene.converters.openlabel.store.FRAMES_PER_SHARD`).
        single_document_max_bytes: write ``OUT/annotations.openlabel.json`` when the shards
            hold at most this many bytes (0: never); a larger run's stale copy is removed.

    Returns:
        ``(path, summary)``: the single document written, else the store folder, and an
        :class:`AnnotationSummary`.

    Raises:
        OutputError: no masks, unreadable masks, or a part the schema rejects (that part is
            not written). DocumentError: the document does not match the render.
    """
    from usdscene.converters.openlabel import store as stores
    from usdscene.converters.openlabel.annotations import add_annotations
    from usdscene.document import output_layout as layout
    from usdscene.labels.image_labels import label_images
    from usdscene.validation import resolve_schema

    out, pairs, labeller, document, scene = _prepare(out_dir, document_path, epsilon_px, min_visible_fraction,
                                                     amodal, labeller)
    per_shard = stores.FRAMES_PER_SHARD if frames_per_shard is None else int(frames_per_shard)
    writer = stores.StoreWriter(stores.store_folder(out), per_shard, schema=resolve_schema(schema))
    single = out / layout.ANNOTATIONS_FILE
    _forget_store(out, single)
    root = document["openlabel"]
    input_frames = root.get("frames") or {}
    input_pointers = {uid: list((element or {}).get("object_data_pointers") or ())
                      for uid, element in (root.get("objects") or {}).items() if isinstance(element, dict)}
    by_range: dict[tuple[int, int], list] = {}
    for frame, camera in pairs:
        by_range.setdefault(stores.shard_range(frame, per_shard), []).append((frame, camera))
    planned = set(by_range) | {stores.shard_range(int(k), per_shard) for k in input_frames}
    done: set = set()
    merged = None
    per_class: dict[str, int] = {}
    hidden = 0
    input_by_range: dict[tuple[int, int], dict] = {}  # the input document's frames, by shard range
    for key, frame in input_frames.items():
        input_by_range.setdefault(stores.shard_range(int(key), per_shard), {})[key] = frame
    with _progress_bar(progress, len(pairs)) as advance:
        while planned - done:
            first, last = span = min(planned - done)
            done.add(span)
            images = []
            for frame, camera in by_range.get(span, ()):
                image = labeller.labels(frame, camera)
                images.append(image)
                for label in image.objects:
                    if label.visible:
                        per_class[label.class_name] = per_class.get(label.class_name, 0) + 1
                    else:
                        hidden += 1
                advance()
            annotations = label_images(images, epsilon_px=labeller.epsilon_px,
                                       min_visible_fraction=labeller.min_visible_fraction)
            densities, cuboids = _geometry_labels(annotations, labeller)
            part = {key: (input_by_range.get(span, {}) if key == "frames" else value) for key, value in root.items()}
            result = add_annotations({"openlabel": part}, scene, annotations, out, densities=densities,
                                     cuboids=cuboids)["openlabel"]
            frames = result.get("frames") or {}
            # Frames the document gains outside this range (a moving camera's per-frame
            # poses, the same in every range) are written by their own range.
            planned |= {stores.shard_range(int(k), per_shard) for k in frames}
            writer.write_shard(first, last, {k: f for k, f in frames.items() if first <= int(k) <= last})
            result["frames"] = {}
            merged = result if merged is None else _merge_static(merged, result)
    if merged is None:  # no frame at all: the document as add_annotations makes it
        merged = add_annotations(document, scene, label_images([]), out)["openlabel"]
    _order_pointers(merged, input_pointers)
    static = {"openlabel": merged}
    index = writer.finish(static)
    written = None
    if single_document_max_bytes and sum(e["bytes"] for e in writer.entries) <= single_document_max_bytes:
        record = stores.AnnotationStore(writer.folder).write_document(single)
        stores.record_single_document(writer.folder, record)
        written = single
    else:
        import logging

        single.unlink(missing_ok=True)  # a copy of an earlier, smaller labelling would mislead
        logging.getLogger(__name__).info("labels in %s; one document: usdscene export-openlabel %s -o FILE",
                                         index.parent, out)
    summary = AnnotationSummary(out_dir=out, pairs=tuple(pairs), visible_per_class=dict(sorted(per_class.items())),
                                hidden=hidden, store=writer.folder, single_document=written)
    return (written or writer.folder), summary


def _forget_store(out: Path, single: Path) -> None:
    """Before the store is rewritten: remove its index (a killed or failed rewrite then leaves
    no store that names shards half replaced) and its single-document copy (which would
    otherwise read as a document of the user's). A document not written by the store stays."""
    from usdscene.converters.openlabel import store as stores

    index = stores.store_folder(out) / stores.INDEX_FILE
    if not index.is_file():
        return
    try:
        copy = stores.single_document_is_copy(out, stores.AnnotationStore(index.parent).index)
    except OutputError:  # an unreadable index: nothing it names can be trusted
        copy = False
    if copy:
        single.unlink(missing_ok=True)
    index.unlink(missing_ok=True)


def _merge_static(merged: dict, part: dict) -> dict:
    """The document root without frames after two ranges: ``merged`` (earlier ranges) with the
    objects' data pointers, their frame intervals and the root frame intervals of ``part``
    joined in (everything else is the same in every range's result)."""
    from usdscene.converters.openlabel.annotations import ANNOTATION_METADATA_KEY
    from usdscene.document.model import FrameInterval, union_intervals

    def union(*lists) -> list[dict]:
        return [{"frame_start": iv.frame_start, "frame_end": iv.frame_end}
                for iv in union_intervals(FrameInterval(int(i["frame_start"]), int(i["frame_end"]))
                                          for raw in lists for i in (raw or ()))]

    objects = merged.get("objects") or {}
    for uid, element in (part.get("objects") or {}).items():
        pointers = (element or {}).get("object_data_pointers")
        mine = objects.get(uid)
        if not pointers or mine is None or mine == element:
            continue
        if not mine.get("object_data_pointers"):
            objects[uid] = element  # first labelled in this range
            continue
        into = mine["object_data_pointers"]
        for name, pointer in pointers.items():
            if name not in into:
                into[name] = pointer
            elif into[name] != pointer:  # equal ones stay as given (the input's own key order)
                into[name]["frame_intervals"] = union(into[name].get("frame_intervals"), pointer.get("frame_intervals"))
        if mine.get("frame_intervals") != element.get("frame_intervals"):
            mine["frame_intervals"] = union(mine.get("frame_intervals"), element.get("frame_intervals"))
    if merged.get("frame_intervals") != part.get("frame_intervals"):
        merged["frame_intervals"] = union(merged.get("frame_intervals"), part.get("frame_intervals"))
    cuboid = (((part.get("metadata") or {}).get(ANNOTATION_METADATA_KEY)) or {}).get("cuboid")
    if cuboid is not None:
        merged["metadata"][ANNOTATION_METADATA_KEY]["cuboid"] = cuboid
    return merged


def _order_pointers(root: dict, input_pointers: dict) -> None:
    """Data pointers in the order one labelling of the whole run writes them: the input
    document's own first, then the new names sorted."""
    for uid, element in (root.get("objects") or {}).items():
        pointers = (element or {}).get("object_data_pointers") if isinstance(element, dict) else None
        if not pointers:
            continue
        given = [n for n in input_pointers.get(uid, ()) if n in pointers]
        element["object_data_pointers"] = {n: pointers[n] for n in
                                           [*given, *sorted(n for n in pointers if n not in set(given))]}


def _geometry_labels(annotations, labeller):
    """``(densities, cuboids)`` of some frames' labels (None, None without stage geometry)."""
    if labeller.geometry is None:
        return None, None
    from usdscene.labels.cross_camera import object_densities
    from usdscene.labels.cuboids import labelled_cuboids

    densities = object_densities(annotations, labeller.cameras, labeller.geometry)
    cuboids = labelled_cuboids(annotations.frames(), labeller.geometry, labeller.uids)
    return densities, cuboids


@contextlib.contextmanager
def _progress_bar(shown: bool, total: int):
    """A function advancing a ``rich`` progress bar on stderr by one (a no-op when not shown)."""
    if not shown:
        yield lambda: None
        return
    from rich.progress import Progress

    bar = Progress(transient=True)
    bar.start()
    task = bar.add_task("annotating", total=total)
    try:
        yield lambda: bar.advance(task)
    finally:
        bar.stop()


def _source_document(stage_path):
    """The stage's recorded source document when it still exists unchanged, else None."""
    import hashlib
    import logging

    from usdscene.render.stage_reader import recorded_source

    source, digest = recorded_source(stage_path)
    if source is None or not source.is_file():
        return None
    if digest and hashlib.sha256(source.read_bytes()).hexdigest() != digest:
        logging.getLogger(__name__).warning("%s changed since the stage was composed; the labels go "
                                            "into the scene read back from the stage", source)
        return None
    return source


class ImageLabeller:
    """Labels the images of one output folder, one (frame, camera) at a time.

    Each image's labels are kept in ``OUT/labels/<camera>/<frame:06d>.json`` with a key made
    of the mask's sha256, the labelling settings, the id map, the stage layers and the
    usdscene version, so they are computed once: while the image is rendered (``usdscene
    run`` labels each image as it arrives) or afterwards (``usdscene annotate``), and again
    only when the key changes. Labels read back are equal to labels computed anew.

    Not thread-safe: call from one thread at a time.

    Raises (constructor):
        OutputError: no or unreadable id map (``OUT/masks/ids.json``).
    """

    def __init__(self, out_dir: str | os.PathLike, *, epsilon_px: float | None = None,
                 min_visible_fraction: float = 0.0, amodal: bool = True) -> None:
        import hashlib
        import json

        from usdscene import __version__

        from usdscene.document import output_layout as layout
        from usdscene.labels.amodal import RASTER_REVISION
        from usdscene.labels.image_labels import LABELS_REVISION
        from usdscene.errors import OutputError

        self.out = Path(out_dir)
        self.settings = self.settings_key(epsilon_px, min_visible_fraction, amodal)
        self.epsilon_px, self.min_visible_fraction, _ = self.settings
        id_file = self.out / layout.ID_MAP_FILE
        try:
            id_bytes = id_file.read_bytes()
            id_map = json.loads(id_bytes)
            owners = layout.id_map_entries(id_map)
            self.uids = {str(v["uid"]) for v in owners}
            self.classes = {str(v["uid"]): str(v.get("class", "")) for v in owners}
            # mask id → uid; ids shared over time (long sequences) are resolved per frame.
            self.ids = layout.mask_owners(id_map)
            self._shared_ids = id_map if len(owners) > len(id_map) else None
        except FileNotFoundError:
            raise OutputError("no mask id map; render the output first", where=str(id_file)) from None
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise OutputError(f"unreadable mask id map: {exc}", where=str(id_file)) from None
        self.cameras: dict = {}
        self.geometry = None
        stage_path = layout.stage_root(self.out)
        if amodal:
            from usdscene.render.stage_reader import read_stage_plan, stage_digest
            from usdscene.scene.stage_geometry import StageGeometry

            # The cameras exactly as rendered (per-frame poses from the stage).
            self.cameras = {c.name: c for c in read_stage_plan(stage_path).cameras}
            self.geometry = StageGeometry(stage_path)
        self._key = {"usdscene": __version__, "epsilon_px": self.epsilon_px,
                     "min_visible_fraction": self.min_visible_fraction, "amodal": bool(amodal),
                     "amodal_raster_revision": RASTER_REVISION if amodal else None,
                     "labels_revision": LABELS_REVISION,
                     "ids_sha256": hashlib.sha256(id_bytes).hexdigest(),
                     "stage_sha256": stage_digest(stage_path) if amodal else None}
        self._triangles: tuple[int, dict] | None = None  # (frame, uid → triangles) of the last frame
        self._keypoints: tuple[int, dict] | None = None  # (frame, uid → (17, 3) world keypoints)

    @staticmethod
    def settings_key(epsilon_px: float | None, min_visible_fraction: float, amodal: bool) -> tuple:
        """``(epsilon_px, min_visible_fraction, amodal)`` with the defaults filled in."""
        from usdscene.labels.image_labels import DEFAULT_EPSILON_PX

        return (DEFAULT_EPSILON_PX if epsilon_px is None else float(epsilon_px), float(min_visible_fraction),
                bool(amodal))

    def labels(self, frame: int, camera: str):
        """The labels of one rendered image: kept ones when their key matches, else computed
        and kept.

        Returns:
            :class:`usdscene.labels.image_labels.ImageLabels`.

        Raises:
            OutputError: the mask is missing or not a single-channel 16-bit image.
        """
        import hashlib
        import json

        from usdscene.document import output_layout as layout
        from usdscene.errors import OutputError
        from usdscene.files import write_json_atomic
        from usdscene.labels.image_labels import image_labels_from_json, image_labels_to_json

        mask_file = layout.mask_path(self.out, camera, frame)
        try:
            mask_bytes = mask_file.read_bytes()
        except OSError as exc:
            raise OutputError(f"cannot read the mask: {exc.strerror or exc}", where=str(mask_file)) from None
        key = dict(self._key, mask_sha256=hashlib.sha256(mask_bytes).hexdigest())
        kept_file = layout.labels_path(self.out, camera, frame)
        try:
            kept = json.loads(kept_file.read_text(encoding="utf-8"))
            if kept.get("key") == key:
                return image_labels_from_json(kept["labels"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            pass  # missing or unreadable: label anew
        payload = image_labels_to_json(self._compute(mask_bytes, mask_file, frame, camera))
        write_json_atomic(kept_file, {"key": key, "labels": payload}, compact=True)
        # What a later run reads back, so that fresh and kept labels give identical documents.
        return image_labels_from_json(payload)

    def _compute(self, mask_bytes: bytes, mask_file: Path, frame: int, camera_name: str):
        import cv2
        import numpy as np

        from usdscene.document import output_layout as layout
        from usdscene.labels.amodal import amodal_projections
        from usdscene.labels.cross_camera import camera_for_image
        from usdscene.errors import OutputError
        from usdscene.labels.image_labels import label_image
        from usdscene.labels.projection import project_points

        mask = cv2.imdecode(np.frombuffer(mask_bytes, np.uint8), cv2.IMREAD_UNCHANGED)
        if mask is None or mask.ndim != 2 or mask.dtype.kind != "u":
            raise OutputError("not a single-channel 16-bit instance mask", where=str(mask_file))
        amodal_masks = keypoints = None
        camera = self.cameras.get(camera_name)
        if self.geometry is not None and camera is not None:
            if self._triangles is None or self._triangles[0] != frame:
                self._triangles = (frame, self.geometry.triangles(frame, self.uids))
            height, width = mask.shape
            # as rendered: its pose at the frame, its intrinsics at the image's resolution scale
            camera = camera_for_image(camera, frame, width, height)
            amodal_masks = amodal_projections(camera, self._triangles[1], frame)
            # Objects the camera does not see at all carry no label there.
            amodal_masks = {uid: a for uid, a in amodal_masks.items() if a.pixel_count}
            if self._keypoints is None or self._keypoints[0] != frame:
                self._keypoints = (frame, self.geometry.keypoints(frame, self.uids))
            # The same lens model and pose as the amodal projections; every person's in one call.
            people = self._keypoints[1]
            keypoints = {}
            if people:
                uv, valid = project_points(camera, np.concatenate(list(people.values())), frame)
                starts = np.cumsum([0] + [len(points) for points in people.values()])
                keypoints = {uid: (uv[a:b], valid[a:b]) for uid, a, b in zip(people, starts[:-1], starts[1:])}
        ids = self.ids if self._shared_ids is None else layout.mask_owners(self._shared_ids, frame)
        return label_image(mask, ids, amodal_masks, classes=self.classes, camera=camera_name,
                           frame=frame, epsilon_px=self.epsilon_px,
                           min_visible_fraction=self.min_visible_fraction, keypoints=keypoints)


class LabelsWhileRendering:
    """A render event handler (``render(..., on_event=...)``) that labels each image as soon as
    the renderer reports it written, so that labelling overlaps rendering and an interrupted
    run keeps the labels of every finished image.

    A failure is logged and labelling stops; :func:`annotate_output` afterwards labels what is
    missing and reports the problem properly.

    Attributes:
        images: images labelled.
        seconds: wall seconds spent labelling.
        labeller: the :class:`ImageLabeller` it opened (None before the first image or after a
            failure), for the annotate step to reuse.
    """

    def __init__(self, out_dir: str | os.PathLike, **labeller_options) -> None:
        self.out = Path(out_dir)
        self.options = labeller_options
        self.images = 0
        self.seconds = 0.0
        self.labeller: ImageLabeller | None = None
        self._failed = False

    def __call__(self, event: dict) -> None:
        import logging
        import time

        from usdscene.errors import UsdSceneError

        if event.get("event") != "done" or self._failed:
            return
        started = time.perf_counter()
        try:
            if self.labeller is None:  # the id map exists once rendering has started
                self.labeller = ImageLabeller(self.out, **self.options)
            self.labeller.labels(int(event["frame"]), str(event["camera"]))
            self.images += 1
        except (UsdSceneError, OSError) as exc:
            self._failed = True
            self.labeller = None
            logging.getLogger(__name__).warning("labelling while rendering stopped (%s); the images "
                                                "are labelled after rendering", exc)
        finally:
            self.seconds += time.perf_counter() - started


def annotate_output(out_dir, *, document_path=None, epsilon_px: float | None = None,
                    min_visible_fraction: float = 0.0, amodal: bool = True, progress: bool = False,
                    labeller: ImageLabeller | None = None):
    """Label every mask of a rendered output folder (images labelled before, e.g. while they
    were rendered, are read back, see :class:`ImageLabeller`).

    Args:
        out_dir: output folder (``stage/``, ``masks/``, ``masks/ids.json``).
        document_path: scene document to extend; None = see the module docstring.
        epsilon_px: polygon tolerance (None = :data:`usdscene.labels.image_labels.DEFAULT_EPSILON_PX`).
        min_visible_fraction: minimum-visibility filter.
        amodal: compute amodal boxes and visible fractions from the stage geometry.
        progress: show a ``rich`` progress bar on stderr.
        labeller: an open :class:`ImageLabeller` of ``out_dir`` to reuse (its stage and geometry
            stay loaded, e.g. the one that labelled while rendering); used only when its
            settings are the ones asked for.

    Returns:
        ``(document, annotations)``: the annotated ``{"openlabel": ...}`` dict (not yet
        written) and the :class:`usdscene.labels.image_labels.Annotations`.

    Raises:
        OutputError: no masks, unreadable mask or id map.
        DocumentError: the document does not match the render (unknown camera or object).
    """
    from usdscene.converters.openlabel.annotations import add_annotations
    from usdscene.labels.image_labels import label_images

    out, pairs, labeller, document, scene = _prepare(out_dir, document_path, epsilon_px, min_visible_fraction,
                                                     amodal, labeller)
    images = []
    with _progress_bar(progress, len(pairs)) as advance:
        for frame, camera_name in pairs:
            images.append(labeller.labels(frame, camera_name))
            advance()
    annotations = label_images(images, epsilon_px=labeller.epsilon_px,
                               min_visible_fraction=labeller.min_visible_fraction)
    densities, cuboids = _geometry_labels(annotations, labeller)
    return (add_annotations(document, scene, annotations, out, densities=densities, cuboids=cuboids),
            annotations)


def _prepare(out_dir, document_path, epsilon_px, min_visible_fraction, amodal, labeller):
    """``(out, pairs, labeller, document, scene)`` of an output folder to label: its masks'
    sorted ``(frame, camera)`` pairs, an :class:`ImageLabeller` of the settings asked for (the
    one given when it fits), and the document and scene the labels go into."""
    from usdscene.converters.openlabel import load_document, read_openlabel, write_openlabel
    from usdscene.document import output_layout as layout
    from usdscene.errors import OutputError

    out = Path(out_dir)
    # What a killed annotate left half-written (kept labels, shards, the single document).
    from usdscene.files import remove_stale_temporaries

    remove_stale_temporaries(out / layout.LABELS_DIR)
    remove_stale_temporaries(out / layout.ANNOTATION_STORE_DIR)
    remove_stale_temporaries(out, recursive=False)
    stage_path = layout.stage_root(out)
    masks_dir = out / layout.MASKS_DIR
    pairs = sorted((int(p.stem), p.parent.name) for p in masks_dir.glob("*/*.png") if p.stem.isdigit())
    if not pairs:
        raise OutputError("no masks found; render the output first", where=str(masks_dir))
    wanted = ImageLabeller.settings_key(epsilon_px, min_visible_fraction, amodal)
    if labeller is None or labeller.out != out or labeller.settings != wanted:
        labeller = ImageLabeller(out, epsilon_px=epsilon_px, min_visible_fraction=min_visible_fraction,
                                 amodal=amodal)
    if document_path is None and stage_path.is_file():
        document_path = _source_document(stage_path)
    if document_path is not None:
        document = load_document(document_path)
        scene = read_openlabel(document)
    else:
        from usdscene.converters.stage.usd_stage import scene_from_stage

        # Keep the stage's scene (its uids are the mask map's) even where the writer has to
        # renumber uids for OpenLABEL; add_annotations matches those by name and class.
        scene = scene_from_stage(stage_path)
        document = write_openlabel(scene)
    return out, pairs, labeller, document, scene
