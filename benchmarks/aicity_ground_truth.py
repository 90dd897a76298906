"""AI City Challenge ground truth at the challenge's scale: 9,000 frames x 10 cameras x 100 people
(targets: under 10 minutes and 4 GB).

``python benchmarks/aicity_ground_truth.py [--frames 9000] [--cameras 10] [--people 100]
[--seen-by 10] [--folder DIR]``

1. Writes a synthetic labels file: one line per frame, each an OpenLABEL frame body as an
   annotated document holds it (per person ``pose_matrix4x4``, ``ground_position_m``, the
   ``box3d`` cuboid, and ``<camera>_bbox`` / ``<camera>_amodal_bbox`` in ``--seen-by`` cameras),
   the first line the document's ``objects``. People walk at 1.4 m/s at 30 fps.
2. Builds ``ground_truth.json`` and ``track1.txt`` from it frame by frame with the exporter's
   own code (:func:`usdscene.converters.exports.aicity.frame_objects` and
   :func:`~usdscene.converters.exports.aicity.write_ground_truth`), timing that step (wall
   clock and this process's CPU time, which a loaded machine stretches less) and reporting the
   process's peak resident memory (``ru_maxrss``) after it.
3. With ``--check``, reads ``ground_truth.json`` back once with ``json.load`` (what a reader
   does) to check the count; that takes several GB at the full scale (a reader's cost, not the
   export's).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_labels(path: Path, frames: int, cameras: int, people: int, seen_by: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    objects = {str(k): {"name": f"walking_{k:03d}", "type": "person"} for k in range(people)}
    start = rng.uniform(-20, 20, size=(people, 2))
    heading = rng.uniform(0, 2 * np.pi, size=people)
    step = 1.4 / 30.0
    names = [f"cam_{c:02d}" for c in range(cameras)]
    # Each person's boxes are the same text in every frame (the writer parses them all the
    # same): building 18 million boxes' JSON anew would make the file, not the export, the cost.
    boxes = []
    for k in range(people):
        items = []
        for cam in (names[(k % cameras):] + names[:(k % cameras)])[:seen_by]:
            cx, cy = 100.0 + 17 * k % 1700, 300.0 + 3 * k % 400
            items.append({"name": f"{cam}_bbox", "val": [cx, cy - 10, 40.0, 100.0],
                          "attributes": {"num": [{"name": "visible_fraction", "val": 0.8}]}})
            items.append({"name": f"{cam}_amodal_bbox", "val": [cx, cy, 40.0, 120.0]})
        boxes.append(json.dumps(items, separators=(",", ":")))
    with open(path, "w", encoding="utf-8") as out:
        out.write(json.dumps({"objects": objects}) + "\n")
        for f in range(frames):
            # bounce inside a 40 m square: a smooth walk, never faster than 1.4 m/s
            xy = start + f * step * np.c_[np.cos(heading), np.sin(heading)]
            xy = 20 - np.abs((xy + 20) % 80 - 40)
            parts = []
            for k in range(people):
                x, y = float(xy[k, 0]), float(xy[k, 1])
                c, s = float(np.cos(heading[k])), float(np.sin(heading[k]))
                qz, qw = float(np.sin(heading[k] / 2)), float(np.cos(heading[k] / 2))
                parts.append(
                    f'"{k}":{{"object_data":{{"vec":[{{"name":"pose_matrix4x4","val":[{c!r},{-s!r},0,{x!r},{s!r},'
                    f'{c!r},0,{y!r},0,0,1,0,0,0,0,1]}},{{"name":"ground_position_m","val":[{x!r},{y!r},0.0]}}],'
                    f'"cuboid":[{{"name":"box3d","val":[{x!r},{y!r},0.9,0.0,0.0,{qz!r},{qw!r},0.5,0.3,1.8]}}],'
                    f'"bbox":{boxes[k]}}}}}')
            out.write(f'{{"frame":{f},"objects":{{{",".join(parts)}}}}}\n')


def build_ground_truth(labels: Path, folder: Path, cameras: int) -> dict:
    from usdscene.converters.exports.aicity import frame_objects, write_ground_truth

    camera_ids = {f"cam_{c:02d}": f"Camera_{c:04d}" for c in range(cameras)}
    with open(labels, encoding="utf-8") as source:
        objects = json.loads(source.readline())["objects"]
        ids = {uid: int(uid) for uid in objects}

        def frames():
            start = time.perf_counter()
            for line in source:
                body = json.loads(line)
                if body["frame"] and body["frame"] % 1000 == 0:
                    print(f"  frame {body['frame']}: {time.perf_counter() - start:.0f} s, load "
                          f"{os.getloadavg()[0]:.1f}", file=sys.stderr, flush=True)
                yield body["frame"], frame_objects(objects, str(body["frame"]), body, ids=ids,
                                                   class_map={"person": "Person"}, camera_ids=camera_ids, extents={})

        return write_ground_truth(frames(), folder, edition="2025", scene_id=1, fps=30.0,
                                  camera_numbers={v: k for k, v in enumerate(camera_ids.values())})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=9000)
    parser.add_argument("--cameras", type=int, default=10)
    parser.add_argument("--people", type=int, default=100)
    parser.add_argument("--seen-by", type=int, default=10, help="cameras that see each person")
    parser.add_argument("--folder", help="work folder (default: a temporary one, removed)")
    parser.add_argument("--check", action="store_true", help="json.load the ground truth back (several GB)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.folder) as tmp:
        folder = Path(tmp)
        labels = folder / "labels.jsonl"
        t0 = time.perf_counter()
        write_labels(labels, args.frames, args.cameras, args.people, args.seen_by)
        t1 = time.perf_counter()
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        c1 = time.process_time()
        counts = build_ground_truth(labels, folder, args.cameras)
        t2, c2 = time.perf_counter(), time.process_time()
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        size = (folder / "ground_truth.json").stat().st_size
        print(f"labels file: {labels.stat().st_size / 1e6:.0f} MB written in {t1 - t0:.0f} s "
              f"({args.frames} frames, {args.cameras} cameras, {args.people} people, each seen by {args.seen_by})")
        print(f"ground truth: {counts['frames']} frames, {counts['objects']} objects, {counts['boxes']} boxes; "
              f"ground_truth.json {size / 1e6:.0f} MB, track1.txt "
              f"{(folder / 'track1.txt').stat().st_size / 1e6:.0f} MB")
        print(f"build time: {t2 - t1:.1f} s wall, {c2 - c1:.1f} s CPU of this process (target 600 s); "
              f"peak resident memory {peak:.0f} MB "
              f"(before the build {before:.0f} MB; target 4096 MB)", flush=True)
        if args.check:
            t3 = time.perf_counter()
            with open(folder / "ground_truth.json", encoding="utf-8") as gt:
                read = json.load(gt)
            assert len(read) == args.frames and sum(len(v) for v in read.values()) == counts["objects"]
            print(f"json.load of ground_truth.json (as a reader does): {time.perf_counter() - t3:.0f} s, "
                  f"peak resident memory then {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    print(f"load average: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
