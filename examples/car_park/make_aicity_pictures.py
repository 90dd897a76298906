"""The pictures of the AI City Challenge example, drawn only from the exported scene (what a reader
of the layout has): ``map.png`` with every camera (dot and viewing direction) and every
person's trajectory placed by ``scaleFactor`` and ``translationToGlobalCoordinates``, and one
video frame per camera with the ``2d bounding box`` (thin) and ``2d bounding box visible``
(thick) of ``ground_truth.json``.

``python examples/car_park/make_aicity_pictures.py SCENE_DIR OUT_DIR [--frame N] [--scale K]``
writes ``OUT_DIR/aicity_map.jpg`` and ``OUT_DIR/aicity_frame.jpg``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import cv2
import numpy as np


def colour(k: int) -> tuple[int, int, int]:
    hue = (k * 47) % 180
    bgr = cv2.cvtColor(np.uint8([[[hue, 220, 255]]]), cv2.COLOR_HSV2BGR)[0, 0]
    return int(bgr[0]), int(bgr[1]), int(bgr[2])


def map_picture(scene: Path, scale: int) -> np.ndarray:
    sensors = json.loads((scene / "calibration.json").read_text())["sensors"]
    gt = json.loads((scene / "ground_truth.json").read_text())
    picture = cv2.imread(str(scene / "map.png"))
    height = picture.shape[0]
    picture = cv2.resize(picture, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    s, t = sensors[0]["scaleFactor"], sensors[0]["translationToGlobalCoordinates"]

    def pixel(x: float, y: float) -> tuple[int, int]:
        return int(round((x + t["x"]) * s * scale)), int(round((height - (y + t["y"]) * s) * scale))

    tracks: dict[int, list[tuple[int, int]]] = {}
    for key in sorted(gt, key=int):
        for obj in gt[key]:
            tracks.setdefault(obj["object id"], []).append(pixel(*obj["3d location"][:2]))
    for oid, points in tracks.items():
        cv2.polylines(picture, [np.array(points, np.int32)], False, colour(oid), max(1, scale), cv2.LINE_AA)
        cv2.circle(picture, points[-1], 2 * scale, colour(oid), -1, cv2.LINE_AA)
    for sensor in sensors:
        attributes = {a["name"]: a["value"] for a in sensor["attributes"]}
        x, y = sensor["coordinates"]["x"], sensor["coordinates"]["y"]
        heading = math.radians(float(attributes["direction"]))
        p, q = pixel(x, y), pixel(x + 3 * math.cos(heading), y + 3 * math.sin(heading))
        cv2.arrowedLine(picture, p, q, (0, 0, 255), max(1, scale), cv2.LINE_AA, tipLength=0.3)
        cv2.circle(picture, p, 3 * scale, (0, 0, 255), -1, cv2.LINE_AA)
        cv2.putText(picture, sensor["id"][-2:], (p[0] + 4 * scale, p[1] - 2 * scale), cv2.FONT_HERSHEY_SIMPLEX,
                    0.3 * scale, (255, 255, 255), max(1, scale // 2), cv2.LINE_AA)
    return picture


def frame_picture(scene: Path, frame: int, scale: int) -> np.ndarray:
    import av

    gt = json.loads((scene / "ground_truth.json").read_text())[str(frame)]
    tiles = []
    for video in sorted((scene / "videos").glob("Camera_*.mp4")):
        with av.open(str(video)) as container:
            image = next(f for k, f in enumerate(container.decode(video=0)) if k == frame).to_ndarray(format="bgr24")
        image = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
        for obj in gt:
            c = colour(obj["object id"])
            for key, thickness in (("2d bounding box", 1), ("2d bounding box visible", 2)):
                box = obj[key].get(video.stem)
                if box:
                    x0, y0, x1, y1 = (int(v * scale) for v in box)
                    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), c, thickness)
        cv2.putText(image, video.stem, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(image)
    columns = 3
    while len(tiles) % columns:
        tiles.append(np.zeros_like(tiles[0]))
    return np.vstack([np.hstack(tiles[r:r + columns]) for r in range(0, len(tiles), columns)])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--frame", type=int, default=0)
    parser.add_argument("--scale", type=int, default=2)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out / "aicity_map.jpg"), map_picture(args.scene, args.scale), [cv2.IMWRITE_JPEG_QUALITY, 88])
    cv2.imwrite(str(args.out / "aicity_frame.jpg"), frame_picture(args.scene, args.frame, args.scale),
                [cv2.IMWRITE_JPEG_QUALITY, 85])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
