"""How long labelling one image takes (mask → boxes, polygons, visibility).

A 640x480 uint16 instance mask with 60 overlapping objects (ellipses and rotated boxes, some
with holes, drawn far to near so that later ones occlude earlier ones) plus each object's
amodal mask; then the whole labelling of one image as ``usdscene annotate`` does it: amodal
projections of 60 objects of 960 triangles each (UV spheres) through a perspective, an
OpenCV pinhole (distorted) and an equisolid fisheye camera, and the labels from the instance
mask (boxes, polygons, visible fractions).

    python benchmarks/annotate_speed.py [--repeat 50] [--objects 60] [--stage-frames 500] [--output OUT]

With ``--output OUT`` (a rendered output folder, e.g. of ``usdscene run`` on the cabin example)
it labels every image of it anew with :class:`usdscene.dataset.annotation.ImageLabeller` (as ``usdscene
run`` does while rendering, its kept labels ignored) and reports the time per image.

With ``--stage-frames N`` (needs usd-core) it also times reading world triangles from a
synthetic composed-layout stage of N frames (half the objects static, half moving), first
pass and cached second pass.
"""

from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np

from usdscene.labels.amodal import amodal_projections
from usdscene.labels.image_labels import DEFAULT_EPSILON_PX, label_image
from usdscene.document.model import Camera, Intrinsics, LensModel

W, H = 640, 480


def synthetic_image(objects: int, seed: int = 0) -> tuple[np.ndarray, dict[int, str], dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    mask = np.zeros((H, W), np.uint16)
    amodal = {}
    for k in range(1, objects + 1):
        layer = np.zeros((H, W), np.uint8)
        cx, cy = int(rng.integers(0, W)), int(rng.integers(0, H))
        ax, ay = int(rng.integers(10, 70)), int(rng.integers(10, 70))
        if k % 2:
            cv2.ellipse(layer, (cx, cy), (ax, ay), float(rng.uniform(0, 180)), 0, 360, 1, -1)
        else:
            box = cv2.boxPoints(((cx, cy), (2 * ax, 2 * ay), float(rng.uniform(0, 90))))
            cv2.fillPoly(layer, [np.round(box).astype(np.int32)], 1)
        if k % 5 == 0:  # a hole
            cv2.circle(layer, (cx, cy), min(ax, ay) // 2, 0, -1)
        region = layer.astype(bool)
        amodal[str(k)] = region
        mask[region] = k
    return mask, {k: str(k) for k in range(1, objects + 1)}, amodal


def uv_sphere(radius_m: float, rings: int = 16, segments: int = 32) -> np.ndarray:
    """(T, 3, 3) triangles of a closed UV sphere, wound counter-clockwise seen from outside;
    T = 2 * segments * (rings - 1)."""
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments + 1)
    p = radius_m * np.stack([np.sin(theta)[:, None] * np.cos(phi)[None, :],
                             np.sin(theta)[:, None] * np.sin(phi)[None, :],
                             np.cos(theta)[:, None] * np.ones_like(phi)[None, :]], axis=-1)
    # One vertex per seam point and per pole, as a mesh shares them (sin π, sin 2π are not 0).
    p[:, -1] = p[:, 0]
    p[0], p[-1] = (0.0, 0.0, radius_m), (0.0, 0.0, -radius_m)
    tris = []
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = p[i, j], p[i + 1, j], p[i + 1, j + 1], p[i, j + 1]
            if i > 0:
                tris.append((a, b, d))
            if i < rings - 1:
                tris.append((b, c, d))
    return np.array(tris)


def lens_cameras() -> dict[str, Camera]:
    """The three lens families of the target, 640x480, looking down +z from the origin."""
    cx, cy = (W - 1) / 2, (H - 1) / 2
    return {
        "perspective": Camera("cam", Intrinsics(LensModel.PERSPECTIVE, W, H, 500.0, 500.0, cx, cy)),
        "OpenCV pinhole (k1 -0.25, k2 0.07)": Camera("cam", Intrinsics(
            LensModel.OPENCV_PINHOLE, W, H, 500.0, 500.0, cx, cy, distortion=(-0.25, 0.07, 0.0, 0.0, 0.0))),
        "equisolid fisheye (118 deg)": Camera("cam", Intrinsics(
            LensModel.FISHEYE_EQUISOLID, W, H, 280.0, 280.0, cx, cy, fov_deg=118.0)),
    }


def composite_mask(projections: dict, centres: np.ndarray) -> np.ndarray:
    """(H, W) uint16 instance mask: the projections drawn far to near (id = uid)."""
    mask = np.zeros((H, W), np.uint16)
    for k in np.argsort(-centres[:, 2]):
        mask[projections[str(k + 1)].mask] = k + 1
    return mask


def timed(fn, repeat: int) -> tuple[float, float]:
    fn()  # warm-up
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples) * 1e3, min(samples) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--objects", type=int, default=60)
    parser.add_argument("--stage-frames", type=int, default=0, metavar="N")
    parser.add_argument("--output", metavar="OUT", help="also label every image of this rendered output")
    args = parser.parse_args()
    if args.output:
        output_benchmark(args.output)
    mask, ids, amodal = synthetic_image(args.objects)
    visible = sum(1 for k in ids if (mask == k).any())
    print(f"image {W}x{H}, {args.objects} objects ({visible} visible), repeat {args.repeat}; "
          f"median / best in ms")
    for title, kwargs in [
        (f"label_image, mask only, epsilon {DEFAULT_EPSILON_PX}", {}),
        (f"label_image + amodal masks, epsilon {DEFAULT_EPSILON_PX}", {"amodal_masks": amodal}),
        ("label_image + amodal masks, epsilon 0 (exact)", {"amodal_masks": amodal, "epsilon_px": 0}),
    ]:
        median, best = timed(lambda: label_image(mask, ids, **kwargs), args.repeat)
        print(f"  {title:55s} {median:7.2f} / {best:6.2f}")

    rng = np.random.default_rng(1)
    centres = np.stack([rng.uniform(-1.5, 1.5, args.objects), rng.uniform(-1.0, 1.0, args.objects),
                        rng.uniform(2.0, 6.0, args.objects)], axis=1)
    sphere = uv_sphere(0.15)
    meshes = {str(k + 1): sphere + c for k, c in enumerate(centres)}
    print(f"amodal + visible labels of one image, {args.objects} objects x {len(sphere)} triangles "
          f"(target: median < 20 ms); median / best in ms")
    for title, camera in lens_cameras().items():
        projections = amodal_projections(camera, meshes)
        mask = composite_mask(projections, centres)
        ids = {int(uid): uid for uid in meshes}

        def labels(camera=camera, mask=mask, ids=ids):
            label_image(mask, ids, amodal_projections(camera, meshes))

        amodal_median, _ = timed(lambda camera=camera: amodal_projections(camera, meshes), args.repeat)
        median, best = timed(labels, args.repeat)
        seen = sum(1 for p in projections.values() if p.pixel_count)
        print(f"  {title:40s} {median:7.2f} / {best:6.2f}   (amodal alone {amodal_median:.2f}; "
              f"{seen} objects in view)")
    if args.stage_frames:
        stage_benchmark(args.objects, args.stage_frames, camera)


def output_benchmark(out: str) -> None:
    """Label every image of a rendered output anew (its kept labels are not read or changed)."""
    import shutil
    import tempfile
    from pathlib import Path

    from usdscene.document import output_layout as layout
    from usdscene.dataset.annotation import ImageLabeller

    # A copy without out/labels, so nothing is read back; beside the original (same depth), so
    # that the stage's relative asset paths resolve the same.
    copy = Path(tempfile.mkdtemp(prefix="annotate-speed-", dir=Path(out).resolve().parent))
    try:
        shutil.copytree(out, copy, dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns(layout.LABELS_DIR, layout.EXPORTS_DIR))
        pairs = sorted((int(p.stem), p.parent.name) for p in (copy / layout.MASKS_DIR).glob("*/*.png"))
        t0 = time.perf_counter()
        labeller = ImageLabeller(copy)
        opened = time.perf_counter() - t0
        times = []
        for frame, camera in pairs:
            t0 = time.perf_counter()
            labeller.labels(frame, camera)
            times.append(time.perf_counter() - t0)
    finally:
        shutil.rmtree(copy, ignore_errors=True)
    first_of_frame = {f: i for i, (f, _) in reversed(list(enumerate(pairs)))}.values()
    later = [t for i, t in enumerate(times) if i not in set(first_of_frame)]
    print(f"{out}: {len(pairs)} images; labeller opened in {opened * 1e3:.0f} ms; per image median "
          f"{statistics.median(times) * 1e3:.1f} ms, mean {statistics.mean(later) * 1e3:.1f} ms without "
          f"the first image of each frame (which reads the frame's triangles: "
          f"{statistics.mean([times[i] for i in first_of_frame]) * 1e3:.0f} ms)")


def stage_benchmark(objects: int, frames: int, camera: Camera) -> None:
    import tempfile
    from pathlib import Path

    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage
    from usdscene.scene.stage_geometry import StageGeometry

    rng = np.random.default_rng(2)
    spheres = []
    for k in range(objects):
        centre = (float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-1, 1)), float(rng.uniform(2, 6)))
        moving = tuple((f, (centre[0] + 0.001 * f, centre[1], centre[2])) for f in range(frames)) if k % 2 else ()
        spheres.append(SphereSpec(str(k), centre, 0.15, (0.5, 0.5, 0.5), k + 1, frame_centres=moving))
    with tempfile.TemporaryDirectory() as tmp:
        path = write_synthetic_stage(SyntheticScene(cameras=(camera,), spheres=tuple(spheres),
                                                    frame_end=frames - 1), Path(tmp) / "stage")
        t0 = time.perf_counter()
        geometry = StageGeometry(path)
        opened = time.perf_counter() - t0
        t0 = time.perf_counter()
        for frame in range(frames):
            geometry.triangles(frame)
        per_frame = (time.perf_counter() - t0) / frames * 1e3
        title = f"stage triangles, {objects} objects (half moving), {frames} frames"
        print(f"  {title:55s} {per_frame:7.2f} ms/frame")
        print(f"  {'stage open + mesh triangulation':55s} {opened * 1e3:7.2f} ms")


if __name__ == "__main__":
    main()
