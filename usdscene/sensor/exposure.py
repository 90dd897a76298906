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

**Adapting over frames, deterministically.** With ``exposure_speed`` s < 1 the exposure of frame
t is the adaptation (:func:`adapt_ev`) run over the meter readings of frames ``t - W .. t`` of
that camera, instant at the window's first frame (or at the sequence's first frame when the
window reaches before it): W = :func:`warmup_frames` (s) is the number of frames after which
less than 1 % of an exposure step is left to correct, ``ceil(ln 0.01 / ln(1 - s))`` (7 frames
for s = 0.5, 44 for 0.1), at most :data:`MAX_WARMUP_FRAMES`. So the exposure of a frame is a
function of the readings of that frame and the W before it, and nothing else: whichever worker,
shard or executor renders it, and in whatever order, computes the same value. The reading of
each frame comes from a pre-pass render that depends only on the frame (the worker's
``meter_prepass``: a quarter-resolution render at :data:`PREPASS_SAMPLES` samples without
denoising), never from the full image, so a shard that starts at frame t renders the W frames
before it as pre-passes only.
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
# The adaptation window: frames after which less than this share of a step is left.
WARMUP_RESIDUAL = 0.01
MAX_WARMUP_FRAMES = 100
# The pre-pass that meters each frame of an adapting camera: a quarter of the resolution (the
# meter reads a quarter-resolution copy anyway) at this many samples, without denoising.
PREPASS_SCALE_PERCENT = 25
PREPASS_SAMPLES = 8


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


def warmup_frames(speed: float) -> int:
    """Frames of the adaptation window before a frame (0 for an instant exposure): the fewest
    after which less than :data:`WARMUP_RESIDUAL` of an exposure step is left, ``(1 - speed)^W
    <= 0.01``, at most :data:`MAX_WARMUP_FRAMES`."""
    if speed >= 1.0:
        return 0
    return min(MAX_WARMUP_FRAMES, math.ceil(math.log(WARMUP_RESIDUAL) / math.log(1.0 - speed) - 1e-9))


def meter_window(frame: int, warmup: int, first_frame: int) -> range:
    """The frames whose meter readings decide ``frame``'s exposure: the ``warmup`` frames
    before it (not before the sequence's ``first_frame``) and itself, ascending."""
    return range(max(int(first_frame), int(frame) - int(warmup)), int(frame) + 1)


def sequence_ev(metered: list[float], target_grey: float, min_ev: float, max_ev: float, speed: float) -> tuple[float, float]:
    """``(exposure_ev, target_ev)`` of the last frame of a window of meter readings (linear
    luminances, :func:`meter_window`'s frames in order): the adaptation from an instant
    exposure at the window's first frame, and the last frame's own instant exposure."""
    targets = [exposure_ev(m, target_grey, min_ev, max_ev) for m in metered]
    return adapted_evs(targets, speed)[-1], targets[-1]
