"""The per-pixel core of the linear chain as one compiled pass: exposure, vignetting, the tone
curve to 8 bits and the noise (numba, through :mod:`usdscene.compiled`).

Done with numpy and OpenCV the same steps are six passes over the image and two 65536-entry
table lookups, each lookup about 2.5 ms per 640x480 image (numpy's fancy indexing); fused, every
value is read once and written once (``benchmarks/sensor_postprocess.py``). The arithmetic is
what :func:`usdscene.sensor.tone.encode` states: ``x = gain · falloff · linear`` in float32,
the tone table indexed by ``sqrt(x / W)``, then, with noise, the noise table at ``level << 8 |
draw`` (:mod:`usdscene.sensor.pipeline`). Deterministic: no fast-math, one thread.

Importing this module imports numba; the kernel is compiled on first use (cached on disk).
"""

from __future__ import annotations

import functools

import numpy as np

from usdscene.sensor import tone


@functools.lru_cache(maxsize=1)
def _kernel():
    from usdscene.compiled import njit

    @njit(nogil=True)
    def encode_levels(linear, falloff, channels, scale, top, tone_table, noise_table, draws, out):
        with_noise = noise_table.size > 0
        pixels = linear.size // channels
        for p in range(pixels):
            gain = scale * falloff[p] if falloff.size > 0 else scale
            for c in range(channels):
                i = p * channels + c
                x = linear[i] * gain
                if not x > 0.0:  # negative, or NaN (an index from it would read anywhere)
                    x = np.float32(0.0)
                elif x > top:
                    x = top
                level = tone_table[np.int64(np.sqrt(x) + np.float32(0.5))]
                if with_noise:
                    level = noise_table[(np.int64(level) << 8) | np.int64(draws[i])]
                out[i] = level

    return encode_levels


_NONE_F32 = np.zeros(0, dtype=np.float32)
_NONE_U8 = np.zeros(0, dtype=np.uint8)


def encode_with_noise(linear: np.ndarray, wdr_stops: float, gain: float, falloff: np.ndarray | None,
                      noise_table: np.ndarray | None, rng: np.random.Generator | None) -> np.ndarray:
    """8-bit levels of ``gain · falloff · linear`` through the tone curve, with the noise drawn
    from ``rng`` when ``noise_table`` is given.

    Args:
        linear: float32 image, (H, W) or (H, W, C) (not modified).
        wdr_stops: the tone curve (:func:`usdscene.sensor.tone.wdr_curve`).
        gain: the exposure, ``2^ev``.
        falloff: (H, W) float32 vignetting of linear light (the same for every channel), or None.
        noise_table: (65536,) uint8 noisy level of ``level << 8 | draw``, or None (no noise).
        rng: the image's generator; one random byte per value (the draw), in the image's C order.

    Returns:
        uint8 levels of ``linear``'s shape.
    """
    source = np.ascontiguousarray(linear, dtype=np.float32).reshape(-1)
    channels = 1 if linear.ndim == 2 else int(linear.shape[2])
    top = np.float32(float(tone.TABLE_STEPS - 1) ** 2)
    scale = np.float32(gain * float(top) / tone.white_linear(wdr_stops))
    shade = _NONE_F32 if falloff is None else np.ascontiguousarray(falloff, dtype=np.float32).reshape(-1)
    if noise_table is None:
        table, draws = _NONE_U8, _NONE_U8
    else:
        table = noise_table
        draws = np.frombuffer(rng.bytes(source.size), dtype=np.uint8)
    out = np.empty(source.size, dtype=np.uint8)
    _kernel()(source, shade, channels, scale, top, tone.tone_table(float(wdr_stops)), table, draws, out)
    return out.reshape(linear.shape)
