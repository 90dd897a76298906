"""The job file handed from the driver to a worker: plain JSON, no pxr, no bpy.

A job is one shard: the stage to import and the prims it needs, objects with their mask ids
and the frames where they are visible, cameras with intrinsics and per-frame poses, render
settings and the ordered (frame, camera) pairs to render. The worker never opens the stage
with pxr: everything it must know besides the geometry is in here.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any, Mapping

from usdscene.document.model import Intrinsics, LensModel, Pose, cv_pose_to_usd_pose


def intrinsics_to_json(intr: Intrinsics) -> dict[str, Any]:
    """Intrinsics as JSON values for a worker job (the lens model by name)."""
    data = asdict(intr)
    data["lens"] = LensModel(intr.lens).value
    data["distortion"] = list(intr.distortion)
    return data


def intrinsics_from_json(data: Mapping[str, Any]) -> Intrinsics:
    """Inverse of :func:`intrinsics_to_json`."""
    values = dict(data)
    values["lens"] = LensModel(values["lens"])
    values["distortion"] = tuple(values.get("distortion", ()))
    return Intrinsics(**values)


def usd_camera_matrix(pose_cv_rowmajor: list[float]) -> list[list[float]]:
    """4x4 camera → world matrix in Blender/USD camera axes (looking down -Z) of an OpenCV-axes
    camera pose given as 16 row-major numbers."""
    return cv_pose_to_usd_pose(Pose(tuple(pose_cv_rowmajor))).as_array().tolist()
