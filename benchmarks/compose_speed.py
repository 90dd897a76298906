"""Compose speed: a 500-frame scene with 60 objects present in every frame.

    python benchmarks/compose_speed.py [--frames 500] [--objects-per-frame 60] [--repeat 3]

The scene uses the shipped asset library (the aircraft cabin): 120 objects, each present in
one of two halves of the frame range (plus overlap), so 60 are present in every frame; they
sit on, under and in front of seats, in bins and in the aisle, with position/rotation noise,
random colours and appearances; every tenth object changes place every 50 frames. Four
cameras, one of which moves in every frame, and three lights. Prints the time of placement,
of the whole composition and of reading the stage back, and the layer sizes; then the same
for the scene with an explicit pose for every object in every frame.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from usdscene.converters.stage.usd_stage import scene_from_stage
from usdscene.document import model as m
from usdscene.scene.catalog import load_catalog
from usdscene.scene.compose import compose_stage
from usdscene.scene.placement import place_objects

SPOTS = (  # (class, relation, place pattern)
    ("laptop", "is_on", "seat_{row:02d}{seat}"),
    ("book", "is_on", "seat_{row:02d}{seat}"),
    ("coffee_cup", "is_below", "seat_{row:02d}{seat}"),
    ("headphones", "is_in_front_of", "seat_{row:02d}{seat}"),
    ("duffel_bag", "is_in", "bin_{row:02d}{side}"),
    ("trolley_suitcase", "is_on", "aisle_{row:02d}"),
)


def animate(scene: m.SceneSpec, seed: int = 1) -> m.SceneSpec:
    """The same scene with an explicit pose for every object in every frame it is present (a
    scene read back from an animated stage): the worst case for time samples."""
    import dataclasses

    rng = np.random.default_rng(seed)
    objects = []
    for obj in scene.objects:
        iv = obj.frame_intervals[0]
        steps = rng.normal(0.0, 0.002, (iv.frame_end - iv.frame_start + 1, 3)).cumsum(axis=0) + (-5.0, 0.0, 0.0)
        poses = tuple((f, m.Pose.from_rotation_translation(np.eye(3), steps[k])) for k, f in enumerate(iv.frames()))
        objects.append(dataclasses.replace(obj, pose=poses[0][1], frame_poses=poses))
    return dataclasses.replace(scene, objects=tuple(objects))


def build_scene(n_frames: int, per_frame: int, seed: int = 0) -> m.SceneSpec:
    rng = np.random.default_rng(seed)
    half = n_frames // 2
    objects, places, relations = [], {}, []

    def place(name: str) -> str:
        if name not in places:
            places[name] = m.PlaceRef(f"place_{len(places)}", name)
        return places[name].uid

    for i in range(2 * per_frame):
        cls, rel, pattern = SPOTS[i % len(SPOTS)]
        # Object i is there in the first half, object i + per_frame in the second half (in the
        # mirrored row), so every frame has per_frame objects.
        slot = i % per_frame
        row = 1 + slot // len(SPOTS) % 20
        seat, side = "ABCDEF"[(slot + slot // (len(SPOTS) * 20)) % 6], "LR"[slot // (len(SPOTS) * 20) % 2]
        first = i < per_frame
        interval = m.FrameInterval(0, half - 1) if first else m.FrameInterval(half, n_frames - 1)
        uid = f"obj_{i:04d}"
        objects.append(m.SceneObject(
            uid, f"{cls} {i}", cls, (interval,),
            randomization=m.Randomization(0.01, 8.0, random_color=bool(i % 2), random_appearance=True)))
        target = place(pattern.format(row=row if first else 21 - row, seat=seat, side=side))
        if i % 10 == 0:
            # moves one row on every 50 frames, through the rows the other half leaves free
            free_rows = 11 if first else 1
            for k, start in enumerate(range(interval.frame_start, interval.frame_end + 1, 50)):
                other = place(pattern.format(row=free_rows + (row - 1 + k) % 10, seat=seat, side=side))
                relations.append(m.Relation(f"rel_{i}_{k}", rel, uid, other,
                                            (m.FrameInterval(start, min(start + 49, interval.frame_end)),)))
        else:
            relations.append(m.Relation(f"rel_{i}", rel, uid, target))
    intr = m.Intrinsics(m.LensModel.OPENCV_PINHOLE, 640, 480, 500, 500, 319.5, 239.5, (-0.1, 0.01, 0, 0, 0))
    cameras = [m.Camera(f"cam_{k}", intr, m.Pose.from_rotation_translation(np.eye(3), (-2.0 * k, 0.0, 2.0)))
               for k in range(4)]
    cameras[0] = m.Camera("cam_0", intr, cameras[0].pose, tuple(
        (f, m.Pose.from_rotation_translation(m.euler_zyx_to_rotation(0.002 * f, 0, 0), (-0.01 * f, 0, 2.0)))
        for f in range(n_frames)))
    lights = tuple(m.Light(f"light_{k}", f"light_{k}", kind, m.Pose.from_rotation_translation(np.eye(3), (-3.0 * k, 0, 2.2)))
                   for k, kind in enumerate((m.LightKind.AREA, m.LightKind.SPOT, m.LightKind.POINT)))
    return m.SceneSpec(name="bench", frame_start=0, frame_end=n_frames - 1, cameras=tuple(cameras), lights=lights,
                       objects=tuple(objects), places=tuple(places.values()), relations=tuple(relations),
                       seed=seed, environment="aircraft_cabin")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500)
    parser.add_argument("--objects-per-frame", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    catalog = load_catalog()
    scene = build_scene(args.frames, args.objects_per_frame)
    present = [len(scene.objects_present(f)) for f in scene.frames]
    print(f"scene: {len(scene.frames)} frames, {len(scene.objects)} objects ({min(present)}-{max(present)} per frame), "
          f"{len(scene.relations)} relations, {len(scene.cameras)} cameras, {len(scene.lights)} lights")
    placement = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        place_objects(scene, catalog, np.random.default_rng(scene.seed))
        placement.append(time.perf_counter() - t0)
    print(f"placement (place_objects): best {min(placement):.2f} s, median {np.median(placement):.2f} s")
    for label, variant in (("relations", scene), ("every object posed in every frame", animate(scene))):
        total, read = [], []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                result = compose_stage(variant, catalog, Path(tmp) / "stage")
                total.append(time.perf_counter() - t0)
                sizes = {p.name: p.stat().st_size for p in result.layers}
                t0 = time.perf_counter()
                scene_from_stage(result.root_layer)
                read.append(time.perf_counter() - t0)
        print(f"compose_stage, {label} (placement + layers + atomic writes): best {min(total):.2f} s, "
              f"median {np.median(total):.2f} s")
        print(f"  scene_from_stage (read it back): best {min(read):.2f} s, median {np.median(read):.2f} s")
        print("  layer sizes: " + ", ".join(f"{name} {size / 1024:.0f} KiB" for name, size in sizes.items()))


if __name__ == "__main__":
    main()
