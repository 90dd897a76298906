"""MOTChallenge export of an annotated moving sequence. Pure (no pxr, no bpy).

``OUT/exports/mot/``, one sequence per camera (the layout of MOT17/MOT20 and of the AI City
Challenge's multi-camera tracks, whose frame numbers agree across cameras)::

    mot/<camera>/seqinfo.ini        [Sequence] name, imDir=img1, frameRate, seqLength,
                                    imWidth, imHeight, imExt=.png
    mot/<camera>/img1/000001.png    the rendered images (relative links; copies with copy_images)
    mot/<camera>/gt/gt.txt          frame,id,left,top,width,height,conf,class,visibility
    mot/tracks.json                 the uid → id and class → MOT class tables, the first frame,
                                    the sequence → camera table, the rules

With ``layout_name="mot17"`` or ``"mot20"`` the sequences are laid out as TrackEval's
``MotChallenge2DBox`` reads a benchmark (``BENCHMARK=MOT17|MOT20``, ``SPLIT_TO_EVAL=train``,
``GT_FOLDER=mot``)::

    mot/MOT20-train/MOT20-01/{seqinfo.ini,img1/,gt/gt.txt}   one sequence per camera, numbered
                                    01, 02, ... in camera name order (``tracks.json`` says which)
    mot/seqmaps/MOT20-train.txt     ``name`` then one sequence name a line

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
* **class** MOTChallenge's ground-truth class numbers (:data:`MOT_CLASSES`: 1 pedestrian,
  3 car, 7 static person ...): people (the catalog's person classes) are 1, or 7 for a person
  that stands still when asked (``static_people``: its ground position moves less than
  :data:`STILL_M` over the sequence, or it is a fixed object of the document); vehicles (the
  catalog's vehicle classes) are 3; ``class_map`` sets the number of any class (or leaves it
  out). A class with no MOT number is left out, never given one of its own (``tracks.json``
  lists those left out).
* **conf** MOT17's ignore flag: 1 for every row, 0 for rows without a visible pixel when
  ``ignore_occluded`` is asked (TrackEval then neither rewards nor punishes tracking them).
* **visibility** the visible fraction (visible / whole-projection pixels, 0..1).

Labels are those of each frame's instant (``timestamp = frame / fps``; with motion blur, the
shutter's centre). The export needs a document that states its frame rate
(``metadata.usdscene.fps``): a sequence of independent situations has no tracks.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from usdscene.document import output_layout as layout
from usdscene.converters.openlabel.annotations import LabelIndex, image_records, label_classes
from usdscene.converters.exports.tracks import ID_RULE, ground_positions, require_tracks, track_ids
from usdscene.converters.exports.yolo import link_or_copy
from usdscene.errors import OutputError, Problem
from usdscene.files import dumps_json, staged_folder

log = logging.getLogger(__name__)

MOT_DIR = "mot"
MOT_CLASSES = {1: "pedestrian", 2: "person_on_vehicle", 3: "car", 4: "bicycle", 5: "motorbike",
               6: "non_mot_vehicle", 7: "static_person", 8: "distractor", 9: "occluder",
               10: "occluder_on_ground", 11: "occluder_full", 12: "reflection", 13: "crowd"}
"""MOTChallenge's ground-truth classes (MOT16/17/20), number → TrackEval's name."""
PEDESTRIAN, CAR, STATIC_PERSON = 1, 3, 7
STILL_M = 0.2
"""A person whose ground position spans less than this (metres) over the sequence stands still."""
LAYOUTS = ("cameras", "mot17", "mot20")
"""``cameras``: ``mot/<camera>/``; ``mot17``/``mot20``: a TrackEval benchmark tree."""
MAPPING_OPTION = "--mot-class"


@dataclass(frozen=True)
class MotClasses:
    """Which MOT class number each document class gets (see the module docstring).

    Attributes:
        people: the classes of people (pedestrian, 1).
        vehicles: the classes of vehicles (car, 3).
        class_map: class → MOT number (1..13), or None to leave the class out; wins over the
            two lists.
        static_people: people that stand still get 7 (static person) instead of 1.
    """

    people: tuple[str, ...] = ()
    vehicles: tuple[str, ...] = ()
    class_map: Mapping[str, int | None] = field(default_factory=dict)
    static_people: bool = False

    def number(self, class_name: str, still: bool) -> int | None:
        """The MOT class of an object of ``class_name`` (``still``: it stands still), None = left out."""
        if class_name in self.class_map:
            number = self.class_map[class_name]
        elif class_name in self.people:
            number = PEDESTRIAN
        elif class_name in self.vehicles:
            number = CAR
        else:
            return None
        if number == PEDESTRIAN and still and self.static_people:
            return STATIC_PERSON
        return number


def parse_class_map(items: Iterable[str], known: Iterable[str], option: str = MAPPING_OPTION) -> dict[str, int | None]:
    """``CLASS=NUMBER`` / ``CLASS=NAME`` / ``CLASS=none`` items → class → MOT number (None: left out).

    NUMBER is one of :data:`MOT_CLASSES` (1..13), NAME its TrackEval name (``car``,
    ``static_person`` ...).

    Raises:
        OutputError: an item without ``=``, a class not among ``known``, or a number or name MOT
            does not have (one problem naming ``option`` and the value).
    """
    known = set(known)
    names = {name: number for number, name in MOT_CLASSES.items()}
    out: dict[str, int | None] = {}
    for item in items:
        cls, sep, value = str(item).partition("=")
        if not sep or not cls:
            raise OutputError([Problem(option, f"{item!r} is not CLASS=NUMBER (e.g. bicycle=4, or CLASS=none)")])
        if cls not in known:
            raise OutputError([Problem(option, f"unknown class {cls!r} in {item!r}; the classes are "
                                               f"{', '.join(sorted(known)) or '(none)'}")])
        value = value.strip().lower()
        if value == "none":
            out[cls] = None
        elif value.isdigit() and int(value) in MOT_CLASSES:
            out[cls] = int(value)
        elif value in names:
            out[cls] = names[value]
        else:
            raise OutputError([Problem(option, f"{value!r} in {item!r} is no MOTChallenge class; expected "
                                               f"none or one of 1..13 ({', '.join(MOT_CLASSES.values())})")])
    return out


def still_objects(document: dict) -> set[str]:
    """uids of the tracked objects that stand still: ground positions spanning less than
    :data:`STILL_M`, or none at all (fixed objects of the document)."""
    spans: dict[str, list[np.ndarray]] = {}
    for by_uid in ground_positions(document).values():
        for uid, p in by_uid.items():
            spans.setdefault(uid, []).append(p[:2])
    moving = {uid for uid, points in spans.items() if np.ptp(np.asarray(points), axis=0).max() >= STILL_M}
    return set(track_ids(document)) - moving


def sequence_names(cameras: Iterable[str], layout_name: str) -> dict[str, str]:
    """camera → the folder of its sequence under ``mot/`` (see the module docstring)."""
    cameras = sorted(cameras)
    if layout_name == "cameras":
        return {c: c for c in cameras}
    bench = layout_name.upper()
    return {c: f"{bench}-train/{bench}-{k + 1:02d}" for k, c in enumerate(cameras)}


def mot_rows(document: dict, records: Iterable[dict], ids: Mapping[str, int], classes: Mapping[str, int],
             first_frame: int, index: LabelIndex | None = None, *, ignore_occluded: bool = False) -> list[str]:
    """``gt.txt`` lines (without newlines) of some images of one camera, in record order.

    Args:
        ids: uid → track id. classes: uid → MOT class number (objects not in it are left out).
        ignore_occluded: conf 0 for rows without a visible pixel.
    """
    index = index or LabelIndex(document)
    lines = []
    for record in records:
        mot_frame = record["frame"] - first_frame + 1
        for label in index.held_labels(record["frame"], record["camera"]):
            box = label["amodal_bbox"] or label["bbox"]
            if box is None or label["uid"] not in classes or label["uid"] not in ids:
                continue
            cx, cy, w, h = (float(v) for v in box)
            visibility = label["attributes"].get("visible_fraction")
            if visibility is None:
                visibility = 1.0 if label["bbox"] is not None else 0.0
            conf = 0 if ignore_occluded and label["bbox"] is None else 1
            lines.append(f"{mot_frame},{ids[label['uid']]},{_num(cx - w / 2.0 + 1.5)},{_num(cy - h / 2.0 + 1.5)},"
                         f"{_num(w)},{_num(h)},{conf},{classes[label['uid']]},{_num(float(visibility))}")
    return lines


def _num(value: float) -> str:
    text = f"{round(value, 4):.4f}".rstrip("0").rstrip(".")
    return text if text not in ("-0", "") else "0"


def export_mot(document: dict, out_dir: str | os.PathLike, *, classes: Iterable[str] | None = None,
               mot_classes: MotClasses = MotClasses(), ignore_occluded: bool = False, layout_name: str = "cameras",
               copy_images: bool = False, index: LabelIndex | None = None) -> Path:
    """Write ``<out_dir>/exports/mot/`` (see the module docstring); returns that folder.

    The folder is built beside the old one and replaces it at the end: an interrupted export
    leaves the old folder (or none), never a half-written one.

    Args:
        document: annotated document of a moving sequence.
        out_dir: the output folder holding the document and the images.
        classes: classes that may be exported; None = the document's labelled types.
        mot_classes: the MOT class number of each class (:class:`MotClasses`).
        ignore_occluded: conf 0 (MOT17's "ignore") for rows without a visible pixel.
        layout_name: one of :data:`LAYOUTS`.
        copy_images: copy the images instead of linking them.
        index: the document's :class:`LabelIndex` when another export reads it too.

    Raises:
        OutputError: the document states no frame rate (no tracks), has no labelled image, an
            unknown layout, or no exported class has a MOT number.
    """
    check_layout(layout_name)
    fps = require_tracks(document, "MOT")
    records = image_records(document)
    if not records:
        raise OutputError("the document has no labelled image; render and annotate it first",
                          where=str(Path(out_dir) / layout.ANNOTATIONS_FILE))
    names = label_classes(document, classes)
    # a pass over every frame, read only when static people get their own class
    still = still_objects(document) if mot_classes.static_people else set()
    objects = document["openlabel"].get("objects", {}) or {}
    ids = track_ids(document)
    numbers = {name: mot_classes.number(name, False) for name in names}
    present = {(objects.get(uid) or {}).get("type") for uid in ids}
    left_out = sorted(name for name, number in numbers.items() if number is None and name in present)
    if not any(number is not None for number in numbers.values()):
        raise OutputError([Problem(MAPPING_OPTION, f"no exported class has a MOTChallenge number (classes "
                                                   f"{', '.join(names) or '(none)'}); map one, e.g. "
                                                   f"{MAPPING_OPTION} {names[0] if names else 'CLASS'}=1")])
    if left_out:
        log.warning("classes %s have no MOTChallenge number and are left out of the MOT export (map them "
                    "with %s CLASS=NUMBER)", left_out, MAPPING_OPTION)
    uid_classes = {}
    for uid in ids:
        name = (objects.get(uid) or {}).get("type")
        number = mot_classes.number(name, uid in still) if name in numbers else None
        if number is not None:
            uid_classes[uid] = number
    first = min(r["frame"] for r in records)
    last = max(r["frame"] for r in records)
    index = index or LabelIndex(document)
    by_camera: dict[str, list[dict]] = {}
    for record in records:
        by_camera.setdefault(record["camera"], []).append(record)
    sequences = sequence_names(by_camera, layout_name)
    # Frame by frame (the records' order), every camera's rows at once: the index keeps a few
    # frames, so a pass per camera would read every frame's labels once per camera.
    camera_rows: dict[str, list[str]] = {camera: [] for camera in by_camera}
    for record in records:
        camera_rows[record["camera"]].extend(
            mot_rows(document, (record,), ids, uid_classes, first, index, ignore_occluded=ignore_occluded))
    target = Path(out_dir) / layout.EXPORTS_DIR / MOT_DIR
    with staged_folder(target, what="MOT export folder") as staging:
        for camera, camera_records in sorted(by_camera.items()):
            seq = staging / sequences[camera]
            (seq / "gt").mkdir(parents=True)
            (seq / "img1").mkdir()
            for record in camera_records:
                link_or_copy((Path(out_dir) / record["uri"]).resolve(),
                             seq / "img1" / f"{record['frame'] - first + 1:06d}.png", copy_images)
            (seq / "gt" / "gt.txt").write_text("".join(f"{row}\n" for row in camera_rows[camera]), encoding="utf-8")
            width, height = camera_records[0]["width_px"], camera_records[0]["height_px"]
            (seq / "seqinfo.ini").write_text(
                f"[Sequence]\nname={Path(sequences[camera]).name}\nimDir=img1\nframeRate={fps:g}\n"
                f"seqLength={last - first + 1}\nimWidth={width}\nimHeight={height}\nimExt=.png\n", encoding="utf-8")
        if layout_name != "cameras":
            bench = layout_name.upper()
            (staging / "seqmaps").mkdir()
            (staging / "seqmaps" / f"{bench}-train.txt").write_text(
                "name\n" + "".join(f"{Path(sequences[c]).name}\n" for c in sorted(by_camera)), encoding="utf-8")
        (staging / "tracks.json").write_text(dumps_json({
            "id_rule": ID_RULE, "ids": ids,
            "classes": {name: number for name, number in numbers.items() if number is not None},
            "static_person": sorted((u for u, n in uid_classes.items() if n == STATIC_PERSON), key=ids.get),
            "left_out_classes": left_out, "mot_classes": {str(k): v for k, v in MOT_CLASSES.items()},
            "sequences": {sequences[c]: c for c in sorted(by_camera)},
            "first_frame": first, "fps": fps,
            "frame_rule": "MOT frame = document frame - first_frame + 1",
            "conf": "0: ignore (no visible pixel)" if ignore_occluded else "1: every row counts",
            "box": "whole projection clipped to the image (amodal), MOT 1-based pixels: left = cx - w/2 + 1.5",
        }) + "\n", encoding="utf-8")
    return target


def job_mot_classes(job) -> MotClasses:
    """The :class:`MotClasses` of an export job: people and vehicles are the catalog's person
    and vehicle classes (none without a catalog, where only ``mot_class_map`` names MOT
    classes); a mapping item's class is known when the catalog has it or the document has an
    object of it.

    Raises:
        OutputError: a mapping item naming an unknown class or no MOT class.
    """
    document = job.document
    known = {(o or {}).get("type") for o in (document["openlabel"].get("objects", {}) or {}).values()} - {None}
    if job.catalog is not None:
        known |= set(job.catalog.classes())
    people, vehicles = job.catalog_movers()
    return MotClasses(people=tuple(people), vehicles=tuple(vehicles),
                      class_map=parse_class_map(job.options.mot_class_map, known),
                      static_people=job.options.mot_static_people)


def check_mot(job) -> None:
    """The registry's check: the class mapping and the layout, before anything is written."""
    job_mot_classes(job)
    check_layout(job.options.mot_layout)


def check_layout(layout_name: str) -> None:
    """Refuse a layout that is not one of :data:`LAYOUTS` (``OutputError`` naming ``--mot-layout``)."""
    if layout_name not in LAYOUTS:
        raise OutputError([Problem("--mot-layout", f"unknown layout {layout_name!r}; expected one of "
                                                   f"{', '.join(LAYOUTS)}")])


def write_mot(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_mot`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    options = job.options
    return export_mot(job.document, job.out_dir, classes=job.object_classes(), mot_classes=job_mot_classes(job),
                      ignore_occluded=options.mot_ignore_occluded, layout_name=options.mot_layout,
                      copy_images=options.copy_images, index=job.label_index())
