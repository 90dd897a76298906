"""Make the camera-profile picture of ``docs/sensors.md``: one view of the README's cabin
(``corridor_19``, the camera whose clean render clips most: 32 % of its pixels, the sunlit
windows) as the clean render and through each camera profile.

Writes ``OUT/camera_profiles.openlabel.json`` (the cabin document, frame 0, that camera five
times: without a sensor and with each profile), runs it with ``usdscene run`` into ``OUT/run``,
prints the look statistics of each tile (``benchmarks/look_statistics.py``) and tiles the
images into ``docs/img/camera_profiles.jpg`` (JPEG quality 85).

Usage (from the repository root; five 320x240 renders, about a minute on an idle 2-core
machine)::

    python docs/make_camera_pictures.py OUT
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import json
from pathlib import Path

import cv2

from usdscene.dataset.contact_sheet import contact_sheet
from usdscene.document import output_layout as layout
from usdscene.document.camera_profiles import PROFILES
from usdscene.files import write_bytes_atomic

REPO = Path(__file__).resolve().parents[1]
CABIN = REPO / "examples" / "aircraft_cabin" / "cabin.openlabel.json"
IMG = Path(__file__).resolve().parent / "img"
VIEW = "corridor_19"


def _look_statistics():
    spec = importlib.util.spec_from_file_location("look_statistics", REPO / "benchmarks" / "look_statistics.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.look_statistics


def _document() -> dict:
    doc = json.loads(CABIN.read_text())
    body = doc["openlabel"]
    block = body["metadata"]["usdscene"]
    block["frame_range"] = {"frame_start": 0, "frame_end": 0}
    block["exports"] = []
    block["asset_paths"] = [str((CABIN.parent / p).resolve()) for p in block.get("asset_paths", [])]
    view = body["streams"][VIEW]
    streams = {}
    for name in ("clean", *PROFILES):
        stream = copy.deepcopy(view)
        usd = stream["stream_properties"].setdefault("usdscene", {})
        usd.pop("sensor", None)
        if name != "clean":
            usd["sensor"] = {"profile": name}
        streams[name] = stream
    body["streams"] = streams
    # the coordinate systems name the cameras: one copy of the view's per stream, no others
    systems = body.get("coordinate_systems", {})
    if VIEW in systems:
        pose = systems[VIEW]
        kept = {k: cs for k, cs in systems.items() if cs.get("type") != "sensor_cs"}
        for cs in kept.values():
            cs["children"] = [c for c in cs.get("children", []) if c in kept]
        for name in streams:
            kept[name] = copy.deepcopy(pose)
            if pose.get("parent") in kept:
                kept[pose["parent"]]["children"].append(name)
        body["coordinate_systems"] = kept
    return doc


def main() -> None:
    from usdscene.converters.openlabel import write_document
    from usdscene.pipeline import RunOptions, run_pipeline

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    doc_path = args.out / "camera_profiles.openlabel.json"
    write_document(doc_path, _document())
    out = args.out / "run"
    run_pipeline(doc_path, out, RunOptions(exports=[], report=False), progress=False)
    look = _look_statistics()
    tiles = []
    for name in ("clean", *PROFILES):
        image = cv2.imread(str(layout.image_path(out, name, 0)), cv2.IMREAD_COLOR)
        stats = look(image[..., ::-1])
        print(f"{name:16s} " + "  ".join(f"{k} {v:.2f}" for k, v in stats.items()))
        tiles.append((f"{name}: clipped {stats['clipped_pct']:.1f} %" if name == "clean" else name, image))
    ok, jpeg = cv2.imencode(".jpg", contact_sheet(tiles, 320, columns=3), [cv2.IMWRITE_JPEG_QUALITY, 85])
    write_bytes_atomic(IMG / "camera_profiles.jpg", jpeg.tobytes())


if __name__ == "__main__":
    main()
