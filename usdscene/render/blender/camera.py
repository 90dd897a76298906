"""A lens as Blender camera data: the render camera's settings for a native lens, and the
settings that determine an image (to detect a user's edits in a .blend)."""

from __future__ import annotations


def apply_intrinsics(scene, data, intr) -> None:
    """Set the render resolution and the Blender camera data for ``intr`` (a native lens).

    Blender measures lens shift in units of the fitted sensor dimension (the width with
    ``sensor_fit = 'HORIZONTAL'``) and puts an unshifted optical axis at the image centre,
    ``((W - 1) / 2, (H - 1) / 2)`` in OpenCV pixel coordinates; y shift points up.
    """
    from usdscene.lens import lens_for

    w, h = intr.width_px, intr.height_px
    scene.render.resolution_x = w
    scene.render.resolution_y = h
    # Square pixels only: the driver renders other cameras through a square-pixel native lens
    # and remaps (usdscene.labels.projection.native_renderable).
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    sensor_w = intr.sensor_width_mm
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = sensor_w
    data.sensor_height = sensor_w * h / w
    data.shift_x = ((w - 1) / 2.0 - intr.cx_px) / w
    data.shift_y = (intr.cy_px - (h - 1) / 2.0) / w
    # Set in the order the lens gives (a panoramic type before its fisheye parameters).
    for name, value in lens_for(intr).blender_camera(intr).items():
        setattr(data, name, value)


def camera_data_json(data) -> dict:
    """The Blender camera settings that determine the image (to detect edits in Blender)."""
    return {"type": data.type, "lens": round(data.lens, 6), "sensor_width": round(data.sensor_width, 6),
            "shift_x": round(data.shift_x, 6), "shift_y": round(data.shift_y, 6),
            "ortho_scale": round(data.ortho_scale, 6), "panorama_type": data.panorama_type,
            "fisheye_lens": round(data.fisheye_lens, 6), "fisheye_fov": round(data.fisheye_fov, 6),
            "k1": round(data.fisheye_polynomial_k1, 9)}
