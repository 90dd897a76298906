"""What the people cost: a cabin frame at 30 % occupancy rendered at the example's settings,
with this checkout's passengers against another checkout's (e.g. the ellipsoid figures before
the people family), and the labels including keypoints per 640x480 image.

    python benchmarks/people_render_cost.py --before CHECKOUT [--cameras 3] [--out DIR]

The document is ``examples/aircraft_cabin/cabin.openlabel.json`` (320x240, 4 samples +
denoising, 1 bounce) with passengers added on free seats until 36 of the 120 seats (30 %) are
taken, frame 0, the first ``--cameras`` aisle cameras. Each checkout renders it once with
``usdscene render`` in a fresh process (``PYTHONPATH`` = the checkout); the figure is the
wall time of the render command per image (Blender's start and the stage import included,
the same for both), and the printed ratio is after / before. Then this checkout's images are
labelled in process (:class:`usdscene.dataset.annotation.ImageLabeller`, the labelling
``usdscene run`` does while rendering): median milliseconds per image with keypoints and
without them (the stage's keypoints hidden), so the keypoints' own cost shows.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
OCCUPANCY = 0.30
SEATS = 120


def occupied_document(cameras: int) -> dict:
    """The example document with passengers on free seats up to :data:`OCCUPANCY`."""
    doc = json.loads((REPO / "examples" / "aircraft_cabin" / "cabin.openlabel.json").read_text())
    root = doc["openlabel"]
    objects, relations = root["objects"], root["relations"]
    places = {o["name"]: uid for uid, o in objects.items() if o["type"] == "place"}
    passengers = [uid for uid, o in objects.items() if o["type"] == "passenger"]
    taken = {objects[r["rdf_objects"][0]["uid"]]["name"] for r in relations.values()
             if r["type"] == "is_on" and r["rdf_subjects"][0]["uid"] in passengers}
    template = objects[passengers[0]]
    next_uid = max(int(k) for k in objects) + 1
    next_rel = max(int(k) for k in relations) + 1
    free = [f"seat_{row:02d}{letter}" for row in range(1, 21) for letter in "ABCDEF"
            if f"seat_{row:02d}{letter}" not in taken]
    want = int(round(OCCUPANCY * SEATS)) - len(passengers)
    for k, seat in enumerate(free[::max(1, len(free) // want)][:want]):
        if seat not in places:
            objects[str(next_uid)] = {"name": seat, "type": "place"}
            places[seat] = str(next_uid)
            next_uid += 1
        uid = str(next_uid)
        next_uid += 1
        objects[uid] = dict(copy.deepcopy(template), name=f"passenger_extra_{k:03d}")
        relations[str(next_rel)] = {"name": "", "type": "is_on", "rdf_subjects": [{"uid": uid, "type": "object"}],
                                    "rdf_objects": [{"uid": places[seat], "type": "object"}],
                                    "frame_intervals": [{"frame_start": 0, "frame_end": 1}]}
        next_rel += 1
    names = sorted(n for n in root["streams"] if "aisle" in n)[:cameras] or sorted(root["streams"])[:cameras]
    root["metadata"]["usdscene"]["frame_range"] = {"frame_start": 0, "frame_end": 0}
    return doc, names


def render_seconds(checkout: Path, doc_path: Path, out: Path, cameras: list[str]) -> float:
    """Wall seconds per image of one ``usdscene render`` of frame 0 with ``checkout``'s code."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    start = time.monotonic()
    subprocess.run([sys.executable, "-m", "usdscene", "render", str(doc_path), "-o", str(out), "--frames", "0",
                    "--cameras", *cameras, "--no-progress", "--workers", "1"],
                   check=True, env=env, cwd=str(doc_path.parent))
    return (time.monotonic() - start) / len(cameras)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True, help="checkout to compare with (its repository root)")
    parser.add_argument("--cameras", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="people-cost-"))
    doc, cameras = occupied_document(args.cameras)
    doc_path = work / "cabin30.openlabel.json"
    work.mkdir(parents=True, exist_ok=True)
    doc_path.write_text(json.dumps(doc))
    before = render_seconds(args.before.resolve(), doc_path, work / "before", cameras)
    after = render_seconds(REPO, doc_path, work / "after", cameras)
    print(f"cameras {cameras}, {int(OCCUPANCY * 100)} % occupancy, frame 0 (Blender start included)")
    print(f"render per image: before {before:.1f} s, after {after:.1f} s, ratio {after / before:.2f}")
    import statistics

    from usdscene.dataset.annotation import ImageLabeller
    from usdscene.document import output_layout as layout

    import cv2

    masks = {}
    for camera in cameras:  # the rendered masks scaled to 640x480 (nearest): the label cost there
        mask = cv2.imread(str(layout.mask_path(work / "after", camera, 0)), cv2.IMREAD_UNCHANGED)
        masks[camera] = cv2.imencode(".png", cv2.resize(mask, (640, 480), interpolation=cv2.INTER_NEAREST))[1].tobytes()

    def per_image_ms(labeller) -> tuple[float, float, int]:
        first, rest = [], []
        for _ in range(5):
            labeller._triangles = labeller._keypoints = None  # a new frame: its stage reads again
            for k, camera in enumerate(cameras):
                start = time.perf_counter()
                labels = labeller._compute(masks[camera], Path(camera), 0, camera)
                (first if k == 0 else rest).append(1000 * (time.perf_counter() - start))
        people = sum(1 for o in labels.objects if o.keypoints is not None)
        return statistics.median(first), statistics.median(rest), people

    labeller = ImageLabeller(work / "after")
    first_kp, rest_kp, people = per_image_ms(labeller)
    labeller.geometry.keypoints = lambda frame, uids=None: {}
    first, rest, _ = per_image_ms(labeller)
    print("labels per 640x480 image, median ms: first camera of a frame (it reads the frame's triangles and "
          f"keypoints from the stage) {first_kp:.1f} with keypoints / {first:.1f} without; every further "
          f"camera {rest_kp:.1f} / {rest:.1f} ({people} people with keypoints in the last image)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
