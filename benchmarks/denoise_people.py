"""Does the denoiser smear small people into the background? The car park at its default
samples against a many-sample reference of the same images.

    python benchmarks/denoise_people.py [--document DOC] [--frames 0,50] [--samples 2,8,64]
                                        [--out DIR] [--images DIR ...]  # score finished runs

The document (default ``examples/car_park/moving.openlabel.json``) is rendered at 640x480 on its
non-fisheye cameras (as ``benchmarks/hog_people.py`` does) once per sample count, with the
document's own denoiser settings (OpenImageDenoise on the albedo and normal passes), the last
count being the reference. Per run:

* HOG recall for people 40-80 px and 80-160 px tall and false alarms per image
  (``hog_people.score_run``: the same detector and matching);
* edge contrast of the people 40-80 px tall: the mean Sobel gradient magnitude (grey levels per
  pixel) on their outline (the visible mask's 1 px band inside and outside its edge, from the
  COCO segmentation), and its ratio to the same person in the reference run (1.0: as crisp as
  the reference; a smeared edge falls below);
* the render cost per image (wall time of the run over its images).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import hog_people as hp  # noqa: E402 (a sibling script, not a package)

SMALL_PX = (40, 80)


def _outline(segmentation, height_px: int, width_px: int) -> np.ndarray:
    """(H, W) bool: the 1 px band on each side of the edge of a COCO segmentation."""
    import cv2
    from pycocotools import mask as cocomask

    if isinstance(segmentation, dict):
        rle = segmentation
        if isinstance(rle.get("counts"), list):
            rle = cocomask.frPyObjects(rle, height_px, width_px)
        mask = cocomask.decode(rle).astype(np.uint8)
    else:
        mask = cocomask.decode(cocomask.merge(cocomask.frPyObjects(segmentation, height_px, width_px)))
    kernel = np.ones((3, 3), np.uint8)
    return (cv2.dilate(mask, kernel) - cv2.erode(mask, kernel)) > 0


def edge_contrast(out: Path) -> dict:
    """(image file, uid) → mean gradient magnitude on the outline, for counted people 40-80 px."""
    import cv2

    coco_path = out / "exports" / "coco" / "annotations.json"
    coco = json.loads(coco_path.read_text())
    root = (coco_path.parent / coco["info"]["image_root"]).resolve()
    person_ids = {c["id"] for c in coco["categories"] if c["name"] == "person"}
    images = {i["id"]: i for i in coco["images"]}
    grads: dict[str, np.ndarray] = {}
    contrast = {}
    for a in coco["annotations"]:
        if a["category_id"] not in person_ids or a["truncated"] or (a["visible_fraction"] or 0) < hp.MIN_VISIBLE_FRACTION:
            continue
        if not SMALL_PX[0] <= a["bbox"][3] < SMALL_PX[1]:
            continue
        image = images[a["image_id"]]
        name = image["file_name"]
        if name not in grads:
            grey = cv2.imread(str(root / name), cv2.IMREAD_GRAYSCALE).astype(np.float32)
            grads[name] = np.hypot(cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3))
        band = _outline(a["segmentation"], image["height"], image["width"])
        if band.any():
            contrast[(name, a["uid"])] = float(grads[name][band].mean())
    return contrast


def render_with_samples(source: Path, work: Path, samples: int, frames: str) -> tuple[Path, float]:
    """Render ``source`` at 640x480 with ``samples``; (run folder, seconds per image)."""
    doc, cameras = hp.scaled_document(json.loads(source.read_text()), *hp.RESOLUTION_PX)
    meta = doc["openlabel"]["metadata"]["usdscene"]
    meta["render"]["samples"] = samples
    meta["asset_paths"] = [str((source.parent / p).resolve()) for p in meta.get("asset_paths", [])]
    os.environ["USDSCENE_ASSET_PATH"] = str(source.parent)
    folder = work / f"samples_{samples}"
    folder.mkdir(parents=True, exist_ok=True)
    doc_path = folder / "document.openlabel.json"
    doc_path.write_text(json.dumps(doc))
    seconds = hp.render(doc_path, folder / "run", frames, cameras)
    return folder / "run", seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--document", type=Path, default=hp.DEFAULT_DOCUMENT)
    parser.add_argument("--frames", default="0,50")
    parser.add_argument("--samples", default="2,64", help="sample counts, the reference last (default 2,64)")
    parser.add_argument("--out", type=Path, default=None, help="work folder (default: a new temporary one)")
    parser.add_argument("--images", type=Path, nargs="*", default=None,
                        help="finished runs to score instead of rendering, the reference last")
    args = parser.parse_args()
    runs: list[tuple[str, Path, float | None]] = []
    if args.images:
        runs = [(str(p), p, None) for p in args.images]
    else:
        work = (args.out or Path(tempfile.mkdtemp(prefix="denoise-people-"))).resolve()
        for n in (int(s) for s in args.samples.split(",")):
            run, seconds = render_with_samples(args.document.resolve(), work, n, args.frames)
            runs.append((f"{n} samples", run, seconds))
    reference = edge_contrast(runs[-1][1])
    print(f"reference: {runs[-1][0]} ({len(reference)} people {SMALL_PX[0]}-{SMALL_PX[1]} px)")
    for label, run, seconds in runs:
        figures = hp.score_run(run)
        contrast = edge_contrast(run)
        common = sorted(set(contrast) & set(reference))
        ratio = np.array([contrast[k] / reference[k] for k in common if reference[k] > 0])
        recall = ", ".join(f"{name} px {r:.2f} of {n}" if r is not None else f"{name} px - of {n}"
                           for name, (r, n) in figures["recall"].items())
        print(f"{label}: HOG recall {recall}; false alarms/image {figures['false_alarms_per_image']:.2f}; "
              f"outline contrast {np.mean([contrast[k] for k in common]) if common else float('nan'):.1f} "
              f"grey/px, {ratio.mean() if ratio.size else float('nan'):.2f} of the reference "
              f"(median {np.median(ratio) if ratio.size else float('nan'):.2f}, {ratio.size} people)"
              + (f"; {seconds:.1f} s per image" if seconds is not None else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
