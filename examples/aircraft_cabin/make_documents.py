"""Write the aircraft-cabin scene documents of the paper from code.

The cabin environment comes from the shipped asset library (``aircraft_cabin``); this script
reads its places from the catalog, so cameras and luggage follow the cabin if it changes.

Documents written next to this script:

* ``cabin.openlabel.json`` — the README's main job: the paper's 39-camera layout, 16 point
  lights + sun through the windows, a short sequence with about 50 assets per frame (luggage
  and passengers) in allowed and not-allowed positions for taxi, take-off and landing. Small
  resolution and few samples so that it finishes in a few minutes on a 2-core CPU.

Scale it up with the options (``--frames``, ``--width``, ``--samples``) or edit the
document's ``metadata.usdscene.render`` block.

Usage::

    python examples/aircraft_cabin/make_documents.py [--frames 3] [--width 320] [--samples 4]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from usdscene.converters.openlabel import write_document, write_openlabel
from usdscene.scene.catalog import load_catalog
from usdscene.document.imaging import profile_sensor
from usdscene.document.model import (Camera, FrameInterval, Intrinsics, LensModel, Light, LightKind, PlaceRef,
                            Pose, Randomization, Relation, RenderSettings, SceneObject, SceneSpec)

HERE = Path(__file__).resolve().parent

# The paper's camera: a wide-angle lens with FOV 118°, focal length 2.13 mm, sensor 4 mm.
# As an equisolid fisheye (r = 2 f sin(θ/2)) these three are consistent: 2.13 mm on a 4 mm-wide
# sensor spans about 112° horizontally and the 118° image circle reaches into the corners.
FOCAL_LENGTH_MM = 2.13
SENSOR_WIDTH_MM = 4.0
FOV_DEG = 118.0

CAMERA_HEIGHT_M = 1.95  # just below the ceiling panels, above the aisle and the seats
# What the cameras do to their images: a ceiling fisheye's sensor, lens and processing, with
# auto exposure and WDR so that the sunlit windows do not clip (docs/sensors.md).
CAMERA_PROFILE = "fisheye_ceiling"

# Luggage is put in authorised positions (is_below the seat in front, is_in a bin) and in
# positions that are not allowed for taxi, take-off and landing (on a seat, in the legroom, in
# the aisle); the ROI crops are labelled by these rules.
ROI_RULES = {"is_below": "correct", "is_in": "correct", "is_on": "incorrect",
             "is_in_front_of": "incorrect"}
# The rules judge luggage: a seated passenger (catalog kind ``passenger``) leaves a seat empty.
ROI_IGNORE = ("passenger",)

# Bags that fit the 0.28 m clearance under a seat (laid on their side where needed) and the legroom.
UNDER_SEAT_LUGGAGE = ("backpack", "handbag", "laptop_bag", "briefcase", "camera_bag")
LEGROOM_LUGGAGE = ("handbag", "laptop_bag", "shopping_bag", "camera_bag", "briefcase")
ON_SEAT_ITEMS = ("laptop", "tablet", "book", "magazine", "newspaper", "jacket", "pillow", "blanket",
                 "handbag", "backpack", "water_bottle", "headphones", "coffee_cup", "phone")


def look_at_pose(position_m, target_m, up=(0.0, 0.0, 1.0)) -> Pose:
    """Camera → world pose in OpenCV axes (z forward, y down) looking from ``position_m`` at
    ``target_m`` with the image's up direction closest to ``up``."""
    eye = np.asarray(position_m, float)
    forward = np.asarray(target_m, float) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up, float))
    if np.linalg.norm(right) < 1e-9:  # looking straight down: pick any right vector
        right = np.array([0.0, -1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return Pose.from_rotation_translation(np.column_stack([right, down, forward]), eye)


def region_centre(place, relation: str) -> np.ndarray:
    return place.regions[relation].pose.translation_m


def cabin_cameras(places, width_px: int, height_px: int) -> list[Camera]:
    """The paper's 39 cameras: 19 above the aisle aligned with the seat rows, looking along the
    aisle, and 20 above the seat blocks looking towards the windows."""
    f_px = FOCAL_LENGTH_MM * width_px / SENSOR_WIDTH_MM
    intr = Intrinsics(lens=LensModel.FISHEYE_EQUISOLID, width_px=width_px, height_px=height_px,
                      fx_px=f_px, fy_px=f_px, cx_px=(width_px - 1) / 2, cy_px=(height_px - 1) / 2,
                      fov_deg=FOV_DEG, sensor_width_mm=SENSOR_WIDTH_MM)
    rows = sorted({name[5:7] for name in places if name.startswith("seat_")})
    cams: list[Camera] = []
    # Corridor cameras: one per row gap from the front, above the aisle, looking backwards and down.
    for i, row in enumerate(rows[:19]):
        aisle = region_centre(places[f"aisle_{row}"], "is_on")
        pos = (aisle[0], 0.0, CAMERA_HEIGHT_M)
        target = (aisle[0] - 1.6, 0.0, 0.3)
        cams.append(Camera(name=f"corridor_{i + 1:02d}", intrinsics=intr, pose=look_at_pose(pos, target),
                           model_name="wide-angle 2.13 mm", description=f"above the aisle at row {row}",
                           sensor=profile_sensor(CAMERA_PROFILE)))
    # Seat cameras: 10 per side, every second row, above the aisle-side seat, towards the window.
    for side, letters in (("L", "ABC"), ("R", "DEF")):
        window, aisle_seat = (letters[0], letters[2]) if side == "L" else (letters[2], letters[0])
        for j, row in enumerate(rows[0:20:2]):
            next_row = rows[min(rows.index(row) + 1, len(rows) - 1)]
            a = region_centre(places[f"seat_{row}{aisle_seat}"], "is_on")
            b = region_centre(places[f"seat_{next_row}{window}"], "is_on")
            pos = (0.5 * (a[0] + b[0]), a[1] * 0.6, CAMERA_HEIGHT_M)
            target = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]) * 1.3, 0.2)
            cams.append(Camera(name=f"seats_{side}{j + 1:02d}", intrinsics=intr,
                               pose=look_at_pose(pos, target), model_name="wide-angle 2.13 mm",
                               description=f"above seats {row}{aisle_seat}-{next_row}{window}, towards the window",
                               sensor=profile_sensor(CAMERA_PROFILE)))
    return cams


def cabin_lights(places) -> list[Light]:
    """16 ceiling point lights along the aisle and a sun shining through the left windows."""
    rows = sorted({name[5:7] for name in places if name.startswith("seat_")})
    xs = [region_centre(places[f"aisle_{r}"], "is_on")[0] for r in rows]
    lights = []
    for i, x in enumerate(np.linspace(min(xs), max(xs), 16)):
        lights.append(Light(uid=f"light_{i + 1:02d}", name=f"ceiling_{i + 1:02d}", kind=LightKind.POINT,
                            pose=Pose.from_rotation_translation(np.eye(3), (float(x), 0.0, 2.0)),
                            power_w=60.0, color_rgb=(1.0, 0.95, 0.88), radius_m=0.1))
    # The sun comes from the +Y (left) side, 35° above the horizon.
    elevation = math.radians(35.0)
    direction = np.array([0.3, -math.cos(elevation), -math.sin(elevation)])  # where light travels
    z_axis = -direction / np.linalg.norm(direction)
    x_axis = np.cross([0.0, 0.0, 1.0], z_axis)
    x_axis /= np.linalg.norm(x_axis)
    rot = np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])
    lights.append(Light(uid="sun", name="sun", kind=LightKind.SUN,
                        pose=Pose.from_rotation_translation(rot, (0.0, 5.0, 5.0)),
                        power_w=4.0, color_rgb=(1.0, 0.97, 0.9)))
    return lights


def cabin_objects(places, catalog, frames: int, rng: np.random.Generator):
    """About 50 assets per frame: seated passengers and luggage in allowed and not-allowed
    positions; some luggage appears or moves between frames."""
    rows = sorted({name[5:7] for name in places if name.startswith("seat_")})
    seats = [f"seat_{r}{c}" for r in rows for c in "ABCDEF"]
    objects: list[SceneObject] = []
    relations: list[Relation] = []
    place_refs: dict[str, PlaceRef] = {}
    all_frames = (FrameInterval(0, frames - 1),)

    def place(name: str) -> str:
        if name not in place_refs:
            place_refs[name] = PlaceRef(uid=name, name=name)
        return name

    def add(class_name: str, relation: str, place_name: str, intervals=all_frames, **kw):
        uid = f"{class_name}_{len(objects) + 1:03d}"
        # Luggage lies a little askew; a passenger sits in the middle of the seat facing forward
        # like it (the people are baked to fit the seat there, as usdscene generate seats them).
        noise = ({} if catalog[class_name].kind == "passenger"
                 else dict(position_noise_m=0.02, rotation_noise_deg=15.0))
        objects.append(SceneObject(uid=uid, name=uid, class_name=class_name, frame_intervals=intervals,
                                   randomization=Randomization(random_appearance=True, **noise), **kw))
        relations.append(Relation(uid=f"rel_{len(relations) + 1:03d}", type=relation, subject_uid=uid,
                                  object_uid=place(place_name), frame_intervals=intervals))
        return uid

    occupied = sorted(rng.choice(len(seats), size=18, replace=False).tolist())
    free = [s for i, s in enumerate(seats) if i not in occupied]
    for i in occupied:
        add("passenger", "is_on", seats[i])
    cursor = iter(rng.permutation(len(free)).tolist())
    # Allowed: under the seat in front, in the overhead bins.
    for _ in range(12):
        add(UNDER_SEAT_LUGGAGE[int(rng.integers(len(UNDER_SEAT_LUGGAGE)))], "is_below", free[next(cursor)])
    bins = [n for n in places if n.startswith("bin_")]
    for k in rng.choice(len(bins), size=6, replace=False).tolist():
        add(("trolley_suitcase", "small_suitcase", "duffel_bag")[k % 3], "is_in", sorted(bins)[k])
    # Not allowed during taxi, take-off and landing: on a seat, in the legroom, in the aisle.
    for _ in range(8):
        add(ON_SEAT_ITEMS[int(rng.integers(len(ON_SEAT_ITEMS)))], "is_on", free[next(cursor)])
    for _ in range(4):
        add(LEGROOM_LUGGAGE[int(rng.integers(len(LEGROOM_LUGGAGE)))], "is_in_front_of", free[next(cursor)])
    aisles = sorted(n for n in places if n.startswith("aisle_"))
    for k in rng.choice(len(aisles), size=2, replace=False).tolist():
        add("trolley_suitcase", "is_on", aisles[k])
    # A bag that is moved from the legroom (not allowed) to under the seat (allowed) mid-sequence.
    if frames >= 2:
        seat = free[next(cursor)]
        half = frames // 2
        uid = add("laptop_bag", "is_in_front_of", seat, intervals=(FrameInterval(0, frames - 1),))
        relations[-1] = Relation(uid=relations[-1].uid, type="is_in_front_of", subject_uid=uid,
                                 object_uid=seat, frame_intervals=(FrameInterval(0, half - 1),))
        relations.append(Relation(uid=f"rel_{len(relations) + 1:03d}", type="is_below", subject_uid=uid,
                                  object_uid=seat, frame_intervals=(FrameInterval(half, frames - 1),)))
    missing = sorted({o.class_name for o in objects} - set(catalog.entries))
    if missing:
        raise SystemExit(f"the asset catalog lacks classes {missing}")
    return objects, relations, list(place_refs.values())


def cabin_scene(frames: int, width_px: int, samples: int, seed: int) -> SceneSpec:
    catalog = load_catalog()
    places = catalog.places("aircraft_cabin")
    rng = np.random.default_rng(seed)
    height_px = width_px * 3 // 4
    objects, relations, place_refs = cabin_objects(places, catalog, frames, rng)
    return SceneSpec(
        name="aircraft_cabin",
        frame_start=0,
        frame_end=frames - 1,
        cameras=tuple(cabin_cameras(places, width_px, height_px)),
        lights=tuple(cabin_lights(places)),
        objects=tuple(objects),
        places=tuple(place_refs),
        relations=tuple(relations),
        # 4 spp + OIDN fast/fast: about 3.4 s per 640x480 image at 27-28 dB (benchmarks/README.md),
        # so that the example finishes in a few minutes; the library default trades more time
        # for 30 dB.
        render=RenderSettings(samples=samples, resolution_px=(width_px, height_px), max_bounces=1,
                              denoise=True, denoising_quality="fast", denoising_prefilter="fast", seed=seed),
        seed=seed,
        environment="aircraft_cabin",
        exports=("coco", "yolo"),
        roi_rules=ROI_RULES,
        roi_ignore=ROI_IGNORE,
        description="Single-aisle aircraft cabin with the paper's 39-camera layout: luggage in "
                    "allowed and not-allowed positions for taxi, take-off and landing.",
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2, help="sequence length (default 2)")
    parser.add_argument("--width", type=int, default=320, help="image width in px; height = 3/4 (default 320)")
    parser.add_argument("--samples", type=int, default=4, help="Cycles samples per pixel (default 4)")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("-o", "--output", type=Path, default=HERE / "cabin.openlabel.json")
    args = parser.parse_args(argv)
    scene = cabin_scene(args.frames, args.width, args.samples, args.seed)
    write_document(args.output, write_openlabel(scene))
    print(f"wrote {args.output}: {len(scene.cameras)} cameras, {len(scene.lights)} lights, "
          f"{len(scene.objects)} objects, {args.frames} frames")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
