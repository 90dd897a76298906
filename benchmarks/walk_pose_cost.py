"""What rendering each walker's walk-cycle pose per frame costs: compose, stage geometry
(amodal labels and keypoints) and render of a moving car park sequence, with the per-frame poses
(one child prim per shown pose, see :mod:`usdscene.scene.compose`) and with the same document
stripped of them (one pose per walker, as before the poses were rendered).

Usage::

    python benchmarks/walk_pose_cost.py [--frames 200] [--people 20] [--render-frames 4]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SETUP = ROOT / "examples" / "car_park" / "setup_moving.openlabel.json"


def _best(fn, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        started = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - started)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--people", type=int, default=20)
    parser.add_argument("--render-frames", type=int, default=4)
    args = parser.parse_args()

    from usdscene.cli import main as cli
    from usdscene.converters.openlabel import read_openlabel, write_document, write_openlabel
    from usdscene.generate.motion import TrackOptions, generate_tracks_document
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage, frame_pose_data
    from usdscene.scene.stage_geometry import StageGeometry

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        posed_doc, still_doc = tmp / "posed.openlabel.json", tmp / "still.openlabel.json"
        generate_tracks_document(SETUP, posed_doc, TrackOptions(
            frames=args.frames, fps=5.0, people=args.people, vehicles=2, seed=1, person_classes=("person",)))
        scene = read_openlabel(posed_doc)
        still = dataclasses.replace(scene, objects=tuple(dataclasses.replace(o, frame_extra=()) for o in scene.objects))
        write_document(still_doc, write_openlabel(still))
        catalog = load_catalog(scene.asset_paths, base_dir=tmp)
        walkers = sum(1 for o in scene.objects if frame_pose_data(o))
        print(f"{args.frames} frames, {len(scene.objects)} objects, {walkers} with a pose per frame")
        rows = {}
        for name, spec, doc in (("one pose", still, still_doc), ("pose per frame", scene, posed_doc)):
            stage = tmp / name.replace(" ", "_")
            compose_s = _best(lambda: compose_stage(spec, catalog, stage))
            result = compose_stage(spec, catalog, stage)
            size = (result.stage_dir / "objects.usda").stat().st_size
            frames = range(0, args.frames, max(1, args.frames // 20))

            def labels():
                geometry = StageGeometry(result.root_layer)
                for f in frames:
                    geometry.triangles(f)
                    geometry.keypoints(f)
            geometry_s = _best(labels, 1)
            out = tmp / f"run_{stage.name}"
            last = args.frames // 2 + args.render_frames - 1
            started = time.perf_counter()
            assert cli(["render", str(doc), "-o", str(out), "--frames", f"{args.frames // 2}:{last}",
                        "--cameras", "entrance_wide", "--samples", "1", "--workers", "1", "--no-progress",
                        "--asset-path", str(SETUP.parent / "assets")]) == 0
            render_s = time.perf_counter() - started
            rows[name] = (compose_s, size, geometry_s, len(frames), render_s)
        for name, (compose_s, size, geometry_s, n, render_s) in rows.items():
            print(f"{name:15s} compose {compose_s:.3f} s (objects.usda {size / 1e3:.0f} kB), "
                  f"geometry+keypoints of {n} frames {geometry_s:.2f} s, "
                  f"render {args.render_frames} images {render_s:.1f} s")
        base, posed = rows["one pose"], rows["pose per frame"]
        print(f"ratios pose per frame / one pose: compose {posed[0] / base[0]:.2f}, "
              f"geometry {posed[2] / base[2]:.2f}, render {posed[4] / base[4]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
