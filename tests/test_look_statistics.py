"""benchmarks/look_statistics.py: each statistic reads what it was defined to read on images
whose answer is known."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.unit

_SPEC = importlib.util.spec_from_file_location(
    "look_statistics", Path(__file__).resolve().parents[1] / "benchmarks" / "look_statistics.py")
look = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(look)


def _ramp(height=480, width=640):
    ys, xs = np.mgrid[0:height, 0:width]
    return 60.0 + 100.0 * xs / width + 20.0 * np.sin(ys / 30.0)


@pytest.mark.parametrize("sigma", [1.0, 1.6, 2.0, 3.0])
def test_noise_sigma_reads_the_gaussian_noise_added_to_a_smooth_image(sigma):
    noisy = _ramp() + np.random.default_rng(3).normal(0.0, sigma, (480, 640))
    grey = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    stats = look.look_statistics(np.dstack([grey] * 3))
    # 8-bit rounding adds 1/12 of a level² of its own
    assert stats["noise_sigma"] == pytest.approx(np.hypot(sigma, np.sqrt(1 / 12)), rel=0.04)


def test_a_clean_smooth_image_has_no_noise_and_edges_do_not_count():
    image = np.clip(np.rint(_ramp()), 0, 255).astype(np.uint8)
    image[:, 300:] = np.clip(image[:, 300:].astype(int) + 60, 0, 255)  # a hard edge
    stats = look.look_statistics(np.dstack([image] * 3))
    assert stats["noise_sigma"] < 0.4


def test_brightness_clipped_crushed_and_colourfulness():
    image = np.full((100, 100, 3), 128, dtype=np.uint8)
    image[:10] = 255            # 10 % clipped
    image[10:15, :, 0] = 252    # red channel alone clips: 5 % more
    image[90:] = 3              # 10 % crushed
    stats = look.look_statistics(image)
    assert stats["clipped_pct"] == pytest.approx(15.0)
    assert stats["crushed_pct"] == pytest.approx(10.0)
    luma = look.luma_of(image)
    assert stats["brightness"] == pytest.approx(float(luma.mean()), abs=1e-3)
    grey = look.look_statistics(np.full((50, 50, 3), 90, dtype=np.uint8))
    assert grey["colourfulness"] == pytest.approx(0.0)
    red = np.zeros((50, 50, 3), dtype=np.uint8)
    red[..., 0] = 200
    # rg = 200, yb = 100 everywhere: 0.3 · sqrt(200² + 100²)
    assert look.look_statistics(red)["colourfulness"] == pytest.approx(0.3 * np.hypot(200, 100))


def test_sharpness_falls_with_blur():
    rng = np.random.default_rng(0)
    texture = np.clip(rng.normal(128, 30, (120, 160)), 0, 255).astype(np.uint8)
    sharp = look.look_statistics(np.dstack([texture] * 3))["sharpness"]
    blurred = cv2.GaussianBlur(texture, (0, 0), 1.5)
    soft = look.look_statistics(np.dstack([blurred] * 3))["sharpness"]
    assert soft < sharp / 10


def test_cli_prints_a_row_per_folder_and_refuses_a_missing_one(tmp_path, capsys):
    run = tmp_path / "run"
    (run / "images" / "cam").mkdir(parents=True)
    (run / "masks" / "cam").mkdir(parents=True)
    cv2.imwrite(str(run / "images" / "cam" / "000000.png"), np.full((20, 30, 3), 100, dtype=np.uint8))
    cv2.imwrite(str(run / "masks" / "cam" / "000000.png"), np.zeros((20, 30), dtype=np.uint16))
    assert look.main([f"mine={run}", "--markdown"]) == 0
    out = capsys.readouterr().out
    assert "| mine | 1 | 100.00 |" in out
    assert look.main([str(tmp_path / "absent")]) == 1
    assert "absent: not a folder" in capsys.readouterr().err


def test_a_fisheye_counts_only_its_image_circle():
    """The black outside a fisheye's image circle is not crushed: the lens's valid pixels."""
    from usdscene.document.model import Intrinsics, LensModel
    from usdscene.lens import valid_pixels

    fisheye = Intrinsics(LensModel.FISHEYE_EQUIDISTANT, 160, 120, 40.0, 40.0, 79.5, 59.5, fov_deg=180.0)
    inside = valid_pixels(fisheye)
    # the image circle: radius fx · π/2 ≈ 62.8 px, wider than the image's 60 px half height
    ys, xs = np.mgrid[0:120, 0:160]
    expected = np.hypot(xs - 79.5, ys - 59.5) <= 40.0 * np.pi / 2
    assert np.mean(inside != expected) < 0.005 and 0.5 < inside.mean() < 0.95
    assert valid_pixels(Intrinsics(LensModel.PERSPECTIVE, 160, 120, 100.0, 100.0, 79.5, 59.5)).all()
    image = np.full((120, 160, 3), 120, dtype=np.uint8)
    image[~inside] = 0
    image[:10, 70:90] = 2  # a dark patch inside the circle: 200 pixels
    whole, circle = look.look_statistics(image), look.look_statistics(image, inside)
    assert whole["crushed_pct"] > 100.0 * (1.0 - inside.mean())
    assert circle["crushed_pct"] == pytest.approx(100.0 * 200 / inside.sum())
    assert circle["brightness"] > whole["brightness"]
