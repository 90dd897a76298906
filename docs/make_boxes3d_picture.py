"""The 3D boxes of an annotated moving run drawn on its frames (docs/img/boxes3d_car_park.jpg).

Reads only the annotated document (``OUT/annotations.openlabel.json``: the ``box3d`` cuboids,
the cameras as calibrated) and the rendered images. Each box's 12 edges are sampled and
projected through the camera's own lens model (``usdscene.labels.projection.project_points``),
so edges bend on the fisheye as the image does; one colour per track id, the same in every
camera. Rows are cameras, columns frames.

Usage (after ``usdscene run examples/car_park/moving.openlabel.json -o OUT --frames 10,50,90``)::

    python docs/make_boxes3d_picture.py OUT [--frames 10 50 90] [--scale 2] [-o docs/img/boxes3d_car_park.jpg]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

# The 12 edges of a Cuboid's corners (bit 0 = +x, bit 1 = +y, bit 2 = +z).
EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
SAMPLES_PER_EDGE = 24


def _colour(track_id: int) -> tuple[int, int, int]:
    hue = (track_id * 47) % 180
    bgr = cv2.cvtColor(np.uint8([[[hue, 220, 255]]]), cv2.COLOR_HSV2BGR)[0, 0]
    return tuple(int(v) for v in bgr)


def main(argv=None) -> int:
    from usdscene.converters.exports.tracks import track_ids
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.labels.cross_camera import camera_for_image
    from usdscene.labels.cuboids import document_cuboids
    from usdscene.labels.projection import project_points

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, nargs="+", default=[10, 50, 90])
    parser.add_argument("--scale", type=int, default=2)
    parser.add_argument("--quality", type=int, default=85)
    parser.add_argument("-o", "--output", type=Path,
                        default=Path(__file__).resolve().parent / "img" / "boxes3d_car_park.jpg")
    args = parser.parse_args(argv)
    path = args.out / "annotations.openlabel.json"
    document = json.loads(path.read_text())
    boxes = document_cuboids(document)
    scene = read_openlabel(path)
    ids = track_ids(document)
    objects = document["openlabel"]["objects"]
    movers = {uid for uid, o in objects.items() if o["type"] in ("person", "pedestrian", "vehicle")}
    t = np.linspace(0.0, 1.0, SAMPLES_PER_EDGE)[:, None]
    rows = []
    for camera in sorted(scene.cameras, key=lambda c: c.name):
        tiles = []
        for frame in args.frames:
            image = cv2.imread(str(args.out / "images" / camera.name / f"{frame:06d}.png"), cv2.IMREAD_COLOR)
            if image is None:
                raise SystemExit(f"{args.out}: no image of {camera.name} at frame {frame}")
            h, w = image.shape[:2]
            posed = camera_for_image(camera, frame, w, h)
            image = cv2.resize(image, None, fx=args.scale, fy=args.scale, interpolation=cv2.INTER_CUBIC)
            for uid, box in sorted(boxes.get(frame, {}).items()):
                if uid not in movers:
                    continue
                corners = box.corners()
                points = np.concatenate([corners[a] + t * (corners[b] - corners[a]) for a, b in EDGES])
                uv, valid = project_points(posed, points)
                uv = (uv + 0.5) * args.scale - 0.5  # pixel centres at integers, scaled
                colour = _colour(ids[uid])
                for k in range(len(EDGES)):
                    seg = slice(k * SAMPLES_PER_EDGE, (k + 1) * SAMPLES_PER_EDGE)
                    for (p, q), ok in zip(zip(uv[seg][:-1], uv[seg][1:]), valid[seg][:-1] & valid[seg][1:]):
                        if ok:
                            cv2.line(image, tuple(int(round(v)) for v in p), tuple(int(round(v)) for v in q),
                                     colour, 1, cv2.LINE_AA)
            cv2.putText(image, f"{camera.name}  frame {frame}", (4, image.shape[0] - 6), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(image)
        rows.append(np.hstack(tiles))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.output), np.vstack(rows), [cv2.IMWRITE_JPEG_QUALITY, args.quality])
    print(args.output, args.output.stat().st_size, "bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
