"""The AI City Challenge example: the moving car park seen by six pinhole cameras, generated,
rendered small, exported as an AIC Track 1 scene and drawn from the export.

Usage (from anywhere)::

    python examples/car_park/make_aicity.py WORK [--frames 12] [--fps 6] [--people 10]
        [--resolution 256 144] [--samples 2] [--pictures DIR]

writes ``WORK/setup_aicity.openlabel.json`` (``setup_moving.openlabel.json`` with its fisheye
and distorted cameras replaced by six perspective cameras: AIC's calibration has no distortion),
``WORK/aicity.openlabel.json`` (``usdscene generate tracks``), the run ``WORK/out`` (with 16-bit depth) and its
export ``WORK/out/exports/aicity/Scene_000``; with ``--pictures`` also the map and frame
pictures of ``make_aicity_pictures.py``. Nothing is written into the repository unless
``--pictures`` names a folder in it.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# (name, position, target): poles at the deck's corners and edges above head height, the two
# under the roof deck (row B side) below it.
CAMERAS = (
    ("pole_north", (-16.0, 11.5, 6.0), (-1.0, 2.0, 0.0)),
    ("pole_east", (16.5, 9.0, 5.5), (0.0, -4.0, 0.0)),
    ("pole_north_mid", (0.0, 12.8, 5.0), (0.0, 3.0, 0.0)),
    ("pole_north_east", (16.0, 12.5, 5.0), (4.0, 8.0, 0.0)),
    ("deck_south_west", (-16.5, -11.0, 2.8), (-2.0, -3.0, 0.0)),
    ("deck_south_east", (16.5, -11.0, 2.8), (2.0, -3.0, 0.0)),
)


def setup_document(resolution: tuple[int, int], samples: int) -> dict:
    setup = json.loads((HERE / "setup_moving.openlabel.json").read_text())
    root = setup["openlabel"]
    root["metadata"]["usdscene"]["render"].update(samples=samples, resolution_px=list(resolution), depth="png16")
    root["metadata"]["usdscene"]["exports"] = []
    root["streams"] = {name: {"type": "camera", "description": f"AIC example: perspective camera {name}",
                              "stream_properties": {"usdscene": {
                                  "model": "perspective", "model_name": "bullet camera 4 mm",
                                  "resolution_px": list(resolution), "sensor_size_mm": [5.6, 3.15],
                                  "fov_deg": 75.0, "position_m": list(position), "target_m": list(target)}}}
                       for name, position, target in CAMERAS}
    root["metadata"]["comment"] = ("AI City Challenge example: the moving car park setup seen by six perspective "
                                   "cameras (written by examples/car_park/make_aicity.py)")
    return setup


def run(*args: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "usdscene", *args], check=True)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("work", type=Path)
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--fps", type=float, default=6.0)
    parser.add_argument("--people", type=int, default=10)
    parser.add_argument("--resolution", type=int, nargs=2, default=(256, 144))
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--map-m-per-px", type=float, default=0.05)
    parser.add_argument("--pictures", type=Path)
    args = parser.parse_args()
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    for name in ("assets", "source"):
        if not (work / name).exists():
            shutil.copytree(HERE / name, work / name)
    setup, doc, out = work / "setup_aicity.openlabel.json", work / "aicity.openlabel.json", work / "out"
    setup.write_text(json.dumps(setup_document(tuple(args.resolution), args.samples), indent=2))
    times = {"generate": run("generate", "tracks", "--setup", str(setup), "-o", str(doc), "--frames", str(args.frames),
                             "--fps", f"{args.fps:g}", "--people", str(args.people), "--standing", "2",
                             "--vehicles", "2", "--seed", "3")}
    times["run"] = run("run", str(doc), "-o", str(out), "--no-progress")
    times["export"] = run("export", "aicity", str(out), "--map-m-per-px", f"{args.map_m_per_px:g}")
    scene = out / "exports" / "aicity" / "Scene_000"
    size = sum(p.stat().st_size for p in scene.rglob("*") if p.is_file())
    print(f"times (s): " + ", ".join(f"{k} {v:.0f}" for k, v in times.items()))
    print(f"scene folder {scene}: {size / 1e6:.2f} MB")
    if args.pictures:
        subprocess.run([sys.executable, str(HERE / "make_aicity_pictures.py"), str(scene), str(args.pictures),
                        "--frame", str(args.frames // 2)], check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
