"""Render settings vs seconds per 640x480 image vs PSNR against a high-sample reference.

One camera of the benchmark scene (the cabin example when it composes, else the synthetic
cabin-like scene of ``usdscene.render.synthetic.cabin_like_scene``), frame 0. Every row renders
two cameras in one worker and times the second, so the figures are steady-state seconds per
image (BVH already built, as in a long run); PSNR is computed on the 8-bit sRGB PNG of that
second camera against a ``--reference-samples`` render (1 bounce, no denoising).

Run: python benchmarks/render_settings.py [--reference-samples 1024] [--quick]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from render_throughput import scene_stage  # noqa: E402

from usdscene import layout  # noqa: E402
from usdscene.render.driver import render  # noqa: E402


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def run(stage: Path, out: Path, cams: list[str], override: dict, scale: float):
    """(wall s, CPU s, 8-bit image) of the last camera's render (the ones before it warm the
    worker up)."""
    times = {}
    render(stage, out, frames=[0], cameras=cams, settings_override=dict(override, resolution_scale=scale),
           progress=False,
           on_event=lambda e: times.__setitem__(e["camera"], (e["render_s"], e["render_cpu_s"]))
           if e.get("event") == "done" else None)
    wall, cpu = times[cams[-1]]
    return wall, cpu, cv2.imread(str(layout.image_path(out, cams[-1], 0)))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reference-samples", type=int, default=1024)
    parser.add_argument("--quick", action="store_true", help="fewer rows")
    parser.add_argument("--scale", type=float, default=1.0, help="resolution scale (0.5 = 320x240)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        stage, what = scene_stage(root, 1)
        from usdscene.render.stage_reader import read_stage_plan

        plan = read_stage_plan(stage)
        cams = [c.name for c in plan.cameras][:2]
        w = round(plan.cameras[1].intrinsics.width_px * args.scale)
        h = round(plan.cameras[1].intrinsics.height_px * args.scale)
        print(f"scene: {what}; cameras {cams}, timing and PSNR on {cams[1]} at {w}x{h}")
        rows = []
        denoisers = [("off", {"denoise": False}),
                     ("OIDN fast/fast", {"denoise": True, "denoising_quality": "FAST", "denoising_prefilter": "FAST"}),
                     ("OIDN high/accurate", {"denoise": True, "denoising_quality": "HIGH",
                                             "denoising_prefilter": "ACCURATE"})]
        for spp in ((1, 4, 8) if args.quick else (1, 2, 4, 8, 16)):
            for name, knobs in denoisers:
                rows.append((f"{spp} spp, denoise {name}, 1 bounce", dict(samples=spp, max_bounces=1, **knobs)))
        rows += [
            ("8 spp, OIDN fast, 0 bounces", dict(samples=8, max_bounces=0)),
            ("8 spp, OIDN fast, 2 bounces", dict(samples=8, max_bounces=2)),
            ("8 spp, OIDN fast, 4 bounces", dict(samples=8, max_bounces=4)),
            ("8 spp, OIDN fast, 1 bounce, caustics", dict(samples=8, max_bounces=1, caustics=True)),
            ("8 spp, OIDN fast, 1 bounce, tile 256", dict(samples=8, max_bounces=1, tile_size_px=256)),
            ("16 spp, adaptive 0.05, OIDN fast, 1 bounce", dict(samples=16, adaptive_threshold=0.05, max_bounces=1)),
        ]
        print(f"| settings | s / image (wall) | CPU s / image | PSNR (dB) vs {args.reference_samples} spp |")
        print("|---|---|---|---|")
        ref_wall, ref_cpu, reference = run(stage, root / "ref", cams[1:],
                                           {"samples": args.reference_samples, "denoise": False, "max_bounces": 1},
                                           args.scale)
        for i, (label, override) in enumerate(rows):
            seconds, cpu, image = run(stage, root / f"row{i}", cams, override, args.scale)
            print(f"| {label} | {seconds:.2f} | {cpu:.2f} | {psnr(image, reference):.1f} |", flush=True)
        print(f"reference ({args.reference_samples} spp, 1 bounce, no denoising): {ref_wall:.0f} s wall, "
              f"{ref_cpu:.0f} CPU s; rows with other bounce counts or caustics are compared with it too, "
              "so their PSNR includes the change in light transport")

if __name__ == "__main__":
    main()
