"""Would a detector trained on real photographs find our people? OpenCV's HOG people detector
(Dalal and Triggs' HOG + linear SVM, trained on real pedestrians) on rendered car-park people.

    python benchmarks/hog_people.py [--document DOC] [--frames 0,50] [--out DIR]
                                    [--images DIR]   # score an existing run instead of rendering

The document (default ``examples/car_park/moving.openlabel.json``: walkers and standing people
of the ``person`` family) is rendered at 640x480 (its pinhole cameras' matrices scaled with
the resolution) with its own render settings (2 samples + OpenImageDenoise), on its non-fisheye
cameras, for a handful of frames, with ``usdscene run`` (COCO export). Then:

* each image is upscaled 2x (bilinear) and searched with ``cv2.HOGDescriptor`` and
  ``HOGDescriptor_getDefaultPeopleDetector`` (window stride 8, padding 16, scale step 1.05);
  a detection window (64x128 around a 96 px person) is shrunk to the person it frames (the
  middle half of its width, the middle three quarters of its height) and scaled back;
* detections, best score first, are matched greedily to the labelled visible (tight, mask)
  boxes of people at IoU >= 0.5. People that count: ``visible_fraction`` >= 0.7, not cut by the
  image border. A detection matching an uncounted person (occluded, cut) is neither a hit nor a
  false alarm; any other unmatched detection is a false alarm;
* recall is reported for counted people 40-80 px and 80-160 px tall, with false alarms per
  image; and the render cost per image (wall time of the run over the images it rendered).

The look statistics of the same images (``benchmarks/look_statistics.py``: brightness, clipped
and crushed %, noise sigma, sharpness, colourfulness) are printed too. ``--sheet FILE
--compare-with BEFORE_RUN`` writes crops of the same people and vehicles in both runs, one
above the other.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DOCUMENT = REPO / "examples" / "car_park" / "moving.openlabel.json"
RESOLUTION_PX = (640, 480)
HEIGHT_BINS_PX = ((40, 80), (80, 160))
MIN_VISIBLE_FRACTION = 0.7
MATCH_IOU = 0.5
UPSCALE = 2.0


def scaled_document(document: dict, width_px: int, height_px: int) -> tuple[dict, list[str]]:
    """The document rendered at ``width_px`` x ``height_px``, and its non-fisheye cameras.

    Pinhole camera matrices are scaled with the resolution (same field of view); the friendly
    ``resolution_px`` of the render settings is set to match.
    """
    doc = copy.deepcopy(document)
    root = doc["openlabel"]
    cameras = []
    for name, stream in root["streams"].items():
        props = stream.get("stream_properties", {})
        intr = props.get("intrinsics_pinhole")
        if intr is None:
            continue  # fisheye: not the kind of image the detector was trained on
        sx, sy = width_px / intr["width_px"], height_px / intr["height_px"]
        k = list(intr["camera_matrix"])
        # Pixel centres at integers: c' = (c + 0.5) * s - 0.5.
        k[0], k[5] = k[0] * sx, k[5] * sy
        k[2], k[6] = (k[2] + 0.5) * sx - 0.5, (k[6] + 0.5) * sy - 0.5
        intr.update(width_px=width_px, height_px=height_px, camera_matrix=k)
        cameras.append(name)
    root["metadata"]["usdscene"]["render"]["resolution_px"] = [width_px, height_px]
    return doc, cameras


def render(doc_path: Path, out: Path, frames: str, cameras: list[str]) -> float:
    """Seconds per image of ``usdscene run`` (Blender's start and the stage import included)."""
    start = time.monotonic()
    subprocess.run([sys.executable, "-m", "usdscene", "run", str(doc_path), "-o", str(out), "--frames", frames,
                    "--cameras", *cameras, "--export", "coco", "--no-report", "--no-progress"],
                   check=True, cwd=str(doc_path.parent), env=dict(os.environ))
    images = len(frames.split(",")) * len(cameras)
    return (time.monotonic() - start) / images


def hog_people(image_bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Person boxes ``(N, 4)`` as ``[x, y, w, h]`` pixels of ``image_bgr`` and their SVM scores ``(N,)``."""
    import cv2

    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    big = cv2.resize(image_bgr, None, fx=UPSCALE, fy=UPSCALE, interpolation=cv2.INTER_LINEAR)
    rects, weights = hog.detectMultiScale(big, winStride=(8, 8), padding=(16, 16), scale=1.05)
    if len(rects) == 0:
        return np.zeros((0, 4)), np.zeros(0)
    rects = np.asarray(rects, dtype=float)
    # The 64x128 window frames a 96 px tall person with margins: keep the person.
    x, y, w, h = rects.T
    person = np.stack([x + 0.25 * w, y + 0.125 * h, 0.5 * w, 0.75 * h], axis=1) / UPSCALE
    return person, np.asarray(weights, dtype=float).reshape(-1)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two ``[x, y, w, h]`` boxes."""
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def match_image(detections: np.ndarray, scores: np.ndarray, people: list[dict]) -> tuple[list[bool], int]:
    """Greedy matching, best detection first: (hit per person, false alarms).

    ``people``: dicts with ``bbox`` (``[x, y, w, h]``) and ``counted``.
    """
    hit = [False] * len(people)
    taken = [False] * len(people)
    false_alarms = 0
    for d in np.argsort(-scores, kind="stable"):
        best, best_iou = None, MATCH_IOU
        for p, person in enumerate(people):
            if not taken[p]:
                overlap = iou(detections[d], np.asarray(person["bbox"], dtype=float))
                if overlap >= best_iou:
                    best, best_iou = p, overlap
        if best is None:
            false_alarms += 1
            continue
        taken[best] = True
        hit[best] = people[best]["counted"]
    return hit, false_alarms


def score_run(out: Path) -> dict:
    """HOG figures of a run's COCO export: recall per height bin, false alarms per image."""
    import cv2

    coco_path = out / "exports" / "coco" / "annotations.json"
    coco = json.loads(coco_path.read_text())
    root = (coco_path.parent / coco["info"]["image_root"]).resolve()
    person_ids = {c["id"] for c in coco["categories"] if c["name"] == "person"}
    by_image: dict[int, list] = {}
    for a in coco["annotations"]:
        if a["category_id"] in person_ids:
            by_image.setdefault(a["image_id"], []).append(a)
    found = {b: 0 for b in HEIGHT_BINS_PX}
    total = {b: 0 for b in HEIGHT_BINS_PX}
    false_alarms, paths = 0, []
    for image in coco["images"]:
        path = root / image["file_name"]
        paths.append(path)
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        people = [{"bbox": a["bbox"], "counted": (a["visible_fraction"] or 0) >= MIN_VISIBLE_FRACTION
                   and not a["truncated"]} for a in by_image.get(image["id"], [])]
        detections, scores = hog_people(bgr)
        hit, alarms = match_image(detections, scores, people)
        false_alarms += alarms
        for person, ok in zip(people, hit):
            h = person["bbox"][3]
            for lo, hi in HEIGHT_BINS_PX:
                if person["counted"] and lo <= h < hi:
                    total[(lo, hi)] += 1
                    found[(lo, hi)] += int(ok)
    return {"images": len(coco["images"]), "paths": paths,
            "recall": {f"{lo}-{hi}": (found[(lo, hi)] / total[(lo, hi)] if total[(lo, hi)] else None,
                                      total[(lo, hi)]) for lo, hi in HEIGHT_BINS_PX},
            "false_alarms_per_image": false_alarms / max(1, len(coco["images"]))}


def look_statistics(run: Path) -> dict:
    """The camera issue's look statistics (``benchmarks/look_statistics.py``), mean over the run's images."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    import look_statistics as look  # noqa: E402 (a sibling script, not a package)

    return look.folder_statistics(run)


def crop_sheet(runs: list[Path], out: Path, classes=("person", "vehicle"), per_class: int = 12,
               crop_px: tuple[int, int] = (64, 128)) -> Path:
    """Crops of the same labelled objects in each run, side by side (one column block per
    run), one row block per class: the largest visible, unoccluded ones of the first run.

    Every crop is the object's box with a 15 % margin, scaled into ``crop_px`` (w, h) for
    people and its transpose for vehicles; written as JPEG.
    """
    import cv2

    def coco(run):
        path = run / "exports" / "coco" / "annotations.json"
        data = json.loads(path.read_text())
        return data, (path.parent / data["info"]["image_root"]).resolve()

    first, _ = coco(runs[0])
    names = {c["id"]: c["name"] for c in first["categories"]}
    images = {i["id"]: i for i in first["images"]}
    blocks = []
    for name in classes:
        chosen = sorted((a for a in first["annotations"] if names[a["category_id"]] == name
                         and (a["visible_fraction"] or 0) >= MIN_VISIBLE_FRACTION and not a["truncated"]),
                        key=lambda a: -a["bbox"][3])
        size = crop_px if name == "person" else crop_px[::-1]
        chosen = chosen[:per_class if name == "person" else per_class // 2]  # vehicle crops are twice as wide
        columns = []
        for run in runs:
            data, root = coco(run)
            # The same object in this run (its box may differ where new clutter hides part of it).
            run_images = {i["id"]: i["file_name"] for i in data["images"]}
            by_key = {(run_images[a["image_id"]], a["uid"]): a for a in data["annotations"]}
            tiles = []
            for a in chosen:
                file_name = images[a["image_id"]]["file_name"]
                bgr = cv2.imread(str(root / file_name), cv2.IMREAD_COLOR)
                x, y, w, h = by_key.get((file_name, a["uid"]), a)["bbox"]
                m = 0.15 * max(w, h)
                x0, y0 = int(max(0, x - m)), int(max(0, y - m))
                x1, y1 = int(min(bgr.shape[1], x + w + m)), int(min(bgr.shape[0], y + h + m))
                tiles.append(cv2.resize(bgr[y0:y1, x0:x1], size, interpolation=cv2.INTER_AREA))
            columns.append(np.hstack(tiles) if tiles else np.zeros((size[1], size[0], 3), np.uint8))
        # One row per run, a white rule between them.
        rule = np.full((4, columns[0].shape[1], 3), 255, np.uint8)
        blocks.append(np.vstack([c for pair in zip(columns, [rule] * len(columns)) for c in pair][:-1]))
    width = max(b.shape[1] for b in blocks)
    sheet = np.vstack([np.pad(b, ((0, 12), (0, width - b.shape[1]), (0, 0))) for b in blocks])
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), sheet, [cv2.IMWRITE_JPEG_QUALITY, 85])
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--document", type=Path, default=DEFAULT_DOCUMENT)
    parser.add_argument("--frames", default="0,50", help="frames to render (a list N,M,...)")
    parser.add_argument("--out", type=Path, default=None, help="work folder (default: a new temporary one)")
    parser.add_argument("--images", type=Path, default=None, help="score this finished run instead of rendering")
    parser.add_argument("--sheet", type=Path, default=None,
                        help="write a JPEG of people and vehicle crops: the --compare-with runs above this one")
    parser.add_argument("--compare-with", type=Path, nargs="*", default=[], metavar="RUN",
                        help="finished runs of the same document (e.g. before) for --sheet")
    args = parser.parse_args()
    seconds = None
    if args.images is None:
        work = (args.out or Path(tempfile.mkdtemp(prefix="hog-people-"))).resolve()
        work.mkdir(parents=True, exist_ok=True)
        source = args.document.resolve()
        doc, cameras = scaled_document(json.loads(source.read_text()), *RESOLUTION_PX)
        # The copy lives in the work folder: its asset folders become absolute, and the
        # original's folder (which they and their sources lie in) readable.
        meta = doc["openlabel"]["metadata"]["usdscene"]
        meta["asset_paths"] = [str((source.parent / p).resolve()) for p in meta.get("asset_paths", [])]
        os.environ["USDSCENE_ASSET_PATH"] = str(source.parent)
        doc_path = work / "document.openlabel.json"
        doc_path.write_text(json.dumps(doc))
        seconds = render(doc_path, work / "run", args.frames, cameras)
        out = work / "run"
    else:
        out = args.images
    figures = score_run(out)
    print(f"{out}: {figures['images']} images of {RESOLUTION_PX[0]}x{RESOLUTION_PX[1]}"
          + (f", {seconds:.1f} s per image (render command)" if seconds is not None else ""))
    for name, (recall, n) in figures["recall"].items():
        shown = f"{recall:.2f}" if recall is not None else "-"
        print(f"  HOG recall, people {name} px tall: {shown} of {n}")
    print(f"  false alarms per image: {figures['false_alarms_per_image']:.2f}")
    stats = look_statistics(out)
    print("  look: " + ", ".join(f"{k} {v:.2f}" for k, v in stats.items()))
    if args.sheet is not None:
        print(f"  crops: {crop_sheet([*args.compare_with, out], args.sheet)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
