"""The sensor post-process (usdscene.sensor.pipeline) on small synthetic images: deterministic per
seed, inputs untouched, each effect doing what its field says."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.document.imaging import Sensor, image_seed
from usdscene.sensor.pipeline import apply_sensor, has_effect, vignetting_map


def scene_image(height=48, width=64) -> np.ndarray:
    """(H, W, 3) uint8: a horizontal ramp in red, a vertical one in green, flat blue."""
    img = np.zeros((height, width, 3), np.uint8)
    img[..., 0] = np.linspace(0, 255, width, dtype=np.uint8)[None, :]
    img[..., 1] = np.linspace(30, 220, height, dtype=np.uint8)[:, None]
    img[..., 2] = 90
    return img


def rng(camera="cam", frame=0, seed=7):
    return np.random.default_rng(image_seed(seed, camera, frame))


def test_same_seed_same_bytes_other_image_other_noise():
    img = scene_image()
    sensor = Sensor(iso=3200, compression="jpeg", quality=50)
    a = apply_sensor(img, sensor, rng())
    assert np.array_equal(a, apply_sensor(img, sensor, rng()))
    assert not np.array_equal(a, apply_sensor(img, sensor, rng(frame=1)))
    assert not np.array_equal(a, apply_sensor(img, sensor, rng(camera="other")))
    assert image_seed(7, "cam", 3) == image_seed(7, "cam", 3) != image_seed(8, "cam", 3)


def test_input_is_not_modified():
    img = scene_image()
    before = img.copy()
    apply_sensor(img, Sensor(iso=6400, vignetting=0.5, exposure_bias_ev=1.0, ir_night=True,
                             compression="h264_like", quality=10), rng())
    assert np.array_equal(img, before)


def test_defaults_change_nothing():
    img = scene_image()
    assert not has_effect(Sensor()) and not has_effect(None)
    assert has_effect(Sensor(iso=100)) and has_effect(Sensor(compression="jpeg"))
    out = apply_sensor(img, Sensor(shutter_frames=0.5), rng())  # the shutter acts while rendering
    assert np.array_equal(out, img) and out is not img


def test_noise_grows_with_iso_and_is_centred():
    flat = np.full((96, 128, 3), 118, np.uint8)  # sRGB 118: linear 0.18, mid grey
    stds = []
    for iso in (100, 800, 6400):
        out = apply_sensor(flat, Sensor(iso=iso), rng()).astype(float)
        stds.append(out.std())
        assert abs(out.mean() - 118) < 0.5
    assert stds[0] < stds[1] < stds[2]
    # 0.181 linear at ISO 6400: 57 electrons, read noise 3: sigma = sqrt(66)/312.5 = 0.026
    # linear, times the sRGB curve's slope there (305 levels per unit): 7.9 levels
    assert 7.0 < stds[2] < 8.8


def test_read_noise_shows_in_the_dark():
    black = np.zeros((96, 128, 3), np.uint8)
    quiet = apply_sensor(black, Sensor(iso=1600, read_noise_e=0.0), rng())
    loud = apply_sensor(black, Sensor(iso=1600, read_noise_e=20.0), rng())
    assert quiet.max() == 0 and loud.mean() > 1


def test_exposure_bias_doubles_linear_light():
    grey = np.full((4, 4, 3), 118, np.uint8)  # linear 0.184
    out = apply_sensor(grey, Sensor(exposure_bias_ev=1.0), rng())
    assert np.all(out == 162)  # linear 0.362 → sRGB 162


def test_vignetting_darkens_corners_not_the_centre():
    flat = np.full((49, 65, 3), 200, np.uint8)
    out = apply_sensor(flat, Sensor(vignetting=0.5), rng()).astype(int)
    assert out[24, 32].tolist() == [200, 200, 200]
    assert out[0, 0, 0] < 170 and out[0, 0, 0] == out[48, 64, 0]
    falloff = vignetting_map(49, 65, 0.5)
    assert falloff[24, 32] == pytest.approx(1.0) and falloff[0, 0] == pytest.approx(0.5 ** (1 / 2.2), rel=1e-5)


def test_lower_jpeg_quality_loses_more():
    img = scene_image()
    img[::2, ::2] = 255  # detail a coarse quantiser loses
    errors = [np.abs(apply_sensor(img, Sensor(compression="jpeg", quality=q), rng()).astype(int) - img).mean()
              for q in (95, 50, 5)]
    assert 0 < errors[0] < errors[1] < errors[2]


def test_h264_like_is_blocky_at_16_pixels():
    ys, xs = np.mgrid[0:64, 0:64]
    smooth = 128 + 60 * np.sin(xs / 9.0) * np.cos(ys / 7.0)
    img = np.repeat(smooth[..., None], 3, axis=2).astype(np.uint8)
    out = apply_sensor(img, Sensor(compression="h264_like", quality=1), rng()).astype(float)
    steps = np.abs(np.diff(out[..., 0], axis=1))  # steps between neighbouring columns
    edges = steps[:, [15, 31, 47]].mean()  # across macroblock boundaries
    inside = np.delete(steps, [15, 31, 47], axis=1).mean()
    assert edges > 2 * inside


def test_ir_night_is_one_channel_even_compressed():
    img = scene_image()
    for compression in ("", "jpeg", "h264_like"):
        out = apply_sensor(img, Sensor(ir_night=True, iso=800, compression=compression), rng())
        assert out.shape == img.shape
        assert np.array_equal(out[..., 0], out[..., 1]) and np.array_equal(out[..., 1], out[..., 2])
    # red weighs most in the near-infrared response
    red = np.zeros((4, 4, 3), np.uint8)
    red[..., 0] = 200
    blue = np.zeros((4, 4, 3), np.uint8)
    blue[..., 2] = 200
    assert apply_sensor(red, Sensor(ir_night=True), rng())[0, 0, 0] > apply_sensor(blue, Sensor(ir_night=True), rng())[0, 0, 0]
