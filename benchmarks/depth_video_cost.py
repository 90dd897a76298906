"""What the 3D ground truth costs: render time per image with the depth output off and on, and
the video export's time per image.

    python benchmarks/depth_video_cost.py [--size 320 240] [--frames 10] [--samples 4] [--repeat 2] [--out DIR]

The moving car park (``examples/car_park/setup_moving.openlabel.json`` through ``usdscene
generate tracks``: 6 walkers, 1 standing, 2 vehicles, 5 fps) at ``--size``, ``--samples``
samples without denoising, 1 bounce, cameras ``pole_north`` (perspective),
``ceiling_fisheye`` (equidistant fisheye) and ``entrance_wide`` (OpenCV pinhole: rendered wider
and remapped, the depth with the mask's nearest-neighbour map), rendered by ``usdscene run`` with ``render.depth``
absent, then ``png16``, then ``exr``, ``--repeat`` times in turn (so a change of the machine's
load hits every variant alike). The render figure is per image from the manifest: Cycles'
render plus the worker's decoding and writing (``render_s + decode_s + post_s``), without
Blender's start, the stage import and the labelling; the median of the run's images, and the
ratio on / off; then the same per camera. The video figure is ``export_video`` of the ``png16`` run (its images, both
cameras), seconds per image, best of ``--repeat``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CAR_PARK = REPO / "examples" / "car_park"
CAMERAS = ("pole_north", "ceiling_fisheye", "entrance_wide")


def _document(folder: Path, size, frames: int, samples: int, depth) -> Path:
    from usdscene.cli import main

    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    for stream in setup["openlabel"]["streams"].values():
        stream["stream_properties"]["usdscene"]["resolution_px"] = list(size)
    render = setup["openlabel"]["metadata"]["usdscene"]["render"]
    render.update(samples=samples, denoise=False, max_bounces=1)
    if depth is not None:
        render["depth"] = depth
    setup_path = folder / f"setup_{depth}.json"
    setup_path.write_text(json.dumps(setup))
    doc = folder / f"doc_{depth}.json"
    assert main(["generate", "tracks", "--setup", str(setup_path), "-o", str(doc), "--frames", str(frames),
                 "--fps", "5", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "1"]) == 0
    return doc


def _seconds_per_image(out: Path, camera: str | None = None) -> float:
    """Median seconds per image of a run (of one camera's images when ``camera`` is given)."""
    manifest = json.loads((out / "manifest.json").read_text())
    times = [t["render_s"] + t.get("decode_s", 0.0) + t.get("post_s", 0.0)
             for name, frames in manifest["done"].items() if camera in (None, name) for t in frames.values()]
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(320, 240))
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    from usdscene.cli import main as cli
    from usdscene.converters.exports.video import export_video

    folder = args.out or Path(tempfile.mkdtemp(prefix="depth_video_cost_"))
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("assets", "source"):
        if not (folder / name).exists():
            shutil.copytree(CAR_PARK / name, folder / name)
    variants = (None, "png16", "exr")
    docs = {v: _document(folder, args.size, args.frames, args.samples, v) for v in variants}
    figures: dict = {v: [] for v in variants}
    per_camera: dict = {}
    for k in range(args.repeat):
        for v in variants:
            out = folder / f"out_{v}_{k}"
            shutil.rmtree(out, ignore_errors=True)
            assert cli(["run", str(docs[v]), "-o", str(out), "--cameras", *CAMERAS, "--no-progress"]) == 0
            figures[v].append(_seconds_per_image(out))
            for camera in CAMERAS:
                per_camera.setdefault((v, camera), []).append(_seconds_per_image(out, camera))
    images = args.frames * len(CAMERAS)
    print(f"{args.size[0]}x{args.size[1]}, {args.samples} samples, {images} images per run, "
          f"load {os.getloadavg()[0]:.1f}")
    off = min(figures[None])
    for v in variants:
        best = min(figures[v])
        runs = ", ".join(f"{s:.3f}" for s in figures[v])
        print(f"depth {v or 'off':6s}: {best:.3f} s per image (median per run: {runs}); on / off {best / off:.3f}")
    for camera in CAMERAS:
        off = min(per_camera[(None, camera)])
        print(f"  {camera}: " + ", ".join(f"{v or 'off'} {min(per_camera[(v, camera)]):.3f} s "
                                         f"({min(per_camera[(v, camera)]) / off:.3f})" for v in variants))
    document = json.loads((folder / "out_png16_0" / "annotations.openlabel.json").read_text())
    seconds = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        export_video(document, folder / "out_png16_0")
        seconds.append(time.perf_counter() - start)
    per_image = min(seconds) / images
    print(f"video export: {per_image * 1000:.1f} ms per image ({images} images, best of {args.repeat}); "
          f"10,000 images: {per_image * 10000:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
