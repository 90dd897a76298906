"""A strip of frames per camera of a crowd in the station, each person's instance mask outlined
by a box in its own colour (the boxes come from the rendered masks, not from the scene).

Generates a crowd (``generate tracks --motion crowd`` as a library call), makes its cameras
small, renders the chosen frames of the chosen cameras with ``usdscene run`` and tiles them.

Usage (from the repository root)::

    python examples/station/make_strip.py OUT [--people 150] [--frames 0 40 80]
        [--cameras 3] [-o docs/img/station_strip.jpg]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
WIDTH, HEIGHT = 320, 240


def _colour(mask_id: int) -> tuple[int, int, int]:
    hue = (mask_id * 47) % 180
    bgr = cv2.cvtColor(np.uint8([[[hue, 220, 255]]]), cv2.COLOR_HSV2BGR)[0, 0]
    return tuple(int(v) for v in bgr)


def _document(out: Path, people: int, frames: int, cameras: int) -> tuple[Path, list[str]]:
    from usdscene.converters.openlabel import read_openlabel, write_openlabel
    from usdscene.generate.crowd import CrowdOptions, generate_crowd
    from usdscene.generate.motion import environment_obstacles
    from usdscene.scene.catalog import load_catalog

    setup_path = HERE / "setup.openlabel.json"
    setup = read_openlabel(setup_path)
    catalog = load_catalog(setup.asset_paths, base_dir=HERE)
    options = CrowdOptions(frames=frames, fps=10.0, people=people, seed=39, arrivals_per_min=4.0, queue_share=0.3,
                           wait_share=0.2, group_share=0.2, conversations=4, seated=4, person_classes=("person",))
    scene = generate_crowd(setup, catalog, options, obstacles=environment_obstacles(setup, catalog)).scene
    chosen = scene.cameras[:cameras]
    small = tuple(dataclasses.replace(c, intrinsics=c.intrinsics.resized(WIDTH, HEIGHT)) for c in chosen)
    scene = dataclasses.replace(scene, cameras=small, asset_paths=tuple(str((HERE / p).resolve()) for p in scene.asset_paths))
    path = out / "strip.openlabel.json"
    path.write_text(json.dumps(write_openlabel(scene)))
    return path, [c.name for c in small]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--people", type=int, default=150)
    parser.add_argument("--frames", type=int, nargs="+", default=[0, 40, 80])
    parser.add_argument("--cameras", type=int, default=3)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("-o", "--output", type=Path, default=HERE.parents[1] / "docs" / "img" / "station_strip.jpg")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    doc, cameras = _document(args.out, args.people, max(args.frames) + 1, args.cameras)
    run = args.out / "run"
    subprocess.run([sys.executable, "-m", "usdscene", "run", str(doc), "-o", str(run), "--frames",
                    ",".join(str(f) for f in args.frames), "--cameras", *cameras, "--samples", str(args.samples),
                    "--workers", "1"], check=True)
    rows = []
    for camera in cameras:
        tiles = []
        for frame in args.frames:
            image = cv2.imread(str(run / "images" / camera / f"{frame:06d}.png"))
            mask = cv2.imread(str(run / "masks" / camera / f"{frame:06d}.png"), cv2.IMREAD_UNCHANGED)
            for mask_id in (int(i) for i in np.unique(mask) if i):
                rows_at, cols_at = np.nonzero(mask == mask_id)
                cv2.rectangle(image, (int(cols_at.min()), int(rows_at.min())), (int(cols_at.max()), int(rows_at.max())),
                              _colour(mask_id), 1)
            cv2.putText(image, f"{camera}  frame {frame}", (4, image.shape[0] - 5), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(image)
        rows.append(np.hstack(tiles))
    cv2.imwrite(str(args.output), np.vstack(rows), [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
