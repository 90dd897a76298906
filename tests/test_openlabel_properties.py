"""Property test: any scene in the reader's canonical form survives write → official schema →
read unchanged (provenance aside)."""

from __future__ import annotations

import dataclasses
import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from usdscene.converters.openlabel import read_openlabel, schema_problems, write_openlabel
from usdscene.document.model import (
    Camera,
    FrameInterval,
    Intrinsics,
    LensModel,
    Light,
    LightKind,
    PlaceRef,
    Pose,
    Provenance,
    Randomization,
    Relation,
    SceneObject,
    SceneSpec,
)

positive = st.floats(min_value=0.01, max_value=5000.0, allow_nan=False)
coord = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False)
nonzero = st.floats(min_value=-0.5, max_value=0.5, allow_nan=False).filter(lambda v: abs(v) > 1e-6)
unit = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)
name = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_0123456789", min_size=1, max_size=8)


@st.composite
def poses(draw):
    q = draw(st.tuples(coord, coord, coord, coord).filter(lambda v: sum(x * x for x in v) > 1e-3))
    return Pose.from_quaternion(q, draw(st.tuples(coord, coord, coord)))


@st.composite
def intervals(draw):
    starts = sorted(draw(st.sets(st.integers(0, 50), max_size=3)))
    return tuple(FrameInterval(s, s + draw(st.integers(0, 5))) for s in starts)


@st.composite
def intrinsics(draw):
    lens = draw(st.sampled_from(list(LensModel)))
    distortion: tuple = ()
    fov = None
    if lens is LensModel.OPENCV_PINHOLE:
        distortion = tuple(draw(st.lists(nonzero, min_size=8, max_size=8)))[: draw(st.sampled_from([4, 5, 8]))]
    elif lens in (LensModel.OPENCV_FISHEYE, LensModel.KANNALA):
        distortion = tuple(draw(st.lists(nonzero, min_size=4, max_size=4)))
    elif lens is LensModel.RADIAL_POLY:
        distortion = tuple(draw(st.lists(nonzero, min_size=3, max_size=4)))
    if lens in (LensModel.OPENCV_FISHEYE, LensModel.KANNALA, LensModel.RADIAL_POLY,
                LensModel.FISHEYE_EQUIDISTANT, LensModel.FISHEYE_EQUISOLID):
        fov = draw(st.none() | st.floats(min_value=10.0, max_value=360.0))
    return Intrinsics(lens=lens, width_px=draw(st.integers(1, 8000)), height_px=draw(st.integers(1, 8000)),
                      fx_px=draw(positive), fy_px=draw(positive), cx_px=draw(coord), cy_px=draw(coord),
                      distortion=distortion, fov_deg=fov, sensor_width_mm=draw(positive))


@st.composite
def scenes(draw):
    cam_names = draw(st.lists(name, unique=True, max_size=3))
    cameras = []
    for cam_name in cam_names:
        frames = sorted(draw(st.sets(st.integers(0, 30), max_size=2)))
        near = draw(st.floats(min_value=0.001, max_value=1.0))
        cameras.append(Camera(cam_name, draw(intrinsics()), pose=draw(poses()),
                              frame_poses=tuple((f, draw(poses())) for f in frames),
                              clip_near_m=near, clip_far_m=near + draw(positive), model_name=draw(st.text(max_size=5)),
                              description=draw(st.text(max_size=5)),
                              custom=draw(st.dictionaries(name, st.integers() | st.text(max_size=3), max_size=2))))
    uids = iter(str(u) for u in draw(st.lists(st.integers(-50, 500), unique=True, min_size=8, max_size=8)))
    lights = tuple(Light(next(uids), f"light{i}", draw(st.sampled_from(list(LightKind))), pose=draw(poses()),
                         power_w=draw(positive), color_rgb=(draw(unit), draw(unit), draw(unit)),
                         spot_angle_deg=draw(st.floats(1.0, 180.0)), spot_blend=draw(unit),
                         size_m=(draw(positive), draw(positive)), frame_intervals=draw(intervals()))
                   for i in range(draw(st.integers(0, 2))))
    places = tuple(PlaceRef(next(uids), f"seat_{i:02d}A") for i in range(draw(st.integers(0, 2))))
    objects = []
    for i in range(draw(st.integers(0, 3))):
        frames = sorted(draw(st.sets(st.integers(0, 30), max_size=2)))
        objects.append(SceneObject(
            next(uids), draw(st.text(max_size=6)), draw(st.sampled_from(["backpack", "laptop", "passenger"])),
            frame_intervals=draw(intervals()), pose=draw(st.none() | poses()),
            frame_poses=tuple((f, draw(poses())) for f in frames),
            appearance=draw(st.none() | name), color_rgb=draw(st.none() | st.tuples(unit, unit, unit)),
            randomization=Randomization(draw(st.floats(0, 1)), draw(st.floats(0, 90)), draw(st.booleans()),
                                        draw(st.booleans()))))
    targets = [e.uid for e in (*places, *objects)]
    relations = []
    for i, obj in enumerate(objects):
        if targets and draw(st.booleans()):
            target = draw(st.sampled_from([t for t in targets if t != obj.uid] or [None]))
            if target is not None:
                relations.append(Relation(str(i), draw(st.sampled_from(["is_on", "is_below", "is_in", "is_in_front_of"])),
                                          obj.uid, target, frame_intervals=draw(intervals())))
    start = draw(st.integers(0, 20))
    return SceneSpec(name=draw(name), frame_start=start, frame_end=start + draw(st.integers(0, 20)),
                     cameras=tuple(cameras), lights=lights, objects=tuple(objects), places=places,
                     relations=tuple(relations), seed=draw(st.integers(0, 2**31)),
                     environment=draw(st.none() | st.just("aircraft_cabin")),
                     exports=tuple(draw(st.lists(st.sampled_from(["coco", "yolo", "rois"]), unique=True))),
                     roi_rules=draw(st.dictionaries(st.sampled_from(["is_on", "is_below"]), name, max_size=2)),
                     roi_ignore=tuple(draw(st.lists(name, max_size=2))),
                     description=draw(st.text(max_size=10)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene=scenes())
def test_any_canonical_scene_round_trips(scene, openlabel_schema_path):
    document = json.loads(json.dumps(write_openlabel(scene), allow_nan=False))
    assert schema_problems(document, openlabel_schema_path) == []
    again = read_openlabel(document)
    assert dataclasses.replace(again, provenance=Provenance()) == scene
