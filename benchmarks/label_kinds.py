"""Are a run's labels still exact? The checks the realism issue asks to hold after new
materials and geometry, on a finished run with a COCO export.

    python benchmarks/label_kinds.py RUN [RUN ...]

Per run: every polygon rasterised (pycocotools) against its object's pixels in the mask image
(IoU; the figure is the count at >= 0.95 and the lowest), every amodal box holding its visible
box (within 1 px), and every keypoint flagged visible lying on its person's mask (within 1 px).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def check_run(run: Path) -> dict:
    import cv2
    from pycocotools import mask as cocomask

    coco_path = run / "exports" / "coco" / "annotations.json"
    coco = json.loads(coco_path.read_text())
    ids = {v["uid"]: int(k) for k, v in json.loads((run / "masks" / "ids.json").read_text()).items()}
    images = {i["id"]: i for i in coco["images"]}
    masks: dict[str, np.ndarray] = {}
    ious, amodal_ok, kp_on, kp_all = [], 0, 0, 0
    kernel = np.ones((3, 3), np.uint8)
    for a in coco["annotations"]:
        image = images[a["image_id"]]
        key = f"{image['camera']}/{image['frame']:06d}.png"
        if key not in masks:
            masks[key] = cv2.imread(str(run / "masks" / key), cv2.IMREAD_UNCHANGED)
        mine = masks[key] == ids[a["uid"]]
        seg = a["segmentation"]
        h, w = image["height"], image["width"]
        if isinstance(seg, dict):
            drawn = cocomask.decode(cocomask.frPyObjects(seg, h, w) if isinstance(seg["counts"], list) else seg)
        else:
            drawn = cocomask.decode(cocomask.merge(cocomask.frPyObjects(seg, h, w)))
        drawn = drawn.astype(bool)
        union = (drawn | mine).sum()
        ious.append(float((drawn & mine).sum() / union) if union else 1.0)
        x, y, bw, bh = a["bbox"]
        ax, ay, aw, ah = a["amodal_bbox"]
        amodal_ok += int(ax <= x + 1 and ay <= y + 1 and ax + aw >= x + bw - 1 and ay + ah >= y + bh - 1)
        near = cv2.dilate(mine.astype(np.uint8), kernel) > 0
        kps = np.asarray(a.get("keypoints") or [], dtype=float).reshape(-1, 3)
        for kx, ky, v in kps:
            if v == 2:
                kp_all += 1
                ix, iy = int(round(kx)), int(round(ky))
                kp_on += int(0 <= ix < w and 0 <= iy < h and near[iy, ix])
    ious_arr = np.array(ious)
    return {"labels": len(ious), "iou_ge_095": int((ious_arr >= 0.95).sum()), "iou_min": float(ious_arr.min()),
            "amodal_holds_visible": amodal_ok, "keypoints_visible": kp_all, "keypoints_on_mask": kp_on}


def main(argv: list[str]) -> int:
    for run in argv:
        r = check_run(Path(run))
        print(f"{run}: {r['labels']} labels; polygon vs mask IoU >= 0.95: {r['iou_ge_095']} of {r['labels']} "
              f"(lowest {r['iou_min']:.3f}); amodal box holds visible: {r['amodal_holds_visible']} of {r['labels']}; "
              f"visible keypoints on their mask: {r['keypoints_on_mask']} of {r['keypoints_visible']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
