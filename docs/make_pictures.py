"""Make the quickstart's pictures from a real ``usdscene run`` output folder.

Writes into ``docs/img/``:

* ``contact_sheet.jpg`` — every camera's image of one frame, camera names on the tiles;
* ``labels.png`` — one image with its boxes (green: visible, grey dashed: amodal) and polygons
  drawn from ``annotations.openlabel.json``, i.e. from the written labels, not from internal state;
* ``stats.png`` — the chart of ``usdscene stats``.

Usage::

    usdscene run examples/aircraft_cabin/cabin.openlabel.json -o out/
    python docs/make_pictures.py out/ [--camera seats_L03] [--frame 0]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from usdscene.converters.openlabel import load_document
from usdscene.converters.openlabel.annotations import image_records, labels_in
from usdscene.document import output_layout as layout
from usdscene.dataset.contact_sheet import contact_sheet
from usdscene.dataset.statistics import draw_chart, label_statistics
from usdscene.files import write_bytes_atomic, write_png_atomic

IMG = Path(__file__).resolve().parent / "img"


def draw_labels(image: np.ndarray, labels: list[dict], scale: int = 2) -> np.ndarray:
    """Boxes and polygons of one image drawn on a copy enlarged ``scale`` times.

    Args:
        image: (H, W, 3) uint8 BGR.
        labels: :func:`usdscene.converters.openlabel.annotations.labels_in` records.
    """
    big = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    subpixel_bits = 4  # OpenCV's fixed-point drawing: coordinates in 1/16 px

    def corners(box):
        """OpenLABEL [cx, cy, w, h] (pixel centres at integer coordinates) → the first and last
        enlarged pixel inside the box, so that both edges are drawn on the box's own pixels."""
        cx, cy, w, h = box
        return ((cx - w / 2 + 0.5) * scale, (cy - h / 2 + 0.5) * scale), ((cx + w / 2 + 0.5) * scale - 1,
                                                                          (cy + h / 2 + 0.5) * scale - 1)

    def drawn(points):
        """Image coordinates (pixel centres at integers) → OpenCV's fixed-point coordinates of
        the enlarged picture, where enlarged pixel j has its centre at j: pixel-outline
        vertices land on the pixels' edges, not half a pixel beside them."""
        return np.round(((points + 0.5) * scale - 0.5) * (1 << subpixel_bits)).astype(np.int32)

    for label in labels:
        if label["amodal_bbox"]:
            (x0, y0), (x1, y1) = corners(label["amodal_bbox"])
            cv2.rectangle(big, (round(x0), round(y0)), (round(x1), round(y1)), (160, 160, 160), 1)
        for poly in label["polygons"]:
            pts = np.asarray(poly["points"], float).reshape(-1, 2)
            colour = (0, 0, 255) if poly["is_hole"] else (255, 200, 0)
            cv2.polylines(big, [drawn(pts)], True, colour, 1, cv2.LINE_AA, subpixel_bits)
        if label["bbox"]:
            (x0, y0), (x1, y1) = corners(label["bbox"])
            cv2.rectangle(big, (round(x0), round(y0)), (round(x1), round(y1)), (0, 220, 0), 1)
            fraction = label["attributes"].get("visible_fraction")
            text = label["type"] + (f" {fraction:.2f}" if isinstance(fraction, (int, float)) else "")
            cv2.putText(big, text, (round(x0) + 2, max(10, round(y0) - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 255, 0), 1, cv2.LINE_AA)
    return big


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="quickstart pictures from a run's output folder")
    parser.add_argument("output", type=Path, help="output folder of `usdscene run`")
    parser.add_argument("--camera", default="seats_L03", help="camera of the labelled picture")
    parser.add_argument("--frame", type=int, default=0)
    args = parser.parse_args(argv)

    document = load_document(args.output / layout.ANNOTATIONS_FILE)
    records = [r for r in image_records(document) if r["frame"] == args.frame]
    tiles = [(r["camera"], cv2.imread(str(layout.image_path(args.output, r["camera"], args.frame))))
             for r in records]
    # JPEG: a sheet of 39 noisy camera images is a photograph (a PNG of it took 1.8 MB)
    ok, sheet = cv2.imencode(".jpg", contact_sheet(tiles, tile_width=180, columns=8), [cv2.IMWRITE_JPEG_QUALITY, 80])
    write_bytes_atomic(IMG / "contact_sheet.jpg", sheet.tobytes())

    image = cv2.imread(str(layout.image_path(args.output, args.camera, args.frame)))
    # the strongest PNG compression: a noisy camera image at the default level took 400 KB
    ok, drawn = cv2.imencode(".png", draw_labels(image, labels_in(document, args.frame, args.camera)),
                             [cv2.IMWRITE_PNG_COMPRESSION, 9])
    write_bytes_atomic(IMG / "labels.png", drawn.tobytes())
    write_png_atomic(IMG / "stats.png", draw_chart(label_statistics(document)))
    print(f"wrote {IMG / 'contact_sheet.jpg'}, {IMG / 'labels.png'}, {IMG / 'stats.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
