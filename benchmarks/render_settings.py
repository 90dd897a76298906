"""Render settings vs seconds per 640x480 image vs PSNR against a high-sample reference.

Two modes.

Side by side (``--side-by-side``, the one that decides defaults): candidate settings and the
baseline (the defaults of ``RenderSettings()`` when this mode was written: 8 spp, OIDN high/accurate, light tree, 1 bounce) are
rendered interleaved (baseline, candidates, baseline, reversed candidates, ...) for
``--rounds`` rounds on several cabin cameras, so load from other jobs on a shared machine
falls on all of them alike. Each call renders a warm-up camera first and times the others
(steady state). Per setting it prints the ratio of median seconds per image (wall and worker
CPU) to the baseline's, and PSNR / SSIM of every camera against a high-sample reference
rendered with the baseline's light transport (no denoising). Rendering is deterministic (fixed
seed), so one image per setting and camera is compared.

Table mode (default): one row per setting, described below.

One camera of the benchmark scene (the cabin example when it composes, else the synthetic
cabin-like scene of ``usdscene.render.synthetic.cabin_like_scene``), frame 0. Every row renders
two cameras in one worker and times the second, so the figures are steady-state seconds per
image (BVH already built, as in a long run); PSNR is computed on the 8-bit sRGB PNG of that
second camera against a ``--reference-samples`` render (1 bounce, no denoising).

Run: python benchmarks/render_settings.py [--reference-samples 1024] [--quick]
     python benchmarks/render_settings.py --side-by-side [--rounds 3] [--reference-samples 128]
         [--reference-dir DIR] [--only LABEL ...] [--candidate 'LABEL:samples=4,light_tree=false']
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from render_throughput import scene_stage  # noqa: E402

from usdscene.document import output_layout as layout  # noqa: E402
from usdscene.render.driver import render  # noqa: E402


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean structural similarity (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5,
    K1 = 0.01, K2 = 0.03) of two (H, W, 3) uint8 images, averaged over channels."""
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    x, y = a.astype(np.float64), b.astype(np.float64)

    def blur(img: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(img, (11, 11), 1.5, borderType=cv2.BORDER_REFLECT)

    mx, my = blur(x), blur(y)
    vx, vy, cov = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    return float(np.mean((2 * mx * my + c1) * (2 * cov + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2))))


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


# The defaults of RenderSettings() when this mode was written, spelled out so that the comparison survives a change of
# RenderSettings(); every candidate starts from it.
BASELINE = {"samples": 8, "adaptive_threshold": 0.0, "adaptive_min_samples": 0, "denoise": True,
            "denoiser": "openimagedenoise", "denoising_quality": "high", "denoising_prefilter": "accurate",
            "denoising_input_passes": "rgb_albedo_normal", "light_tree": True, "path_guiding": False,
            "clamp_indirect": 10.0, "sampling_pattern": "tabulated_sobol", "max_bounces": 1, "caustics": False,
            "tile_size_px": 2048, "fast_gi": False, "fast_gi_method": "replace", "fast_gi_ao_bounces": 1,
            "fast_gi_distance_m": 10.0, "scrambling_distance": 1.0, "auto_scrambling_distance": False}
CANDIDATES = {  # label -> knobs changed from BASELINE
    "OIDN high / fast prefilter": {"denoising_prefilter": "fast"},
    "OIDN balanced / fast": {"denoising_quality": "balanced", "denoising_prefilter": "fast"},
    "OIDN fast / fast": {"denoising_quality": "fast", "denoising_prefilter": "fast"},
    "4 spp, OIDN high / accurate": {"samples": 4},
    "4 spp, OIDN balanced / fast": {"samples": 4, "denoising_quality": "balanced", "denoising_prefilter": "fast"},
    "light tree off": {"light_tree": False},
    "path guiding": {"path_guiding": True},
    "clamp indirect 1": {"clamp_indirect": 1.0},
    "denoiser guides RGB + albedo": {"denoising_input_passes": "rgb_albedo"},
    "blue noise": {"sampling_pattern": "blue_noise"},
    "blue noise, 4 spp": {"sampling_pattern": "blue_noise", "samples": 4},
    "blue noise, 6 spp, OIDN fast / accurate": {"sampling_pattern": "blue_noise", "samples": 6,
                                                "denoising_quality": "fast"},
    "OIDN fast / accurate": {"denoising_quality": "fast"},
    "12 spp adaptive 0.1 min 4, OIDN fast / accurate": {"samples": 12, "adaptive_threshold": 0.1,
                                                         "adaptive_min_samples": 4, "denoising_quality": "fast"},
    "16 spp adaptive 0.05 min 4, OIDN balanced / fast": {"samples": 16, "adaptive_threshold": 0.05,
                                                          "adaptive_min_samples": 4, "denoising_quality": "balanced",
                                                          "denoising_prefilter": "fast"},
    "fast GI replace": {"fast_gi": True},
    "fast GI add": {"fast_gi": True, "fast_gi_method": "add"},
    "fast GI replace, 4 spp": {"fast_gi": True, "samples": 4},
    "scrambling distance 0.5": {"scrambling_distance": 0.5},
    "scrambling distance 0.5, 4 spp": {"scrambling_distance": 0.5, "samples": 4},
}


def parse_knobs(text: str) -> tuple[str, dict]:
    """``LABEL:key=value,key=value`` → (label, knobs); values read as JSON where they parse."""
    label, _, spec = text.rpartition(":")
    knobs = {}
    for item in filter(None, spec.split(",")):
        key, _, value = item.partition("=")
        try:
            knobs[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            knobs[key.strip()] = value.strip()
    return label or spec, knobs


def render_cameras(stage: Path, out: Path, warmup: str, cams: list[str], override: dict, scale: float):
    """Render ``warmup`` then ``cams`` of frame 0 in one worker.

    Returns:
        ``{camera: (wall s, worker CPU s, (H, W, 3) uint8 BGR image)}`` for ``cams``.
    """
    times: dict[str, tuple[float, float]] = {}
    render(stage, out, frames=[0], cameras=[warmup, *cams], settings_override=dict(override, resolution_scale=scale),
           progress=False,
           on_event=lambda e: times.__setitem__(e["camera"], (e["render_s"], e["render_cpu_s"]))
           if e.get("event") == "done" else None)
    return {c: (*times[c], cv2.imread(str(layout.image_path(out, c, 0)))) for c in cams}


def reference_images(stage: Path, root: Path, args) -> dict:
    """``{camera: (H, W, 3) uint8 BGR}``: the baseline's light transport at
    ``--reference-samples`` spp, denoised with OIDN high / accurate (at a few hundred samples
    the denoiser removes the remaining noise and adds almost no bias, where a raw render's own
    noise would cap every PSNR). Kept in ``--reference-dir`` when given, and read back from it
    by later runs with the same samples and scale."""
    folder = Path(args.reference_dir) if args.reference_dir else root / "ref"
    tag = f"{args.reference_samples}spp-x{args.scale:g}"
    paths = {c: folder / f"{c}-{tag}.png" for c in args.cameras}
    missing = [c for c, path in paths.items() if not path.exists()]
    if missing:
        out = root / "ref-render"
        # No warm-up: untimed.
        render(stage, out, frames=[0], cameras=missing, progress=False,
               settings_override=dict(BASELINE, samples=args.reference_samples, resolution_scale=args.scale))
        folder.mkdir(parents=True, exist_ok=True)
        for c in missing:
            shutil.copyfile(layout.image_path(out, c, 0), paths[c])
    return {c: cv2.imread(str(path)) for c, path in paths.items()}


def side_by_side(args) -> None:
    """Interleaved baseline / candidate renders; prints ratios of medians and PSNR / SSIM."""
    import statistics
    import time

    candidates = dict(parse_knobs(c) for c in args.candidate) if args.candidate else CANDIDATES
    if args.only:
        candidates = {k: v for k, v in candidates.items() if k in args.only}
    settings = {"baseline (8 spp, OIDN high / accurate)": {},
                **candidates}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        stage, what = scene_stage(root, 1)
        started = time.perf_counter()
        reference = reference_images(stage, root, args)
        size = reference[args.cameras[0]].shape
        print(f"scene: {what}; {size[1]}x{size[0]}; cameras {args.cameras} (warm-up {args.warmup}); reference "
              f"{args.reference_samples} spp + OIDN high / accurate: {time.perf_counter() - started:.0f} s", flush=True)
        walls: dict[str, dict[str, list[float]]] = {k: {c: [] for c in args.cameras} for k in settings}
        cpus: dict[str, dict[str, list[float]]] = {k: {c: [] for c in args.cameras} for k in settings}
        quality: dict[str, dict[str, tuple[float, float]]] = {}
        names = list(settings)
        for r in range(args.rounds):
            order = names if r % 2 == 0 else [names[0], *reversed(names[1:])]
            # The baseline between every candidate: A B A C A D ...
            sequence = ([x for name in order[1:] for x in (names[0], name)] if args.interleave else order)
            for k, name in enumerate(sequence):
                out = root / f"r{r}-{k}"
                result = render_cameras(stage, out, args.warmup, args.cameras, dict(BASELINE, **settings[name]),
                                        args.scale)
                for cam, (wall, cpu, image) in result.items():
                    walls[name][cam].append(wall)
                    cpus[name][cam].append(cpu)
                    if name not in quality or cam not in quality[name]:
                        ref = reference[cam]
                        quality.setdefault(name, {})[cam] = (psnr(image, ref), ssim(image, ref))
                shutil.rmtree(out)
            print(f"round {r + 1}/{args.rounds} done ({time.perf_counter() - started:.0f} s)", flush=True)

        def median_total(table: dict[str, list[float]]) -> float:
            return sum(statistics.median(v) for v in table.values())

        base = names[0]
        print()
        print("| settings | s / image, median (wall) | ratio wall | ratio CPU | "
              + " | ".join(f"{c} PSNR dB / SSIM" for c in args.cameras) + " | mean ΔPSNR dB |")
        print("|---|---|---|---|" + "---|" * len(args.cameras) + "---|")
        for name in names:
            wall_ratio = median_total(walls[name]) / median_total(walls[base])
            cpu_ratio = median_total(cpus[name]) / median_total(cpus[base])
            cells = " | ".join(f"{quality[name][c][0]:.2f} / {quality[name][c][1]:.4f}" for c in args.cameras)
            delta = statistics.mean(quality[name][c][0] - quality[base][c][0] for c in args.cameras)
            per_image = median_total(walls[name]) / len(args.cameras)
            print(f"| {name} | {per_image:.2f} | {wall_ratio:.3f} | {cpu_ratio:.3f} | {cells} | {delta:+.2f} |")
        order = "baseline rendered before every candidate" if args.interleave else "baseline once per round"
        print(f"\n{args.rounds} round(s), {order}; ratios are sums over cameras of per-camera medians; total "
              f"{time.perf_counter() - started:.0f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reference-samples", type=int, default=1024)
    parser.add_argument("--quick", action="store_true", help="fewer rows")
    parser.add_argument("--scale", type=float, default=1.0, help="resolution scale (0.5 = 320x240)")
    parser.add_argument("--side-by-side", action="store_true",
                        help="interleaved candidates vs the baseline defaults on several cameras")
    parser.add_argument("--cameras", nargs="+", default=["corridor_05", "corridor_10", "seats_L03", "seats_R07"])
    parser.add_argument("--warmup", default="corridor_01", help="camera rendered first and not timed")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--candidate", action="append",
                        help="LABEL:key=value,... (repeatable; default: the built-in list)")
    parser.add_argument("--no-interleave", dest="interleave", action="store_false",
                        help="render the baseline once per round instead of before every candidate")
    parser.add_argument("--reference-dir", help="folder keeping the reference images between runs")
    parser.add_argument("--only", action="append", help="keep the built-in candidate of this label (repeatable)")
    args = parser.parse_args()
    if args.side_by_side:
        side_by_side(args)
        return
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
