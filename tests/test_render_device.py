"""Quality-per-second knobs reach Cycles without touching the labels; ``render.device: gpu``
either renders on a GPU or fails with one message naming what is missing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usdscene import layout
from usdscene.errors import RenderError
from usdscene.model import Camera, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

BASE = {"samples": 2, "denoise": True}


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from usdscene.render.synthetic import BoxSpec, PointLightSpec, SphereSpec, SyntheticScene, write_synthetic_stage

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x
    intr = Intrinsics(LensModel.PERSPECTIVE, 64, 48, 45.0, 45.0, 31.5, 23.5)
    scene = SyntheticScene(
        cameras=(Camera("front", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),),
        spheres=(SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1),
                 SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2)),
        boxes=(BoxSpec("room", (0.0, 0.0, 1.5), (12.0, 8.0, 3.0), (0.6, 0.6, 0.6), inward=True),),
        lights=(PointLightSpec("lamp", (-2.0, 0.0, 2.5), 200.0), PointLightSpec("lamp2", (1.0, -2.0, 2.5), 50.0)))
    return write_synthetic_stage(scene, tmp_path_factory.mktemp("device") / "stage")


def _render(stage, out, override):
    from usdscene.render.driver import render

    render(stage, out, frames=[0], settings_override={**BASE, **override}, progress=False)
    return (cv2.imread(str(layout.image_path(out, "front", 0))),
            cv2.imread(str(layout.mask_path(out, "front", 0)), cv2.IMREAD_UNCHANGED))


def test_speed_knobs_change_the_image_and_never_the_mask(stage, tmp_path):
    image, mask = _render(stage, tmp_path / "default", {})
    knobs = {"light_tree": False, "clamp_indirect": 0.05, "denoising_input_passes": "rgb",
             "path_guiding": True, "adaptive_threshold": 0.1, "adaptive_min_samples": 1,
             "sampling_pattern": "blue_noise"}
    other_image, other_mask = _render(stage, tmp_path / "knobs", knobs)
    assert set(np.unique(mask)) == {0, 1, 2}
    np.testing.assert_array_equal(other_mask, mask)
    # Clamping indirect light at 0.05 darkens the room: the knobs reached Cycles.
    assert other_image.mean() < image.mean() - 1.0


def test_gpu_device_renders_or_names_what_is_missing(stage, tmp_path):
    try:
        image, mask = _render(stage, tmp_path / "gpu", {"device": "gpu"})
    except RenderError as err:
        text = str(err)
        assert "render.device 'gpu'" in text and "found no GPU" in text and "'cpu'" in text
        assert "CUDA" in text and "OPTIX" in text
        assert "Traceback" not in text
        assert not layout.image_path(tmp_path / "gpu", "front", 0).exists()
    else:  # a machine with a GPU: the same labels as on the CPU
        _, cpu_mask = _render(stage, tmp_path / "cpu", {})
        np.testing.assert_array_equal(mask, cpu_mask)
        assert image.mean() > 5


def test_optix_denoiser_needs_a_gpu_device(stage, tmp_path):
    with pytest.raises(RenderError, match="denoiser 'optix' runs on an NVIDIA GPU only"):
        _render(stage, tmp_path / "optix", {"denoiser": "optix"})
