"""The tone curve: linear light (after exposure) to 8-bit sRGB levels, plain or with wide
dynamic range. Pure module (numpy + OpenCV).

Without WDR the curve is the sRGB OETF clipped at linear 1, what the renderer wrote before. With
``wdr_stops`` = D > 0 a global curve ``T(x) = ln(1 + c x) / ln(1 + c W)`` with ``W = 2^D`` maps
linear W to white (the D stops above 1 that would clip keep their detail) and passes through mid
grey (``T(0.18) = 0.18``, c solved for it), before the sRGB curve. Below mid grey it rises
faster than the identity: its slope at black is ``c / ln(1 + c W)`` (1.15 for D = 1, 1.29 for
D = 2, 1.44 for D = 3; :func:`shadow_gain`), so the shadows are lifted and **their noise with
them, by the same factor** (the noise is added before the curve, in electrons); highlights are
compressed and their noise shrinks. That is what a camera's digital WDR does to noise: dark areas
of a WDR picture are grainier than the same areas without it.

The curve is applied through a 65536-entry table indexed by ``sqrt(x / W)``, so that the
shadows, where the curve is steepest, get the finest steps (within half a level of the exact
curve everywhere, tests/test_camera_pipeline.py).
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

MID_GREY = 0.18
TABLE_STEPS = 65536


def _srgb(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0), 1.0 / 2.4) - 0.055)


@functools.lru_cache(maxsize=16)
def wdr_constant(wdr_stops: float) -> float:
    """c of the WDR curve of ``wdr_stops`` (0 for none): ``ln(1 + c·0.18) / ln(1 + c·W) = 0.18``,
    solved by bisection on log c."""
    if wdr_stops <= 0.0:
        return 0.0
    white = 2.0 ** wdr_stops
    lo, hi = -12.0, 12.0  # log10 c
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        c = 10.0 ** mid
        if math.log1p(c * MID_GREY) / math.log1p(c * white) < MID_GREY:
            lo = mid
        else:
            hi = mid
    return 10.0 ** (0.5 * (lo + hi))


def wdr_curve(x: np.ndarray, wdr_stops: float) -> np.ndarray:
    """T(x): linear light → linear display value 0-1 (identity clipped at 1 without WDR)."""
    x = np.asarray(x, dtype=np.float64)
    if wdr_stops <= 0.0:
        return np.clip(x, 0.0, 1.0)
    c = wdr_constant(wdr_stops)
    white = 2.0 ** wdr_stops
    return np.clip(np.log1p(c * np.maximum(x, 0.0)) / math.log1p(c * white), 0.0, 1.0)


def shadow_gain(wdr_stops: float) -> float:
    """Slope of the WDR curve at black: how much the darkest tones and their noise are raised."""
    if wdr_stops <= 0.0:
        return 1.0
    c = wdr_constant(wdr_stops)
    return c / math.log1p(c * 2.0 ** wdr_stops)


def white_linear(wdr_stops: float) -> float:
    """Linear value that the curve maps to white: ``2^wdr_stops``."""
    return 2.0 ** max(wdr_stops, 0.0)


def levels(x: np.ndarray, wdr_stops: float) -> np.ndarray:
    """Exact 8-bit levels (float64, unrounded) of linear ``x`` through the curve and sRGB."""
    return 255.0 * _srgb(wdr_curve(x, wdr_stops))


@functools.lru_cache(maxsize=16)
def tone_table(wdr_stops: float) -> np.ndarray:
    """(65536,) uint8: the level of linear ``W · (i / 65535)²``."""
    xs = white_linear(wdr_stops) * (np.arange(TABLE_STEPS, dtype=np.float64) / (TABLE_STEPS - 1)) ** 2
    table = np.floor(levels(xs, wdr_stops) + 0.5).astype(np.uint8)
    table.setflags(write=False)
    return table


def encode(linear: np.ndarray, wdr_stops: float, gain: float = 1.0, falloff: np.ndarray | None = None) -> np.ndarray:
    """``gain · falloff · linear`` → uint8 levels through the tone curve (table lookup), in one
    pass over the float image.

    Args:
        linear: float32 image, (H, W) or (H, W, C) (not modified).
        wdr_stops: the curve (:func:`wdr_curve`).
        gain: the exposure, ``2^ev``.
        falloff: float32 vignetting of the image's shape (channels repeated), or None.
    """
    top = float(TABLE_STEPS - 1) ** 2
    scale = gain * top / white_linear(wdr_stops)
    x = cv2.multiply(linear, falloff, scale=scale) if falloff is not None else cv2.multiply(linear, scale)
    np.clip(x, 0.0, top, out=x)
    cv2.sqrt(x, x)
    x += np.float32(0.5)
    # OpenCV returns a 1-D input as a column: give the caller its own shape back
    return tone_table(wdr_stops)[x.astype(np.uint16)].reshape(linear.shape)


@functools.lru_cache(maxsize=16)
def level_linear_and_slope(wdr_stops: float) -> tuple[np.ndarray, np.ndarray]:
    """For each 8-bit level: the linear value that shows at it and the curve's slope there in
    levels per unit of linear light, ((256,), (256,)) float64, for the noise tables."""
    grid = white_linear(wdr_stops) * np.linspace(0.0, 1.0, 200001) ** 2
    lv = levels(grid, wdr_stops)
    linear = np.interp(np.arange(256, dtype=np.float64), lv, grid)
    slope = np.gradient(np.arange(256, dtype=np.float64), linear)
    return linear, slope
