"""Camera streams of an OpenLABEL document → :class:`usdscene.document.model.Camera`. Pure module.

A camera is a ``stream`` of type ``camera`` with its intrinsics in ``stream_properties``
(:mod:`usdscene.converters.openlabel.intrinsics`) and its pose from the coordinate system of
the same name, or from the friendly ``position_m`` + ``orientation_deg`` / ``target_m``
(:mod:`usdscene.converters.openlabel.poses`). Streams of other types are read past.
"""

from __future__ import annotations

import logging
from typing import Mapping

from usdscene.document.model import Camera, Pose, RenderSettings

from usdscene.converters.openlabel.carry import stream_residue
from usdscene.converters.openlabel.intrinsics import FRIENDLY_KEYS, read_intrinsics
from usdscene.converters.openlabel.load import DocumentBody
from usdscene.converters.openlabel.poses import CoordinateSystems, read_coordinate_systems, read_friendly_pose
from usdscene.converters.openlabel.values import (
    INVALID,
    describe,
    read_numbers,
    read_object,
    read_text,
    suggest,
)

log = logging.getLogger(__name__)

DEFAULT_CLIP_RANGE_M = (0.01, 1000.0)


def read_cameras(doc: DocumentBody, render: RenderSettings) -> list[Camera]:
    """Every camera stream of ``doc``, in document order.

    Args:
        doc: the document; problems are recorded in it.
        render: the scene's render settings (default resolution of the friendly form).

    Returns:
        The cameras that could be read; a stream without usable intrinsics is left out with a
        warning, a bad one with a problem.
    """
    R = doc.root
    systems = read_coordinate_systems(doc)
    streams = doc.section("streams")
    cameras = []
    for name, stream in streams.items():
        where = f"{R}.streams.{name}"
        if not isinstance(stream, dict):
            doc.add(where, f"expected a JSON object, got {describe(stream)}")
            continue
        if stream.get("type") != "camera":
            if not isinstance(stream.get("type"), str):
                doc.add(f"{where}.type", f"expected 'camera', 'lidar', 'radar', 'gps_imu' or 'other', "
                                         f"got {describe(stream.get('type'))}")
            continue
        camera = _read_camera(doc, name, stream, where, render, systems)
        if camera is not None:
            cameras.append(camera)
    return cameras


def _read_camera(doc: DocumentBody, name: str, stream: Mapping, where: str, render: RenderSettings,
                 systems: CoordinateSystems) -> Camera | None:
    problems = doc.problems
    props = stream.get("stream_properties", {})
    if not isinstance(props, dict):
        doc.add(f"{where}.stream_properties", f"expected a JSON object, got {describe(props)}")
        return None
    where_props = f"{where}.stream_properties"
    friendly = props.get("usdscene")
    if friendly is not None and not isinstance(friendly, dict):
        doc.add(f"{where_props}.usdscene", f"expected a JSON object, got {describe(friendly)}")
        return None
    friendly = friendly or {}
    where_f = f"{where_props}.usdscene"
    for key in friendly:
        if key not in FRIENDLY_KEYS:
            doc.add(f"{where_f}.{key}", f"unknown camera key {key!r}{suggest(key, FRIENDLY_KEYS)}; "
                                        f"known: {', '.join(FRIENDLY_KEYS)}")
    intrinsics = read_intrinsics(props, friendly, where_props, render, problems)
    # pose: the coordinate system of the same name, else the friendly pose (read even when
    # the intrinsics are bad, so that all problems are reported in one pass)
    friendly_pose = read_friendly_pose(friendly, where_f, problems)
    if intrinsics is INVALID:
        return None
    if intrinsics is None:
        log.warning("%s: camera stream %r has no intrinsics usdscene can use (intrinsics_pinhole, "
                    "intrinsics_fisheye, orthographic intrinsics_custom or stream_properties.usdscene); "
                    "it is not read as a camera", where, name)
        return None
    parents = systems.parents
    frame_poses: tuple[tuple[int, Pose], ...] = ()
    if name in parents and (parents[name] or friendly_pose is None):
        pose, frame_poses = systems.track(name)
        if parents[name] and friendly_pose not in (None, INVALID):
            doc.add(f"{where_f}", f"camera {name!r} has a pose in coordinate system {name!r}; "
                                  f"remove position_m/orientation_deg/target_m from the friendly form")
    elif friendly_pose is INVALID:
        return None
    elif friendly_pose is not None:
        pose = friendly_pose
    else:
        if parents:
            doc.add(where, f"camera stream {name!r} has no coordinate system of the same name "
                           f"(and no position_m in stream_properties.usdscene)")
            return None
        pose = Pose()
    clip = DEFAULT_CLIP_RANGE_M
    if "clip_range_m" in friendly:
        values = read_numbers(friendly["clip_range_m"], f"{where_f}.clip_range_m", problems, lengths=(2,))
        if values is not None:
            if not 0 < values[0] < values[1]:
                doc.add(f"{where_f}.clip_range_m", f"expected [near, far] with 0 < near < far, got {list(values)}")
            else:
                clip = values
    model_name = ""
    if "model_name" in friendly:
        model_name = read_text(friendly["model_name"], f"{where_f}.model_name", problems) or ""
    custom = {}
    if "custom" in friendly:
        custom = read_object(friendly["custom"], f"{where_f}.custom", problems) or {}
    sensor = None
    if "sensor" in friendly:
        from usdscene.converters.openlabel.imaging import read_sensor

        sensor = read_sensor(friendly["sensor"], f"{where_f}.sensor", problems)
    description = stream.get("description", "")
    if not isinstance(description, str):
        doc.add(f"{where}.description", f"expected a string, got {describe(description)}")
        description = ""
    return Camera(name=name, intrinsics=intrinsics, pose=pose, frame_poses=tuple(frame_poses),
                  clip_near_m=clip[0], clip_far_m=clip[1], model_name=model_name,
                  description=description, custom=dict(custom), extra=stream_residue(stream), sensor=sensor)
