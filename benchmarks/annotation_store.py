"""Annotation store at length: annotate, export and ``export-openlabel`` of a synthetic long run,
each step's wall time and peak memory, at two lengths to show how each grows with frames.

``python benchmarks/annotation_store.py [--frames 1000] [--cameras 2] [--objects 20] [--folder DIR]``

The run is labelled without Cycles: the benchmark writes the instance masks itself (one
rectangle per object and camera, moving a pixel per frame, 16-bit PNGs as the renderer writes
them) with their ``masks/ids.json`` and a scene document of ``--objects`` objects over the
frames (the minimal example's cameras and lights). Every step after that is the real code:

1. ``annotate``: :func:`usdscene.dataset.annotation.write_annotations` without amodal
   geometry (there is no stage), into the store, without the single document;
2. ``export coco yolo``: :func:`usdscene.dataset.export.export_formats` reading the store;
3. ``stats``: :func:`usdscene.dataset.statistics.label_statistics` of the store;
4. ``export-openlabel``: :meth:`usdscene.converters.openlabel.store.AnnotationStore.write_document`.

Each step runs in a fresh Python process and reports the wall time and the CPU time (which a
loaded machine stretches less) of its call, its modules imported before the clock starts, and
the process's peak resident memory (``ru_maxrss``, imports included). The same steps run at ``--frames`` / 2 and ``--frames``; the ratios of the two
are printed (2.0 for time means linear; 1.0 for memory means memory does not grow with frames).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"
WIDTH, HEIGHT = 64, 48

STEPS = {  # name: (imports, the timed call)
    "annotate": ("from usdscene.dataset.annotation import write_annotations",
                 "write_annotations(OUT, document_path=OUT.parent / 'doc.json', amodal=False, progress=False, "
                 "single_document_max_bytes=0)"),
    "export coco yolo": ("from usdscene.dataset.export import ExportOptions, export_formats",
                         "export_formats(OUT, ['coco', 'yolo'], ExportOptions(document_classes=True))"),
    "stats": ("from usdscene.converters.openlabel.store import open_annotations\n"
              "from usdscene.dataset.statistics import label_statistics",
              "label_statistics(open_annotations(OUT))"),
    "export-openlabel": ("from usdscene.converters.openlabel.store import AnnotationStore, store_folder",
                         "AnnotationStore(store_folder(OUT)).write_document(OUT.parent / 'one.openlabel.json')"),
}
TIMED = ("import json, resource, sys, time\nfrom pathlib import Path\nOUT = Path(sys.argv[1])\n{imports}\n"
         "start, cpu = time.perf_counter(), time.process_time()\n{call}\n"
         "usage = resource.getrusage(resource.RUSAGE_SELF)\n"
         "print(json.dumps({{'wall_s': time.perf_counter() - start, 'cpu_s': time.process_time() - cpu, "
         "'peak_mb': usage.ru_maxrss / 1024}}))\n")


def make_run(folder: Path, frames: int, cameras: int, objects: int) -> Path:
    """Masks, id map and scene document of a synthetic run in ``folder/out``; returns ``out``."""
    import cv2
    import numpy as np

    out = folder / "out"
    folder.mkdir(parents=True)
    document = json.loads(MINIMAL.read_text())
    root = document["openlabel"]
    span = [{"frame_start": 0, "frame_end": frames - 1}]
    root["metadata"]["usdscene"]["frame_range"] = {"frame_start": 0, "frame_end": frames - 1}
    root["frame_intervals"] = span
    root.pop("frames", None)
    root.pop("relations", None)
    lights = {k: v for k, v in root["objects"].items() if v["type"] == "light"}
    root["objects"] = dict(lights)
    ids = {}
    for k in range(objects):
        uid = str(len(lights) + k)
        root["objects"][uid] = {"name": f"laptop_{k:03d}", "type": "laptop", "frame_intervals": span,
                                "object_data": {"vec": [{"name": "position_m", "val": [1.0 + 0.05 * k, 0.0, 0.45]}]}}
        ids[str(k + 1)] = {"uid": uid, "class": "laptop", "name": f"laptop_{k:03d}"}
    (folder / "doc.json").write_text(json.dumps(document))
    names = sorted(root["streams"])[:cameras]
    (out / "masks").mkdir(parents=True)
    (out / "masks" / "ids.json").write_text(json.dumps(ids))
    for c, camera in enumerate(names):
        (out / "masks" / camera).mkdir()
        (out / "images" / camera).mkdir(parents=True)
        image = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
        for f in range(frames):
            mask = np.zeros((HEIGHT, WIDTH), np.uint16)
            for k in range(objects):
                x = (3 * k + f + 5 * c) % (WIDTH - 8)
                y = (7 * k) % (HEIGHT - 6)
                mask[y:y + 6, x:x + 8] = k + 1
            cv2.imwrite(str(out / "masks" / camera / f"{f:06d}.png"), mask)
            cv2.imwrite(str(out / "images" / camera / f"{f:06d}.png"), image)
    return out


def run_steps(out: Path) -> dict:
    figures = {}
    for name, (imports, call) in STEPS.items():
        done = subprocess.run([sys.executable, "-c", TIMED.format(imports=imports, call=call), str(out)],
                              capture_output=True,
                              text=True, cwd=REPO)
        if done.returncode != 0:
            raise SystemExit(f"{name} failed:\n{done.stderr}")
        figures[name] = json.loads(done.stdout.strip().splitlines()[-1])
    return figures


def disk_mb(folder: Path) -> float:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) / 1e6


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--cameras", type=int, default=2)
    parser.add_argument("--objects", type=int, default=20)
    parser.add_argument("--folder", type=Path, default=None)
    args = parser.parse_args(argv)
    base = args.folder or Path(tempfile.mkdtemp(prefix="annotation_store_"))
    results = {}
    for frames in (args.frames // 2, args.frames):
        folder = base / f"frames_{frames}"
        out = make_run(folder, frames, args.cameras, args.objects)
        results[frames] = run_steps(out)
        store = out / "annotations"
        print(f"{frames} frames x {args.cameras} cameras x {args.objects} objects: store {disk_mb(store):.1f} MB "
              f"({len(list((store / 'frames').glob('*.json')))} shards), one document "
              f"{(folder / 'one.openlabel.json').stat().st_size / 1e6:.1f} MB")
        for name, figure in results[frames].items():
            print(f"  {name:18s} {figure['wall_s']:7.2f} s wall {figure['cpu_s']:7.2f} s CPU  "
                  f"peak {figure['peak_mb']:7.1f} MB")
    short, long = (results[f] for f in (args.frames // 2, args.frames))
    print(f"ratios {args.frames} / {args.frames // 2} frames (time 2.0 = linear; memory 1.0 = flat):")
    for name in STEPS:
        print(f"  {name:18s} CPU time {long[name]['cpu_s'] / short[name]['cpu_s']:.2f}  "
              f"memory {long[name]['peak_mb'] / short[name]['peak_mb']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
