"""Depth images: Cycles' Z pass → distance to the image plane, encoded as 16-bit PNG or EXR.
Pure (numpy, cv2, OpenEXR; never bpy), used by the render worker.

**What is written.** ``OUT/depth/<camera>/<frame:06d>.png`` or ``.exr``: per pixel, the
distance in metres from the camera's *image plane*, the plane through the optical centre
perpendicular to the optical axis, to the surface the pixel sees: the OpenCV camera-frame
``z`` of that surface point, for every lens model alike. For a fisheye a pixel whose ray lies
``θ`` off the axis at distance ``d`` along the ray has ``z = d·cos θ``; rays at 90° or more
off the axis have no positive ``z`` and carry no depth.

**Cycles' Z pass** (``camera_z_depth`` in Cycles' kernel) is already the camera-frame ``z`` for
perspective and orthographic cameras, but the distance along the ray for panoramic (fisheye)
ones: :func:`plane_depth` multiplies the latter by ``cos θ`` of each pixel's ray in the native
render. It is written from the first sample only, from the same camera ray as the object-index
pass, so the depth of a pixel is the depth of the object the mask gives it. Lenses Blender
lacks are remapped after the conversion with the mask's nearest-neighbour map, so depth and
mask come from the same native pixel: pixel for pixel the same surface point.

**Encodings** (:data:`DEPTH_FORMATS`, the document's ``metadata.usdscene.render.depth``):

* ``png16``: uint16 millimetres (rounded to nearest), 0 = no depth (background, or no
  positive ``z``), 65535 = 65.535 m or farther (saturated).
* ``exr``: one float32 channel ``Z`` in metres (OpenEXR, ZIP compressed), 0 = no depth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from usdscene.document.model import Intrinsics, LensModel

from usdscene.converters.openlabel.metadata import DEPTH_FORMATS  # noqa: F401  (the one list)
PNG_MAX_MM = 65535
# Cycles writes 1e10 where a ray leaves the scene (the world); anything beyond this is no surface.
BACKGROUND_M = 1e9
PANORAMIC = frozenset({LensModel.FISHEYE_EQUIDISTANT, LensModel.FISHEYE_EQUISOLID})


def ray_cosines(render: Intrinsics) -> np.ndarray:
    """(H, W) cos θ of each pixel's ray off the optical axis in a native render (0 where the
    pixel has no ray, e.g. outside a fisheye's image circle)."""
    vs, us = np.mgrid[0:render.height_px, 0:render.width_px]
    from usdscene.labels.projection import pixel_rays

    rays, valid = pixel_rays(render, np.stack([us.ravel(), vs.ravel()], 1).astype(np.float64))
    cos = np.where(valid, rays[:, 2], 0.0)
    return cos.reshape(render.height_px, render.width_px)


def plane_depth(z_pass: np.ndarray, render: Intrinsics, cosines: np.ndarray | None = None) -> np.ndarray:
    """Cycles' Z pass of a native render → distance to the image plane.

    Args:
        z_pass: (H, W) float Z pass of the render (metres; 1e10 where no surface).
        render: the native render's intrinsics (its lens says what the pass holds).
        cosines: :func:`ray_cosines` of ``render`` (cache them per camera); None = computed.

    Returns:
        (H, W) float32 metres, 0 where there is no surface or no positive ``z``.
    """
    z = np.asarray(z_pass, dtype=np.float64)
    surface = np.isfinite(z) & (z < BACKGROUND_M) & (z > 0)
    if LensModel(render.lens) in PANORAMIC:
        cos = ray_cosines(render) if cosines is None else cosines
        z = z * cos
        surface &= cos > 0
    return np.where(surface, z, 0.0).astype(np.float32)


def remap_depth(depth_m: np.ndarray, map_x: np.ndarray, map_y: np.ndarray) -> np.ndarray:
    """A native render's depth through the remap of a lens Blender lacks.

    Nearest-neighbour with the mask's maps (:func:`cv2.remap` ``INTER_NEAREST``, as the worker
    remaps the object index), so each output pixel takes its depth and its mask id from the same
    native pixel: the depth is that of the very surface point whose object the mask names, seen
    along that native pixel's ray (up to half a native pixel from the output pixel's own ray).
    Interpolating instead would mix depths of different surfaces across silhouettes.

    Args:
        depth_m: (h, w) float plane depth of the native render (:func:`plane_depth`).
        map_x, map_y: (H, W) float32 source positions (:func:`usdscene.labels.projection.remap_grids`).

    Returns:
        (H, W) float32 metres, 0 outside the native image.
    """
    import cv2

    return cv2.remap(np.asarray(depth_m, dtype=np.float32), map_x, map_y, cv2.INTER_NEAREST,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def encode_depth(depth_m: np.ndarray, depth_format: str) -> bytes:
    """Encode a (H, W) float depth image (metres, 0 = none) → file bytes (see the module
    docstring). Raises ValueError on an unknown format."""
    depth = np.asarray(depth_m, dtype=np.float32)
    if depth_format == "png16":
        import cv2

        mm = np.clip(np.rint(depth.astype(np.float64) * 1000.0), 0, PNG_MAX_MM).astype(np.uint16)
        ok, data = cv2.imencode(".png", mm, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise RuntimeError("PNG encoding of a depth image failed")
        return data.tobytes()
    if depth_format == "exr":
        return _exr_bytes(depth)
    raise ValueError(f"depth format {depth_format!r} is not one of {list(DEPTH_FORMATS)}")


def _exr_bytes(depth: np.ndarray) -> bytes:
    import os
    import tempfile

    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    handle, name = tempfile.mkstemp(suffix=".exr")
    os.close(handle)
    try:
        with OpenEXR.File(header, {"Z": np.ascontiguousarray(depth, dtype=np.float32)}) as exr:
            exr.write(name)
        return Path(name).read_bytes()
    finally:
        os.unlink(name)


def read_depth(path: str | Path) -> np.ndarray:
    """A written depth image back in metres: (H, W) float32 (0 = no depth)."""
    path = Path(path)
    if path.suffix == ".exr":
        import OpenEXR

        with OpenEXR.File(str(path)) as exr:
            return np.asarray(exr.channels()["Z"].pixels, dtype=np.float32)
    import cv2

    mm = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if mm is None or mm.dtype != np.uint16 or mm.ndim != 2:
        raise ValueError(f"{path}: not a 16-bit single-channel depth PNG")
    return mm.astype(np.float32) / 1000.0
