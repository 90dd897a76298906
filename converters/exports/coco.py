"""COCO export of an annotated OpenLABEL document. Pure (json + numpy).

Reads only the document written by :func:`usdscene.converters.openlabel.annotations.add_annotations`
(never internal state), so any annotated document can be exported.

* One image record per (frame, camera), with the extra fields ``camera`` and ``frame``;
  ``file_name`` is the image uri of the document, relative to the output folder that holds
  the document (``images/<camera>/<frame:06d>.png``); the export records that folder as
  ``info.image_root`` relative to the COCO file.
* Categories: the sorted class names (catalog classes when given), ids 1, 2, ... in that order.
* One annotation per visible object and camera: ``bbox`` ``[x, y, w, h]`` with the top-left
  corner in COCO's pixel convention (pixel ``i`` covers ``[i, i + 1)``: OpenLABEL's centre
  ``cx`` becomes ``x = cx - w / 2 + 0.5``), ``area`` = visible pixel count, ``iscrowd`` 0,
  ``segmentation`` = one polygon per outer contour, its holes joined in by zero-width bridges
  (COCO polygons cannot express holes otherwise), vertices shifted by +0.5 px into COCO's
  convention. The document's polygons lie on the pixel outline (pixel corners), so COCO gets
  integer corners, and pycocotools fills them back to the mask's pixels
  (:mod:`usdscene.labels.pixel_outline`). Objects of fewer than ``rle_below_px`` pixels get
  an uncompressed RLE of those pixels instead (``{"size": [h, w], "counts": [...]}``).
  Extra fields: ``uid``, ``visible_fraction``, ``truncated``, ``amodal_bbox``, and for a moving
  sequence (a document with ``metadata.usdscene.fps``) ``track_id``, the object's id in every
  export (:func:`usdscene.converters.exports.tracks.track_ids`); ``box3d``, the object's 3D
  box in that frame when the document has one (:mod:`usdscene.labels.cuboids`: OpenLABEL's
  10 values ``[x, y, z, qx, qy, qz, qw, sx, sy, sz]``, world metres).
  People (labels with keypoints) also get ``keypoints`` (17 ``x, y, v`` triples in COCO's
  pixel convention, ``0, 0, 0`` where v = 0) and ``num_keypoints`` (v > 0); their category
  gets ``keypoints`` (the COCO-17 names) and ``skeleton``, supercategory ``person``. Every other
  annotation has ``num_keypoints`` 0 and 17 zero triples, so that ``COCOeval(..., "keypoints")``
  runs with its default category list (all) and ignores those objects.
  Fully occluded objects (amodal box only) are not exported, nor are labels that
  :class:`LabelFilter` drops (fewer pixels or a smaller visible fraction than asked).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from usdscene.converters.exports.tracks import document_fps, track_ids
from usdscene.converters.openlabel.annotations import LabelIndex, image_records, label_classes
from usdscene.document import output_layout as layout
from usdscene.files import write_json_atomic
from usdscene.labels.cuboids import document_cuboids
from usdscene.labels.image_labels import bridge_rings
from usdscene.labels.pixel_outline import fill_rings
from usdscene.labels.keypoints import COCO_KEYPOINTS

COCO_DIR = "coco"
COCO_FILE = "annotations.json"


def corner_box(center_size: list[float]) -> list[float]:
    """OpenLABEL ``[cx, cy, w, h]`` (pixel centres at integers) → COCO ``[x, y, w, h]``."""
    cx, cy, w, h = (float(v) for v in center_size)
    return [cx - w / 2.0 + 0.5, cy - h / 2.0 + 0.5, w, h]


@dataclass(frozen=True)
class LabelFilter:
    """Which visible labels a dataset export keeps (COCO, YOLO).

    Attributes:
        min_pixels: smallest visible pixel count kept (0 keeps every label).
        min_visible_fraction: smallest visible fraction kept (0 keeps every label; labels
            without a fraction, computed without geometry, are kept).
    """

    min_pixels: int = 0
    min_visible_fraction: float = 0.0

    def keeps(self, label: dict) -> bool:
        """Whether to export one label of :class:`LabelIndex` (a visible one)."""
        attrs = label["attributes"]
        pixels = attrs.get("pixel_count")
        if pixels is not None and pixels < self.min_pixels:
            return False
        fraction = attrs.get("visible_fraction")
        return fraction is None or fraction >= self.min_visible_fraction


KEEP_ALL = LabelFilter()


def object_rings(polygons: list[dict]) -> list[np.ndarray]:
    """One ring per outer contour, with that contour's holes bridged in; (N, 2) float64 each,
    in the document's pixel-centre convention."""
    rings = []
    for index, poly in enumerate(polygons):
        if poly["is_hole"]:
            continue
        parts = [np.asarray(poly["points"], dtype=np.float64).reshape(-1, 2)]
        parts += [np.asarray(h["points"], dtype=np.float64).reshape(-1, 2)
                  for h in polygons if h["is_hole"] and h["parent"] == index]
        rings.append(bridge_rings(parts))
    return rings


def _coco_polygon(ring: np.ndarray) -> list[float]:
    pts = ring + 0.5
    if len(pts) < 3:  # single pixels and 1-px lines: pycocotools needs >= 3 vertices
        pts = np.concatenate([pts, np.repeat(pts[-1:], 3 - len(pts), axis=0)])
    return [round(float(v), 3) for v in pts.reshape(-1)]


def _rle(rings: list[np.ndarray], width_px: int, height_px: int) -> dict:
    """Uncompressed COCO RLE (column-major runs, starting with background) of the pixels
    whose centres the rings enclose (document convention)."""
    filled = fill_rings(rings, (height_px, width_px)).T.reshape(-1)
    edges = np.flatnonzero(np.diff(filled.astype(np.int8))) + 1
    bounds = np.concatenate([[0], edges, [filled.size]])
    counts = np.diff(bounds).tolist()
    if filled[0]:
        counts = [0] + counts
    return {"size": [int(height_px), int(width_px)], "counts": [int(c) for c in counts]}


def document_tables(document: dict) -> tuple:
    """``(track ids or None, 3D boxes)`` of a document, as :func:`coco_entries` reads them:
    each is a pass over every frame, so a caller exporting one image at a time reads them once."""
    # Only moving sequences carry track ids: the COCO files of other documents keep their bytes.
    return (track_ids(document) if document_fps(document) is not None else None), document_cuboids(document)


def coco_entries(document: dict, records: Iterable[dict], category_ids: Mapping[str, int],
                 image_ids: Iterable[int], first_annotation_id: int = 1,
                 uri_prefix: str = "", index: LabelIndex | None = None,
                 label_filter: LabelFilter = KEEP_ALL, rle_below_px: int = 0,
                 tables: tuple | None = None) -> tuple[list[dict], list[dict]]:
    """COCO image and annotation records of some images of one document.

    Args:
        document: annotated document.
        records: its images (:func:`image_records` items), in the order to write.
        category_ids: class name → COCO category id; labels of other types are left out.
        image_ids: one id per record (ids unique across the documents of a dataset).
        first_annotation_id: id of the first annotation written, then +1 each.
        uri_prefix: prepended (``prefix/uri``) to each image uri for ``file_name``, so images
            of several output folders can share one ``image_root``.
        index: the document's :class:`LabelIndex` when the caller exports many images of it.
        label_filter: which visible labels to keep.
        rle_below_px: objects with fewer visible pixels get an RLE segmentation (0: never).
        tables: :func:`document_tables` of the document when the caller has them.

    Returns:
        ``(images, annotations)`` lists of COCO dicts.
    """
    images, annotations = [], []
    index = index or LabelIndex(document)
    tracks, boxes3d = tables if tables is not None else document_tables(document)
    for image_id, record in zip(image_ids, records):
        file_name = f"{uri_prefix}/{record['uri']}" if uri_prefix else record["uri"]
        images.append({"id": image_id, "file_name": file_name, "width": record["width_px"],
                       "height": record["height_px"], "camera": record["camera"],
                       "frame": record["frame"]})
        for label in index.labels(record["frame"], record["camera"]):
            if label["bbox"] is None or label["type"] not in category_ids or not label_filter.keeps(label):
                continue
            attrs = label["attributes"]
            rings = object_rings(label["polygons"])
            if rings and attrs.get("pixel_count", rle_below_px) < rle_below_px:
                segmentation = _rle(rings, record["width_px"], record["height_px"])
            elif rings:
                segmentation = [_coco_polygon(r) for r in rings]
            else:  # no polygon stored: the box outline
                x, y, w, h = corner_box(label["bbox"])
                segmentation = [[x, y, x + w, y, x + w, y + h, x, y + h]]
            annotations.append({
                "id": first_annotation_id + len(annotations), "image_id": image_id,
                "category_id": category_ids[label["type"]],
                "bbox": corner_box(label["bbox"]),
                "area": float(attrs.get("pixel_count", label["bbox"][2] * label["bbox"][3])),
                "segmentation": segmentation, "iscrowd": 0,
                "uid": label["uid"],
                "visible_fraction": attrs.get("visible_fraction"),
                "truncated": bool(attrs.get("truncated", False)),
                "amodal_bbox": corner_box(label["amodal_bbox"]) if label["amodal_bbox"] else None,
            })
            if tracks is not None and label["uid"] in tracks:
                annotations[-1]["track_id"] = tracks[label["uid"]]
            box3d = boxes3d.get(int(record["frame"]), {}).get(label["uid"])
            if box3d is not None:
                annotations[-1]["box3d"] = box3d.openlabel_val()
            if label.get("keypoints") is not None:
                # COCO's pixel convention (+0.5); x = y = 0 where v = 0.
                flat: list[float] = []
                for x, y, v in label["keypoints"]:
                    flat += [x + 0.5, y + 0.5, v] if v else [0, 0, 0]
                annotations[-1]["keypoints"] = flat
                annotations[-1]["num_keypoints"] = sum(1 for _, _, v in label["keypoints"] if v > 0)
            else:
                # COCOeval("keypoints") reads both fields of every annotation of every category
                # it evaluates (its default: all); num_keypoints 0 makes it ignore the object.
                annotations[-1]["keypoints"] = [0] * (3 * len(COCO_KEYPOINTS))
                annotations[-1]["num_keypoints"] = 0
    return images, annotations


def coco_document(images: list[dict], annotations: list[dict], names: list[str],
                  image_root: str = "../..", **info) -> dict:
    """The COCO dict from its records; categories are ``names`` with ids 1, 2, ...

    Args:
        image_root: folder that ``file_name`` is relative to, relative to the COCO file.
        info: extra ``info`` fields (e.g. ``split``).
    """
    return {
        "info": {"description": "usdscene export", "image_root": image_root,
                 "bbox": "[x, y, w, h], top-left corner, pixel i covers [i, i + 1)", **info},
        "images": images,
        "annotations": annotations,
        "categories": [_category(k + 1, n, {a["category_id"] for a in annotations if a.get("num_keypoints")})
                       for k, n in enumerate(names)],
    }


def _category(category_id: int, name: str, with_keypoints: set[int]) -> dict:
    """A COCO category; person-like ones (with an annotation of at least one labelled keypoint)
    name the 17 keypoints and COCO's skeleton."""
    out = {"id": category_id, "name": name, "supercategory": "object"}
    if category_id in with_keypoints:
        from usdscene.labels.keypoints import COCO_SKELETON

        out.update(supercategory="person", keypoints=list(COCO_KEYPOINTS), skeleton=[list(p) for p in COCO_SKELETON])
    return out


def coco_dataset(document: dict, classes: Iterable[str] | None = None, *,
                 label_filter: LabelFilter = KEEP_ALL, rle_below_px: int = 0) -> dict:
    """The COCO dict (``info``, ``images``, ``annotations``, ``categories``) of a document
    (``label_filter``, ``rle_below_px``: as in :func:`coco_entries`)."""
    names = label_classes(document, classes)
    category_ids = {name: k + 1 for k, name in enumerate(names)}
    records = image_records(document)
    images, annotations = coco_entries(document, records, category_ids, range(1, len(records) + 1),
                                       label_filter=label_filter, rle_below_px=rle_below_px)
    return coco_document(images, annotations, names)


def export_coco(document: dict, out_dir: str | os.PathLike,
                classes: Iterable[str] | None = None, *, label_filter: LabelFilter = KEEP_ALL,
                rle_below_px: int = 0) -> Path:
    """Write ``<out_dir>/exports/coco/annotations.json`` atomically; returns its path.

    ``file_name`` of each image is relative to ``out_dir`` (``info.image_root`` = ``"../.."``
    relative to the COCO file).
    """
    target = Path(out_dir) / layout.EXPORTS_DIR / COCO_DIR / COCO_FILE
    return write_json_atomic(target, coco_dataset(document, classes, label_filter=label_filter,
                                                  rle_below_px=rle_below_px))
