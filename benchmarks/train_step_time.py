"""Seconds per optimiser step of the ROI experiment's EfficientNet-B0 on this CPU.

    python benchmarks/train_step_time.py [--sizes 32 64] [--threads 1 2] [--batch 40] [--steps 6]

One RMSprop step (forward, cross-entropy, backward, update) on a random batch, as
``examples/aircraft_cabin/train_roi.py`` takes them; the figure is the median of the steps after
the first two (which allocate). Needs the ``train`` extra (torch).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "aircraft_cabin"))


def step_seconds(size_px: int, threads: int, batch: int, steps: int) -> float:
    import torch

    import train_roi

    torch.manual_seed(0)
    torch.set_num_threads(threads)
    model = train_roi.efficientnet_b0(3)
    optimiser = torch.optim.RMSprop(model.parameters(), lr=1e-3)
    pixels, labels = torch.randn(batch, 3, size_px, size_px), torch.randint(0, 3, (batch,))
    times = []
    for _ in range(steps):
        start = time.perf_counter()
        optimiser.zero_grad()
        torch.nn.functional.cross_entropy(model(pixels), labels).backward()
        optimiser.step()
        times.append(time.perf_counter() - start)
    return statistics.median(times[2:])


def main() -> None:
    import os

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--batch", type=int, default=40)
    parser.add_argument("--steps", type=int, default=6)
    args = parser.parse_args()
    print(f"batch {args.batch}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    for size in args.sizes:
        for threads in args.threads:
            print(f"{size:4d} px, {threads} thread(s): {step_seconds(size, threads, args.batch, args.steps):.3f} s/step")


if __name__ == "__main__":
    main()
