"""How long a moving car park sequence takes to generate, compose and export for tracking.

Times, each as one in-process call on ``examples/car_park/setup_moving.openlabel.json``:

* ``generate``: ``usdscene.generate.motion.generate_tracks_document``, 1,000 frames at 10 fps with
  50 walkers and 8 vehicles (reading the setup, drawing collision-free tracks, writing the
  document and its report, and the placement check that the document composes); target < 10 s;
* ``compose``: ``usdscene.pipeline.compose_document`` of that document (per-frame time samples of
  every mover); target < 30 s;
* ``export``: ``usdscene.dataset.export.export_formats(["mot", "multiview"])`` of 10,000 labelled
  images (2,500 frames x the 4 cameras); target < 10 s. The labels are not rendered: each
  present object gets a box around the projection of its centre in every camera that sees it,
  written where ``add_annotations`` writes real ones, so the exporters read a document of the
  real size and shape. The image links point at files that do not exist. The same export is
  then timed in the MVDet flavours (``mot20`` layout + ``wildtrack``, ``mot17`` + ``multiviewx``).
* ``mot + multiview + video``: the same 10,000 images exported to all three in one
  ``export_formats`` call, each format timed on its own too. The video needs pixels: a short
  sequence of the same car park (``--video-frames`` frames, 4 cameras, the setup's 160x120 and
  render settings) is rendered with Cycles by ``run_pipeline``, and each camera's images are
  hard-linked in turn (frame ``f`` shows rendered frame ``f mod --video-frames``) to the 2,500
  image paths of the long document, so the encoder gets real renders and motion, not a still
  picture. ``--video-frames 0`` skips this part. The peak memory of the process (``ru_maxrss``)
  is printed before and after the exports.

Usage::

    python benchmarks/motion_speed.py [--frames 1000] [--people 50] [--vehicles 8] [--images 10000]
                                      [--video-frames 10]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CAR_PARK = ROOT / "examples" / "car_park"


def _labelled_document(doc_path: Path, out: Path) -> int:
    """Fake labels in the annotated document's layout for every (frame, camera) of the document;
    returns the image count."""
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.labels.projection import project_points

    scene = read_openlabel(doc_path)
    document = json.loads(doc_path.read_text())
    frames = document["openlabel"].setdefault("frames", {})
    images = 0
    for cam in scene.cameras:
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        for obj in scene.objects:
            poses = dict(obj.frame_poses)
            if not poses:
                continue
            fs = np.array(sorted(poses))
            centres = np.array([poses[f].translation_m + [0, 0, 0.8] for f in fs])
            uv, valid = project_points(cam, centres)
            inside = valid & (uv[:, 0] > 5) & (uv[:, 0] < w - 5) & (uv[:, 1] > 10) & (uv[:, 1] < h - 10)
            for f, (u, v) in zip(fs[inside], uv[inside]):
                box = [float(round(u)), float(round(v)), 9.0, 19.0]
                entry = frames[str(f)]["objects"].setdefault(obj.uid, {}).setdefault("object_data", {})
                attrs = {"num": [{"name": "visible_fraction", "val": 0.8}, {"name": "pixel_count", "val": 120}]}
                entry.setdefault("bbox", []).extend([
                    {"name": f"{cam.name}_bbox", "val": box, "attributes": attrs},
                    {"name": f"{cam.name}_amodal_bbox", "val": box, "attributes": attrs}])
        for f in scene.frames:
            props = frames.setdefault(str(f), {}).setdefault("frame_properties", {})
            props.setdefault("streams", {})[cam.name] = {"uri": f"images/{cam.name}/{f:06d}.png"}
            props.setdefault("usdscene", {}).setdefault("streams", {})[cam.name] = {
                "mask_uri": f"masks/{cam.name}/{f:06d}.png", "width_px": w, "height_px": h}
            images += 1
    (out / "annotations.openlabel.json").write_text(json.dumps(document))
    return images


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--people", type=int, default=50)
    # 8 of the deck's 10 bays: with each vehicle's own footprint (a van is 5 m long and nearly 2 m
    # wide) and the pillars in the way of a reversing van, all 10 often do not fit in 200 draws.
    parser.add_argument("--vehicles", type=int, default=8)
    parser.add_argument("--images", type=int, default=10000)
    parser.add_argument("--video-frames", type=int, default=10)
    args = parser.parse_args(argv)

    from usdscene.dataset.export import export_formats
    from usdscene.generate.motion import TrackOptions, generate_tracks_document
    from usdscene.pipeline import compose_document

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in ("assets", "source", "setup_moving.openlabel.json"):
            (shutil.copytree if (CAR_PARK / name).is_dir() else shutil.copy)(CAR_PARK / name, tmp / name)
        doc = tmp / "moving.openlabel.json"
        options = TrackOptions(frames=args.frames, fps=10.0, people=args.people, vehicles=args.vehicles, seed=1)
        t0, c0 = time.perf_counter(), time.process_time()
        result = generate_tracks_document(tmp / "setup_moving.openlabel.json", doc, options)
        t_generate, c_generate = time.perf_counter() - t0, time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        compose_document(doc, tmp / "stage")
        t_compose, c_compose = time.perf_counter() - t0, time.process_time() - c0
        report = result.report
        print(f"document: {args.frames} frames, {report['tracks']} tracks, {doc.stat().st_size / 1e6:.1f} MB; "
              f"people per frame {report['people_per_frame']['min']}..{report['people_per_frame']['max']}")
        # CPU seconds beside wall seconds: on a shared machine the wall time says more about the
        # neighbours than about this code.
        print(f"generate tracks (incl. composability check): {t_generate:6.2f} s wall, {c_generate:6.2f} s CPU"
              f"   (target < 10 s)")
        print(f"compose:                                     {t_compose:6.2f} s wall, {c_compose:6.2f} s CPU"
              f"   (target < 30 s)")
        # The stage keeps the document's carried per-frame content (ground positions, walk
        # phases) in the object prims' customData: its size beside the document's.
        layers = {p.name: p.stat().st_size for p in (tmp / "stage").glob("*.usda")}
        print(f"stage: {sum(layers.values()) / 1e6:.1f} MB in {len(layers)} layers, objects.usda "
              f"{layers.get('objects.usda', 0) / 1e6:.1f} MB")

        cameras = 4
        frames = -(-args.images // cameras)
        long_doc = tmp / "long.openlabel.json"
        generate_tracks_document(tmp / "setup_moving.openlabel.json", long_doc,
                                 TrackOptions(frames=frames, fps=10.0, people=args.people,
                                              vehicles=args.vehicles, seed=2))
        out = tmp  # the document's asset folder is relative to it
        images = _labelled_document(long_doc, out)
        t0, c0 = time.perf_counter(), time.process_time()
        export_formats(out, ["mot", "multiview"])
        t_export, c_export = time.perf_counter() - t0, time.process_time() - c0
        rows = sum(len((p / "gt" / "gt.txt").read_text().splitlines())
                   for p in (out / "exports" / "mot").iterdir() if p.is_dir())
        print(f"MOT + multiview export of {images} images ({rows} MOT rows): {t_export:6.2f} s wall, "
              f"{c_export:6.2f} s CPU   (target < 10 s)")
        from usdscene.dataset.export import ExportOptions

        for layout, flavour in (("mot20", "wildtrack"), ("mot17", "multiviewx")):
            t0, c0 = time.perf_counter(), time.process_time()
            export_formats(out, ["mot", "multiview"], ExportOptions(mot_layout=layout, multiview_flavour=flavour))
            t_flavour, c_flavour = time.perf_counter() - t0, time.process_time() - c0
            print(f"  the same as MOT {layout} + multiview {flavour}: {t_flavour:6.2f} s wall, {c_flavour:6.2f} s CPU"
                  f"   (target < 10 s)")
        if args.video_frames > 0:
            _video_exports(tmp, long_doc, images, args)
    return 0


def _peak_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def _video_exports(tmp: Path, long_doc: Path, images: int, args) -> None:
    """Render a short sequence, link its images to every image path of the long document, and
    time MOT + multi-view + video of all ``images`` (see the module docstring)."""
    import os

    from usdscene.dataset.export import export_formats
    from usdscene.generate.motion import TrackOptions, generate_tracks_document
    from usdscene.pipeline import RunOptions, run_pipeline

    short_doc = tmp / "short.openlabel.json"
    generate_tracks_document(tmp / "setup_moving.openlabel.json", short_doc,
                             TrackOptions(frames=args.video_frames, fps=10.0, people=args.people,
                                          vehicles=args.vehicles, seed=2))
    rendered = tmp / "rendered"
    t0 = time.perf_counter()
    run_pipeline(short_doc, rendered, RunOptions(exports=[], report=False), progress=False)
    print(f"rendered {args.video_frames} frames x 4 cameras for the video in {time.perf_counter() - t0:.1f} s")
    document = json.loads((tmp / "annotations.openlabel.json").read_text())
    linked = 0
    for frame in document["openlabel"]["frames"].values():
        for camera, stream in (frame.get("frame_properties", {}).get("streams") or {}).items():
            source = sorted((rendered / "images" / camera).glob("*.png"))
            number = int(Path(stream["uri"]).stem)
            target = tmp / stream["uri"]
            target.parent.mkdir(parents=True, exist_ok=True)
            if not target.exists():
                os.link(source[number % len(source)], target)
            linked += 1
    print(f"{linked} image paths linked to the rendered images; peak memory so far {_peak_mb():.0f} MB")
    timed = {}
    for formats in (["mot"], ["multiview"], ["video"], ["mot", "multiview", "video"]):
        t0, c0 = time.perf_counter(), time.process_time()
        export_formats(tmp, formats)
        timed["+".join(formats)] = (time.perf_counter() - t0, time.process_time() - c0)
    for name, (wall, cpu) in timed.items():
        print(f"export {name:22s} of {images} images: {wall:7.2f} s wall, {cpu:7.2f} s CPU "
              f"({1000 * wall / images:.2f} ms per image)")
    videos = json.loads((tmp / "exports" / "video" / "videos.json").read_text())
    print(f"videos: {len(videos['cameras'])} MP4 of {sorted({len(c['frames']) for c in videos['cameras'].values()})} "
          f"frames, {sum((tmp / 'exports' / 'video' / c['file']).stat().st_size for c in videos['cameras'].values()) / 1e6:.1f} MB; "
          f"peak memory {_peak_mb():.0f} MB; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    sys.exit(main())
