"""How long ``usdscene validate`` takes on a large document.

Generates a 1,000-frame document with 100 objects (70 dynamic objects, 20 places, 10 lights),
4 cameras (one with a pose per frame), 50 placement relations, every object listed in every
frame it is present in (10⁵ frame entries) and 10 objects moving with a pose in every frame
(10⁴ per-frame poses), then measures:

* ``python -m usdscene validate DOC`` wall time minus ``python -c pass`` (interpreter start),
  best of ``--repeat`` runs;
* the same with ``--schema`` (official schema through jsonschema), when a schema is given;
* in-process ``read_openlabel`` time.

Usage::

    python benchmarks/validate_speed.py [--schema PATH] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FRAMES = 1000
N_OBJECTS, N_PLACES, N_LIGHTS = 70, 20, 10


def make_document(frames: int = FRAMES) -> dict:
    objects: dict = {}
    for i in range(N_LIGHTS):
        objects[str(i)] = {"name": f"light_{i}", "type": "light", "object_data": {
            "text": [{"name": "kind", "val": "point"}], "num": [{"name": "power_w", "val": 60.0}],
            "vec": [{"name": "position_m", "val": [0.8 * i, 0.0, 2.0]}]}}
    for i in range(N_PLACES):
        objects[str(100 + i)] = {"name": f"seat_{i // 6 + 1:02d}{'ABCDEF'[i % 6]}", "type": "place"}
    classes = ("backpack", "laptop", "passenger", "handbag", "suitcase")
    for i in range(N_OBJECTS):
        start = (i * 7) % 50
        objects[str(200 + i)] = {
            "name": f"obj_{i}", "type": classes[i % len(classes)],
            "frame_intervals": [{"frame_start": start, "frame_end": frames - 1}],
            "object_data": {"num": [{"name": "position_noise_m", "val": 0.02}],
                            "boolean": [{"name": "random_appearance", "val": True}]}}
    relations = {str(i): {"name": "", "type": "is_below" if i % 2 else "is_on",
                          "rdf_subjects": [{"uid": str(200 + i), "type": "object"}],
                          "rdf_objects": [{"uid": str(100 + i % N_PLACES), "type": "object"}]}
                 for i in range(50)}
    streams, systems = {}, {"world": {"type": "scene_cs", "parent": "", "children": []}}
    for c in range(4):
        name = f"cam_{c:02d}"
        streams[name] = {"type": "camera", "stream_properties": {"usdscene": {
            "model": "fisheye_equisolid", "resolution_px": [640, 480], "focal_length_mm": 2.13,
            "sensor_size_mm": [4.0, 3.0], "fov_deg": 118.0}}}
        systems[name] = {"type": "sensor_cs", "parent": "world", "children": [], "pose_wrt_parent": {
            "quaternion": [0.0, 0.0, 0.0, 1.0], "translation": [float(c), 0.0, 1.95]}}
        systems["world"]["children"].append(name)
    frame_table = {}
    for f in range(frames):
        objs = {}
        for i in range(N_OBJECTS):
            if f >= (i * 7) % 50:
                objs[str(200 + i)] = {}
        for i in range(10):  # moving objects: 200..209 start at frame 0..63
            uid = str(200 + i)
            if uid in objs:
                objs[uid] = {"object_data": {"vec": [{"name": "position_m", "val": [0.01 * f, 0.1 * i, 0.0]}]}}
        a = 0.001 * f
        frame_table[str(f)] = {"objects": objs, "frame_properties": {"transforms": {"cam_00_to_world": {
            "src": "cam_00", "dst": "world", "transform_src_to_dst": {
                "quaternion": [0.0, 0.0, math.sin(a / 2), math.cos(a / 2)], "translation": [0.0, 0.0, 1.95]}}}}}
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "benchmark", "usdscene": {"seed": 1, "environment": "aircraft_cabin"}},
        "coordinate_systems": systems, "streams": streams, "objects": objects, "relations": relations,
        "frames": frame_table, "frame_intervals": [{"frame_start": 0, "frame_end": frames - 1}]}}


def wall(cmd: list[str]) -> tuple[float, int, float]:
    """(wall seconds, exit code, CPU seconds user+system) of one run of ``cmd``.

    CPU time is reported beside wall time because the machine may be shared: it is much less
    sensitive to other jobs than wall time."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    result = subprocess.run(cmd, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if result.returncode not in (0,):
        print(result.stderr[:2000], file=sys.stderr)
    return elapsed, result.returncode, cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--schema", help="official OpenLABEL schema, to time --schema too")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    env_schema = os.environ.pop("USDSCENE_OPENLABEL_SCHEMA", None)
    document = make_document()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.openlabel.json"
        path.write_text(json.dumps(document), encoding="utf-8")
        size_mb = path.stat().st_size / 1e6
        n_entries = sum(len(f["objects"]) for f in document["openlabel"]["frames"].values())
        print(f"document: {FRAMES} frames, {len(document['openlabel']['objects'])} objects, "
              f"{n_entries} frame entries, {size_mb:.1f} MB")
        base_runs = [wall([sys.executable, "-c", "pass"]) for _ in range(args.repeat)]
        base, base_cpu = min(r[0] for r in base_runs), min(r[2] for r in base_runs)
        cli = [sys.executable, "-m", "usdscene", "validate", "--no-catalog", str(path)]
        runs = [wall(cli) for _ in range(args.repeat)]
        assert all(r[1] == 0 for r in runs), "the benchmark document must be valid"
        print(f"interpreter start (python -c pass): {base:.3f} s wall, {base_cpu:.3f} s CPU")
        print(f"usdscene validate: best {min(r[0] for r in runs):.3f} s wall, "
              f"{min(r[0] for r in runs) - base:.3f} s wall / {min(r[2] for r in runs) - base_cpu:.3f} s CPU "
              f"beyond interpreter start (best of {args.repeat})")
        if args.schema or env_schema:
            schema = args.schema or env_schema
            runs_s = [wall(cli[:-1] + ["--schema", schema, str(path)]) for _ in range(args.repeat)]
            print(f"usdscene validate --schema: best {min(r[0] for r in runs_s):.3f} s wall, "
                  f"{min(r[0] for r in runs_s) - base:.3f} s wall / {min(r[2] for r in runs_s) - base_cpu:.3f} s CPU "
                  f"beyond interpreter start")
        from usdscene.converters.openlabel import read_openlabel

        start = time.perf_counter()
        scene = read_openlabel(path)
        print(f"in-process read_openlabel: {time.perf_counter() - start:.3f} s "
              f"({len(scene.objects)} objects, {sum(len(o.frame_poses) for o in scene.objects)} object poses)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
