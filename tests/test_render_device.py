"""Quality-per-second knobs reach Cycles without touching the labels; ``render.device: gpu``
either renders on a GPU or fails with one message naming what is missing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.errors import RenderError
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

BASE = {"samples": 2, "denoise": True}


def _scene(render=None):
    from usdscene.render.synthetic import BoxSpec, PointLightSpec, SphereSpec, SyntheticScene

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x
    intr = Intrinsics(LensModel.PERSPECTIVE, 64, 48, 45.0, 45.0, 31.5, 23.5)
    scene = SyntheticScene(
        cameras=(Camera("front", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),),
        spheres=(SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1),
                 SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2)),
        boxes=(BoxSpec("room", (0.0, 0.0, 1.5), (12.0, 8.0, 3.0), (0.6, 0.6, 0.6), inward=True),),
        lights=(PointLightSpec("lamp", (-2.0, 0.0, 2.5), 200.0), PointLightSpec("lamp2", (1.0, -2.0, 2.5), 50.0)),
        render=render)
    return scene


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from usdscene.render.synthetic import write_synthetic_stage

    return write_synthetic_stage(_scene(), tmp_path_factory.mktemp("device") / "stage")


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


def test_fast_gi_and_scrambling_reach_the_blender_scene(tmp_path):
    """Stage attributes → the worker's Blender scene, read back from the .blend it saves."""
    import bpy

    from usdscene.document.model import RenderSettings
    from usdscene.render.blend_io import write_blend
    from usdscene.render.synthetic import write_synthetic_stage

    settings = RenderSettings(samples=2, fast_gi=True, fast_gi_method="add", fast_gi_ao_bounces=3,
                              fast_gi_distance_m=2.5, scrambling_distance=0.25, auto_scrambling_distance=True)
    stage = write_synthetic_stage(_scene(settings), tmp_path / "stage")
    blend = write_blend(stage, tmp_path / "scene.blend")
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    cycles = bpy.context.scene.cycles
    assert (cycles.use_fast_gi, cycles.fast_gi_method) == (True, "ADD")
    assert (cycles.ao_bounces_render, cycles.ao_bounces) == (3, 3)
    assert bpy.context.scene.world.light_settings.distance == pytest.approx(2.5)
    assert cycles.scrambling_distance == pytest.approx(0.25)
    assert cycles.auto_scrambling_distance is True


def test_fast_gi_and_scrambling_change_the_image_and_never_the_mask(stage, tmp_path):
    image, mask = _render(stage, tmp_path / "default", {})
    # Cycles' own semantics: 0 AO bounces turns fast GI off, and automatic scrambling
    # multiplies the distance by 4 / sqrt(2 spp) > 1, which is full scrambling.
    same, same_mask = _render(stage, tmp_path / "same", {"fast_gi": True, "fast_gi_ao_bounces": 0,
                                                          "auto_scrambling_distance": True})
    np.testing.assert_array_equal(same, image)
    # Replace the one indirect bounce by ambient occlusion of the black world: a darker room.
    fast, fast_mask = _render(stage, tmp_path / "fast_gi", {"fast_gi": True})
    assert fast.mean() < image.mean() - 1.0
    # Neighbouring pixels share correlated sample sequences: another image (at 2 spp the
    # correlated error does not average out over the image, so even its mean moves).
    scrambled, scrambled_mask = _render(stage, tmp_path / "scrambled", {"scrambling_distance": 0.1})
    assert np.abs(scrambled.astype(int) - image).max() > 10
    for other in (same_mask, fast_mask, scrambled_mask):
        np.testing.assert_array_equal(other, mask)


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
