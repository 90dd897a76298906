"""What exposure that adapts over frames costs: render seconds per image of the car park's
``pole_north`` through ``outdoor_bullet`` with an instant exposure and with ``exposure_speed``
0.5 (every frame metered by a pre-pass, usdscene.sensor.exposure), and for a shard that starts
mid-sequence (it pre-passes the 7 frames of its window before its first image).

    python benchmarks/exposure_prepass_cost.py OUT [--frames 3] [--width 320]

Each variant renders its frames in one worker (the document's 8 samples + denoising). Printed
per variant: the render CPU seconds (all threads; the pre-passes are inside the pair's render
time) of the first image and the mean of the others, as ratios to the instant exposure, and the
exposures chosen.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CAR_PARK = REPO / "examples" / "car_park"


def document(sensor: dict, frames: range, width: int) -> dict:
    doc = json.loads((CAR_PARK / "car_park.openlabel.json").read_text())
    setup = json.loads((CAR_PARK / "setup.openlabel.json").read_text())
    body = doc["openlabel"]
    block = body["metadata"]["usdscene"]
    block["asset_paths"] = [str(CAR_PARK / "assets")]
    block["frame_range"] = {"frame_start": 0, "frame_end": frames.stop - 1}
    block["exports"] = []
    del body["coordinate_systems"]
    stream = copy.deepcopy(setup["openlabel"]["streams"]["pole_north"])
    stream["stream_properties"]["usdscene"]["resolution_px"] = [width, width * 3 // 4]
    stream["stream_properties"]["usdscene"]["sensor"] = sensor
    body["streams"] = {"pole_north": stream}
    return doc


def main() -> None:
    from usdscene.document import output_layout as layout
    from usdscene.pipeline import RunOptions, run_pipeline
    from usdscene.sensor.exposure import warmup_frames

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--width", type=int, default=320)
    args = parser.parse_args()
    os.environ["USDSCENE_ASSET_PATH"] = str(CAR_PARK)
    warmup = warmup_frames(0.5)
    start = range(0, args.frames)
    later = range(warmup, warmup + args.frames)
    variants = {
        "instant exposure": ({"profile": "outdoor_bullet"}, start),
        "exposure_speed 0.5, frames from 0": ({"profile": "outdoor_bullet", "exposure_speed": 0.5}, start),
        f"exposure_speed 0.5, frames from {warmup}": ({"profile": "outdoor_bullet", "exposure_speed": 0.5}, later),
    }
    results = {}
    for i, (name, (sensor, frames)) in enumerate(variants.items()):
        folder = args.out / f"variant{i}"
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / "scene.openlabel.json"
        path.write_text(json.dumps(document(sensor, frames, args.width)))
        run_pipeline(path, folder / "out", RunOptions(frames=list(frames), exports=[], report=False), progress=False)
        done = json.loads((folder / "out" / "manifest.json").read_text())["done"]["pole_north"]
        cpu = [done[str(f)]["render_cpu_s"] for f in frames]
        evs = [json.loads(layout.exposure_path(folder / "out", "pole_north", f).read_text())["exposure_ev"]
               for f in frames]
        results[name] = (cpu[0], float(np.mean(cpu[1:])), evs)
    base_first, base_rest, _ = results["instant exposure"]
    print(f"car park pole_north, outdoor_bullet, {args.width}x{args.width * 3 // 4}, 8 samples + denoising, "
          f"{args.frames} frames, window {warmup} frames, load average {os.getloadavg()[0]:.1f}")
    print(f"{'variant':40s} {'first cpu s':>11s} {'ratio':>6s} {'later cpu s':>11s} {'ratio':>6s}  exposures (EV)")
    for name, (first, rest, evs) in results.items():
        print(f"{name:40s} {first:11.2f} {first / base_first:6.2f} {rest:11.2f} {rest / base_rest:6.2f}  "
              + " ".join(f"{ev:+.3f}" for ev in evs))


if __name__ == "__main__":
    main()
