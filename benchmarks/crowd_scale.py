"""Crowd generation at scale: ``generate tracks --motion crowd`` on the station, N people kept
inside over F frames at 10 fps (target: 500 people x 3,000 frames under 2 minutes; 1,000
feasible). Each case runs in a fresh process; it prints the engine's time, the whole generation
(engine, tracks and document) and the process's peak memory.

Usage::

    python benchmarks/crowd_scale.py [--cases 500x3000 1000x3000] [--compose 50 200 500]

``--compose N ...`` also generates a 20-frame crowd of N people, composes it (seconds, the
stage's layers in MB, peak memory) and renders one 320 x 240 image (1 sample) of frame 10 with
one worker: the worker's wall time, USD import, render call, its memory after the image, and
the people's meshes before and after :mod:`usdscene.render.blender.mesh_sharing` shares them.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SETUP = ROOT / "examples" / "station" / "setup.openlabel.json"

_CASE = r"""
import json, resource, sys, time
from pathlib import Path
from usdscene.converters.openlabel import read_openlabel
from usdscene.generate import crowd as crowd_module
from usdscene.generate.crowd import CrowdOptions, generate_crowd
from usdscene.generate.motion import environment_obstacles
from usdscene.scene.catalog import load_catalog

setup_path, people, frames = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
scene = read_openlabel(setup_path)
catalog = load_catalog(scene.asset_paths, base_dir=setup_path.parent)
obstacles = environment_obstacles(scene, catalog)
engine_s = []
simulate = crowd_module.simulate
def timed(*args, **kwargs):
    started = time.perf_counter()
    out = simulate(*args, **kwargs)
    engine_s.append(time.perf_counter() - started)
    return out
crowd_module.simulate = timed
started, cpu = time.perf_counter(), time.process_time()
generated = generate_crowd(scene, catalog, CrowdOptions(frames=frames, fps=10.0, people=people, seed=1,
                           queue_share=0.2, wait_share=0.1, group_share=0.2, person_classes=("person",)),
                           obstacles=obstacles)
total, total_cpu = time.perf_counter() - started, time.process_time() - cpu
print(json.dumps({"people": people, "frames": frames, "engine_s": round(engine_s[0], 1), "generate_s": round(total, 1),
                  "generate_cpu_s": round(total_cpu, 1),
                  "tracks": len(generated.tracks),
                  "people_per_frame": generated.report["people_per_frame"],
                  "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)}))
"""

_COMPOSE = r"""
import dataclasses, json, os, resource, sys, time
from pathlib import Path
from usdscene.converters.openlabel import read_openlabel
from usdscene.generate.crowd import CrowdOptions, generate_crowd
from usdscene.generate.motion import environment_obstacles
from usdscene.render.driver import render
from usdscene.scene.catalog import load_catalog
from usdscene.scene.compose import compose_stage

setup_path, people, folder = Path(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])
scene = read_openlabel(setup_path)
catalog = load_catalog(scene.asset_paths, base_dir=setup_path.parent)
generated = generate_crowd(scene, catalog, CrowdOptions(frames=20, fps=10.0, people=people, seed=1,
                                                        person_classes=("person",)),
                           obstacles=environment_obstacles(scene, catalog))
crowd = generated.scene
camera = crowd.cameras[0]
camera = dataclasses.replace(camera, intrinsics=camera.intrinsics.resized(WIDTH, HEIGHT))
crowd = dataclasses.replace(crowd, cameras=(camera,))
started, cpu = time.perf_counter(), time.process_time()
result = compose_stage(crowd, catalog, folder / f"stage_{people}")
compose_s, compose_cpu_s = time.perf_counter() - started, time.process_time() - cpu
size = sum(f.stat().st_size for f in result.stage_dir.glob("*.usd*"))
events = []
report = render(result.root_layer, folder / f"run_{people}", frames=[10], cameras=[camera.name],
                settings_override={"samples": 1, "denoise": False}, progress=False, workers=1,
                on_event=events.append)
imported = next(e for e in events if e.get("event") == "imported")
done = [e for e in events if e.get("event") == "done"]
print(json.dumps({"people": people, "objects": len(crowd.objects), "compose_s": round(compose_s, 2),
                  "compose_cpu_s": round(compose_cpu_s, 2), "stage_mb": round(size / 1e6, 2),
                  "compose_peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0),
                  "render_wall_s": round(report.wall_s, 1), "import_s": round(report.import_s, 1),
                  "render_s": round(report.render_s, 2), "render_cpu_s": round(report.render_cpu_s, 1),
                  "meshes": imported.get("object_meshes"), "shared_meshes": imported.get("shared_meshes"),
                  "worker_rss_mb": round(max(e["rss_mb"] for e in done))}))
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=["500x3000", "1000x3000"])
    parser.add_argument("--compose", nargs="*", type=int, default=[])
    parser.add_argument("--setup", type=Path, default=SETUP)
    args = parser.parse_args()
    for case in args.cases:
        people, frames = (int(v) for v in case.split("x"))
        out = subprocess.run([sys.executable, "-c", _CASE, str(args.setup), str(people), str(frames)],
                             check=True, capture_output=True, text=True)
        print(out.stdout.strip().splitlines()[-1])
    with tempfile.TemporaryDirectory(prefix="crowd-bench-") as tmp:
        for people in args.compose:
            out = subprocess.run([sys.executable, "-c", _COMPOSE.replace("WIDTH, HEIGHT", "320, 240"),
                                  str(args.setup), str(people), tmp],
                                 check=True, capture_output=True, text=True)
            print(json.loads(out.stdout.strip().splitlines()[-1]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
