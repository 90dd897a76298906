"""A box of whole pixels, the unit every label of an image is measured in. Pure.

Pixel convention (OpenCV's, the one of :class:`usdscene.document.model.Intrinsics`): pixel
centres sit at integer coordinates and pixel ``(x, y)`` covers ``[x - 0.5, x + 0.5] ×
[y - 0.5, y + 0.5]``. Both the amodal projection (:mod:`usdscene.labels.amodal`) and the labels
of instance masks (:mod:`usdscene.labels.image_labels`) return boxes of this kind.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence


@dataclass(frozen=True)
class PixelBox:
    """An axis-aligned box of whole pixels: inclusive column/row indices.

    Attributes:
        x_min, y_min: first covered column and row (pixels, may be negative for an unclipped
            projection).
        x_max, y_max: last covered column and row, inclusive (``>= x_min``, ``>= y_min``).
    """

    x_min: int
    y_min: int
    x_max: int
    y_max: int

    @property
    def width_px(self) -> int:
        """Covered columns, edge to edge (pixels)."""
        return self.x_max - self.x_min + 1

    @property
    def height_px(self) -> int:
        """Covered rows, edge to edge (pixels)."""
        return self.y_max - self.y_min + 1

    def center_size(self) -> tuple[float, float, float, float]:
        """OpenLABEL ``bbox`` value ``[cx, cy, w, h]`` (pixel centres at integers), pixels."""
        return ((self.x_min + self.x_max) / 2.0, (self.y_min + self.y_max) / 2.0,
                float(self.width_px), float(self.height_px))

    def xywh_corner(self) -> tuple[float, float, float, float]:
        """COCO ``[x, y, w, h]``: top-left corner where pixel ``i`` covers ``[i, i + 1)``."""
        return (float(self.x_min), float(self.y_min), float(self.width_px), float(self.height_px))

    @staticmethod
    def from_center_size(value: Sequence[float]) -> "PixelBox":
        """Inverse of :meth:`center_size` (values are rounded to whole pixels)."""
        cx, cy, w, h = (float(v) for v in value)
        x_min = int(round(cx - (w - 1.0) / 2.0))
        y_min = int(round(cy - (h - 1.0) / 2.0))
        return PixelBox(x_min, y_min, x_min + int(round(w)) - 1, y_min + int(round(h)) - 1)
