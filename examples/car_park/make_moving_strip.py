"""A strip of frames per camera of the moving car park, with the MOT track ids drawn.

Reads what ``usdscene export mot OUT`` wrote (``OUT/exports/mot/<camera>/gt/gt.txt`` and
``img1/``): the boxes and ids come from the export, not from the scene, so the picture shows
what a tracker is trained on. Every id keeps its colour in every camera.

Usage (from this folder, after ``usdscene run moving.openlabel.json -o OUT`` and
``usdscene export mot OUT``)::

    python make_moving_strip.py OUT [--frames 1 21 41 61 81 100] [-o moving_strip.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np


def _colour(track_id: int) -> tuple[int, int, int]:
    hue = (track_id * 47) % 180
    bgr = cv2.cvtColor(np.uint8([[[hue, 220, 255]]]), cv2.COLOR_HSV2BGR)[0, 0]
    return tuple(int(v) for v in bgr)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, nargs="+", default=[1, 21, 41, 61, 81, 100],
                        help="MOT frame numbers (1-based)")
    parser.add_argument("--scale", type=int, default=2)
    parser.add_argument("-o", "--output", type=Path, default=Path(__file__).with_name("moving_strip.png"))
    args = parser.parse_args(argv)
    rows = []
    for seq in sorted(p for p in (args.out / "exports" / "mot").iterdir() if p.is_dir()):
        gt = np.loadtxt(seq / "gt" / "gt.txt", delimiter=",", ndmin=2)
        tiles = []
        for frame in args.frames:
            image = cv2.imread(str(seq / "img1" / f"{frame:06d}.png"))
            image = cv2.resize(image, None, fx=args.scale, fy=args.scale, interpolation=cv2.INTER_NEAREST)
            for _, ident, left, top, width, height, _, _, visibility in gt[gt[:, 0] == frame]:
                if visibility <= 0:
                    continue
                x0, y0 = (left - 1) * args.scale, (top - 1) * args.scale
                x1, y1 = x0 + width * args.scale, y0 + height * args.scale
                colour = _colour(int(ident))
                cv2.rectangle(image, (int(x0), int(y0)), (int(x1) - 1, int(y1) - 1), colour, 1)
                cv2.putText(image, str(int(ident)), (int(x0), max(int(y0) - 2, 8)), cv2.FONT_HERSHEY_SIMPLEX,
                            0.35, colour, 1, cv2.LINE_AA)
            cv2.putText(image, f"{seq.name}  frame {frame}", (4, image.shape[0] - 5), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(image)
        rows.append(np.hstack(tiles))
    cv2.imwrite(str(args.output), np.vstack(rows))
    print(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
