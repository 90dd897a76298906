"""What the cross-camera table adds to annotating a run.

A synthetic composed-layout stage (usd-core) with ``--objects`` spheres (half of them moving)
seen by ``--cameras`` pinhole cameras over ``--frames`` frames; every camera labels every object
in every frame (the worst case: all objects visible everywhere). Times, in one run:

* ``object_densities``: world triangles per frame from the stage, centres, px/m per image;
* ``cross_camera_table``: rows and DORI classes from the labels;
* ``add_annotations`` with the table (what ``usdscene annotate`` writes), for the ratio.

    python benchmarks/cross_camera_speed.py [--objects 60] [--cameras 8] [--frames 50]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from usdscene.converters.openlabel import write_openlabel
from usdscene.converters.openlabel.annotations import add_annotations
from usdscene.labels.cross_camera import cross_camera_table, object_densities
from usdscene.labels.image_labels import ImageLabels, ObjectLabel, PixelBox, label_images
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose, SceneObject, SceneSpec
from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage
from usdscene.scene.stage_geometry import StageGeometry

W, H = 640, 480


def _cameras(count: int) -> tuple[Camera, ...]:
    """Cameras on a circle of 8 m around the origin, 2 m up, looking at the origin."""
    from usdscene.design.candidates import look_rotation

    cameras = []
    for k in range(count):
        angle = 2 * np.pi * k / count
        position = np.array([8 * np.cos(angle), 8 * np.sin(angle), 2.0])
        cameras.append(Camera(f"cam_{k}", Intrinsics(LensModel.PERSPECTIVE, W, H, 500.0, 500.0, (W - 1) / 2, (H - 1) / 2),
                              pose=Pose.from_rotation_translation(look_rotation(-position), position)))
    return tuple(cameras)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=60)
    parser.add_argument("--cameras", type=int, default=8)
    parser.add_argument("--frames", type=int, default=50)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    cameras = _cameras(args.cameras)
    spheres = []
    for k in range(args.objects):
        centre = tuple(float(v) for v in rng.uniform([-2, -2, 0], [2, 2, 1.5]))
        track = (tuple((f, (centre[0] + 0.01 * f, centre[1], centre[2])) for f in range(args.frames))
                 if k % 2 else ())
        spheres.append(SphereSpec(str(k + 1), centre, 0.2, (0.5, 0.5, 0.5), k + 1, frame_centres=track))
    with tempfile.TemporaryDirectory() as folder:
        stage = write_synthetic_stage(SyntheticScene(cameras=cameras, spheres=tuple(spheres),
                                                     frame_end=args.frames - 1), Path(folder) / "stage")
        geometry = StageGeometry(stage)
        box = PixelBox(10, 10, 29, 29)
        images = [ImageLabels(c.name, f, W, H, tuple(
                      ObjectLabel(uid=s.uid, class_name="sphere", mask_id=s.mask_id, box=box, pixel_count=400,
                                  amodal_box=box, amodal_pixel_count=400, visible_fraction=1.0) for s in spheres))
                  for f in range(args.frames) for c in cameras]
        annotations = label_images(images)
        scene = SceneSpec(name="bench", frame_start=0, frame_end=args.frames - 1, cameras=cameras,
                          objects=tuple(SceneObject(uid=s.uid, name=f"sphere_{s.uid}", class_name="sphere")
                                        for s in spheres))
        by_name = {c.name: c for c in cameras}
        started = time.perf_counter()
        densities = object_densities(annotations, by_name, geometry)
        t_densities = time.perf_counter() - started
        started = time.perf_counter()
        rows = cross_camera_table(annotations, scene, densities=densities)
        t_table = time.perf_counter() - started
        document = write_openlabel(scene)
        started = time.perf_counter()
        add_annotations(document, scene, annotations, folder, densities=densities)
        t_add = time.perf_counter() - started
    n_images = len(images)
    print(f"{args.objects} objects x {args.cameras} cameras x {args.frames} frames = {n_images} images, "
          f"{len(rows)} rows, {len(densities)} densities")
    print(f"object_densities   {t_densities:8.3f} s  {1e3 * t_densities / n_images:6.2f} ms/image")
    print(f"cross_camera_table {t_table:8.3f} s  {1e3 * t_table / n_images:6.2f} ms/image")
    print(f"add_annotations    {t_add:8.3f} s  {1e3 * t_add / n_images:6.2f} ms/image (table included)")
    print(f"table share of add_annotations: {t_table / t_add:.2f}; densities / add_annotations: "
          f"{t_densities / t_add:.2f}")


if __name__ == "__main__":
    main()
