"""The camera sensor as an image operation, in two chains. Pure module (numpy + OpenCV; no
bpy, no pxr).

* :func:`process_image`, the linear chain, for a sensor with a profile, auto exposure, WDR, a
  lens blur, sharpening or 4:2:0 chroma (:func:`uses_linear`): it starts from the linear render
  (see its docstring for the order);
* :func:`apply_sensor`, the 8-bit chain of sensors without them (exposure bias, vignetting,
  shot and read noise, IR mode, compression on the rendered 8-bit sRGB image), described below;
  its bytes are those of the documents written before the linear chain existed.

The render is the light that reaches the sensor; this module is what the sensor and the encoder
make of it (:class:`usdscene.document.imaging.Sensor`). Masks and labels never pass through it. The
operations run in a camera's order:

1. exposure bias: each sRGB level decoded to linear light, times ``2^exposure_bias_ev``,
   clipped and encoded again (one 256-entry table, exact);
2. IR night mode: one near-infrared channel, the linear RGB weighted by
   :data:`usdscene.document.imaging.IR_RGB_WEIGHTS` and encoded again (exact);
3. vignetting: the linear falloff ``1 - v · ρ²`` applied to the sRGB values as
   ``(1 - v · ρ²)^(1/2.2)`` (the sRGB curve taken as a 2.2 power: within 2 levels of the exact
   curve where the falloff is 0.7 or more, within 5 where it is 0.3);
4. noise in electrons: a linear value x holds ``n = x · full_well_e · 100 / iso`` electrons;
   shot noise (variance n) and read noise (``read_noise_e``) are Gaussian, scaled back by the
   gain and carried through the sRGB curve to first order (its slope at each level); each
   pixel draws one of 256 equally likely standard normal values (the quantiles of the normal
   distribution, rescaled to unit variance: a Gaussian truncated at 2.7 sigma) and one table
   of 256 x 256 entries gives the rounded 8-bit result for every (level, draw);
5. compression: a JPEG or H.264-like round trip at ``quality``.

Working on the 8-bit image with small tables keeps a 640x480 image within about 10 ms of CPU
(``benchmarks/sensor_postprocess.py``). The shutter and the IR illuminator act while rendering
(the worker). The draws are random bytes of the ``numpy.random.Generator`` the caller passes,
seeded per image by :func:`usdscene.document.imaging.image_seed`: the same document gives the same bytes
whatever the order, worker or executor.
"""

from __future__ import annotations

import functools
from statistics import NormalDist

import cv2
import numpy as np

from usdscene.document.imaging import IR_RGB_WEIGHTS, Sensor
from usdscene.sensor import exposure, kernels, optics, tone

# Linear values are encoded through a table of this many steps: the darkest step (1/16383 linear)
# is 0.2 of an sRGB level, so rounding matches the exact curve to within one level.
_ENCODE_STEPS = 16384


def _decode_curve(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _encode_curve(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0), 1.0 / 2.4) - 0.055)


_DECODE = _decode_curve(np.arange(256, dtype=np.float64) / 255.0)
_ENCODE = np.floor(_encode_curve(np.arange(_ENCODE_STEPS, dtype=np.float64) / (_ENCODE_STEPS - 1)) * 255.0
                   + 0.5).astype(np.uint8)
# Slope of the sRGB curve at each level, in levels per unit of linear light (central differences).
_SLOPE = np.gradient(np.arange(256, dtype=np.float64), _DECODE)
_GAUSS = np.array([NormalDist().inv_cdf((i + 0.5) / 256) for i in range(256)])
_GAUSS /= _GAUSS.std()


def has_effect(sensor: Sensor | None) -> bool:
    """Whether ``sensor`` changes an image at all (a sensor of defaults does not)."""
    return sensor is not None and (sensor.exposure_bias_ev != 0.0 or sensor.vignetting > 0.0
                                   or sensor.iso is not None or bool(sensor.compression) or sensor.ir_night
                                   or uses_linear(sensor))


@functools.lru_cache(maxsize=16)
def vignetting_map(height_px: int, width_px: int, vignetting: float, exponent: float = 1.0 / 2.2) -> np.ndarray:
    """(H, W) float32 falloff ``(1 - vignetting · ρ²)^exponent`` with ρ the distance from the
    image centre over the half-diagonal (1 in the corners): of the sRGB values with the default
    exponent, of linear light with 1. Cached: it is the same for every image of a camera."""
    ys = (np.arange(height_px, dtype=np.float64) - (height_px - 1) / 2.0)[:, None]
    xs = (np.arange(width_px, dtype=np.float64) - (width_px - 1) / 2.0)[None, :]
    rho2 = (xs * xs + ys * ys) / (((width_px - 1) / 2.0) ** 2 + ((height_px - 1) / 2.0) ** 2 or 1.0)
    out = np.power(1.0 - vignetting * rho2, exponent).astype(np.float32)
    out.setflags(write=False)
    return out


def noise_sigma_levels(iso: float, full_well_e: float, read_noise_e: float,
                       wdr_stops: float | None = None) -> np.ndarray:
    """(256,) float64: standard deviation of the noise in levels at each 8-bit level: through
    the sRGB curve (``wdr_stops`` None, the 8-bit path), or through the tone curve of
    :mod:`usdscene.sensor.tone` (its slope carries the noise: WDR raises it in the shadows)."""
    electrons_per_unit = full_well_e * 100.0 / iso
    if wdr_stops is None:
        linear, slope = _DECODE, _SLOPE
    else:
        linear, slope = tone.level_linear_and_slope(float(wdr_stops))
    sigma_linear = np.sqrt(linear * electrons_per_unit + read_noise_e ** 2) / electrons_per_unit
    return sigma_linear * slope


@functools.lru_cache(maxsize=64)
def _noise_table(iso: float, full_well_e: float, read_noise_e: float, wdr_stops: float | None = None) -> np.ndarray:
    """(65536,) uint8: the noisy level of (level << 8 | draw), rounded and clipped."""
    sigma = noise_sigma_levels(iso, full_well_e, read_noise_e, wdr_stops)
    levels = np.arange(256, dtype=np.float64)[:, None] + sigma[:, None] * _GAUSS[None, :]
    table = np.clip(np.floor(levels + 0.5), 0, 255).astype(np.uint8).reshape(-1)
    table.setflags(write=False)
    return table


@functools.lru_cache(maxsize=64)
def _exposure_table(exposure_bias_ev: float) -> np.ndarray:
    linear = np.clip(_DECODE * 2.0 ** exposure_bias_ev, 0.0, 1.0)
    return _ENCODE[np.rint(linear * (_ENCODE_STEPS - 1)).astype(np.int64)]


def apply_sensor(image: np.ndarray, sensor: Sensor, rng: np.random.Generator) -> np.ndarray:
    """What ``sensor`` makes of a clean rendered image.

    Args:
        image: (H, W, 3) uint8 sRGB image in RGB order (not modified).
        sensor: the camera's sensor at this frame (``Sensor.at_frame``).
        rng: the image's generator (:func:`usdscene.document.imaging.image_seed`); only noise draws from it.

    Returns:
        (H, W, 3) uint8 sRGB image, a new array; in IR night mode the three channels are equal.
    """
    height, width = image.shape[:2]
    out = image
    if sensor.exposure_bias_ev != 0.0:
        out = cv2.LUT(out, _exposure_table(float(sensor.exposure_bias_ev)))
    if sensor.ir_night:
        decode = _DECODE.astype(np.float32)
        linear = cv2.transform(cv2.LUT(out, decode), np.asarray([IR_RGB_WEIGHTS], dtype=np.float32))
        out = _ENCODE[(np.clip(linear, 0.0, 1.0) * np.float32(_ENCODE_STEPS - 1) + np.float32(0.5)).astype(np.uint16)]
    if sensor.vignetting > 0.0:
        falloff = vignetting_map(height, width, float(sensor.vignetting))
        # falloff <= 1: no overflow; convertScaleAbs rounds to nearest (values are >= 0)
        out = cv2.convertScaleAbs(cv2.multiply(out.astype(np.float32), falloff if out.ndim == 2 else
                                               cv2.merge([falloff, falloff, falloff])))
    if sensor.iso is not None:
        out = _add_noise(out, _noise_table(float(sensor.iso), float(sensor.full_well_e), float(sensor.read_noise_e)),
                         rng)
    if out is image:
        out = image.copy()
    return _encode(out, sensor)


def _add_noise(levels: np.ndarray, table: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per pixel and channel from ``rng``'s bytes, looked up in a noise table."""
    draws = np.frombuffer(rng.bytes(levels.size), dtype=np.uint8).reshape(levels.shape)
    index = levels.astype(np.uint16)
    index <<= 8
    index |= draws
    return table[index]


def _encode(out: np.ndarray, sensor: Sensor) -> np.ndarray:
    """The compression round trip, then three channels (an IR image's are equal)."""
    if sensor.compression == "jpeg":
        out = _jpeg(out, sensor.quality)
    elif sensor.compression == "h264_like":
        out = _h264_like(out, sensor.quality)
    if out.ndim == 2:
        out = cv2.merge([out, out, out])
    return out


def uses_linear(sensor: Sensor | None) -> bool:
    """Whether ``sensor`` runs the linear chain (:func:`process_image`): a profile, auto
    exposure, WDR, a lens blur, sharpening or 4:2:0 chroma. A sensor without them keeps the
    8-bit chain of :func:`apply_sensor` and its bytes."""
    return sensor is not None and bool(
        sensor.profile or sensor.auto_exposure or sensor.wdr_stops > 0.0 or sensor.mtf50_cy_px is not None
        or sensor.psf_sigma_px is not None or sensor.sharpen > 0.0 or sensor.chroma_420)


def as_linear(render: np.ndarray) -> np.ndarray:
    """The render as (H, W, 3) float32 linear light: itself when it is (the Standard view), else
    an 8-bit sRGB picture decoded through the sRGB curve (the AgX and Filmic views write 8 bits;
    their highlights are already compressed, so auto exposure meters the picture, not the
    scene)."""
    if render.dtype == np.uint8:
        return cv2.LUT(render, _DECODE.astype(np.float32))
    return render


def lens_sigma_px(sensor: Sensor) -> float:
    """The lens's PSF sigma in pixels (0: a sharp lens)."""
    if sensor.psf_sigma_px is not None:
        return float(sensor.psf_sigma_px)
    if sensor.mtf50_cy_px is not None and sensor.mtf50_cy_px < 0.5:
        return optics.psf_sigma_from_mtf50(float(sensor.mtf50_cy_px))
    return 0.0


def meter(linear: np.ndarray, sensor: Sensor, falloff: np.ndarray | None = None) -> float:
    """What ``sensor``'s meter reads of a linear image (after the IR response, the lens and the
    vignetting ``falloff``, as a camera's meter does);
    :func:`usdscene.sensor.exposure.metered_luminance`."""
    return exposure.metered_luminance(linear, sensor.metering, sensor.metering_region,
                                      log_average=sensor.wdr_stops > 0.0, falloff=falloff)


def meter_prepass(linear: np.ndarray, sensor: Sensor) -> float:
    """The meter reading of a frame of an adapting camera (``exposure_speed`` < 1) from its
    pre-pass render (:data:`usdscene.sensor.exposure.PREPASS_SCALE_PERCENT`): the IR response and
    the vignetting as :func:`process_image` applies them, then :func:`meter`; rounded to 6
    significant digits (what the annotations record is what decided the exposure).

    Args:
        linear: (h, w, 3) float32 linear RGB of the pre-pass, after the world's exposure.
        sensor: the camera's sensor at that frame.
    """
    x = linear
    if sensor.ir_night:
        x = cv2.transform(x, np.asarray([IR_RGB_WEIGHTS], dtype=np.float32))
    falloff = None
    if sensor.vignetting > 0.0:
        falloff = vignetting_map(x.shape[0], x.shape[1], float(sensor.vignetting), 1.0)
    return float(f"{meter(x, sensor, falloff):.6g}")


def process_image(linear: np.ndarray, sensor: Sensor, rng: np.random.Generator,
                  adapted: tuple[float, float, float] | None = None) -> tuple[np.ndarray, dict]:
    """The whole camera on a linear render, in its order: IR response, lens blur, vignetting
    (the optics), metering and exposure (auto + bias), the tone curve to 8 bits, noise (added in
    electrons before the curve, carried through its slope), unsharp mask, 4:2:0 chroma,
    compression.

    Args:
        linear: (H, W, 3) float32 linear RGB, the render after the world's exposure (not
            modified).
        sensor: the camera's sensor at this frame (``Sensor.at_frame``).
        rng: the image's generator (:func:`usdscene.document.imaging.image_seed`); only the
            noise draws from it.
        adapted: for ``exposure_speed`` < 1, ``(exposure_ev, target_ev, metered)`` of this
            frame from the camera's sequence (:func:`usdscene.sensor.exposure.sequence_ev` over
            the :func:`meter_prepass` readings): the auto exposure applied instead of this
            image's own instant one (None: instant, metered on this image).

    Returns:
        ``(image, record)``: (H, W, 3) uint8 sRGB RGB (equal channels in IR mode) and what the
        exposure did, ``{"exposure_ev", "metered_luminance"}`` (stops applied, auto exposure and
        bias together; the meter's reading, linear), for the annotations; an adapted exposure
        adds ``target_ev``, the instant exposure of this frame that it is moving towards.
    """
    height, width = linear.shape[:2]
    x = linear
    if sensor.ir_night:
        x = cv2.transform(x, np.asarray([IR_RGB_WEIGHTS], dtype=np.float32))
    sigma = lens_sigma_px(sensor)
    if sigma > 0.0:
        x = optics.lens_blur(x, sigma)
    falloff = None
    if sensor.vignetting > 0.0:
        falloff = vignetting_map(height, width, float(sensor.vignetting), 1.0)
    record = {}
    ev = 0.0
    if adapted is not None:
        ev, record["target_ev"], metered = adapted
    else:
        metered = meter(x, sensor, falloff)
        if sensor.auto_exposure:
            ev = exposure.exposure_ev(metered, float(sensor.target_grey), float(sensor.exposure_min_ev),
                                      float(sensor.exposure_max_ev))
    ev = round(ev + float(sensor.exposure_bias_ev), exposure.EV_DECIMALS)
    table = None
    if sensor.iso is not None:
        table = _noise_table(float(sensor.iso), float(sensor.full_well_e), float(sensor.read_noise_e),
                             float(sensor.wdr_stops))
    # exposure, vignetting, tone curve and noise in one compiled pass (tone.encode + _add_noise)
    out = kernels.encode_with_noise(x, float(sensor.wdr_stops), 2.0 ** ev, falloff, table, rng)
    if sensor.sharpen > 0.0:
        out = optics.unsharp(out, float(sensor.sharpen), float(sensor.sharpen_radius_px))
    if sensor.chroma_420 and out.ndim == 3 and not sensor.compression:
        # JPEG (OpenCV's default sampling) and H.264-like already subsample the chroma 4:2:0
        out = optics.chroma_420(out)
    record.update(exposure_ev=ev, metered_luminance=round(metered, 6))
    return _encode(out, sensor), record


def _jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    """JPEG round trip at ``quality`` (OpenCV's libjpeg, 4:2:0 chroma); a (H, W) image stays
    one channel (a greyscale JPEG), so IR images keep equal channels."""
    bgr = image if image.ndim == 2 else image[..., ::-1]
    ok, data = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    flag = cv2.IMREAD_GRAYSCALE if image.ndim == 2 else cv2.IMREAD_COLOR
    decoded = cv2.imdecode(data, flag)
    return decoded if image.ndim == 2 else decoded[..., ::-1]


def _dct_matrix(n: int) -> np.ndarray:
    k = np.arange(n)[:, None]
    i = np.arange(n)[None, :]
    m = np.cos(np.pi * (2 * i + 1) * k / (2 * n)) * np.sqrt(2.0 / n)
    m[0] /= np.sqrt(2.0)
    return m.astype(np.float32)


_DCT16 = _dct_matrix(16)
_DCT8 = _dct_matrix(8)


def _quantise_blocks(plane: np.ndarray, block: int, step: float) -> np.ndarray:
    """Orthonormal DCT of ``block`` x ``block`` tiles, uniform quantisation with ``step`` (the
    DC term with a quarter of it, as encoders keep flat areas' levels finer), inverse DCT."""
    h, w = plane.shape
    ph, pw = -h % block, -w % block
    padded = np.pad(plane, ((0, ph), (0, pw)), mode="edge") if ph or pw else plane
    H, W = padded.shape
    rows, cols = H // block, W // block
    tiles = padded.reshape(rows, block, cols, block).transpose(0, 2, 1, 3).reshape(-1, block, block)
    d = _DCT16 if block == 16 else _DCT8
    coeffs = _two_sided(tiles, d)
    steps = np.full((block, block), step, dtype=np.float32)
    steps[0, 0] = max(1.0, step / 4.0)
    coeffs = np.round(coeffs / steps) * steps
    back = _two_sided(coeffs, np.ascontiguousarray(d.T))
    back = back.reshape(rows, cols, block, block).transpose(0, 2, 1, 3).reshape(H, W)
    return back[:h, :w]


def _two_sided(tiles: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``d @ tile @ d.T`` for every tile of (N, b, b), as two (N·b, b) x (b, b) products (one
    large product is many times faster than N small ones)."""
    n, b, _ = tiles.shape
    right = (np.ascontiguousarray(tiles).reshape(n * b, b) @ d.T).reshape(n, b, b)
    both = (np.ascontiguousarray(right.transpose(0, 2, 1)).reshape(n * b, b) @ d.T).reshape(n, b, b)
    return both.transpose(0, 2, 1)


def _rounded_levels(values: np.ndarray) -> np.ndarray:
    """float32 levels (any shape; overwritten) rounded half up and clipped to uint8."""
    values += np.float32(0.5)
    np.clip(values, 0, 255, out=values)
    return values.astype(np.uint8)


def _h264_like(image: np.ndarray, quality: int) -> np.ndarray:
    """The look of a low-bitrate video stream: 16 x 16 luma macroblocks and 4:2:0 chroma (8 x 8
    blocks at half resolution), each block's DCT quantised with one flat step (no frequency
    weighting, no deblocking), so low qualities show flat 16-pixel tiles. Not an H.264 encoder.

    Each plane stays contiguous and is rounded on its own; only the 8-bit planes are interleaved
    (passes over an interleaved (H, W, 3) float array cost more than all the DCTs: 10.6 ms per
    640x480 image before, 4.7 after, ``benchmarks/sensor_postprocess.py``). The two chroma planes
    are upsampled together, as one two-channel image, as before: OpenCV's one-channel path
    differs in the last bit and would move a few rounded levels."""
    step = np.float32(2.0 + (100 - int(quality)) * 0.8)  # quality 100: step 2; quality 1: step 81
    if image.ndim == 2:
        return _rounded_levels(_quantise_blocks(image.astype(np.float32), 16, step))
    luma, cr, cb = (plane.astype(np.float32) for plane in cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2YCrCb)))
    h, w = image.shape[:2]
    luma = _rounded_levels(_quantise_blocks(luma, 16, step))
    chroma = [_quantise_blocks(cv2.resize(plane, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA),
                               8, step * 1.5) for plane in (cr, cb)]
    chroma = _rounded_levels(cv2.resize(cv2.merge(chroma), (w, h), interpolation=cv2.INTER_LINEAR))
    return cv2.cvtColor(cv2.merge([luma, chroma]), cv2.COLOR_YCrCb2RGB)


def sensor_provenance(sensor: Sensor, seed: list[int]) -> dict:
    """What was applied to one image, for the annotations: the sensor's fields at this frame
    (defaults left out) and the generator's entropy."""
    from usdscene.document.imaging import spec_to_json

    return {**spec_to_json(sensor), "seed": [int(v) for v in seed]}
