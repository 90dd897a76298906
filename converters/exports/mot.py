"""MOTChallenge export of an annotated moving sequence. Pure (no pxr, no bpy).

``OUT/exports/mot/``, one sequence per camera (the layout of MOT17/MOT20 and of the AI City
Challenge's multi-camera tracks, whose frame numbers agree across cameras)::

    mot/<camera>/seqinfo.ini        [Sequence] name, imDir=img1, frameRate, seqLength,
                                    imWidth, imHeight, imExt=.png
    mot/<camera>/img1/000001.png    the rendered images (relative links; copies with copy_images)
    mot/<camera>/gt/gt.txt          frame,id,left,top,width,height,conf,class,visibility
    mot/tracks.json                 the uid → id and class → id tables, the first frame, the rules

* **Frames**: MOT frame = document frame - first labelled frame + 1 (1-based, the same number in
  every camera; gaps in the rendered frames stay gaps), ``seqLength`` = last - first + 1.
* **Track ids** (:func:`usdscene.converters.exports.tracks.track_ids`, the rule every export of usdscene uses): the document's
  objects that are neither lights nor places, ordered by uid (integer uids by value, then other
  uids by text), numbered 1, 2, ... in that order. The uid is the object's identity in every
  camera and frame, so the id is too.
* **Boxes**: the object's whole projection clipped to the image (``<camera>_amodal_bbox``; the
  visible box when no amodal box is known), MOT's 1-based pixel convention: ``left =
  cx - w/2 + 1.5`` for OpenLABEL's ``[cx, cy, w, h]`` with pixel centres at integers (pixel i
  covers [i + 0.5, i + 1.5) in MOT's numbering). Objects that are fully occluded but inside the
  image are kept with visibility 0, as MOT17 keeps them.
* **conf** 1 (every row counts), **class** the 1-based index of the object's class among the
  exported classes sorted by name (``tracks.json`` lists them), **visibility** the visible
  fraction (visible / whole-projection pixels, 0..1).

Labels are those of each frame's instant (``timestamp = frame / fps``; with motion blur, the
shutter's centre). The export needs a document that states its frame rate
(``metadata.usdscene.fps``): a sequence of independent situations has no tracks.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Mapping

from usdscene.document import output_layout as layout
from usdscene.converters.openlabel.annotations import LabelIndex, image_records, label_classes
from usdscene.converters.exports.tracks import ID_RULE, require_tracks, track_ids
from usdscene.converters.exports.yolo import link_or_copy
from usdscene.errors import OutputError
from usdscene.files import dumps_json, staged_folder

MOT_DIR = "mot"


def mot_rows(document: dict, records: Iterable[dict], ids: Mapping[str, int], class_ids: Mapping[str, int],
             first_frame: int, index: LabelIndex | None = None) -> list[str]:
    """``gt.txt`` lines (without newlines) of some images of one camera, in record order."""
    index = index or LabelIndex(document)
    lines = []
    for record in records:
        mot_frame = record["frame"] - first_frame + 1
        for label in index.labels(record["frame"], record["camera"]):
            box = label["amodal_bbox"] or label["bbox"]
            if box is None or label["type"] not in class_ids or label["uid"] not in ids:
                continue
            cx, cy, w, h = (float(v) for v in box)
            visibility = label["attributes"].get("visible_fraction")
            if visibility is None:
                visibility = 1.0 if label["bbox"] is not None else 0.0
            lines.append(f"{mot_frame},{ids[label['uid']]},{_num(cx - w / 2.0 + 1.5)},{_num(cy - h / 2.0 + 1.5)},"
                         f"{_num(w)},{_num(h)},1,{class_ids[label['type']]},{_num(float(visibility))}")
    return lines


def _num(value: float) -> str:
    text = f"{round(value, 4):.4f}".rstrip("0").rstrip(".")
    return text if text not in ("-0", "") else "0"


def export_mot(document: dict, out_dir: str | os.PathLike, *, classes: Iterable[str] | None = None,
               copy_images: bool = False, index: LabelIndex | None = None) -> Path:
    """Write ``<out_dir>/exports/mot/`` (see the module docstring); returns that folder.

    The folder is built beside the old one and replaces it at the end: an interrupted export
    leaves the old folder (or none), never a half-written one.

    Args:
        document: annotated document of a moving sequence.
        out_dir: the output folder holding the document and the images.
        classes: classes to export (sorted for their ids); None = the document's labelled types.
        copy_images: copy the images instead of linking them.
        index: the document's :class:`LabelIndex` when another export reads it too.

    Raises:
        OutputError: the document states no frame rate (no tracks), or has no labelled image.
    """
    fps = require_tracks(document, "MOT")
    records = image_records(document)
    if not records:
        raise OutputError("the document has no labelled image; render and annotate it first",
                          where=str(Path(out_dir) / layout.ANNOTATIONS_FILE))
    names = label_classes(document, classes)
    class_ids = {name: k + 1 for k, name in enumerate(names)}
    ids = track_ids(document)
    first = min(r["frame"] for r in records)
    last = max(r["frame"] for r in records)
    index = index or LabelIndex(document)
    by_camera: dict[str, list[dict]] = {}
    for record in records:
        by_camera.setdefault(record["camera"], []).append(record)
    target = Path(out_dir) / layout.EXPORTS_DIR / MOT_DIR
    with staged_folder(target, what="MOT export folder") as staging:
        for camera, camera_records in sorted(by_camera.items()):
            seq = staging / camera
            (seq / "gt").mkdir(parents=True)
            (seq / "img1").mkdir()
            for record in camera_records:
                link_or_copy((Path(out_dir) / record["uri"]).resolve(),
                             seq / "img1" / f"{record['frame'] - first + 1:06d}.png", copy_images)
            rows = mot_rows(document, camera_records, ids, class_ids, first, index)
            (seq / "gt" / "gt.txt").write_text("".join(f"{row}\n" for row in rows), encoding="utf-8")
            width, height = camera_records[0]["width_px"], camera_records[0]["height_px"]
            (seq / "seqinfo.ini").write_text(
                f"[Sequence]\nname={camera}\nimDir=img1\nframeRate={fps:g}\nseqLength={last - first + 1}\n"
                f"imWidth={width}\nimHeight={height}\nimExt=.png\n", encoding="utf-8")
        (staging / "tracks.json").write_text(dumps_json({
            "id_rule": ID_RULE, "ids": ids, "classes": class_ids, "first_frame": first, "fps": fps,
            "frame_rule": "MOT frame = document frame - first_frame + 1",
            "box": "whole projection clipped to the image (amodal), MOT 1-based pixels: left = cx - w/2 + 1.5",
        }) + "\n", encoding="utf-8")
    return target


def write_mot(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_mot`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    return export_mot(job.document, job.out_dir, classes=job.object_classes(), copy_images=job.options.copy_images,
                      index=job.label_index())
