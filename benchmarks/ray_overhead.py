"""What the Ray executor costs over local worker processes, and what N nodes would give.

Renders one small synthetic stage (spheres in a room, two cameras, one moving) four ways in
one run, each into a fresh folder: the local executor with 1 and 2 worker processes, and the
Ray executor on a local Ray runtime with 1 task of 2 CPUs and 2 tasks of 1 CPU (the same
threads per worker as the local runs). Prints per run the wall time and images/s, and for Ray:

- scheduling overhead per shard: from handing the shard to Ray to the task's first event on
  the node (task placement, process reuse, fetching the stage bundle from the object store),
  and from the last image to the task's end;
- transfer per image: the PNG bytes of image + mask coming back, and the stage bundle bytes
  that each task fetches once;
- the wall-time overhead per image against the local run with the same slots.

Then projects the wall time of a campaign on N nodes from those figures.

    python benchmarks/ray_overhead.py [--frames 12] [--size 96x72] [--samples 4]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path


def scene(frames: int, width: int, height: int):
    import numpy as np

    from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
    from usdscene.render.synthetic import BoxSpec, PointLightSpec, SphereSpec, SyntheticScene

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x
    f = 0.73 * width
    intr = Intrinsics(LensModel.PERSPECTIVE, width, height, f, f, (width - 1) / 2, (height - 1) / 2)
    span = range(frames)
    cams = (Camera("front", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),
            Camera("moving", intr, Pose.from_rotation_translation(r, [-4.0, 0.5, 1.0]),
                   frame_poses=tuple((i, Pose.from_rotation_translation(r, [-4.0, 0.5 - 0.05 * i, 1.0]))
                                     for i in span)))
    spheres = (SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1),
               SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2),
               SphereSpec("c", (0.0, -1.0, 1.0), 0.3, (0.1, 0.2, 0.9), 3,
                          frame_centres=tuple((i, (0.0, -1.2 + 0.1 * i, 0.6)) for i in span)))
    return SyntheticScene(cameras=cams, spheres=spheres, frame_start=0, frame_end=frames - 1,
                          boxes=(BoxSpec("room", (0.0, 0.0, 1.5), (12.0, 8.0, 3.0), (0.6, 0.6, 0.6), inward=True),),
                          lights=(PointLightSpec("lamp", (-2.0, 0.0, 2.5), 200.0),))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--size", default="96x72", help="image size WxH in pixels")
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--campaign-images", type=int, default=40755)
    parser.add_argument("--campaign-s-per-image", type=float, default=14.0,
                        help="seconds per image on one 2-core node (640x480 cabin, default settings)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))

    import ray

    from usdscene.render.driver import render
    from usdscene.render.executors import LocalExecutor
    from usdscene.render.ray_executor import RayExecutor
    from usdscene.render.synthetic import write_synthetic_stage

    class TimedRay(RayExecutor):
        """RayExecutor that records per-shard scheduling latencies."""

        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            self.first_event_s: list[float] = []
            self.tail_s: list[float] = []

        def run_shard(self, job, out_dir, on_event):
            t0 = time.perf_counter()
            marks: dict[str, float] = {}

            def timed(event):
                now = time.perf_counter()
                marks.setdefault("first", now)
                if event.get("event") == "done":
                    marks["last_done"] = now
                on_event(event)

            outcome = super().run_shard(job, out_dir, timed)
            end = time.perf_counter()
            self.first_event_s.append(marks.get("first", end) - t0)
            self.tail_s.append(end - marks.get("last_done", end))
            return outcome

    work = Path(tempfile.mkdtemp(prefix="ray-overhead-"))
    try:
        stage = write_synthetic_stage(scene(args.frames, width, height), work / "stage")
        settings = {"samples": args.samples, "denoise": False}
        images = 2 * args.frames
        print(f"{images} images of {width}x{height} px, {args.samples} samples, {os.cpu_count()} CPU cores, "
              f"Python {sys.version.split()[0]}, Ray {ray.__version__}")
        results = {}

        def run(label, executor):
            transfer: list[int] = []
            out = work / label.replace(" ", "_")
            started = time.perf_counter()
            report = render(stage, out, settings_override=settings, progress=False, executor=executor,
                            on_event=lambda e: transfer.append(e["transfer_bytes"]) if "transfer_bytes" in e else None)
            wall = time.perf_counter() - started
            shards = sum(int(n["shards"]) for n in report.nodes.values())
            results[label] = (wall, report, transfer, shards)
            print(f"  {label:<24} wall {wall:6.2f} s  {images / wall:5.2f} images/s  {shards} shards  "
                  f"render {report.render_s / images * 1000:6.1f} ms/image  "
                  f"start-up {report.startup_s / max(shards, 1):5.2f} s/shard")
            return out

        ref = run("local 1 worker", LocalExecutor(1))
        run("local 2 workers", LocalExecutor(2))
        t = time.perf_counter()
        ray.init(num_cpus=os.cpu_count() or 1, include_dashboard=False, log_to_driver=False)
        print(f"  (ray.init of a local runtime: {time.perf_counter() - t:.1f} s, not counted below)")
        ray1 = TimedRay(None, task_cpus=os.cpu_count() or 1)
        out1 = run("ray 1 task x all CPUs", ray1)
        ray2 = TimedRay(None, task_cpus=1)
        run("ray 2 tasks x 1 CPU", ray2)
        ray.shutdown()

        same = all((ref / p.relative_to(ref)).read_bytes() == (out1 / p.relative_to(ref)).read_bytes()
                   for p in ref.glob("*/*/*.png"))
        print(f"  images and masks of 'ray 1 task' byte-identical to 'local 1 worker': {same}")

        print("\nRay overhead")
        firsts = ray1.first_event_s + ray2.first_event_s
        tails = ray1.tail_s + ray2.tail_s
        transfer = results["ray 1 task x all CPUs"][2] + results["ray 2 tasks x 1 CPU"][2]
        per_image_bytes = statistics.mean(transfer)
        print(f"  shard to first event on the node: median {statistics.median(firsts) * 1000:.0f} ms, "
              f"max {max(firsts) * 1000:.0f} ms over {len(firsts)} shards")
        print(f"  last image to task end: median {statistics.median(tails) * 1000:.0f} ms")
        print(f"  bytes back per image (PNG image + mask): {per_image_bytes:,.0f}  "
              f"({per_image_bytes / (width * height):.2f} bytes/pixel)")
        print(f"  stage bundle fetched once per task: {ray1.bundle_bytes:,} bytes")
        overheads = {}
        for ray_label, local_label in (("ray 1 task x all CPUs", "local 1 worker"),
                                       ("ray 2 tasks x 1 CPU", "local 2 workers")):
            extra = results[ray_label][0] - results[local_label][0]
            overheads[ray_label] = extra / images
            print(f"  {ray_label} vs {local_label}: {results[ray_label][0] / results[local_label][0]:.2f}x wall, "
                  f"{extra / images * 1000:+.0f} ms/image")
        one, two = results["local 1 worker"][0], results["local 2 workers"][0]
        print(f"  local 1 vs 2 workers: {one / two:.2f}x speed-up with 2 workers")

        print(f"\nProjection: {args.campaign_images:,} images at {args.campaign_s_per_image:.0f} s/image "
              "on one 2-core node, one 2-CPU task per node")
        shard_images = max(1, int(180.0 / args.campaign_s_per_image))
        per_shard_s = statistics.median(firsts) + statistics.median(tails) + statistics.mean(
            [r[1].startup_s / max(r[3], 1) for r in results.values()])
        for nodes in (1, 4, 16, 64, 256):
            shards = -(-args.campaign_images // shard_images)
            hours = (args.campaign_images * args.campaign_s_per_image + shards * per_shard_s) / nodes / 3600
            print(f"  {nodes:4d} nodes: {hours:8.1f} h  ({shards} shards of {shard_images} images, "
                  f"{per_shard_s:.1f} s overhead each = {per_shard_s / (shard_images * args.campaign_s_per_image):.1%})")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
