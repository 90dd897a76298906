"""Camera-system design on the aircraft cabin with the paper's requirement.

    python benchmarks/plan_cameras.py [--out DIR] [--no-verify]

Requirement (the paper's, section 4.2): every seat's ``on``, ``below`` and ``in_front`` region
seen by at least one camera at the *observe* class (62.5 px/m) with at least 25 % of its sample
points visible, with a passenger in every seat. Prints, measured in this run:

1. the planner on automatic ceiling/wall mounts (0.8 m grid) with the shipped lens catalog:
   cameras needed, candidates, solver, LP bound, holes, time per step;
2. the example's 39 hand-placed cameras re-scored against the same requirement: how many of
   them the requirement needs and which targets none of them covers;
3. ``--verify`` of plan 1: agreement of predicted and rendered visibility over
   (camera, target) pairs, and the render time.
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time
from pathlib import Path

from usdscene.design.camera_design import plan_cameras
from usdscene.design.plan_verify import verify_plan
from usdscene.design.plan_request import PlanRequest

CABIN = Path(__file__).resolve().parents[1] / "examples" / "aircraft_cabin" / "cabin.openlabel.json"
TARGETS = ["seat_*:on,below,in_front"]


def _summary(label: str, plan) -> None:
    s = plan.coverage["summary"]
    holes = collections.Counter(name.split(":")[1] for name in s["holes"])
    print(f"{label}: {s['cameras']} cameras ({s['method']}{', optimal' if s['optimal'] else ''}, "
          f"LP bound {s['lower_bound']}, greedy {s['greedy_cameras']}) from {s['candidates']} candidates; "
          f"{s['targets_covered']}/{s['targets']} targets covered; holes by region {dict(holes)}; "
          f"{len(s['uncoverable'])} not coverable by any candidate")
    print("  seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in plan.seconds.items())
          + f"; total {sum(plan.seconds.values()):.1f} (ray casting: {plan.backend})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None, help="keep the plan folders here")
    parser.add_argument("--no-verify", action="store_true", help="skip the Cycles verification")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="plan_cameras_"))
    planned = plan_cameras(PlanRequest.build(CABIN, targets=TARGETS, standard="2015", dori="observe"), root / "auto")
    _summary("planner (auto mounts, shipped lenses)", planned)
    rescored = plan_cameras(PlanRequest.build(CABIN, targets=TARGETS, mounts="setup", standard="2015", dori="observe"), root / "paper39")
    _summary("paper's 39 cameras re-scored", rescored)
    if not args.no_verify:
        started = time.perf_counter()
        result = verify_plan(root / "auto", progress=False)
        print(f"verify: {result.agreeing}/{result.pairs} (camera, target) pairs agree "
              f"({100 * result.agreement:.1f} %, fractions within {result.tolerance:g}); "
              f"{result.points_agreeing}/{result.points} points agree; "
              f"{time.perf_counter() - started:.0f} s ({', '.join(f'{k} {v:.1f}' for k, v in result.seconds.items())})")
    print(f"plan folders: {root}")


if __name__ == "__main__":
    main()
