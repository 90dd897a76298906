"""What the labels of an annotated output contain: counts per class and camera, the histogram
of visible fractions, and a chart of them (OpenCV drawing, no plotting library).

A *label* is one object seen by one camera in one frame (a ``<camera>_bbox``); *hidden* counts
objects whose projection falls in the image but which no pixel shows (amodal box only).
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
    from usdscene.converters.openlabel_annotations import image_records, labels_in

    classes: dict[str, dict] = {}
    cameras: dict[str, dict] = {}
    histogram = [0] * HISTOGRAM_BINS
    unknown = 0
    objects_per_class: dict[str, set] = {}
    records = image_records(document)
    for record in records:
        cam = cameras.setdefault(record["camera"], {"images": 0, "labels": 0, "hidden": 0})
        cam["images"] += 1
        for label in labels_in(document, record["frame"], record["camera"]):
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
            "visibility_unknown": unknown}


def _bar_panel(title: str, names: list[str], values: list[int], width: int, colour) -> np.ndarray:
    row_h, label_w, pad = 22, 170, 10
    height = 40 + row_h * max(1, len(names)) + pad
    panel = np.full((height, width, 3), 255, np.uint8)
    cv2.putText(panel, title, (pad, 26), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
    top = max(values) if values and max(values) > 0 else 1
    bar_w = width - label_w - 2 * pad - 60
    for k, (name, value) in enumerate(zip(names, values)):
        y = 40 + k * row_h
        cv2.putText(panel, name[:22], (pad, y + 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (40, 40, 40), 1, cv2.LINE_AA)
        length = int(round(bar_w * value / top))
        cv2.rectangle(panel, (label_w, y + 3), (label_w + max(length, 1), y + row_h - 4), colour, -1)
        cv2.putText(panel, str(value), (label_w + length + 6, y + 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (40, 40, 40), 1, cv2.LINE_AA)
    return panel


def draw_chart(stats: dict, width_px: int = 720) -> np.ndarray:
    """(H, width_px, 3) uint8 BGR image: bars per class, per camera and the visibility histogram."""
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


def write_chart(path, image: np.ndarray):
    """Write a (H, W, 3) uint8 BGR chart as PNG, atomically; returns the path.

    Raises:
        OutputError: the image cannot be encoded or the file cannot be written.
    """
    from usdscene.errors import OutputError
    from usdscene.files import write_bytes_atomic

    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise OutputError("cannot encode the chart", where=str(path))
    return write_bytes_atomic(path, encoded.tobytes())
