"""Render pipeline throughput: overhead budget, naive baseline, memory over many renders.

1. ``usdscene.render.driver.render`` on every camera of every frame; reports
   wall time / Σ(Blender render calls). Everything that is not inside the render call (process
   start, bpy import, USD import, presence and camera updates, EXR decoding, PNG encoding,
   manifest writes) is overhead; the target is ≤ 1.10.
2. The same images from a naive script: for every image, a factory reset and a fresh USD import
   of the whole stage, a beauty render, then a second render for the mask (1 sample).
3. (``--memory N``) N consecutive tiny renders in one worker: resident memory after the first
   10 and at the end.
4. (``--run``) ``usdscene run`` end to end on the cabin example (validate, compose, render with
   each image labelled as it arrives, annotate, export): its wall time / Σ(Blender render
   calls), the target of labels at render speed being ≤ 1.05.

Both 1 and 2 run at the scene's default settings and at 1-sample preview settings.

Scene: the shipped aircraft cabin example when it composes, else a synthetic cabin-like scene
(``usdscene.render.synthetic.cabin_like_scene``: 40 seat boxes, 60 diffuse spheres, 16 point
lights, 4 cameras at 640x480, 5 frames); the script says which.

Run: python benchmarks/render_throughput.py [--frames 5] [--memory 500] [--skip-naive]
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

NAIVE = textwrap.dedent("""
    import json, sys, time
    from pathlib import Path
    from usdscene.render.blender import outputs, session as sessions
    from usdscene.render.job import from_json
    job = from_json(Path(sys.argv[1]).read_text())
    times = []
    for frame, camera in job.pairs:
        t0 = time.perf_counter()
        session = sessions.Session(job)          # factory reset + full USD import, every image
        session.set_frame(frame)
        session.set_camera(camera, frame)
        session.bpy.ops.render.render(write_still=True)       # beauty
        rgb, _, _ = outputs.read_exr(session.exr_path)
        cycles = session.scene.cycles                          # mask: a second render
        cycles.samples, cycles.use_denoising = 1, False
        session.bpy.ops.render.render(write_still=True)
        _, ids, _ = outputs.read_exr(session.exr_path)
        rgb, ids = session._finish(camera, rgb, ids)
        outputs.write_outputs(Path(job.out_dir), camera, frame, rgb, ids)
        times.append(time.perf_counter() - t0)
    print("@naive " + json.dumps(times))
""")


def scene_stage(root: Path, frames: int) -> tuple[Path, str]:
    """Compose the cabin example if possible, else write the synthetic cabin-like scene."""
    doc = REPO / "examples" / "aircraft_cabin" / "cabin.openlabel.json"
    try:
        from usdscene.pipeline import stage_for_input

        return stage_for_input(doc, root), f"aircraft cabin example ({doc.name})"
    except Exception as exc:  # the example is not composable in this checkout yet
        from usdscene.render.synthetic import CabinLike, cabin_like_scene, write_synthetic_stage

        scene = cabin_like_scene(CabinLike(frames=frames))
        return (write_synthetic_stage(scene, root / "stage"),
                f"synthetic cabin-like scene (cabin example unavailable: {type(exc).__name__})")


def naive(stage: Path, out: Path, override: dict) -> tuple[float, float, list[float]]:
    """Wall seconds, CPU seconds (all threads) and per-image wall seconds of the naive script."""
    from usdscene.render.driver import camera_jobs, resolve_settings
    from usdscene.render.job import JobObject, RenderJob, to_json
    from usdscene.render.stage_reader import read_stage_plan

    plan = read_stage_plan(stage)
    settings = resolve_settings(plan.settings, override)
    frames = list(plan.frames)
    names = [c.name for c in plan.cameras]
    scratch = Path(tempfile.mkdtemp(prefix="naive-", dir="/dev/shm"))
    job = RenderJob(stage=str(plan.stage_path), out_dir=str(out), scratch_dir=str(scratch),
                    prim_path_mask="", settings=settings,
                    objects=tuple(JobObject.of(o) for o in plan.objects),
                    cameras=camera_jobs(plan, names, frames), pairs=tuple((f, c) for f in frames for c in names))
    job_path = scratch / "job.json"
    job_path.write_text(to_json(job))
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-c", NAIVE, str(job_path)], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    shutil.rmtree(scratch, ignore_errors=True)
    line = [l for l in proc.stdout.splitlines() if l.startswith("@naive ")]
    if proc.returncode or not line:
        raise SystemExit(f"naive run failed: {proc.stderr[-2000:]}")
    return wall, cpu, json.loads(line[0][len("@naive "):])


def pipeline(stage: Path, out: Path, override: dict):
    """The report of ``render`` and the CPU seconds of the whole run (driver + worker)."""
    from usdscene.render.driver import render

    cpu0 = time.process_time()
    report = render(stage, out, settings_override=override, progress=False)
    return report, time.process_time() - cpu0 + report.worker_cpu_s


def end_to_end(root: Path) -> None:
    """``usdscene run`` (``run_pipeline``) on the cabin example: wall / Σ render calls."""
    from usdscene.pipeline import run_pipeline

    doc = REPO / "examples" / "aircraft_cabin" / "cabin.openlabel.json"
    t0 = time.perf_counter()
    summary = run_pipeline(doc, root / "run", progress=False)
    wall = time.perf_counter() - t0
    report = summary.render
    steps = ", ".join(f"{k} {v:.1f} s" for k, v in summary.seconds.items())
    print(f"[usdscene run] {report.pairs_rendered} images of {doc.name}: wall {wall:.1f} s / Σ render calls "
          f"{report.render_s:.1f} s = {wall / report.render_s:.3f} ({steps}; "
          f"{summary.images_labelled_while_rendering} images labelled while rendering, "
          f"{1e3 * summary.labelling_s_while_rendering / max(1, summary.images_labelled_while_rendering):.1f} "
          f"ms each)", flush=True)


def memory(root: Path, renders: int) -> tuple[float, float, int]:
    """RSS (MiB) of the rendering worker after 10 renders, at its peak and at the end of
    ``renders`` consecutive renders of one ``render`` call (synthetic cabin-like scene with
    renders/4 frames, 4 cameras, 64x48, 1 sample; the driver recycles the worker process every
    ``MAX_RENDERS_PER_WORKER`` renders, as in any run)."""
    from usdscene.render.driver import render
    from usdscene.render.synthetic import CabinLike, cabin_like_scene, write_synthetic_stage

    stage = write_synthetic_stage(cabin_like_scene(CabinLike(frames=max(3, renders // 4))), root / "mem-stage")
    rss: list[float] = []
    report = render(stage, root / "mem-out",
                    settings_override={"samples": 1, "denoise": False, "resolution_scale": 0.1},
                    progress=False,
                    on_event=lambda e: rss.append(e["rss_mb"]) if e.get("event") == "done" else None)
    marks = [10, 50, 100, 200, 300, 400, len(rss)]
    print("RSS (MiB) after n renders: " + ", ".join(f"{n}: {rss[n - 1]:.0f}" for n in marks if n <= len(rss)))
    print(f"peak RSS {max(rss):.0f} MiB ({100 * (max(rss) - rss[9]) / rss[9]:+.1f} % over the 10th render)")
    return rss[9], rss[-1], report.pairs_rendered


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--memory", type=int, default=0, help="consecutive renders for the memory check")
    parser.add_argument("--memory-only", action="store_true", help="only the memory check")
    parser.add_argument("--skip-naive", action="store_true")
    parser.add_argument("--only", choices=("default", "preview"), help="one of the two settings")
    parser.add_argument("--run", action="store_true", help="only `usdscene run` end to end on the cabin example")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if args.run:
            end_to_end(root)
            return
        if not args.memory_only:
            stage, what = scene_stage(root, args.frames)
            print(f"scene: {what}")
            for label, override in (("default settings", None),
                                    ("1-sample preview", {"samples": 1, "denoise": False})):
                if args.only and not label.startswith(args.only[:3]) and not (
                        args.only == "preview" and label.startswith("1-s")):
                    continue
                report, cpu = pipeline(stage, root / f"pipe-{label[:3]}", override)
                n = report.pairs_rendered
                print(f"[{label}] pipeline: {n} images; wall {report.wall_s:.1f} s / Σ render calls "
                      f"{report.render_s:.1f} s = {report.wall_s / report.render_s:.3f}; CPU {cpu:.1f} s / "
                      f"Σ render-call CPU {report.render_cpu_s:.1f} s = {cpu / report.render_cpu_s:.3f}; "
                      f"{report.wall_s / n:.2f} s/image, {cpu / n:.2f} CPU s/image; startup "
                      f"{report.startup_s:.1f} s, USD import {report.import_s:.2f} s, post (EXR→PNG) "
                      f"{report.post_s:.2f} s", flush=True)
                if not args.skip_naive:
                    wall, naive_cpu, per = naive(stage, root / f"naive-{label[:3]}", override)
                    print(f"[{label}] naive (re-import per image, mask in a 2nd render): wall {wall:.1f} s, "
                          f"CPU {naive_cpu:.1f} s, {wall / len(per):.2f} s/image, {naive_cpu / len(per):.2f} CPU "
                          f"s/image; pipeline speed-up ×{wall / report.wall_s:.2f} (wall), "
                          f"×{naive_cpu / cpu:.2f} (CPU)", flush=True)
        if args.memory:
            first, last, n = memory(root, args.memory)
            print(f"memory over {n} consecutive renders: RSS {first:.0f} MiB after 10, "
                  f"{last:.0f} MiB at the end ({100 * (last - first) / first:+.1f} %)")


if __name__ == "__main__":
    main()
