"""The camera's linear chain (usdscene.sensor): auto exposure follows the light, WDR keeps a
backlit doorway, the lens blur has the MTF it is given, the tone table is the curve, same seed
same bytes, profiles in the document and what validate refuses. Pure tier."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from usdscene.document.imaging import Sensor, image_seed, profile_sensor, spec_from_json, spec_to_json
from usdscene.document.camera_profiles import PROFILES
from usdscene.errors import DocumentError
from usdscene.sensor import exposure, optics, tone
from usdscene.sensor.pipeline import apply_sensor, noise_sigma_levels, process_image, uses_linear

pytestmark = pytest.mark.unit

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"
WHERE = "openlabel.streams.cam_01.stream_properties.usdscene.sensor"


def rng(camera="cam", frame=0, seed=7):
    return np.random.default_rng(image_seed(seed, camera, frame))


def room(height=120, width=160, light=1.0) -> np.ndarray:
    """(H, W, 3) float32 linear: a textured room (albedos 0.05-0.8) under ``light``, with a lamp
    spot 20 times brighter."""
    gen = np.random.default_rng(5)
    albedo = np.clip(gen.normal(0.3, 0.12, (height // 8, width // 8, 3)), 0.05, 0.8)
    image = np.kron(albedo, np.ones((8, 8, 1)))
    image[10:20, 20:30] *= 20.0
    return (image * light).astype(np.float32)


def srgb_to_linear(image: np.ndarray) -> np.ndarray:
    x = image.astype(np.float64) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


@pytest.mark.parametrize("profile", sorted(PROFILES))
def test_auto_exposure_brings_8x_brighter_and_darker_light_to_the_same_mean(profile):
    sensor = profile_sensor(profile)
    means = {}
    for light in (1 / 8, 1.0, 8.0):
        image, record = process_image(room(light=light), sensor, rng())
        means[light] = srgb_to_linear(image).mean()
        assert record["exposure_ev"] == pytest.approx(-np.log2(light) + process_image(room(), sensor, rng())[1]
                                                      ["exposure_ev"], abs=0.02)
    for light in (1 / 8, 8.0):
        assert abs(np.log2(means[light] / means[1.0])) < 0.3, (light, means)
    # without auto exposure the same light changes the picture by stops
    fixed = Sensor(iso=400, wdr_stops=sensor.wdr_stops, chroma_420=True)
    bright = srgb_to_linear(process_image(room(light=1 / 8), fixed, rng())[0]).mean()
    assert abs(np.log2(bright / srgb_to_linear(process_image(room(), fixed, rng())[0]).mean())) > 1.5


def test_exposure_limits_and_metering_modes():
    dark = room(light=1e-4)
    sensor = Sensor(auto_exposure=True, exposure_max_ev=3.0)
    assert process_image(dark, sensor, rng())[1]["exposure_ev"] == 3.0
    image = room()
    image[:, 80:] *= 16.0  # the right half 4 stops brighter
    left = Sensor(auto_exposure=True, metering="region", metering_region=(0.0, 0.0, 0.5, 1.0))
    right = Sensor(auto_exposure=True, metering="region", metering_region=(0.5, 0.0, 1.0, 1.0))
    ev_left = process_image(image, left, rng())[1]["exposure_ev"]
    ev_right = process_image(image, right, rng())[1]["exposure_ev"]
    lum = exposure.luminance(image).astype(np.float64)
    assert ev_left - ev_right == pytest.approx(np.log2(lum[:, 80:].mean() / lum[:, :80].mean()), abs=0.01)
    assert ev_left - ev_right > 3.5
    centre = exposure.metering_weights(48, 64, "centre_weighted")
    assert centre[24, 32] > 5 * centre[0, 0] and centre.sum() == pytest.approx(1.0, abs=1e-5)
    assert exposure.adapted_evs([0.0, 2.0, 2.0, 2.0], 0.5) == [0.0, 1.0, 1.5, 1.75]
    assert exposure.adapted_evs([0.0, 2.0], 1.0) == [0.0, 2.0]


@pytest.mark.parametrize("channels", [1, 3])
def test_the_compiled_pass_is_the_tone_curve_and_the_noise_table(channels):
    """kernels.encode_with_noise (one pass) gives the levels of tone.encode, then the noise
    table at the same draws, up to a level on a few float32 rounding boundaries."""
    from usdscene.sensor import kernels
    from usdscene.sensor.pipeline import _add_noise, _noise_table, vignetting_map

    gen = np.random.default_rng(2)
    shape = (48, 64) if channels == 1 else (48, 64, 3)
    x = (gen.random(shape, dtype=np.float32) ** 3 * 6.0).astype(np.float32)
    x[0, :3] = [np.nan, -1.0, np.inf] if channels == 1 else [[np.nan] * 3, [-1.0] * 3, [np.inf] * 3]
    falloff = vignetting_map(48, 64, 0.4, 1.0)
    shade = falloff if channels == 1 else np.dstack([falloff] * 3)
    table = _noise_table(800.0, 8000.0, 3.0, 2.0)
    for stops in (0.0, 2.0):
        plain = tone.encode(np.nan_to_num(x, posinf=1e9), stops, 1.5, shade)
        fused = kernels.encode_with_noise(x, stops, 1.5, falloff, None, None)
        assert fused.shape == x.shape and np.mean(fused != plain) < 2e-3
        assert np.abs(fused.astype(int) - plain).max() <= 1
        noisy = kernels.encode_with_noise(x, stops, 1.5, falloff, table, rng())
        assert np.array_equal(noisy, _add_noise(fused, table, rng()))


def test_adapting_exposure_follows_a_step_of_light_within_its_speed_and_window():
    """A light that steps up 8 times at frame 10: the exposure falls by 3 stops, moving a share
    ``speed`` of the error per frame, and each frame's value depends only on the readings of its
    window (so any worker that renders the window's pre-passes computes it)."""
    speed = 0.5
    warmup = exposure.warmup_frames(speed)
    assert warmup == 7 and (1 - speed) ** warmup <= 0.01 < (1 - speed) ** (warmup - 1)
    assert exposure.warmup_frames(1.0) == 0 and exposure.warmup_frames(0.1) == 44
    assert exposure.warmup_frames(0.001) == exposure.MAX_WARMUP_FRAMES
    assert list(exposure.meter_window(3, 7, 0)) == [0, 1, 2, 3]
    assert list(exposure.meter_window(20, 7, 0)) == list(range(13, 21))
    readings = [0.05] * 10 + [0.4] * 20  # linear luminance: 8 times brighter from frame 10
    evs, targets = [], []
    for frame in range(len(readings)):
        window = exposure.meter_window(frame, warmup, 0)
        ev, target = exposure.sequence_ev([readings[g] for g in window], 0.2, -10.0, 10.0, speed)
        evs.append(ev)
        targets.append(target)
    assert evs[:10] == [2.0] * 10 and targets[10:] == [-1.0] * 20
    for frame in range(10, 30):  # the remaining error shrinks by (1 - speed) per frame
        assert evs[frame] - targets[frame] == pytest.approx(3.0 * (1 - speed) ** (frame - 9), abs=2e-4 + 0.031)
    assert evs[10] == pytest.approx(0.5) and evs[12] == pytest.approx(-0.625)
    assert abs(evs[10 + warmup] - (-1.0)) <= 0.03 and evs[-1] == -1.0
    # the window reaches back warmup frames: a frame after the window's end ignores the old light
    assert exposure.sequence_ev([0.4] * (warmup + 1), 0.2, -10.0, 10.0, speed)[0] == -1.0
    # applied in place of the image's own meter: the image is exposed by what the sequence chose
    sensor = Sensor(auto_exposure=True, exposure_speed=speed, exposure_bias_ev=0.25)
    image, record = process_image(room(), sensor, rng(), adapted=(0.5, -1.0, 0.4))
    assert record == {"exposure_ev": 0.75, "target_ev": -1.0, "metered_luminance": 0.4}
    instant, instant_record = process_image(room(), sensor, rng())
    assert set(instant_record) == {"exposure_ev", "metered_luminance"}
    assert srgb_to_linear(image).mean() != pytest.approx(srgb_to_linear(instant).mean(), rel=0.05)


def doorway() -> np.ndarray:
    """A dark interior (left two thirds, light 0.05) and a sunlit doorway (right third, light
    5: 100 times brighter), both with the same texture of albedos 0.2-0.6."""
    gen = np.random.default_rng(9)
    albedo = np.kron(gen.uniform(0.2, 0.6, (12, 16, 1)), np.ones((10, 10, 3)))
    light = np.full((120, 160, 1), 0.05)
    light[:, 107:] = 5.0
    return (albedo * light).astype(np.float32)


def detail(image: np.ndarray, part: slice) -> tuple[float, float, float]:
    """(clipped %, crushed %, luma std) of the columns ``part``."""
    region = image[:, part].astype(np.float64)
    luma = region @ np.array([0.299, 0.587, 0.114])
    return 100 * (region >= 250).any(axis=2).mean(), 100 * (luma <= 5).mean(), luma.std()


def test_wdr_keeps_detail_on_both_sides_of_a_backlit_doorway():
    inside, outside = slice(0, 100), slice(112, 160)
    wdr = process_image(doorway(), Sensor(auto_exposure=True, wdr_stops=3.0), rng())[0]
    for part in (inside, outside):
        clipped, crushed, spread = detail(wdr, part)
        assert clipped < 2 and crushed < 2 and spread > 6, (part, clipped, crushed, spread)
    # with the plain sRGB curve the meter exposes for the doorway and the room's texture keeps
    # less than half the contrast
    plain = process_image(doorway(), Sensor(auto_exposure=True), rng())[0]
    assert detail(plain, inside)[2] < 0.5 * detail(wdr, inside)[2]


def test_wdr_raises_shadow_noise_by_the_curve_slope():
    plain = noise_sigma_levels(400, 8000, 2.5, 0.0)
    wdr = noise_sigma_levels(400, 8000, 2.5, 3.0)
    linear_plain, _ = tone.level_linear_and_slope(0.0)
    linear_wdr, _ = tone.level_linear_and_slope(3.0)
    # at the same linear light in the shadows the WDR picture is noisier by about its lift
    x = 0.002
    ratio = np.interp(x, linear_wdr, wdr) / np.interp(x, linear_plain, plain)
    assert ratio == pytest.approx(tone.shadow_gain(3.0), rel=0.1)
    assert tone.shadow_gain(3.0) > tone.shadow_gain(1.0) > 1.0


@pytest.mark.parametrize("stops", [0.0, 1.5, 3.0])
def test_the_tone_table_is_the_curve_within_half_a_level(stops):
    x = np.concatenate([np.geomspace(1e-6, 2 ** stops, 20000),
                        np.random.default_rng(0).uniform(0, 2 ** stops, 20000)]).astype(np.float32)
    exact = tone.levels(x.astype(np.float64), stops)
    assert np.abs(tone.encode(x, stops).astype(np.float64) - exact).max() <= 0.51
    assert tone.wdr_curve(np.array([0.18]), stops)[0] == pytest.approx(0.18, abs=1e-6)
    assert tone.wdr_curve(np.array([2 ** stops]), stops)[0] == pytest.approx(1.0)


def test_lens_blur_has_the_stated_mtf50():
    f50 = 0.2  # cycles per pixel
    xs = np.arange(400, dtype=np.float64)
    wave = (0.5 + 0.25 * np.cos(2 * np.pi * f50 * xs)).astype(np.float32)
    plane = np.tile(wave, (40, 1))
    blurred = optics.lens_blur(plane, optics.psf_sigma_from_mtf50(f50))
    centre = blurred[20, 100:300].astype(np.float64)
    # amplitude of the cosine (its projection; peaks of a 5-pixel period are not sampled)
    modulation = 2.0 * np.mean((centre - centre.mean()) * np.cos(2 * np.pi * f50 * xs[100:300])) / 0.25
    assert modulation == pytest.approx(0.5, abs=0.03)


def test_unsharp_mask_leaves_halos_and_chroma_420_keeps_luma():
    step = np.zeros((20, 40, 3), np.uint8)
    step[:, :20] = 60
    step[:, 20:] = 180
    sharp = optics.unsharp(step, 1.0, 1.0)
    assert sharp[10, 18, 0] < 60 and sharp[10, 21, 0] > 180  # dark and bright halos
    assert sharp[10, 2, 0] == 60 and sharp[10, 38, 0] == 180
    colour = np.zeros((16, 16, 3), np.uint8)
    colour[:, ::2] = (200, 40, 40)
    colour[:, 1::2] = (40, 40, 200)
    import cv2

    out = optics.chroma_420(colour)
    luma = cv2.cvtColor(colour, cv2.COLOR_RGB2YCrCb)[..., 0].astype(int)
    luma_out = cv2.cvtColor(out, cv2.COLOR_RGB2YCrCb)[..., 0].astype(int)
    assert np.abs(luma - luma_out).max() <= 2  # luma kept (rounding through RGB)
    assert np.abs(out[:, ::2, 0].astype(int) - 200).min() > 30  # the colour stripes are averaged


@pytest.mark.parametrize("profile", sorted(PROFILES))
def test_same_seed_same_bytes_other_seed_other_noise(profile):
    sensor = profile_sensor(profile)
    a, ra = process_image(room(), sensor, rng())
    b, rb = process_image(room(), sensor, rng())
    assert np.array_equal(a, b) and ra == rb
    assert not np.array_equal(a, process_image(room(), sensor, rng(frame=1))[0])
    linear = room()
    before = linear.copy()
    process_image(linear, sensor, rng())
    assert np.array_equal(linear, before)  # the render is not modified


def test_sensors_without_the_new_keys_keep_the_8_bit_chain():
    assert not uses_linear(Sensor(iso=800, vignetting=0.3, compression="jpeg"))
    assert uses_linear(Sensor(sharpen=0.5)) and uses_linear(profile_sensor("indoor_dome"))
    img = np.full((8, 8, 3), 100, np.uint8)
    assert np.array_equal(apply_sensor(img, Sensor(vignetting=0.3), rng()),
                          apply_sensor(img, Sensor(vignetting=0.3), rng()))


def test_a_profile_is_written_as_its_name_and_overrides_win():
    dome = profile_sensor("indoor_dome")
    assert spec_to_json(dome) == {"profile": "indoor_dome"}
    assert spec_from_json(Sensor, {"profile": "indoor_dome"}) == dome
    louder = spec_from_json(Sensor, {"profile": "indoor_dome", "iso": 1600, "vignetting": 0.0})
    assert louder.iso == 1600 and louder.vignetting == 0.0 and louder.wdr_stops == dome.wdr_stops
    assert spec_to_json(louder) == {"profile": "indoor_dome", "iso": 1600, "vignetting": 0.0}


def minimal(sensor) -> dict:
    doc = json.loads(MINIMAL.read_text())
    doc["openlabel"]["streams"]["cam_01"]["stream_properties"]["usdscene"]["sensor"] = sensor
    return doc


def problems_of(sensor) -> list[str]:
    from usdscene.converters.openlabel import read_openlabel

    with pytest.raises(DocumentError) as info:
        read_openlabel(minimal(sensor))
    return [str(p) for p in info.value.problems]


@pytest.mark.parametrize("sensor, field, text", [
    ({"profile": "dome"}, "profile", "unknown profile 'dome'"),
    ({"metering": "spot"}, "metering", "unknown metering 'spot'"),
    ({"target_grey": 0}, "target_grey", "target_grey 0 is out of range"),
    ({"target_grey": 1.5}, "target_grey", "target_grey 1.5 is out of range"),
    ({"exposure_speed": 0}, "exposure_speed", "exposure_speed 0 is out of range"),
    ({"exposure_speed": 2}, "exposure_speed", "exposure_speed 2 is out of range"),
    ({"mtf50_cy_px": 0}, "mtf50_cy_px", "mtf50_cy_px 0 is out of range"),
    ({"mtf50_cy_px": -0.2}, "mtf50_cy_px", "mtf50_cy_px -0.2 is out of range"),
    ({"psf_sigma_px": -1}, "psf_sigma_px", "psf_sigma_px -1 is out of range"),
    ({"metering": "region"}, "metering", "needs 'metering_region'"),
    ({"metering": "region", "metering_region": [0.5, 0, 0.2, 1]}, "metering_region", "x0 < x1"),
    ({"mtf50_cy_px": 0.3, "psf_sigma_px": 1.0}, "psf_sigma_px", "not both"),
    ({"exposure_min_ev": 2, "exposure_max_ev": 1}, "exposure_min_ev", "above exposure_max_ev 1"),
])
def test_bad_camera_keys_are_refused_naming_field_and_value(sensor, field, text):
    found = problems_of(sensor)
    assert len(found) == 1 and f"{WHERE}.{field}" in found[0] and text in found[0], found


def test_the_cli_refuses_an_unknown_profile_with_one_line_and_exit_1(tmp_path, monkeypatch, capsys):
    from usdscene.cli import main

    monkeypatch.chdir(tmp_path)
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(minimal({"profile": "ptz", "auto_exposure": True})))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{WHERE}.profile: unknown profile 'ptz'" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
