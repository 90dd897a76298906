"""The lens and the camera's image processing: a Gaussian lens blur stated as MTF50 or PSF
sigma, unsharp-mask edge enhancement and 4:2:0 chroma. Pure module (numpy + OpenCV);
deterministic (no randomness).

* Lens blur: a Gaussian PSF of sigma s pixels has the MTF ``exp(-2 π² s² f²)`` (f in cycles per
  pixel), which is 0.5 at ``f50 = sqrt(ln 2 / 2) / (π s)``; so an MTF50 of f50 cycles per pixel is
  a PSF of ``s = 0.1874 / f50`` pixels (0.25 cy/px: 0.75 px). It blurs the *linear* image, before
  the noise: the lens blurs the light, not the sensor's noise.
* Unsharp mask: ``out = in + amount · (in - G_r * in)`` on the 8-bit image after the noise (the
  camera sharpens what the sensor read, noise included), rounded and clipped; it leaves the
  bright and dark halos along edges that real CCTV pictures show.
* 4:2:0 chroma: Cb and Cr (BT.601, OpenCV's YCrCb) averaged over 2 x 2 blocks and interpolated
  back, luma kept.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

MTF50_PER_SIGMA = math.sqrt(math.log(2.0) / 2.0) / math.pi  # f50 · sigma = 0.1874


def psf_sigma_from_mtf50(mtf50_cy_px: float) -> float:
    """Sigma in pixels of the Gaussian PSF whose MTF is 0.5 at ``mtf50_cy_px`` cycles per pixel."""
    return MTF50_PER_SIGMA / mtf50_cy_px


def mtf(sigma_px: float, frequency_cy_px: np.ndarray | float) -> np.ndarray | float:
    """MTF of a Gaussian PSF of ``sigma_px`` at ``frequency_cy_px`` (cycles per pixel)."""
    return np.exp(-2.0 * math.pi ** 2 * sigma_px ** 2 * np.asarray(frequency_cy_px, dtype=np.float64) ** 2)


def lens_blur(linear: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian blur of a float32 image ((H, W) or (H, W, 3)) with ``sigma_px`` (kernel to 3
    sigma, edges reflected); a new array."""
    radius = max(1, int(math.ceil(3.0 * sigma_px)))
    return cv2.GaussianBlur(linear, (2 * radius + 1, 2 * radius + 1), sigma_px, borderType=cv2.BORDER_REFLECT_101)


def unsharp(image: np.ndarray, amount: float, radius_px: float) -> np.ndarray:
    """Unsharp mask of a uint8 image: ``in + amount · (in - blur)``, rounded, clipped; a new array."""
    radius = max(1, int(math.ceil(3.0 * radius_px)))
    blurred = cv2.GaussianBlur(image, (2 * radius + 1, 2 * radius + 1), radius_px, borderType=cv2.BORDER_REFLECT_101)
    return cv2.addWeighted(image, 1.0 + amount, blurred, -amount, 0.0)


def chroma_420(image: np.ndarray) -> np.ndarray:
    """4:2:0 chroma of a (H, W, 3) uint8 RGB image (luma untouched); a new array."""
    h, w = image.shape[:2]
    luma, cr, cb = cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2YCrCb))
    small = cv2.resize(cv2.merge([cr, cb]), ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
    chroma = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return cv2.cvtColor(cv2.merge([luma, chroma]), cv2.COLOR_YCrCb2RGB)
