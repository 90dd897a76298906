"""A top-down plot of a crowd document's trajectories over the station's walkable area.

Draws the walkable area of ``usdscene generate tracks --motion crowd`` (the walk places minus
the obstacles, in light grey, obstacles dark), the queue and waiting places (outlined), and every
person's ground positions (``ground_position_m`` of the document, one colour per track; standing
and seated people as dots).

Usage (from the repository root, after generating ``crowd.openlabel.json``)::

    python examples/station/make_trajectory_plot.py out/station/crowd.openlabel.json \
        -o docs/img/station_trajectories.png
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np

PX_PER_M = 14
MARGIN_PX = 10
CAPTION_PX = 16


def _colour(k: int) -> tuple[int, int, int]:
    bgr = cv2.cvtColor(np.uint8([[[(k * 47) % 180, 200, 210]]]), cv2.COLOR_HSV2BGR)[0, 0]
    return tuple(int(v) for v in bgr)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("document", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=Path("station_trajectories.png"))
    args = parser.parse_args(argv)

    from usdscene.converters.openlabel import read_openlabel
    from usdscene.generate.crowd_area import crowd_layout
    from usdscene.generate.motion import environment_obstacles
    from usdscene.scene.catalog import load_catalog

    scene = read_openlabel(args.document)
    catalog = load_catalog(scene.asset_paths, base_dir=args.document.parent)
    setup = dataclasses.replace(scene, objects=())
    layout = crowd_layout(setup, catalog, environment_obstacles(setup, catalog))
    x0, y0, x1, y1 = layout.walkable.bounds
    width, height = int((x1 - x0) * PX_PER_M) + 2 * MARGIN_PX, int((y1 - y0) * PX_PER_M) + 2 * MARGIN_PX + CAPTION_PX

    def px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([(xy[:, 0] - x0) * PX_PER_M + MARGIN_PX, (y1 - xy[:, 1]) * PX_PER_M + MARGIN_PX],
                        axis=1).round().astype(np.int32)

    image = np.full((height, width, 3), 70, np.uint8)
    for piece in getattr(layout.walkable, "geoms", [layout.walkable]):
        cv2.fillPoly(image, [px(np.asarray(piece.exterior.coords))], (235, 235, 235))
        for hole in piece.interiors:
            cv2.fillPoly(image, [px(np.asarray(hole.coords))], (150, 150, 150))
    for stage in layout.stages:
        if stage.role in ("queue", "wait", "seat"):
            a = stage.area
            corners = a.centre[:2] + (np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * a.half) @ a.axes.T
            cv2.polylines(image, [px(corners)], True, (40, 40, 200) if stage.role == "queue" else (40, 150, 40), 1)
    people = [o for o in scene.objects if o.frame_extra]
    for k, obj in enumerate(people):
        points = []
        for _, text in obj.frame_extra:
            data = json.loads(text)["object_data"]
            points.append(next(v["val"] for v in data["vec"] if v["name"] == "ground_position_m")[:2])
        p = px(np.asarray(points))
        colour = _colour(k)
        if np.ptp(p, axis=0).max() <= 2:
            cv2.circle(image, tuple(int(v) for v in p[0]), 2, colour, -1, cv2.LINE_AA)
        else:
            cv2.polylines(image, [p], False, colour, 1, cv2.LINE_AA)
    cv2.putText(image, f"{len(people)} people, {scene.frame_end - scene.frame_start + 1} frames at {scene.fps:g} fps; "
                "queues red, waiting places and benches green", (MARGIN_PX, height - 3), cv2.FONT_HERSHEY_SIMPLEX,
                0.4, (255, 255, 255), 1, cv2.LINE_AA)
    cv2.imwrite(str(args.output), image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
