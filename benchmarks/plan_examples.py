"""The shipped planning examples, planned as the docs plan them: the cabin (the paper's
requirement), the indoor car park and the open car park.

    python benchmarks/plan_examples.py [--out DIR] [--only NAME ...]

Prints per example, measured in this run: cameras, solver, lower bound, greedy size, targets
covered, candidates and wall seconds. Run it on two versions of the code (the same requests)
to compare camera counts and coverage; it only uses ``PlanRequest.build`` and ``plan_cameras``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "examples"
EXAMPLES = {
    "cabin": (ROOT / "aircraft_cabin" / "cabin.openlabel.json",
              {"targets": ["seat_*:on,below,in_front"], "standard": "2015", "dori": "observe"}),
    "car_park": (ROOT / "car_park" / "setup.openlabel.json", {"targets": ["*:on"], "occluders": "setup"}),
    "open_car_park": (ROOT / "open_car_park" / "setup.openlabel.json",
                      {"targets": ["bay_*:on", "walkway_*:on"], "occluders": "setup"}),
}


def main() -> None:
    from usdscene.design.camera_design import plan_cameras
    from usdscene.design.plan_request import PlanRequest

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None, help="keep the plan folders here")
    parser.add_argument("--only", nargs="+", choices=sorted(EXAMPLES), help="plan only these examples")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="plan_examples_"))
    for name in args.only or EXAMPLES:
        setup, values = EXAMPLES[name]
        started = time.perf_counter()
        plan = plan_cameras(PlanRequest.build(setup, **values), root / name)
        s = plan.coverage["summary"]
        print(f"{name}: {s['cameras']} cameras ({s['method']}{', optimal' if s['optimal'] else ''}, lower bound "
              f"{s['lower_bound']}, greedy {s['greedy_cameras']}); {s['targets_covered']}/{s['targets']} targets "
              f"covered; {s['candidates']} candidates; holes {sorted(s['holes'])[:4]}...; "
              f"{time.perf_counter() - started:.0f} s", flush=True)
    print(f"plan folders: {root}")


if __name__ == "__main__":
    main()
