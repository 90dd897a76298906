"""COCO-17 person keypoints in an image: projected through the camera's lens model (the same
:func:`usdscene.labels.projection.project_points` as the amodal boxes) and flagged from the
instance mask. Pure: numpy only.

Visibility flags (COCO's):

- ``2``: the keypoint's pixel, or one of its 8 neighbours (within 1 px), belongs to the
  person's own mask: seen;
- ``1``: inside the image but not on the person's own pixels: hidden (behind something, or
  behind the person's own surface where the mask does not reach);
- ``0``: behind the camera, outside the lens's field of view or outside the image; its
  coordinates are written as ``(0, 0)`` like COCO does.
"""

from __future__ import annotations

import numpy as np

COCO_KEYPOINTS = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
                  "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
                  "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle")
"""The 17 COCO keypoints in COCO order (left = the person's left)."""
COCO_SKELETON = ((16, 14), (14, 12), (17, 15), (15, 13), (12, 13), (6, 12), (7, 13), (6, 7), (6, 8),
                 (7, 9), (8, 10), (9, 11), (2, 3), (1, 2), (1, 3), (2, 4), (3, 5), (4, 6), (5, 7))
"""COCO's person skeleton: pairs of 1-based keypoint indices."""
VISIBLE, OCCLUDED, OUTSIDE = 2, 1, 0
MASK_TOLERANCE_PX = 1


def keypoint_visibility(uv: np.ndarray, valid: np.ndarray, mask: np.ndarray, mask_id: int | np.ndarray) -> np.ndarray:
    """Flag projected keypoints against an instance mask.

    Args:
        uv: (K, 2) pixel coordinates (OpenCV: pixel centres at integers).
        valid: (K,) bool, True where the point is in front of the camera and in the lens's
            field of view (:func:`usdscene.labels.projection.project_points`).
        mask: (H, W) instance ids.
        mask_id: the person's id in ``mask``, or (K,) ids, one per keypoint (several people's
            keypoints flagged in one call).

    Returns:
        (K, 3) float64 rows ``(x, y, v)``; ``v`` in {0, 1, 2} (module docstring), ``x = y = 0``
        where ``v = 0``.
    """
    height, width = mask.shape
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    out = np.zeros((len(uv), 3))
    x, y = uv[:, 0], uv[:, 1]
    with np.errstate(invalid="ignore"):
        inside = (np.asarray(valid, dtype=bool) & (x >= -0.5) & (x < width - 0.5)
                  & (y >= -0.5) & (y < height - 0.5))
    if not inside.any():
        return out
    col = np.floor(x[inside] + 0.5).astype(np.int64)
    row = np.floor(y[inside] + 0.5).astype(np.int64)
    # The 3x3 neighbourhood of every keypoint at once (one pass, not nine: the call is per
    # person and image), offsets that leave the image skipped.
    offsets = np.arange(-MASK_TOLERANCE_PX, MASK_TOLERANCE_PX + 1)
    r = np.repeat(row[:, None] + offsets, len(offsets), axis=1)
    c = np.tile(col[:, None] + offsets, len(offsets))
    ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
    owner = np.broadcast_to(np.asarray(mask_id), (len(uv),))[inside][:, None]
    seen = (ok & (mask[np.clip(r, 0, height - 1), np.clip(c, 0, width - 1)] == owner)).any(axis=1)
    out[inside, 0], out[inside, 1] = x[inside], y[inside]
    out[inside, 2] = np.where(seen, VISIBLE, OCCLUDED)
    return out
