"""Camera planning at terminal scale: the whole floor of ``examples/terminal`` (19,560 m² of
places in a 210 x 100 m hall) at *observe* (IEC 62676-4:2015, 62.5 px/m).

    python benchmarks/plan_terminal.py --cell 2 [--cell 1] [--out DIR]

Each ``--cell`` is planned in its own child process (so that its peak memory is its own):
targets are floor cells of that size, 1.8 m tall, sampled every 0.5 m; mounts on the ceiling
and walls every 4 m; the two perspective lenses of the shipped catalog (a 118° fisheye on an
8 m ceiling reaches 43 px/m at best, below observe). Prints, measured in this run, per cell
size: targets, candidates, pairs kept, cameras, method, lower bound, MILP gap, greedy size,
floor area covered, wall seconds per step and in total, the child's CPU seconds (user + system,
all threads: on a loaded machine the figure that does not grow with the load) and its peak
resident memory.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETUP = ROOT / "examples" / "terminal" / "setup.openlabel.json"


def plan_one(cell_m: float, out: Path, time_limit_s: float) -> dict:
    """Plan the terminal at one cell size in this process; the figures as a dict."""
    from usdscene.design.camera_design import plan_cameras
    from usdscene.design.plan_request import PlanRequest

    request = PlanRequest.build(SETUP, targets=["*:on"], spacing_m=4.0, lens_names=["cctv_2.8mm", "cctv_4mm"],
                                standard="2015", dori="observe", occluders="setup", cell_m=cell_m,
                                target_spacing_m=0.5, pole_heights_m=[], time_limit_s=time_limit_s)
    started = time.perf_counter()
    plan = plan_cameras(request, out)
    total = time.perf_counter() - started
    s = plan.coverage["summary"]
    return {"cell_m": cell_m, "targets": s["targets"], "candidates": s["candidates"], "mounts": s["mounts"],
            "pairs": s.get("pairs"), "cameras": s["cameras"], "method": s["method"], "optimal": s["optimal"],
            "lower_bound": s["lower_bound"], "gap": s["gap"], "greedy": s["greedy_cameras"],
            "targets_covered": s["targets_covered"], "area": s.get("floor_area"),
            "seconds": {k: round(v, 1) for k, v in plan.seconds.items()}, "total_s": round(total, 1),
            "peak_rss_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2, 2),
            "cpu_s": round(sum(resource.getrusage(resource.RUSAGE_SELF)[:2]), 1),
            "backend": plan.backend}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cell", type=float, action="append", help="target cell size in metres (repeatable; 2)")
    parser.add_argument("--out", type=Path, default=None, help="keep the plan folders here")
    parser.add_argument("--time-limit", type=float, default=120.0, help="MILP time limit in seconds (120)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    cells = args.cell or [2.0]
    root = args.out or Path(tempfile.mkdtemp(prefix="plan_terminal_"))
    if args.child:
        print(json.dumps(plan_one(cells[0], root / f"cell_{cells[0]:g}", args.time_limit)))
        return
    for cell in cells:
        done = subprocess.run([sys.executable, __file__, "--child", "--cell", str(cell), "--out", str(root),
                               "--time-limit", str(args.time_limit)], capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(f"cell {cell:g} m failed:\n{done.stderr[-3000:]}")
        r = json.loads(done.stdout.strip().splitlines()[-1])
        area = r["area"] or {}
        print(f"cell {r['cell_m']:g} m: {r['targets']} targets, {r['candidates']} candidates ({r['mounts']} mounts), "
              f"{r['pairs']} pairs kept -> {r['cameras']} cameras ({r['method']}"
              f"{', optimal' if r['optimal'] else ''}, lower bound {r['lower_bound']}, gap {100 * r['gap']:.1f} %, "
              f"greedy {r['greedy']}); {r['targets_covered']}/{r['targets']} cells covered, "
              f"{area.get('covered_m2', 0):.0f} of {area.get('total_m2', 0):.0f} m² ({100 * area.get('share', 0):.1f} %)")
        print(f"  {r['total_s']:.0f} s ({', '.join(f'{k} {v}' for k, v in r['seconds'].items())}; ray casting "
              f"{r['backend']}), {r['cpu_s']:.0f} CPU s, peak memory {r['peak_rss_gb']:.2f} GB")
    print(f"plan folders: {root}")


if __name__ == "__main__":
    main()
