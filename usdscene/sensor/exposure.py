"""Auto exposure: meter the linear render, choose the exposure that brings the metered
luminance to a target grey. Pure module (numpy + OpenCV).

The meter reads linear light before any tone curve, as a camera's does before its ISP's gamma.
Luminance is Rec. 709 ``0.2126 R + 0.7152 G + 0.0722 B`` of the linear render, averaged with
the weights of the metering mode on a quarter-resolution copy (the mean of a smooth weighting
does not need every pixel; 0.3 ms instead of 1.5 ms per 640x480 image):

* ``average``: every pixel alike;
* ``centre_weighted``: a Gaussian falloff, ``exp(-ρ² / (2 · 0.35²))`` with ρ the distance from
  the centre over the half-diagonal (the centre 35 % of the half-diagonal holds about half the
  weight of a 4:3 image, like a camera's centre-weighted mode);
* ``region``: the mean over a rectangle of the image (backlight compensation: meter the subject,
  not the window behind it).

With wide dynamic range on (``wdr_stops`` > 0) the meter takes the weighted *geometric* mean
(the log average, ``exp(Σ w ln(Y + 1e-4))``) instead: a window a hundred times brighter than the
room then moves the exposure by its share of the stops, not by its share of the light, and the
WDR curve keeps the window's highlights (:mod:`usdscene.sensor.tone`).

The exposure in stops is ``log2(target_grey / metered)`` clipped to the limits; over frames it
follows :func:`adapt_ev`.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)
CENTRE_SIGMA = 0.35
# Exposures are rounded to this many decimals of a stop: what the annotations record is what
# was applied.
EV_DECIMALS = 4


@functools.lru_cache(maxsize=32)
def metering_weights(height_px: int, width_px: int, metering: str, region: tuple[float, ...] = ()) -> np.ndarray:
    """(H, W) float32 weights summing to 1 of a metering mode (cached per camera)."""
    if metering == "average":
        weights = np.ones((height_px, width_px), dtype=np.float64)
    elif metering == "centre_weighted":
        ys = (np.arange(height_px, dtype=np.float64) - (height_px - 1) / 2.0)[:, None]
        xs = (np.arange(width_px, dtype=np.float64) - (width_px - 1) / 2.0)[None, :]
        rho2 = (xs * xs + ys * ys) / max(((width_px - 1) / 2.0) ** 2 + ((height_px - 1) / 2.0) ** 2, 1.0)
        weights = np.exp(-rho2 / (2.0 * CENTRE_SIGMA ** 2))
    elif metering == "region":
        x0, y0, x1, y1 = region
        weights = np.zeros((height_px, width_px), dtype=np.float64)
        c0, c1 = int(math.floor(x0 * width_px)), max(int(math.ceil(x1 * width_px)), int(math.floor(x0 * width_px)) + 1)
        r0, r1 = int(math.floor(y0 * height_px)), max(int(math.ceil(y1 * height_px)), int(math.floor(y0 * height_px)) + 1)
        weights[r0:r1, c0:c1] = 1.0
    else:
        raise ValueError(f"unknown metering mode {metering!r}")
    out = (weights / weights.sum()).astype(np.float32)
    out.setflags(write=False)
    return out


def luminance(linear: np.ndarray) -> np.ndarray:
    """(H, W) float32 linear luminance of a (H, W, 3) linear RGB image; a (H, W) image is
    already one channel (the IR mode's) and returned as it is."""
    if linear.ndim == 2:
        return linear
    return cv2.transform(linear, np.asarray([LUMINANCE_WEIGHTS], dtype=np.float32))


LOG_EPSILON = 1e-4


def metered_luminance(linear: np.ndarray, metering: str = "average", region: tuple[float, ...] = (),
                      log_average: bool = False, falloff: np.ndarray | None = None) -> float:
    """The weighted mean linear luminance the meter reads (geometric with ``log_average``).

    Args:
        linear: (H, W, 3) float32 linear RGB (or (H, W) one channel), the render before any
            tone curve.
        metering: one of :data:`usdscene.document.imaging.METERING_MODES`.
        region: ``(x0, y0, x1, y1)`` fractions of the image for ``region`` metering.
        log_average: the weighted geometric mean (WDR metering) instead of the arithmetic one.
        falloff: (H, W) float32 vignetting of linear light that the meter sees (None: none),
            applied to the quarter-resolution copy.
    """
    height, width = linear.shape[:2]
    small_w, small_h = max(1, width // 4), max(1, height // 4)
    lum = luminance(cv2.resize(linear, (small_w, small_h), interpolation=cv2.INTER_AREA))
    if falloff is not None:
        lum = lum * cv2.resize(falloff, (small_w, small_h), interpolation=cv2.INTER_AREA)
    weights = metering_weights(small_h, small_w, metering, tuple(float(v) for v in region))
    values = lum.astype(np.float64).ravel()
    w = weights.astype(np.float64).ravel()
    if log_average:
        return float(math.exp(np.dot(np.log(np.maximum(values, 0.0) + LOG_EPSILON), w)))
    return float(np.dot(values, w))


def exposure_ev(metered: float, target_grey: float, min_ev: float, max_ev: float) -> float:
    """Stops that bring ``metered`` linear luminance to ``target_grey``, within [min_ev, max_ev]
    (a black image gets ``max_ev``), rounded to :data:`EV_DECIMALS`."""
    ev = max_ev if metered <= 0.0 else math.log2(target_grey / metered)
    return round(min(max(ev, min_ev), max_ev), EV_DECIMALS)


def adapt_ev(previous_ev: float | None, target_ev: float, speed: float) -> float:
    """One frame of adaptation: the exposure moves ``speed`` (0-1] of the way from the previous
    frame's exposure to this frame's target (1 or no previous frame: instant)."""
    if previous_ev is None or speed >= 1.0:
        return target_ev
    return round(previous_ev + speed * (target_ev - previous_ev), EV_DECIMALS)


def adapted_evs(target_evs: list[float], speed: float) -> list[float]:
    """The exposures of a sequence of frames from their targets (the first frame instant)."""
    out: list[float] = []
    previous = None
    for target in target_evs:
        previous = adapt_ev(previous, target, speed)
        out.append(previous)
    return out
