"""Render seconds of the car park example under a black world, a physical sky, a sky whose
strength changes every frame (what domain randomisation writes) and an HDRI, one camera.

    python benchmarks/world_render_cost.py OUT [--frames 3] [--samples 8] [--width 640]

Each variant renders frames 0..N-1 of ``pole_north`` in one worker (640x480, the document's
8 samples + denoising by default). Printed per variant: the first image's render seconds (it
includes building the world: Blender bakes the sky's texture and Cycles the world's importance
map when the world first syncs), the mean of the others, and both as a ratio to the black world.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
CAR_PARK = REPO / "examples" / "car_park"


def document(world: dict | None, frames: int, samples: int, width: int) -> dict:
    doc = json.loads((CAR_PARK / "car_park.openlabel.json").read_text())
    setup = json.loads((CAR_PARK / "setup.openlabel.json").read_text())
    body = doc["openlabel"]
    block = body["metadata"]["usdscene"]
    block["asset_paths"] = [str(CAR_PARK / "assets")]
    block["render"] = dict(block["render"], samples=samples)
    block["frame_range"] = {"frame_start": 0, "frame_end": frames - 1}
    block["exports"] = []
    block.pop("world", None)
    if world is not None:
        block["world"] = world
    del body["coordinate_systems"]
    stream = copy.deepcopy(setup["openlabel"]["streams"]["pole_north"])
    stream["stream_properties"]["usdscene"]["resolution_px"] = [width, width * 3 // 4]
    body["streams"] = {"pole_north": stream}
    return doc


def main() -> None:
    from usdscene.pipeline import RunOptions, run_pipeline

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--width", type=int, default=640)
    args = parser.parse_args()
    os.environ["USDSCENE_ASSET_PATH"] = str(CAR_PARK)
    args.out.mkdir(parents=True, exist_ok=True)
    hdri = args.out / "variant3" / "sky.hdr"  # in the document's folder: a readable place
    hdri.parent.mkdir(parents=True, exist_ok=True)
    rows = np.linspace(1.0, 0.2, 64, dtype=np.float32)[:, None, None]
    cv2.imwrite(str(hdri), np.concatenate([np.broadcast_to(rows * np.array([0.9, 0.6, 0.4], np.float32), (64, 128, 3)),
                                           np.full((64, 128, 3), 0.15, np.float32)], axis=0))
    variants = {
        "black world (no world block)": None,
        "physical sky (nishita)": {"sky": "nishita"},
        "sky, strength per frame": {"sky": "nishita", "per_frame": {str(f): {"strength": 0.8 + 0.1 * f}
                                                                   for f in range(args.frames)}},
        "HDRI 128x128": {"hdri": hdri.name},
    }
    results = {}
    for name, world in variants.items():
        folder = args.out / f"variant{len(results)}"
        path = folder / "scene.openlabel.json"
        folder.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(document(world, args.frames, args.samples, args.width)))
        run_pipeline(path, folder / "out", RunOptions(exports=[]), progress=False)
        manifest = json.loads((folder / "out" / "manifest.json").read_text())
        times = [manifest["done"]["pole_north"][str(f)]["render_s"] for f in range(args.frames)]
        results[name] = (times[0], float(np.mean(times[1:])) if len(times) > 1 else float("nan"))
    base_first, base_rest = results["black world (no world block)"]
    print(f"car park pole_north, {args.width}x{args.width * 3 // 4}, {args.samples} samples + denoising, "
          f"{args.frames} frames, load average {os.getloadavg()[0]:.1f}")
    print(f"{'world':32s} {'first s':>8s} {'ratio':>6s} {'later s':>8s} {'ratio':>6s}")
    for name, (first, rest) in results.items():
        print(f"{name:32s} {first:8.2f} {first / base_first:6.2f} {rest:8.2f} {rest / base_rest:6.2f}")


if __name__ == "__main__":
    main()
