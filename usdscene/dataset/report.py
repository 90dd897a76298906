"""The browsable report of an output folder: ``OUT/report/index.html``.

A static page that opens from ``file://`` with no server and no network. Chromium refuses
``fetch()`` of ``file://`` URLs, so the data travel as JavaScript files that the page loads with
``<script>`` elements::

    report/index.html, report.js, report.css   the page (package data usdscene/data/report/)
    report/data/index.js        every image's frame, camera, thumbnail kind and label codes
                                (class, visibility bin, visible or hidden): enough to filter,
                                count and draw the grid; loaded at once
    report/data/labels_<k>.js   full labels (boxes, amodal boxes, polygons, visibility,
                                relation text, keypoints) of images k·PAGE_IMAGES ... in
                                (frame, camera) order; loaded when an image of the page is opened
    report/thumbs/<camera>/<frame:06d>.jpg   THUMB_WIDTH_PX wide, for images wider than
                                THUMB_ABOVE_PX (smaller ones: the page shows the image itself)
    report/tints/<camera>/<frame:06d>.png    the instance mask as 8-bit colour indices
                                (:func:`usdscene.dataset.report_pictures.tint_indices`), coloured by the page; none for an
                                image labelled with no objects
    report/balance.png          the balance chart of a generated document (``DOC.report.json``)
    report/coverage.png         the plan picture when the document sits in a camera-plan folder

A page cannot read the pixels of a ``file://`` image (the canvas is tainted) and browsers show
16-bit PNGs as 8 bits, hence the tints: an SVG filter of the page maps their indices to colours. Thumbnails and tints are kept between builds: one is redrawn only when
its image or mask is newer. They are written by replacing a temporary file, without fsync: a
lost one is only redrawn.

Labels come from the annotation store ``OUT/annotations/``, read frame range by frame range
(or ``OUT/annotations.openlabel.json``: :func:`usdscene.converters.openlabel.store.open_annotations`).
In a half-finished run (no annotations yet) they come from the labels kept per image in ``OUT/labels/`` (see
:class:`usdscene.dataset.annotation.ImageLabeller`), and images rendered but not yet labelled are shown
without labels.

Keypoints are read from ``point2d`` object data named ``<camera>_kp_<joint>``
(:func:`usdscene.converters.openlabel.annotations.keypoint_name`) with an optional ``num``
attribute ``visibility`` (COCO flags: 0 outside, 1 occluded, 2 visible).
The track id an object shows is the one of every export (:func:`usdscene.converters.exports.tracks.track_ids`:
MOT, COCO ``track_id``, multi-view); images of a half-finished run, which have no document yet,
show the object's uid instead.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path

from usdscene.converters.openlabel.annotations import KEYPOINT_INFIX
from usdscene.dataset.statistics import HISTOGRAM_BINS
from usdscene.dataset.report_pictures import REPORT_DIR, PictureDrawing, fill_sizes
from usdscene.document import output_layout as layout

log = logging.getLogger(__name__)

INDEX_FILE = "index.html"
DATA_DIR = "data"
PAGE_IMAGES = 250
UNKNOWN_BIN = HISTOGRAM_BINS
_STATIC_FILES = ("index.html", "report.js", "report.css")


@dataclass(frozen=True)
class ReportSummary:
    """What :func:`build_report` wrote.

    Attributes:
        index: the page (``REPORT_DIR/index.html``).
        images: images in the report.
        labels: labels (object × camera × frame, visible or fully occluded) in the report.
        labelled_images: images with labels known (all of them unless half-finished).
        complete: the labels come from the annotations document (False: a half-finished run).
        pictures_drawn: thumbnails and tints drawn by this build (the rest were kept).
        seconds: wall seconds of the build.
    """

    index: Path
    images: int
    labels: int
    labelled_images: int
    complete: bool
    pictures_drawn: int
    seconds: float

    def note(self) -> str:
        """One line for people: what the report holds, and what is missing from a half-finished run."""
        return _note(self.complete, self.images, self.labels, self.labelled_images)


def _note(complete: bool, images: int, labels: int, labelled_images: int) -> str:
    if complete:
        return f"{images} images, {labels} labels"
    return (f"half-finished run: no annotations ({layout.ANNOTATION_STORE_DIR}/) yet; the report shows the "
            f"{images} images rendered so far, {labelled_images} of them labelled")


def build_report(out_dir: str | os.PathLike, report_dir: str | os.PathLike | None = None, *,
                 document: str | os.PathLike | None = None, coverage_map: str | os.PathLike | None = None,
                 workers: int | None = None) -> ReportSummary:
    """Write the browsable report of an output folder.

    Args:
        out_dir: output folder of ``usdscene run`` (or of render + annotate).
        report_dir: where the report goes (default ``out_dir/report``).
        document: the scene document of the run, for the balance chart of its
            ``DOC.report.json`` when it was generated (see :func:`run_document`).
        coverage_map: the plan picture of the camera plan the document comes from
            (``usdscene.design.camera_design.plan_picture_for``), shown beside the labels.
        workers: threads drawing thumbnails and tints (default: the CPU count).

    Returns:
        :class:`ReportSummary`.

    Raises:
        OutputError: no annotations, kept labels or images in ``out_dir``; an unreadable
            annotations document; the report cannot be written.
    """
    from usdscene.errors import OutputError
    from usdscene.files import make_folder

    start = time.perf_counter()
    out = Path(out_dir)
    target = Path(report_dir) if report_dir is not None else out / REPORT_DIR
    if not out.is_dir():
        raise OutputError("not a folder" if out.exists() else "no such output folder", where=str(out))
    from usdscene.converters.openlabel.store import annotations_source

    source, annotations = annotations_source(out)
    if source is not None:
        images, title = _images_from_document(out, annotations, source), _document_title(annotations)
        complete = True
    else:
        images, title, complete = _images_from_kept_labels(out), out.name, False
        if not images:
            raise OutputError(f"no {layout.ANNOTATIONS_FILE}, no labels and no images: nothing to report; "
                              "run `usdscene run DOC -o OUT` first", where=str(out))
    make_folder(target, what="report folder")
    fill_sizes(out, images)
    # The pictures are drawn by threads while this one writes the label pages: decoding,
    # encoding and file writes release the interpreter lock, the pages' JSON holds it.
    pictures = PictureDrawing(out, target, images, workers)
    try:
        return _write_report(out, target, images, title, complete, pictures, document, coverage_map, start)
    finally:
        pictures.close()


def _write_report(out: Path, target: Path, images: list[dict], title: str, complete: bool,
                  pictures: PictureDrawing, document, coverage_map, start: float) -> ReportSummary:
    """The data and page files of :func:`build_report`, written while ``pictures`` are drawn."""
    from usdscene.files import write_text_atomic

    cameras = sorted({im["camera"] for im in images})
    classes = sorted({o["class"] for im in images for o in im["objects"]})
    frames = sorted({im["frame"] for im in images})
    camera_index = {c: k for k, c in enumerate(cameras)}
    class_index = {c: k for k, c in enumerate(classes)}
    frame_index = {f: k for k, f in enumerate(frames)}
    pages = [images[k:k + PAGE_IMAGES] for k in range(0, len(images), PAGE_IMAGES)]
    for k, page in enumerate(pages):
        write_text_atomic(target / DATA_DIR / f"labels_{k:05d}.js",
                          f"usdsceneReportPage({k},{_js_json([_page_entry(im, class_index) for im in page])});\n")
    extras = _extra_pictures(target, document, coverage_map)
    drawn, thumbs = pictures.results()
    index = {
        "title": title, "complete": complete,
        "note": None if complete else _note(False, len(images), 0, sum(1 for im in images if im["labelled"])),
        "cameras": cameras, "classes": classes, "frames": frames,
        "pageImages": PAGE_IMAGES, "pages": len(pages), "histogramBins": HISTOGRAM_BINS,
        "imageRoot": _relative(out, target),
        "pictures": extras,
        # Parallel columns, one entry per image in (frame, camera) order.
        "frame": [frame_index[im["frame"]] for im in images],
        "camera": [camera_index[im["camera"]] for im in images],
        "thumb": [thumbs[k] for k in range(len(images))],
        "labelled": [1 if im["labelled"] else 0 for im in images],
        "codes": [[_label_code(o, class_index) for o in im["objects"]] for im in images],
    }
    write_text_atomic(target / DATA_DIR / "index.js", f"usdsceneReportIndex({_js_json(index)});\n")
    _remove_stale_pages(target / DATA_DIR, len(pages))
    static = _static_folder()
    for name in _STATIC_FILES:
        write_text_atomic(target / name, (static / name).read_text(encoding="utf-8"))
    return ReportSummary(index=target / INDEX_FILE, images=len(images),
                         labels=sum(len(im["objects"]) for im in images),
                         labelled_images=sum(1 for im in images if im["labelled"]), complete=complete,
                         pictures_drawn=drawn, seconds=time.perf_counter() - start)


def _static_folder() -> Path:
    from usdscene.shipped import shipped_data_file

    return shipped_data_file("report")


def _js_json(value) -> str:
    import json

    # "</" inside a string would end an inline script; the files are loaded by src, but a page
    # saved with its data inlined stays safe.
    return json.dumps(value, ensure_ascii=False, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")


def _relative(path: Path, start: Path) -> str:
    return Path(os.path.relpath(path.resolve(), start.resolve())).as_posix()


def _label_code(obj: dict, class_index: dict[str, int]) -> int:
    """One label as an integer: ``(class · (BINS + 1) + visibility bin) · 2 + visible``; the
    bin of an unknown visible fraction is ``BINS``."""
    fraction = obj["visible_fraction"]
    bin_ = UNKNOWN_BIN if fraction is None else min(HISTOGRAM_BINS - 1, int(float(fraction) * HISTOGRAM_BINS))
    return (class_index[obj["class"]] * (HISTOGRAM_BINS + 1) + bin_) * 2 + (1 if obj["box"] is not None else 0)


def _document_title(path: Path) -> str:
    """The scene name of an annotated document, read from its first bytes (the metadata comes
    first in documents usdscene writes), else the folder name."""
    import re

    with open(path, "rb") as handle:
        head = handle.read(4096).decode("utf-8", "replace")
    found = re.search(r'"name"\s*:\s*"([^"\\]{1,200})"', head)
    return found.group(1) if found else path.parent.name


def _images_from_document(out: Path, path: Path, source: str = "document") -> list[dict]:
    """Every labelled image of the annotations with its labels (see :func:`_image`): the
    document at ``path``, or for ``source`` ``"store"`` the store whose static part it is."""
    import json

    from usdscene.converters.exports.tracks import track_ids
    from usdscene.converters.openlabel.annotations import (RESOLVED_PLACE, RESOLVED_RELATION, LabelIndex,
                                                           image_records)

    from usdscene.errors import OutputError

    # A document usdscene wrote: the plain reader (the checking reader of input documents,
    # with its duplicate-key and NaN hooks, took 3x longer on large outputs).
    if source == "store":
        from usdscene.converters.openlabel.store import AnnotationStore

        document = AnnotationStore(path.parent).document()
    else:
        try:
            document = json.loads(path.read_bytes())
        except (OSError, ValueError) as exc:
            raise OutputError(f"unreadable annotations document: {exc}", where=str(path)) from None
    if not isinstance(document, dict) or not isinstance(document.get("openlabel"), dict):
        raise OutputError("not an OpenLABEL document (no 'openlabel' object)", where=str(path))
    root = document["openlabel"]
    frames = root.get("frames", {}) or {}
    index = LabelIndex(document)
    tracks = track_ids(document)
    images = []
    extra_cache: dict[int, dict] = {}
    for record in image_records(document):
        frame, camera = record["frame"], record["camera"]
        if frame not in extra_cache:
            extra_cache = {frame: _frame_extras(frames.get(str(frame), {}) or {}, RESOLVED_PLACE, RESOLVED_RELATION)}
        texts, points = extra_cache[frame]["texts"], extra_cache[frame]["points"]
        objects = []
        for label in index.labels(frame, camera):
            attributes = label["attributes"]
            fraction = attributes.get("visible_fraction")
            objects.append({
                "uid": label["uid"], "track": tracks.get(label["uid"]), "class": label["type"], "name": label["name"],
                "box": label["bbox"], "amodal_box": label["amodal_bbox"],
                "polygons": [(p["points"], p["is_hole"]) for p in label["polygons"]],
                "visible_fraction": None if fraction is None else float(fraction),
                "truncated": bool(attributes.get("truncated", False)),
                "pixel_count": attributes.get("pixel_count"),
                "relation": texts.get(label["uid"], ""),
                "keypoints": points.get((label["uid"], camera), [])})
        images.append({"frame": frame, "camera": camera, "uri": record["uri"], "mask_uri": record["mask_uri"],
                       "width": record["width_px"], "height": record["height_px"], "objects": objects,
                       "labelled": True})
    return images


def _frame_extras(frame: dict, place_key: str, relation_key: str) -> dict:
    """Relation text per uid and keypoints per (uid, camera) of one frame of the document."""
    texts: dict[str, str] = {}
    points: dict[tuple[str, str], list] = {}
    for uid, entry in (frame.get("objects", {}) or {}).items():
        data = (entry or {}).get("object_data", {}) or {}
        values = {t.get("name"): t.get("val") for t in data.get("text", []) or []}
        if values.get(relation_key) and values.get(place_key):
            texts[uid] = f"{values[relation_key]} {values[place_key]}"
        for item in data.get("point2d", []) or []:
            name, value = str(item.get("name", "")), item.get("val") or []
            marker = name.rfind(KEYPOINT_INFIX)
            if marker < 0 or len(value) < 2:
                continue
            flag = next((a.get("val") for kind in (item.get("attributes") or {}).values() for a in kind
                         if a.get("name") == "visibility"), 2)
            camera, joint = name[:marker], name[marker + len(KEYPOINT_INFIX):]
            points.setdefault((uid, camera), []).append([joint, float(value[0]), float(value[1]), int(flag)])
    return {"texts": texts, "points": points}


def _images_from_kept_labels(out: Path) -> list[dict]:
    """The images of a half-finished run: every rendered image, with the labels kept for it
    in ``OUT/labels/`` when they are there."""
    import json

    from usdscene.labels.image_labels import image_labels_from_json

    images = []
    for image_file in sorted((out / layout.IMAGES_DIR).glob("*/*.png")):
        camera, stem = image_file.parent.name, image_file.stem
        if not stem.isdigit():
            continue
        frame = int(stem)
        entry = {"frame": frame, "camera": camera, "uri": f"{layout.IMAGES_DIR}/{camera}/{image_file.name}",
                 "mask_uri": f"{layout.MASKS_DIR}/{camera}/{image_file.name}", "width": None, "height": None,
                 "objects": [], "labelled": False}
        try:
            kept = json.loads(layout.labels_path(out, camera, frame).read_text(encoding="utf-8"))
            labels = image_labels_from_json(kept["labels"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            labels = None
        if labels is not None:
            entry.update(width=labels.width_px, height=labels.height_px, labelled=True, objects=[{
                "uid": o.uid, "class": o.class_name, "name": "",
                "box": None if o.box is None else list(o.box.center_size()),
                "amodal_box": None if o.amodal_box is None else list(o.amodal_box.center_size()),
                "polygons": [(c.flat(), bool(c.is_hole)) for c in o.contours],
                "visible_fraction": o.visible_fraction, "truncated": bool(o.truncated),
                "pixel_count": o.pixel_count, "relation": "", "keypoints": []} for o in labels.objects])
        images.append(entry)
    images.sort(key=lambda im: (im["frame"], im["camera"]))
    return images


def _page_entry(image: dict, class_index: dict[str, int]) -> dict:
    """One image's full labels in a labels page (short keys: pages of 40,000 images add up).
    Values go as the document has them (rounding them here cost a fifth of a build)."""
    return {
        "uri": image["uri"], "w": image["width"], "h": image["height"],
        "o": [{"u": o["uid"], "id": o.get("track"), "k": class_index[o["class"]], "n": o["name"], "b": o["box"], "a": o["amodal_box"],
               "p": [[points, bool(hole)] for points, hole in o["polygons"]], "v": o["visible_fraction"],
               "t": bool(o["truncated"]), "px": o["pixel_count"], "r": o["relation"],
               "kp": o["keypoints"]} for o in image["objects"]]}


# --------------------------------------------------------------------------------------------
# Thumbnails and mask tints


def _remove_stale_pages(folder: Path, pages: int) -> None:
    """Delete label pages beyond ``pages`` left by an earlier, larger build."""
    for path in folder.glob("labels_*.js"):
        stem = path.stem[len("labels_"):]
        if stem.isdigit() and int(stem) >= pages:
            path.unlink(missing_ok=True)


# --------------------------------------------------------------------------------------------
# Pictures of the design tools


def _extra_pictures(target: Path, document, coverage_map) -> dict[str, str]:
    """The balance chart of a generated document and the coverage map of a camera plan, put
    into the report when there are any; ``{"balance": file, "coverage": file}``."""
    import json

    from usdscene.files import write_bytes_atomic, write_png_atomic
    from usdscene.generate.sequences import report_path
    from usdscene.dataset.statistics import draw_balance_chart

    found: dict[str, str] = {}
    balance = report_path(document) if document is not None else None
    if balance is not None and balance.is_file():
        try:
            report = json.loads(balance.read_text(encoding="utf-8"))
            # Only a balance report has per-class counts; another generator's report (``generate
            # tracks``: track lengths, people per frame) has no balance to draw, and nothing is wrong.
            if not isinstance(report, dict) or "classes" in report:
                write_png_atomic(target / "balance.png", draw_balance_chart(report))
                found["balance"] = "balance.png"
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            # a damaged balance report costs its chart, not the report
            log.warning("%s: no balance chart in the report: %s", balance, exc)
    if coverage_map is not None and Path(coverage_map).is_file():
        write_bytes_atomic(target / "coverage.png", Path(coverage_map).read_bytes())
        found["coverage"] = "coverage.png"
    return found


def run_document(out_dir: str | os.PathLike) -> Path | None:
    """The scene document an output folder was made from, as its stage records it (relative to
    the working folder the run started in), when the stage and the document are still there."""
    stage = layout.stage_root(out_dir)
    if not stage.is_file():
        return None
    try:
        from usdscene.render.stage_reader import recorded_source

        source, _ = recorded_source(stage)
    except Exception as exc:  # noqa: BLE001 - a stage pxr cannot read only costs the extras
        log.warning("%s: cannot read the recorded document: %s", stage, exc)
        return None
    return source if source is not None and source.is_file() else None
