"""What a render leaves: Blender's multilayer EXR decoded (beauty and object index), the sRGB
encoding, and the image and mask PNGs written atomically."""

from __future__ import annotations

from pathlib import Path


def read_exr(path: Path):
    """Read the beauty and object index of a multilayer EXR written by Blender.

    Returns:
        ``(rgb, ids)``: (H, W, 3) float32 linear RGB and (H, W) uint16 object indices.
    """
    import numpy as np
    import OpenEXR

    rgb = ids = None
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                if name.endswith("Combined.R"):
                    r = channel.pixels
                elif name.endswith("Combined.G"):
                    g = channel.pixels
                elif name.endswith("Combined.B"):
                    b = channel.pixels
                elif name.endswith("IndexOB.X") or name.endswith("Object Index.X"):
                    ids = channel.pixels
        rgb = np.stack([r, g, b], axis=-1).astype(np.float32)
    if ids is None:
        raise RuntimeError(f"{path}: no object-index channel")
    # The pass stores pass_index as float from the first sample only: exact small integers.
    return rgb, np.rint(ids).astype(np.uint16)


def linear_to_srgb8(rgb):
    """(H, W, 3) linear float → (H, W, 3) uint8 sRGB (IEC 61966-2-1 OETF, round to nearest)."""
    import numpy as np

    x = np.clip(rgb, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.floor(srgb * 255.0 + 0.5).astype(np.uint8)


def write_outputs(out_dir: Path, camera: str, frame: int, rgb, ids) -> None:
    """Write the image (8-bit sRGB PNG of the (H, W, 3) linear ``rgb``) and the mask (uint16
    PNG) atomically."""
    write_display_outputs(out_dir, camera, frame, linear_to_srgb8(rgb), ids)


def write_display_outputs(out_dir: Path, camera: str, frame: int, image, ids, *, clean=None) -> None:
    """Write the image ((H, W, 3) uint8 sRGB, RGB order), the mask (uint16 PNG) and, when
    given, the clean image before the sensor's effects, atomically."""
    import cv2

    from usdscene.document import output_layout as layout
    from usdscene.files import write_bytes_atomic

    ok, image_png = cv2.imencode(".png", image[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
    ok2, mask_png = cv2.imencode(".png", ids, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not (ok and ok2):
        raise RuntimeError(f"PNG encoding failed for {camera} frame {frame}")
    if clean is not None:
        ok3, clean_png = cv2.imencode(".png", clean[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok3:
            raise RuntimeError(f"PNG encoding failed for {camera} frame {frame}")
        write_bytes_atomic(layout.clean_image_path(out_dir, camera, frame), clean_png.tobytes())
    # Mask first: a pair counts as done only when both exist, and the driver records it only
    # after this returns.
    write_bytes_atomic(layout.mask_path(out_dir, camera, frame), mask_png.tobytes())
    write_bytes_atomic(layout.image_path(out_dir, camera, frame), image_png.tobytes())
