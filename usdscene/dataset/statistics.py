"""What the labels of an annotated output contain: counts per class and camera, the histogram
of visible fractions, and a chart of them (OpenCV drawing, no plotting library).

A *label* is one object seen by one camera in one frame (a ``<camera>_bbox``); *hidden* counts
objects whose projection falls in the image but which no pixel shows (amodal box only).

The cross-camera summary (:func:`cross_camera_statistics`) counts *object-frames* (one object
present in one frame) by the number of cameras that see them, and per class gives the median
number of cameras and the best DORI class reached (see :mod:`usdscene.labels.cross_camera`).
"""

from __future__ import annotations

import cv2
import numpy as np

HISTOGRAM_BINS = 10


def label_statistics(document: dict) -> dict:
    """Counts of an annotated document.

    Returns:
        ``{"images": int, "classes": {class: {"labels", "hidden", "objects"}},
        "cameras": {camera: {"images", "labels", "hidden"}}, "visibility": [10 counts of
        visible fractions in [0, 0.1), ..., [0.9, 1.0]], "visibility_unknown": int}``; classes and
        cameras sorted by name. Hidden objects count in the first visibility bin.
    """
    from usdscene.converters.openlabel.annotations import LabelIndex, image_records

    classes: dict[str, dict] = {}
    cameras: dict[str, dict] = {}
    histogram = [0] * HISTOGRAM_BINS
    unknown = 0
    objects_per_class: dict[str, set] = {}
    records = image_records(document)
    index = LabelIndex(document)
    for record in records:
        cam = cameras.setdefault(record["camera"], {"images": 0, "labels": 0, "hidden": 0})
        cam["images"] += 1
        for label in index.labels(record["frame"], record["camera"]):
            cls = classes.setdefault(label["type"], {"labels": 0, "hidden": 0, "objects": 0})
            key = "labels" if label["bbox"] is not None else "hidden"
            cls[key] += 1
            cam[key] += 1
            objects_per_class.setdefault(label["type"], set()).add(label["uid"])
            fraction = label["attributes"].get("visible_fraction")
            if fraction is None:
                unknown += 1
            else:
                histogram[min(HISTOGRAM_BINS - 1, int(float(fraction) * HISTOGRAM_BINS))] += 1
    for name, uids in objects_per_class.items():
        classes[name]["objects"] = len(uids)
    return {"images": len(records), "classes": dict(sorted(classes.items())),
            "cameras": dict(sorted(cameras.items())), "visibility": histogram,
            "visibility_unknown": unknown, "cross_camera": cross_camera_statistics(document)}


def cross_camera_statistics(document: dict) -> dict:
    """Summary of the cross-camera table of an annotated document.

    Returns:
        ``{"object_frames": int, "by_camera_count": {n: object-frames seen by exactly n cameras}
        (n = 0 .. the largest count, every n listed), "classes": {class: {"object_frames",
        "unseen", "median_cameras", "median_best_px_per_m" (None when unknown), "best_px_per_m"
        (None when unknown), "best_dori" (None when unknown, "" below the lowest class)}}}``;
        classes sorted by name. Empty counts for a document without the table.
    """
    from usdscene.converters.openlabel.annotations import cross_camera_rows

    rows = cross_camera_rows(document)
    counts = [len(r["cameras"]) for r in rows]
    by_count = {n: counts.count(n) for n in range(max(counts, default=-1) + 1)}
    per_class: dict[str, list[dict]] = {}
    for row in rows:
        per_class.setdefault(row["type"], []).append(row)
    classes = {}
    for name, class_rows in sorted(per_class.items()):
        best = [r for r in class_rows if r["best_px_per_m"] is not None]
        top = max(best, key=lambda r: float(r["best_px_per_m"]), default=None)
        classes[name] = {
            "object_frames": len(class_rows),
            "unseen": sum(1 for r in class_rows if not r["cameras"]),
            "median_cameras": float(np.median([len(r["cameras"]) for r in class_rows])),
            "median_best_px_per_m": float(np.median([float(r["best_px_per_m"]) for r in best])) if best else None,
            "best_px_per_m": None if top is None else float(top["best_px_per_m"]),
            "best_dori": None if top is None else top["best_dori"]}
    return {"object_frames": len(rows), "by_camera_count": by_count, "classes": classes}


def dori_text(name: str | None) -> str:
    """A DORI class name for tables and charts: ``-`` when unknown, ``none`` below the lowest class."""
    return "-" if name is None else (name or "none")


def _bar_panel(title: str, names: list[str], values: list[float], width: int, colour,
               texts: list[str] | None = None) -> np.ndarray:
    """One chart panel: a bar per name, labelled with ``texts`` (default: the values)."""
    row_h, label_w, pad = 22, 170, 10
    height = 40 + row_h * max(1, len(names)) + pad
    panel = np.full((height, width, 3), 255, np.uint8)
    cv2.putText(panel, title, (pad, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
    top = max(values) if values and max(values) > 0 else 1
    texts = texts if texts is not None else [str(v) for v in values]
    # Room right of the longest bar for the longest value text.
    room = max([60, *(cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] + 12 for t in texts)])
    bar_w = width - label_w - 2 * pad - room
    for k, (name, value, text) in enumerate(zip(names, values, texts)):
        y = 40 + k * row_h
        cv2.putText(panel, name[:22], (pad, y + 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (40, 40, 40), 1, cv2.LINE_AA)
        length = int(round(bar_w * value / top))
        cv2.rectangle(panel, (label_w, y + 3), (label_w + max(length, 1), y + row_h - 4), colour, -1)
        cv2.putText(panel, text, (label_w + length + 6, y + 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (40, 40, 40), 1, cv2.LINE_AA)
    return panel


def draw_chart(stats: dict, width_px: int = 720) -> np.ndarray:
    """(H, width_px, 3) uint8 BGR image: bars per class, per camera, the visibility histogram
    and, when the document has the cross-camera table, object-frames by number of cameras and
    the median cameras per class with its best DORI class."""
    classes = stats["classes"]
    cameras = stats["cameras"]
    bins = [f"{k / HISTOGRAM_BINS:.1f}-{(k + 1) / HISTOGRAM_BINS:.1f}" for k in range(HISTOGRAM_BINS)]
    panels = [
        _bar_panel("labels per class (visible)", list(classes), [c["labels"] for c in classes.values()],
                   width_px, (180, 120, 40)),
        _bar_panel("labels per camera (visible)", list(cameras), [c["labels"] for c in cameras.values()],
                   width_px, (60, 160, 60)),
        _bar_panel("visible fraction", bins, list(stats["visibility"]), width_px, (50, 90, 200)),
    ]
    cross = stats.get("cross_camera") or {}
    if cross.get("object_frames"):
        counts = cross["by_camera_count"]
        panels.append(_bar_panel("object-frames seen by n cameras", [f"{n} camera{'s' * (n != 1)}" for n in counts],
                                 list(counts.values()), width_px, (140, 80, 160)))
        per_class = cross["classes"]
        panels.append(_bar_panel(
            "median cameras per class (best DORI)", list(per_class), [c["median_cameras"] for c in per_class.values()],
            width_px, (40, 150, 190),
            [f"{c['median_cameras']:g} ({dori_text(c['best_dori'])})" for c in per_class.values()]))
    return np.concatenate(panels, axis=0)


def draw_balance_chart(report: dict, width_px: int = 720) -> np.ndarray:
    """(H, width_px, 3) uint8 BGR image: instance-frames per class, per relation, per place kind."""
    classes = report["classes"]
    kinds = report["place_kinds"] or report["places"]
    panels = [
        _bar_panel(f"instance-frames per class ({report['frames']} frames)", list(classes),
                   [c["instance_frames"] for c in classes.values()], width_px, (180, 120, 40)),
        _bar_panel("instance-frames per relation", list(report["relations"]), list(report["relations"].values()),
                   width_px, (60, 160, 60)),
        _bar_panel("instance-frames per place kind" if report["place_kinds"] else "instance-frames per place",
                   list(kinds), list(kinds.values()), width_px, (50, 90, 200)),
    ]
    return np.concatenate(panels, axis=0)
