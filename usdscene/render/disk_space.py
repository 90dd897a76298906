"""Will a render's output fit on the disk? Checked before the first image is rendered, so that
a long run does not stop hours in with "no space left on the device".

The estimate is deliberately generous (a noisy 8-bit RGB render barely compresses as PNG): per
image :data:`IMAGE_BYTES_PER_PIXEL` for the image, :data:`MASK_BYTES_PER_PIXEL` for the
uint16 instance mask (mostly background, so it compresses well), the same image again for
``keep_clean``, and :data:`LABEL_BYTES_PER_IMAGE` for the image's labels.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Iterable

from usdscene.errors import RenderError

IMAGE_BYTES_PER_PIXEL = 2.0
"""PNG bytes per pixel of a rendered 8-bit RGB image (raw: 3); noise keeps it high."""
MASK_BYTES_PER_PIXEL = 0.25
"""PNG bytes per pixel of a uint16 instance-id mask (raw: 2)."""
LABEL_BYTES_PER_IMAGE = 16_384
"""Labels of one image kept beside the render (``OUT/labels/``), a typical size."""


def estimated_output_bytes(image_sizes: Iterable[tuple[int, int]], *, keep_clean: bool = False) -> int:
    """Bytes the render of these images will write.

    Args:
        image_sizes: ``(width_px, height_px)`` of every image still to render.
        keep_clean: the clean image before the sensor is written too.
    """
    per_pixel = IMAGE_BYTES_PER_PIXEL * (2 if keep_clean else 1) + MASK_BYTES_PER_PIXEL
    return int(sum(w * h * per_pixel + LABEL_BYTES_PER_IMAGE for w, h in image_sizes))


def check_free_space(out_dir: Path, image_sizes: Iterable[tuple[int, int]], *, keep_clean: bool = False) -> None:
    """Refuse a render whose estimated output exceeds the free space where it is written.

    Raises:
        RenderError: naming the estimate, the free space and the folder.
    """
    needed = estimated_output_bytes(image_sizes, keep_clean=keep_clean)
    folder = Path(out_dir)
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    if needed > free:
        raise RenderError(f"the render needs about {_size(needed)} (estimated: images, masks and labels) "
                          f"but only {_size(free)} is free on the disk of {folder}; free space or "
                          "render fewer frames or cameras", where=str(out_dir))


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("KB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} bytes"
