"""Training sets from an annotated output: its labels → COCO, YOLO, ROI crops and more.

Exporters read only the annotated document (and the asset catalog for class lists and place
regions), never internal state; the document is the annotation store ``OUT/annotations/``
read frame range by frame range as the writers go (or ``OUT/annotations.openlabel.json``,
see :func:`usdscene.converters.openlabel.store.open_annotations`):

* ``coco``: ``OUT/exports/coco/annotations.json`` (see :mod:`usdscene.converters.exports.coco`);
* ``yolo``: ``OUT/exports/yolo/{detect,segment}/`` with ``data.yaml`` (see :mod:`usdscene.converters.exports.yolo`);
* ``rois``: ``OUT/exports/rois/<label>/*.png`` + ``index.csv`` (see :mod:`usdscene.converters.exports.rois`);
* ``mot``: ``OUT/exports/mot/<camera>/`` MOTChallenge sequences (see :mod:`usdscene.converters.exports.mot`);
* ``multiview``: ``OUT/exports/multiview/`` WILDTRACK-style ground-plane positions and OpenCV
  calibrations in the ``free``, ``wildtrack`` or ``multiviewx`` flavour (see
  :mod:`usdscene.converters.exports.multiview`); tracked are the catalog's person and vehicle classes
  (:func:`usdscene.generate.motion.person_classes`, ``vehicle_classes``);
* ``video``: ``OUT/exports/video/<camera>.mp4`` H.264 at the document's frame rate (see
  :mod:`usdscene.converters.exports.video`; extra ``usdscene[video]``);
* ``aicity``: ``OUT/exports/aicity/<scene>/`` an AI City Challenge Track 1 scene (see
  :mod:`usdscene.dataset.aicity_scene`; extra ``usdscene[aicity]``).

``mot``, ``multiview``, ``video`` and ``aicity`` need a moving sequence (a document with ``metadata.usdscene.fps``).

Class lists come from the asset catalog (object and passenger classes, sorted), so ids are
the same for every scene built from one library; the catalog is the shipped library plus the
document's asset folders (relative to the source document recorded in the stage) plus
``extra_assets``.

Splits and campaigns (:func:`export_dataset`): with a split rule (:mod:`usdscene.document.splits`),
COCO is written as ``coco/annotations_<split>.json`` and YOLO as ``<task>/<split>.txt`` image
lists named by ``data.yaml``, and ``splits.json`` records the split of every image. Several
output folders (one per sequence document) become one dataset in a folder of its own, with
image and annotation ids unique across them and the images of each output folder under a
sub-folder named by its path relative to the folder they share.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

def _source_folder(out_dir):
    """Folder of the stage's source document (asset paths are relative to it), else None."""
    from usdscene.document import output_layout as layout
    from usdscene.render.stage_reader import recorded_source

    source, _ = recorded_source(layout.stage_root(out_dir))
    return source.parent if source is not None else None


def load_export_catalog(document: dict, out_dir, extra_folders=()):
    """The catalog for an annotated document (see the module docstring)."""
    from pathlib import Path

    from usdscene.scene.catalog import load_catalog
    from usdscene.converters.openlabel.load import DocumentBody
    from usdscene.converters.openlabel.metadata import read_metadata
    from usdscene.errors import DocumentError

    # Only the metadata's asset paths: reading the whole scene (every frame's labels) would
    # cost a second on a run's document. ``document`` comes from load_document (root openlabel).
    body = DocumentBody(document["openlabel"])
    asset_paths = read_metadata(body)["asset_paths"]
    body.problems.raise_if_any(DocumentError)
    base = _source_folder(out_dir) or Path(out_dir)
    extra = [Path(p).resolve() for p in extra_folders]  # given on the command line: consented
    return load_catalog([*asset_paths, *extra], base_dir=base, consented=extra)


def _export_classes(document: dict, catalog, document_classes: bool) -> list[str] | None:
    """COCO/YOLO class names of one document: the catalog's object and passenger classes, or
    None (= the document's labelled types) with ``document_classes`` or without a catalog."""
    import logging

    if catalog is None or document_classes:
        return None
    classes = [*catalog.classes("object"), *catalog.classes("passenger")]
    labelled = {e.get("type", "") for e in document["openlabel"].get("objects", {}).values()
                if any(p.get("type") == "bbox" for p in e.get("object_data_pointers", {}).values())}
    unknown = sorted(labelled - set(classes))
    if unknown:
        logging.getLogger(__name__).warning("labelled types %s are not object classes of the catalog; "
                                            "they are left out (use --document-classes)", unknown)
    return classes


def _load_annotated(out_dir, extra_assets, need_catalog: bool):
    """``(document, catalog or None)`` of one annotated output folder."""
    from pathlib import Path

    from usdscene.converters.openlabel.store import open_annotations
    from usdscene.errors import AssetError

    document = open_annotations(out_dir)
    try:
        return document, load_export_catalog(document, out_dir, extra_assets)
    except AssetError:
        if need_catalog:
            raise
        return document, None


def carried_split(out_dirs) -> tuple:
    """The split rule the annotated documents of ``out_dirs`` carry (``metadata.usdscene.split``,
    :func:`usdscene.document.splits.document_split`), for an export given no rule of its own.

    Returns:
        ``(SplitRule, seed)``, or None when no document carries one.

    Raises:
        OutputError: a folder without annotations. DocumentError: a malformed rule, or two
            documents carrying different rules (naming both folders and rules).
    """
    from pathlib import Path

    from usdscene.converters.openlabel.store import open_annotations
    from usdscene.document import output_layout as layout
    from usdscene.errors import DocumentError, Problem
    from usdscene.document.splits import DOCUMENT_FIELD, document_split

    found = None
    for out in out_dirs:
        path = Path(out) / layout.ANNOTATIONS_FILE
        document = open_annotations(out)
        try:
            carried = document_split(document)
        except DocumentError as exc:
            raise DocumentError([Problem(f"{path}: {p.where}", p.message) for p in exc.problems]) from None
        if carried is None:
            continue
        if found is not None and (found[1].text, found[2]) != (carried[0].text, carried[1]):
            raise DocumentError([Problem(f"{path}: {DOCUMENT_FIELD}",
                                         f"rule {carried[0].text!r} (seed {carried[1]}) differs from "
                                         f"{found[1].text!r} (seed {found[2]}) of {found[0]}; "
                                         "give the dataset's rule with --split")])
        found = found or (str(path), *carried)
    return None if found is None else (found[1], found[2])


@dataclass(frozen=True)
class ExportOptions:
    """How the annotated output(s) are exported, whatever the formats.

    Attributes:
        extra_assets: extra asset catalog folders (classes, place regions).
        document_classes: COCO/YOLO/MOT classes from the document's labelled types, not the
            catalog's.
        copy_images: YOLO and MOT copy images instead of linking them.
        min_roi_px: ROIs: smallest crop side in pixels.
        split: a split rule (text or :class:`usdscene.document.splits.SplitRule`) for COCO and
            YOLO; None writes one COCO file and a YOLO ``data.yaml`` naming every image.
        split_seed: seed of a ``fractions`` split rule.
        min_pixels: COCO/YOLO keep visible labels of at least this many pixels (0: all).
        min_visible_fraction: COCO/YOLO keep labels at least this visible (0: all).
        rle_below_px: COCO segmentation as RLE for objects of fewer pixels (0: polygons only).
        grid: the multi-view ground grid (:class:`usdscene.converters.exports.multiview.GroundGrid`);
            None = the default grid over the annotated positions.
        mot_class_map: MOT: ``CLASS=NUMBER`` items setting a class's MOTChallenge class
            (:func:`usdscene.converters.exports.mot.parse_class_map`).
        mot_static_people: MOT: people standing still get class 7 (static person).
        mot_ignore_occluded: MOT: conf 0 for rows without a visible pixel.
        mot_layout: MOT: ``cameras``, ``mot17`` or ``mot20`` (:data:`usdscene.converters.exports.mot.LAYOUTS`).
        multiview_flavour: multi-view: ``wildtrack``, ``multiviewx`` or ``free``
            (:data:`usdscene.converters.exports.multiview.FLAVOURS`).
    """

    extra_assets: Sequence[str] = ()
    document_classes: bool = False
    copy_images: bool = False
    min_roi_px: int = 8
    split: Any = None
    split_seed: int = 0
    min_pixels: int = 0
    min_visible_fraction: float = 0.0
    rle_below_px: int = 0
    grid: Any = None
    mot_class_map: Sequence[str] = ()
    mot_static_people: bool = False
    mot_ignore_occluded: bool = False
    mot_layout: str = "cameras"
    multiview_flavour: str = "free"
    aicity: Any = None
    """The AI City Challenge scene (:class:`usdscene.converters.exports.aicity.AicOptions`,
    None = its defaults); ``aicity_map`` / ``aicity_videos``: render the map, write the videos."""
    aicity_map: bool = True
    aicity_videos: bool = True
    aicity_map_samples: int | None = None
    aicity_map_cut_m: float = 2.5


def export_formats(out_dir, formats, options: ExportOptions = ExportOptions()) -> dict:
    """Export ``OUT/annotations.openlabel.json`` to each of ``formats``.

    Args:
        out_dir: annotated output folder.
        formats: names of :data:`usdscene.converters.exports.registry.FORMATS`, in order
            (duplicates ignored).
        options: what to export and how (:class:`ExportOptions`).

    Returns:
        format → folder (or file) written.

    Raises:
        OutputError: no annotations yet. AssetError: the catalog cannot be read.
        DocumentError: a bad split rule.
    """
    from pathlib import Path

    from usdscene.converters.exports.registry import FORMATS, ExportJob, format_names, require_needs
    from usdscene.document import output_layout as layout
    from usdscene.errors import OutputError
    from usdscene.files import remove_stale_temporaries

    out = Path(out_dir)
    remove_stale_temporaries(out / layout.EXPORTS_DIR)  # what a killed export left half-written
    names = format_names()
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise OutputError(f"unknown export format {unknown[0]!r}; expected one of {names}", where="exports")
    ordered = list(dict.fromkeys(formats))
    written = {}
    # the document (which can be large) and the catalog are read once for every format
    loaded = _load_annotated(out, options.extra_assets,
                             need_catalog=any(FORMATS[f].catalog for f in ordered) or not options.document_classes)
    require_needs(loaded[0], ordered)  # fail before writing any format
    document, catalog = loaded
    job = ExportJob(document, catalog, out, options,
                    object_classes=lambda: _export_classes(document, catalog, options.document_classes),
                    person_classes=lambda: _person_classes(catalog, options.document_classes),
                    catalog_movers=lambda: _catalog_movers(catalog))
    for name in ordered:  # the formats' own checks, also before writing any format
        FORMATS[name].check_job(job)
    dataset_formats = [f for f in ordered if FORMATS[f].dataset]
    if dataset_formats:
        written.update(export_dataset([out], dataset_formats, out / layout.EXPORTS_DIR, options, loaded=[loaded]))
    for name in names:  # in the registry's order, whatever the order asked for
        if name in ordered and not FORMATS[name].dataset:
            written[name] = FORMATS[name].write(job)
    return {fmt: written[fmt] for fmt in ordered}


def _person_classes(catalog, document_classes: bool):
    """Multi-view tracked classes: the catalog's person and vehicle classes (every mover of
    ``generate tracks`` and the fixed ones of the document), or None (every object with ground
    positions) with ``document_classes`` or without a catalog."""
    if catalog is None or document_classes:
        return None
    people, vehicles = _catalog_movers(catalog)
    return (*people, *vehicles)


def _catalog_movers(catalog) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The catalog's person and vehicle classes (both empty without a catalog)."""
    if catalog is None:
        return (), ()
    from usdscene.generate.motion import person_classes, vehicle_classes

    return tuple(person_classes(catalog)), tuple(vehicle_classes(catalog))


def export_dataset(out_dirs, formats, dataset_dir, options: ExportOptions = ExportOptions(), *,
                   loaded=None) -> dict:
    """Export one COCO/YOLO dataset from one or more annotated output folders.

    Images are ordered by output folder (as given), then frame, then camera; image ids are
    1, 2, ... in that order over the whole dataset, so an image has the same id whichever split
    it falls in, and annotation ids are unique across the dataset too. Classes are the union of
    each folder's classes (sorted), so class ids agree between splits and folders.

    Args:
        out_dirs: annotated output folders (each the output of ``usdscene run`` / ``annotate``).
        formats: ``coco`` and/or ``yolo``.
        dataset_dir: the dataset folder; ``coco/`` and ``yolo/`` are written inside it.
        options: as in :func:`export_formats` (ROIs, MOT and the ground grid do not apply).
        loaded: ``(document, catalog or None)`` of each output folder when the caller has read
            them already; None reads them here.

    Returns:
        format → what was written: ``coco/annotations.json`` without a split, else the
        ``coco`` folder; the ``yolo`` folder.

    Raises:
        OutputError: a folder without annotations, a folder given twice, a format other
            than COCO/YOLO. DocumentError: a bad split rule. AssetError: unreadable catalog.
    """
    import logging
    import os
    from pathlib import Path

    from usdscene.converters.exports.coco import (COCO_DIR, COCO_FILE, LabelFilter, coco_document, coco_entries,
                                                  document_tables)
    from usdscene.converters.openlabel.annotations import LabelIndex, image_records, label_classes
    from usdscene.converters.exports.yolo import TASKS, YOLO_DIR, write_yolo_data_yaml, write_yolo_images
    from usdscene.errors import OutputError
    from usdscene.files import write_json_atomic, write_text_atomic
    from usdscene.document.splits import ImageKey, SplitRule, assign_splits, parse_split, split_counts

    extra_assets, document_classes, copy_images = options.extra_assets, options.document_classes, options.copy_images
    split, split_seed = options.split, options.split_seed
    from usdscene.converters.exports.registry import FORMATS

    bad = [f for f in formats if f not in FORMATS or not FORMATS[f].dataset]
    if bad:
        raise OutputError(f"format {bad[0]!r} cannot be exported as one dataset of several output "
                          "folders; export it per output folder", where="exports")
    outs = [Path(o) for o in out_dirs]
    if not outs:
        raise OutputError("no output folder to export", where="exports")
    resolved = [o.resolve() for o in outs]
    for o, r in zip(outs, resolved):
        if resolved.count(r) > 1:
            raise OutputError(f"output folder {str(o)!r} is given twice", where=str(o))
    dataset = Path(dataset_dir)
    label_filter = LabelFilter(int(options.min_pixels), float(options.min_visible_fraction))
    # file_name and the YOLO image folders are relative to the folder common to every output,
    # so a single output gives exactly the one-folder layout (``images/<camera>/...``).
    base = Path(os.path.commonpath(resolved)) if len(resolved) > 1 else resolved[0]
    prefixes = [r.relative_to(base).as_posix() if r != base else "" for r in resolved]
    sources = [p or r.name for p, r in zip(prefixes, resolved)]

    if loaded is None:
        loaded = [_load_annotated(o, extra_assets, need_catalog=not document_classes) for o in outs]
    names = sorted({n for document, catalog in loaded
                    for n in label_classes(document, _export_classes(document, catalog, document_classes))})
    records = [image_records(document) for document, _ in loaded]
    # Each frame's labels read once for every camera and format.
    label_indexes = [LabelIndex(document) for document, _ in loaded]

    # Global order: folder as given, then frame, then camera (image_records' order).
    items, image_id = [], 0
    for index, (source, recs) in enumerate(zip(sources, records)):
        for record in recs:
            image_id += 1
            items.append((ImageKey(source, record["frame"], record["camera"]), image_id, index, record))

    rule = None
    groups: dict = {None: items}
    if split is not None:
        rule = split if isinstance(split, SplitRule) else parse_split(split)
        aliases = {s: {str(o), o.name, r.name} for s, o, r in zip(sources, outs, resolved)}
        assignment = assign_splits([item[0] for item in items], rule, split_seed, source_aliases=aliases)
        groups = {name: [item for item in items if assignment.get(item[0]) == name] for name in rule.names}
        counts = split_counts(assignment, rule.names)
        for name, count in counts.items():
            if not count["images"]:
                logging.getLogger(__name__).warning("split %r has no image", name)
        write_json_atomic(dataset / "splits.json", {
            "rule": rule.text, "kind": rule.kind, "seed": int(split_seed), "counts": counts,
            "sources": [{"name": s, "folder": p or "."} for s, p in zip(sources, prefixes)],
            "images": [{"source": key.source, "frame": key.frame, "camera": key.camera,
                        "split": assignment[key], "image_id": image_id}
                       for key, image_id, _, _ in items if key in assignment]})

    written = {}
    if "coco" in formats:
        category_ids = {n: k + 1 for k, n in enumerate(names)}
        coco_dir = dataset / COCO_DIR
        image_root = Path(os.path.relpath(base, coco_dir.resolve())).as_posix()
        # Annotation ids are numbered over the whole dataset in image order, like image ids.
        entries, next_id = {}, 1
        tables = [document_tables(document) for document, _ in loaded]  # one pass each, not one per image
        for _, image_id, index, record in items:
            entries[image_id] = coco_entries(loaded[index][0], [record], category_ids, [image_id],
                                             first_annotation_id=next_id, uri_prefix=prefixes[index],
                                             index=label_indexes[index], label_filter=label_filter,
                                             rle_below_px=int(options.rle_below_px), tables=tables[index])
            next_id += len(entries[image_id][1])
        for split_name, members in groups.items():
            images = [e for _, image_id, _, _ in members for e in entries[image_id][0]]
            annotations = [a for _, image_id, _, _ in members for a in entries[image_id][1]]
            info = {} if split_name is None else {"split": split_name}
            target = coco_dir / (COCO_FILE if split_name is None else f"annotations_{split_name}.json")
            write_json_atomic(target, coco_document(images, annotations, names, image_root, **info))
        written["coco"] = coco_dir / COCO_FILE if rule is None else coco_dir
    if "yolo" in formats:
        root = dataset / YOLO_DIR
        class_ids = {n: k for k, n in enumerate(names)}
        lists = {}
        for split_name, members in groups.items():
            paths = []
            for _, _, index, record in members:
                paths += write_yolo_images(loaded[index][0], outs[index], root, [record], class_ids,
                                           prefix=prefixes[index], copy_images=copy_images,
                                           index=label_indexes[index], label_filter=label_filter)
            if split_name is not None:
                # "./" makes Ultralytics resolve each line against the list file's folder
                text = "".join(f"./{p}\n" for p in paths)
                for task in TASKS:
                    write_text_atomic(root / task / f"{split_name}.txt", text)
                lists[split_name] = f"{split_name}.txt"
        write_yolo_data_yaml(root, names, lists if rule is not None else None)
        written["yolo"] = root
    return written
