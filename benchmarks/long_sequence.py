"""The long run: a car park sequence of F frames x 10 cameras x 100 people through every step
of the pipeline, each step measured (target: 9,000 frames, peak memory <= 8 GB, every step
linear in frames).

``python benchmarks/long_sequence.py [--frames 9000 ...] [--cameras 10] [--people 100]
[--size 32x24] [--samples 1] [--exports coco yolo mot multiview aicity] [--folder DIR]``

For each ``--frames`` value the script writes a setup (the car park's moving setup with its
cameras replaced by ``--cameras`` perspective cameras on a ring, rendering at ``--size``), then
runs each step as the command a user types, in a fresh process:

1. ``usdscene generate tracks`` (``--people`` walkers, ``--standing`` of them standing still, 30 fps);
2. ``usdscene validate``;
3. ``usdscene compose``;
4. ``usdscene render`` at the tiny size with ``--samples`` (Cycles renders every image: at a
   tiny size and one sample the time is mostly the bookkeeping around the renders, imports
   of the stage per shard, masks, manifest);
5. ``usdscene annotate`` (labels, amodal boxes, keypoints from the stage geometry);
6. ``usdscene export FORMAT`` for each of ``--exports``;
7. ``usdscene report``.

Per step: wall time, CPU time, peak resident memory (``ru_maxrss`` of the step's process,
which Linux reports as the largest of it and the children it waited for, i.e. the render's
workers) and the bytes it added to the run folder; then the document's and the stage's bytes
per person-frame. With two or more ``--frames`` values, each step's CPU-time ratio between the
longest and the shortest run beside the frame ratio (linear: the two ratios agree). CPU time
is the figure to read on a shared machine; the load average is printed with each step.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SETUP = REPO / "examples" / "car_park" / "setup_moving.openlabel.json"


def write_setup(path: Path, cameras: int, size: tuple[int, int], samples: int) -> None:
    """The car park's moving setup with ``cameras`` perspective cameras on a ring around the
    deck centre (6 m up, looking at the deck), each rendering at ``size``."""
    doc = json.loads(SETUP.read_text(encoding="utf-8"))
    body = doc["openlabel"]
    body["metadata"]["usdscene"]["render"].update({"samples": samples, "denoise": False,
                                                    "resolution_px": list(size)})
    body["metadata"]["usdscene"]["asset_paths"] = [os.path.relpath(REPO / "examples" / "car_park" / "assets",
                                                                   path.parent)]
    streams = {}
    for c in range(cameras):
        angle = 2 * math.pi * c / cameras
        streams[f"cam_{c:02d}"] = {"type": "camera", "description": "ring camera of the long-run benchmark",
                                   "stream_properties": {"usdscene": {
                                       "model": "perspective", "resolution_px": list(size),
                                       "sensor_size_mm": [5.6, 4.2], "fov_deg": 78.0,
                                       "position_m": [round(16 * math.cos(angle), 3), round(11 * math.sin(angle), 3), 6.0],
                                       "target_m": [0.0, 0.0, 0.0]}}}
    body["streams"] = streams
    path.write_text(json.dumps(doc, indent=2), encoding="utf-8")


def folder_bytes(folder: Path) -> int:
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            try:
                total += os.lstat(os.path.join(root, name)).st_size
            except FileNotFoundError:
                pass
    return total


def run_step(args: list, cwd: Path, folder: Path, *, refusable: bool = False) -> dict:
    """Run ``usdscene ARGS`` in a fresh process; wall, CPU, peak memory, bytes added. A step
    that fails stops the run, except a ``refusable`` one (an export that refuses the data),
    whose last error line is kept as ``refused``."""
    before = folder_bytes(folder)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen([sys.executable, "-m", "usdscene.cli", *map(str, args)], cwd=cwd,
                                stdout=subprocess.DEVNULL, stderr=errors)
        # wait4: this process's resource use, its waited-for children included.
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            errors.seek(0)
            message = errors.read().decode(errors="replace").strip().splitlines()
            if not refusable:
                raise SystemExit(f"usdscene {' '.join(map(str, args))} failed ({proc.returncode}):\n"
                                 + "\n".join(message[-30:]))
            return {"refused": message[-1] if message else f"exit {proc.returncode}", "wall_s": wall,
                    "cpu_s": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024,
                    "disk_mb": 0.0, "load": os.getloadavg()[0]}
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024,
            "disk_mb": (folder_bytes(folder) - before) / 1e6, "load": (load + os.getloadavg()[0]) / 2}


STEPS = ("generate", "validate", "compose", "render", "annotate", "export", "report")


def run_once(root: Path, frames: int, cameras: int, people: int, size: tuple[int, int], samples: int,
             exports: list[str], steps_wanted=STEPS, standing: int = 0) -> tuple[dict, dict]:
    root.mkdir(parents=True, exist_ok=True)
    setup, doc, out = root / "setup.json", root / "doc.json", root / "run"
    write_setup(setup, cameras, size, samples)
    commands = {
        "generate": ["generate", "tracks", "--setup", setup, "-o", doc, "--frames", frames, "--fps", 30,
                     "--people", people - standing, "--standing", standing, "--seed", 1],
        "validate": ["validate", doc],
        "compose": ["compose", doc, "-o", out],
        "render": ["render", out / "stage" / "scene.usda", "-o", out, "--no-progress"],
        "annotate": ["annotate", out, "--no-progress"],
        **{f"export {fmt}": ["export", fmt, out] for fmt in exports},
        "report": ["report", out],
    }
    steps = {}
    for name, command in commands.items():
        if name.split()[0] in steps_wanted:
            steps[name] = run_step(command, root, root, refusable=name.startswith("export"))
    body = json.loads(doc.read_text(encoding="utf-8"))["openlabel"]
    person_frames = sum(len(entry.get("objects", {})) for entry in body.get("frames", {}).values())
    del body
    stage = out / "stage"
    annotations = out / "annotations.openlabel.json"
    sizes = {"person_frames": person_frames, "document_bytes": doc.stat().st_size,
             "stage_bytes": folder_bytes(stage), "objects_layer_bytes": (stage / "objects.usda").stat().st_size,
             "annotations_bytes": annotations.stat().st_size if annotations.exists() else 0,
             "images": cameras * frames}
    return steps, sizes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[9000])
    parser.add_argument("--cameras", type=int, default=10)
    parser.add_argument("--people", type=int, default=100)
    parser.add_argument("--standing", type=int, default=0,
                        help="of --people, how many stand still (the car park's routes hold about 38 "
                             "walkers at once over 300 frames at 30 fps)")
    parser.add_argument("--size", default="32x24", help="image size WxH (default 32x24)")
    parser.add_argument("--samples", type=int, default=1)
    parser.add_argument("--exports", nargs="*", default=["coco", "yolo", "mot", "multiview", "aicity"])
    parser.add_argument("--steps", nargs="+", choices=STEPS, default=list(STEPS),
                        help="the steps to run (default all; a step needs the ones before it)")
    parser.add_argument("--folder", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))
    base = args.folder or Path(tempfile.mkdtemp(prefix="long_sequence_"))
    # The run folders lie outside the repository: allow the car park's assets there.
    os.environ["USDSCENE_ASSET_PATH"] = str(REPO / "examples" / "car_park")
    results = {}
    for frames in args.frames:
        print(f"## {frames} frames x {args.cameras} cameras x {args.people} people ({args.standing} standing), "
              f"{size[0]}x{size[1]}, "
              f"{args.samples} sample(s) — {base / f'f{frames}'}", flush=True)
        steps, sizes = run_once(base / f"f{frames}", frames, args.cameras, args.people, size, args.samples,
                                args.exports, args.steps, args.standing)
        results[frames] = (steps, sizes)
        print("| step | wall s | CPU s | peak MB | disk MB | load |\n|---|---|---|---|---|---|")
        for name, s in steps.items():
            if "refused" in s:
                print(f"| {name} | refused: {s['refused']} | | | | |")
                continue
            print(f"| {name} | {s['wall_s']:.1f} | {s['cpu_s']:.1f} | {s['peak_mb']:.0f} | {s['disk_mb']:.1f} | "
                  f"{s['load']:.1f} |")
        pf = max(1, sizes["person_frames"])
        print(f"person-frames {sizes['person_frames']}, images {sizes['images']}: document "
              f"{sizes['document_bytes'] / 1e6:.1f} MB ({sizes['document_bytes'] / pf:.0f} B/person-frame), stage "
              f"{sizes['stage_bytes'] / 1e6:.1f} MB ({sizes['stage_bytes'] / pf:.0f} B/person-frame; objects layer "
              f"{sizes['objects_layer_bytes'] / pf:.0f}), annotations {sizes['annotations_bytes'] / 1e6:.1f} MB",
              flush=True)
        peak = max(s["peak_mb"] for s in steps.values())
        print(f"peak memory of any step: {peak:.0f} MB (target 8192)\n", flush=True)
    if len(results) > 1:
        short, long = min(results), max(results)
        print(f"## linearity: {long} / {short} frames = {long / short:.1f}\n| step | CPU ratio | wall ratio |\n|---|---|---|")
        for name in results[short][0]:
            a, b = results[short][0][name], results[long][0][name]
            if "refused" in a or "refused" in b:
                continue
            print(f"| {name} | {b['cpu_s'] / max(a['cpu_s'], 1e-9):.2f} | {b['wall_s'] / max(a['wall_s'], 1e-9):.2f} |")


if __name__ == "__main__":
    main()
