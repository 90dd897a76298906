"""YOLO (Ultralytics layout) export of an annotated OpenLABEL document. Pure (no pxr, bpy).

Two datasets side by side, because a YOLO label file is found from its image path by
replacing the last ``images`` folder with ``labels``::

    exports/yolo/detect/data.yaml
    exports/yolo/detect/images/<camera>/<frame:06d>.png   link (or copy) of the rendered image
    exports/yolo/detect/labels/<camera>/<frame:06d>.txt   "<class> <cx> <cy> <w> <h>"
    exports/yolo/segment/...                              "<class> <x1> <y1> <x2> <y2> ..."

Values are normalised to [0, 1] by the image width and height, with YOLO's pixel convention
(pixel ``i`` covers ``[i, i + 1)``, so OpenLABEL's pixel-centre coordinates gain 0.5 px).
Class ids are 0, 1, ... in sorted class-name order (:func:`label_classes`). A segmentation line
holds one polygon per object: the parts and holes of the visible region joined by zero-width
bridges. Images without visible objects get an empty label file (a background image).
Fully occluded objects are not exported.
"""

from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from usdscene.converters.exports.coco import KEEP_ALL, LabelFilter, corner_box, object_rings
from usdscene.converters.openlabel.annotations import LabelIndex, image_records, label_classes
from usdscene.document import output_layout as layout
from usdscene.files import write_bytes_atomic, write_text_atomic
from usdscene.labels.image_labels import bridge_rings

log = logging.getLogger(__name__)

YOLO_DIR = "yolo"
TASKS = ("detect", "segment")


def _fmt(values: Iterable[float]) -> str:
    return " ".join(f"{min(1.0, max(0.0, float(v))):.6f}" for v in values)


def yolo_lines(document: dict, frame: int, camera: str, width_px: int, height_px: int,
               class_ids: dict[str, int], index: LabelIndex | None = None,
               label_filter: LabelFilter = KEEP_ALL) -> tuple[list[str], list[str]]:
    """Detection and segmentation label lines of one image (``index``: the document's
    :class:`LabelIndex` when the caller reads many images of it; ``label_filter``: which
    visible labels to keep)."""
    detect, segment = [], []
    scale = np.array([width_px, height_px], dtype=np.float64)
    for label in (index or LabelIndex(document)).labels(frame, camera):
        if label["bbox"] is None or label["type"] not in class_ids or not label_filter.keeps(label):
            continue
        cls = class_ids[label["type"]]
        x, y, w, h = corner_box(label["bbox"])
        detect.append(f"{cls} " + _fmt([(x + w / 2) / width_px, (y + h / 2) / height_px,
                                         w / width_px, h / height_px]))
        rings = object_rings(label["polygons"])
        if rings:
            ring = bridge_rings(rings) + 0.5
        else:
            ring = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])
        if len(ring) < 3:
            ring = np.concatenate([ring, np.repeat(ring[-1:], 3 - len(ring), axis=0)])
        segment.append(f"{cls} " + _fmt((ring / scale).reshape(-1)))
    return detect, segment


def link_or_copy(source: Path, target: Path, copy: bool) -> None:
    """``target`` as a relative symbolic link to ``source`` (a copy with ``copy``, or where the
    file system has no links); its folder is created."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.is_symlink() or target.exists():
        target.unlink()
    if not copy:
        try:
            target.symlink_to(os.path.relpath(source, target.parent))
            return
        except OSError:  # file systems without symlinks
            pass
    shutil.copyfile(source, target)


def write_yolo_images(document: dict, out_dir: str | os.PathLike, root: str | os.PathLike,
                      records: Iterable[dict], class_ids: Mapping[str, int], *, prefix: str = "",
                      link_images: bool = True, copy_images: bool = False,
                      index: LabelIndex | None = None, label_filter: LabelFilter = KEEP_ALL) -> list[str]:
    """Write the label files (and image links) of some images of one document, both tasks.

    Args:
        document: annotated OpenLABEL document.
        out_dir: the output folder holding the document and ``images/``.
        root: the ``yolo`` folder (``<root>/<task>/images|labels/...``).
        records: the images (:func:`image_records` items).
        class_ids: class name → YOLO class id.
        prefix: sub-folder under ``images/`` and ``labels/`` (one per output folder of a
            dataset made of several, so their ``<camera>/<frame>`` names cannot collide).
        link_images: link (relative symlink, copy where impossible) each image into the
            dataset; False writes labels only.
        copy_images: copy the images instead of linking them.
        index: the document's :class:`LabelIndex` when the caller exports many images of it.
        label_filter: which visible labels to keep.

    Returns:
        Each record's image path relative to ``<root>/<task>`` (POSIX, same for both tasks).
    """
    out, root = Path(out_dir), Path(root)
    paths = []
    index = index or LabelIndex(document)
    for record in records:
        detect, segment = yolo_lines(document, record["frame"], record["camera"],
                                     record["width_px"], record["height_px"], class_ids, index,
                                     label_filter)
        stem = Path(prefix) / record["camera"] / Path(record["uri"]).stem
        image = stem.with_suffix(Path(record["uri"]).suffix)
        for task, lines in zip(TASKS, (detect, segment)):
            write_text_atomic(root / task / "labels" / stem.with_suffix(".txt"),
                              "".join(line + "\n" for line in lines))
            if link_images:
                source = out / record["uri"]
                if source.exists():
                    link_or_copy(source, root / task / "images" / image, copy_images)
                else:
                    log.warning("image %s is missing; labels written without it", source)
        paths.append(("images" / image).as_posix())
    return paths


def write_yolo_data_yaml(root: str | os.PathLike, names: list[str],
                         lists: Mapping[str, str] | None = None) -> None:
    """Write ``<root>/<task>/data.yaml`` for both tasks.

    Args:
        root: the ``yolo`` folder.
        names: class names in id order.
        lists: split name → image list file relative to the task folder (``train.txt``);
            None names every image (``images``) for both ``train`` and ``val``.
    """
    root = Path(root)
    if lists is None:
        head = ["# usdscene export: every rendered image; split train/val with usdscene export --split",
                "train: images", "val: images"]
    else:
        head = ["# usdscene export: image lists per split (usdscene export --split)"]
        head += [f"{split}: {_yaml_string(path)}" for split, path in lists.items()]
    for task in TASKS:
        # No "path" key: Ultralytics then resolves train/val against this file's folder.
        yaml = [*head, f"task: {task}", "names:"]
        yaml += [f"  {k}: {_yaml_string(name)}" for k, name in enumerate(names)]
        write_bytes_atomic(root / task / "data.yaml", ("\n".join(yaml) + "\n").encode("utf-8"))


def export_yolo(document: dict, out_dir: str | os.PathLike, classes: Iterable[str] | None = None, *,
                link_images: bool = True, copy_images: bool = False) -> Path:
    """Write the detection and segmentation datasets under ``<out_dir>/exports/yolo``.

    Args:
        document: annotated OpenLABEL document.
        out_dir: the output folder holding the document and ``images/``.
        classes: class names (catalog); None = the labelled types of the document.
        link_images: link (relative symlink, copy where impossible) each image into the
            dataset; False writes labels and ``data.yaml`` only.
        copy_images: copy the images instead of linking them.

    Returns:
        The ``exports/yolo`` folder.
    """
    root = Path(out_dir) / layout.EXPORTS_DIR / YOLO_DIR
    names = label_classes(document, classes)
    write_yolo_images(document, out_dir, root, image_records(document),
                      {name: k for k, name in enumerate(names)},
                      link_images=link_images, copy_images=copy_images)
    write_yolo_data_yaml(root, names)
    return root


def _yaml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'
