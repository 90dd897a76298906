"""Contact sheets: many labelled images tiled into one picture (``usdscene preview``, the docs'
pictures, camera-plan previews)."""

from __future__ import annotations

import math

import cv2
import numpy as np


def contact_sheet(tiles: list[tuple[str, np.ndarray]], tile_width: int, columns: int = 0):
    """Tile labelled images into one sheet.

    Args:
        tiles: (name, (H, W, 3) uint8 BGR image) in display order.
        tile_width: tile width in pixels (images are resized keeping their aspect).
        columns: tiles per row; 0 = ceil(sqrt(n)).

    Returns:
        (H, W, 3) uint8 BGR sheet.
    """
    n = len(tiles)
    columns = columns or max(1, math.ceil(math.sqrt(n)))
    rows = math.ceil(n / columns)
    resized = []
    for name, image in tiles:
        h, w = image.shape[:2]
        th = max(1, round(h * tile_width / w))
        resized.append((name, cv2.resize(image, (tile_width, th), interpolation=cv2.INTER_AREA)))
    tile_h = max(img.shape[0] for _, img in resized) + 22
    pad = 4
    sheet = np.full((rows * (tile_h + pad) + pad, columns * (tile_width + pad) + pad, 3), 32, np.uint8)
    for i, (name, img) in enumerate(resized):
        r, c = divmod(i, columns)
        y, x = pad + r * (tile_h + pad), pad + c * (tile_width + pad)
        sheet[y:y + img.shape[0], x:x + tile_width] = img
        cv2.putText(sheet, name, (x + 4, y + tile_h - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return sheet
