"""Make the pictures of ``docs/sensors.md``: one view of the car park example as the clean
render and as a camera's sensor makes it (noisy, compressed, blurred, infrared at night).

Writes ``examples/car_park/sensor_views.openlabel.json`` (daylight, a physical sky, the same
camera five times with different sensors, a car driving through the view) and
``examples/car_park/sensor_views_night.openlabel.json`` (no sun, the lamps, the same camera in
colour and in IR night mode), runs both with ``usdscene run`` into ``OUT/day`` and
``OUT/night``, and tiles the images into ``docs/img/sensors.png`` (plus a 1:1 crop of each in
``docs/img/sensors_crops.png``).

Usage (from the repository root; about 4 minutes on 2 cores at 640x480, 16 samples)::

    python docs/make_sensor_pictures.py OUT [--samples 16]
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path

import cv2
import numpy as np

from usdscene.document import output_layout as layout
from usdscene.dataset.contact_sheet import contact_sheet
from usdscene.files import write_png_atomic

REPO = Path(__file__).resolve().parents[1]
CAR_PARK = REPO / "examples" / "car_park"
IMG = Path(__file__).resolve().parent / "img"
VIEW = "pole_east"
# name → (sensor block, tile label)
DAY_CAMERAS = {
    "clean": (None, "clean render"),
    "noisy": ({"iso": 12800, "read_noise_e": 4.0, "vignetting": 0.35}, "ISO 12800, vignetting"),
    "jpeg": ({"compression": "jpeg", "quality": 12}, "JPEG quality 12"),
    "h264": ({"compression": "h264_like", "quality": 35}, "H.264-like quality 35"),
    "blurred": ({"shutter_frames": 1.0}, "shutter 1 frame"),
}
NIGHT_CAMERAS = {
    "night_colour": (None, "night, colour"),
    "night_ir": ({"ir_night": True, "ir_range_m": 25.0, "iso": 3200}, "IR night, ISO 3200"),
}


def _document(cameras: dict, *, night: bool, samples: int) -> dict:
    doc = json.loads((CAR_PARK / "car_park.openlabel.json").read_text())
    setup = json.loads((CAR_PARK / "setup.openlabel.json").read_text())
    body = doc["openlabel"]
    block = body["metadata"]["usdscene"]
    block["render"] = dict(block["render"], samples=samples, denoise=True)
    block["frame_range"] = {"frame_start": 0, "frame_end": 2}  # frame 1 is rendered
    block["exports"] = []
    if night:
        block.pop("world", None)  # no sun: no sky; a black night
    else:
        block["world"] = {"sky": "nishita"}
    del body["coordinate_systems"]
    body["streams"] = {}
    for name, (sensor, label) in cameras.items():
        stream = copy.deepcopy(setup["openlabel"]["streams"][VIEW])
        stream["description"] = label
        stream["stream_properties"]["usdscene"].pop("sensor", None)  # the example's camera profile
        if sensor is not None:
            stream["stream_properties"]["usdscene"]["sensor"] = sensor
        body["streams"][name] = stream
    objects = body["objects"]
    if night:
        sun = next(k for k, o in objects.items() if o.get("name") == "sun")
        del objects[sun]
    else:
        # A car on the driving lane, 1.5 m further each frame (27 km/h at 5 frames per second):
        # with the shutter open for a whole frame it is blurred, the parked ones are not. Its
        # front faces -Y (the catalog's contract): a quarter turn drives it along +X.
        uid = str(max(int(k) for k in objects) + 1)
        objects[uid] = {"name": "moving_car", "type": "vehicle", "object_data": {
            "text": [{"name": "appearance", "val": "sedan-red"}]}}
        for frame in (0, 1, 2):
            body["frames"] = body.get("frames", {})
            body["frames"].setdefault(str(frame), {}).setdefault("objects", {})[uid] = {"object_data": {
                "vec": [{"name": "position_m", "val": [3.0 + 1.5 * frame, 0.3, 0.0]},
                        {"name": "rotation_xyz_deg", "val": [0.0, 0.0, 90.0]}]}}
    return doc


def main() -> None:
    from usdscene.converters.openlabel import write_document
    from usdscene.pipeline import RunOptions, run_pipeline

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--samples", type=int, default=16)
    args = parser.parse_args()
    tiles, crops = [], []
    for part, cameras, night in (("day", DAY_CAMERAS, False), ("night", NIGHT_CAMERAS, True)):
        doc_path = CAR_PARK / ("sensor_views_night.openlabel.json" if night else "sensor_views.openlabel.json")
        write_document(doc_path, _document(cameras, night=night, samples=args.samples))
        out = args.out / part
        run_pipeline(doc_path, out, RunOptions(frames=[1], exports=[]), progress=False)
        for name, (_, label) in cameras.items():
            image = cv2.imread(str(layout.image_path(out, name, 1)), cv2.IMREAD_COLOR)
            tiles.append((label, image))
            crops.append((label, image[150:330, 200:440]))
    write_png_atomic(IMG / "sensors.png", contact_sheet(tiles, 480, columns=2))
    write_png_atomic(IMG / "sensors_crops.png", contact_sheet(crops, 240, columns=4))


if __name__ == "__main__":
    main()
