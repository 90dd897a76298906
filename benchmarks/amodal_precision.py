"""How close the amodal projections of a rendered output are to a much finer rasterisation.

For every camera of one frame of an output folder (e.g. the README's cabin run), projects
every labelled object twice with :func:`usdscene.labels.amodal.amodal_projections`:

* as ``usdscene run`` does (curved edges split to 8 px, closed meshes from one facing);
* a reference: every face, curved edges split to 0.5 px and up to 8 levels (16 times finer),

and reports the pixels and boxes that differ. Slow (the reference takes minutes on the cabin).

    python benchmarks/amodal_precision.py OUT [--frame 0]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from usdscene.labels import amodal

from usdscene.document import output_layout as layout
from usdscene.labels.cross_camera import camera_for_image
from usdscene.render.stage_reader import read_stage_plan
from usdscene.scene.stage_geometry import StageGeometry


def projections(cameras, triangles, frame, size, *, reference: bool) -> dict:
    """camera → uid → AmodalProjection, as run (reference=False) or the fine reference."""
    saved = amodal._MAX_SUBDIVISIONS, amodal.MAX_CUT_EDGE_PX, amodal._is_closed
    if reference:  # finer splits, and every face of every mesh
        amodal._MAX_SUBDIVISIONS, amodal.MAX_CUT_EDGE_PX = 8, 0.5
        amodal._is_closed = lambda faces, n_points: False
    amodal._INDEXED.clear()
    try:
        return {c.name: amodal.amodal_projections(camera_for_image(c, frame, *size), triangles, frame,
                                                  max_edge_px=0.5 if reference else amodal.MAX_PROJECTED_EDGE_PX)
                for c in cameras}
    finally:
        amodal._MAX_SUBDIVISIONS, amodal.MAX_CUT_EDGE_PX, amodal._is_closed = saved
        amodal._INDEXED.clear()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="a rendered output folder")
    parser.add_argument("--frame", type=int, default=0)
    args = parser.parse_args()
    out = Path(args.out)
    stage = layout.stage_root(out)
    cameras = read_stage_plan(stage).cameras
    ids = json.loads((out / layout.ID_MAP_FILE).read_text())
    triangles = StageGeometry(stage).triangles(args.frame, {str(v["uid"]) for v in ids.values()})
    any_mask = next(iter(sorted((out / layout.MASKS_DIR).glob("*/*.png"))))
    import cv2

    height, width = cv2.imread(str(any_mask), cv2.IMREAD_UNCHANGED).shape
    t0 = time.perf_counter()
    fine = projections(cameras, triangles, args.frame, (width, height), reference=True)
    t1 = time.perf_counter()
    run = projections(cameras, triangles, args.frame, (width, height), reference=False)
    pixels, box_offsets = [], []
    for camera in cameras:
        for uid in triangles:
            a, b = fine[camera.name][uid], run[camera.name][uid]
            if not (a.pixel_count or b.pixel_count):
                continue
            pixels.append(int(np.count_nonzero(a.mask != b.mask)))
            if a.box and b.box:
                box_offsets.append(max(abs(a.box.x_min - b.box.x_min), abs(a.box.y_min - b.box.y_min),
                                       abs(a.box.x_max - b.box.x_max), abs(a.box.y_max - b.box.y_max)))
            else:
                box_offsets.append(10 ** 9)  # one of them covers no pixel centre
    pixels, box_offsets = np.array(pixels), np.array(box_offsets)
    print(f"{out}: frame {args.frame}, {len(cameras)} cameras at {width}x{height}, {len(pixels)} projections "
          f"(reference in {t1 - t0:.0f} s)")
    print(f"  pixels differing from the reference: {pixels.sum()} in all, at most {pixels.max()} for one "
          f"projection, {np.count_nonzero(pixels)} projections with any")
    print(f"  boxes: largest offset {box_offsets.max()} px; {np.count_nonzero(box_offsets > 1)} more than 1 px off")


if __name__ == "__main__":
    main()
