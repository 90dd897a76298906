"""Parent-side pieces of rendering without Blender: settings, shards, manifest, stage reading."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.errors import RenderError
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose, RenderSettings
from usdscene.labels.projection import project_camera_points
from usdscene.render.driver import resolve_settings, scale_intrinsics
from usdscene.render.shards import chunks, shard_size
from usdscene.render.manifest import Manifest, fingerprint


def test_settings_override_and_every_problem_reported():
    s = resolve_settings(RenderSettings(samples=8), {"samples": 2, "denoising_quality": "HIGH"})
    assert s["samples"] == 2 and s["denoising_quality"] == "high" and s["engine"] == "cycles"
    with pytest.raises(RenderError) as err:
        resolve_settings(RenderSettings(), {"engine": "eevee", "samples": 0, "bogus": 1, "device": "tpu"})
    text = str(err.value)
    assert "object-index pass" in text and "'bogus'" in text and "samples 0" in text and "'tpu'" in text
    assert len(err.value.problems) == 4


def test_fast_gi_and_scrambling_overrides_are_checked():
    s = resolve_settings(RenderSettings(), {"fast_gi": True, "fast_gi_method": "add", "fast_gi_ao_bounces": 2,
                                            "fast_gi_distance_m": 0.5, "scrambling_distance": 0.25,
                                            "auto_scrambling_distance": True})
    assert (s["fast_gi"], s["fast_gi_method"], s["fast_gi_ao_bounces"]) == (True, "add", 2)
    assert (s["fast_gi_distance_m"], s["scrambling_distance"], s["auto_scrambling_distance"]) == (0.5, 0.25, True)
    with pytest.raises(RenderError) as err:
        resolve_settings(RenderSettings(), {"fast_gi": "on", "fast_gi_method": "multiply", "fast_gi_ao_bounces": -1,
                                            "fast_gi_distance_m": -3.0, "scrambling_distance": 1.5,
                                            "auto_scrambling_distance": 1})
    wheres = [p.where for p in err.value.problems]
    assert wheres == ["render.fast_gi_method", "render.fast_gi_distance_m", "render.scrambling_distance",
                      "render.fast_gi_ao_bounces", "render.fast_gi", "render.auto_scrambling_distance"]
    text = str(err.value)
    assert "'multiply'" in text and "-3.0" in text and "1.5 must be in [0, 1]" in text and "-1 must be an integer" in text


def test_scale_intrinsics_keeps_the_pixel_convention():
    intr = Intrinsics(LensModel.OPENCV_PINHOLE, 640, 480, 500.0, 500.0, 321.7, 238.2, (-0.1, 0.01, 0.0, 0.0))
    half = scale_intrinsics(intr, 0.5)
    assert (half.width_px, half.height_px) == (320, 240)
    pts = np.array([[0.3, -0.2, 2.0], [-0.5, 0.4, 3.0]])
    full_uv, _ = project_camera_points(intr, pts)
    half_uv, _ = project_camera_points(half, pts)
    # A pixel edge at 0 stays at 0: (p + 0.5) / 2 - 0.5.
    np.testing.assert_allclose(half_uv, (full_uv + 0.5) * 0.5 - 0.5, atol=1e-9)
    assert scale_intrinsics(intr, 1.0) is intr


def test_shards_are_blocks_of_consecutive_frames():
    pairs = [(f, c) for f in range(7) for c in ("a", "b")]
    shards = chunks(pairs, shard_size(len(pairs), 3))
    assert [sorted({f for f, _ in s}) for s in shards] == [[0, 1], [2, 3], [4, 5], [6]]
    assert [p for s in shards for p in s] == pairs
    assert len(chunks(pairs[:2], shard_size(2, 4))) == 2  # one camera of one frame per slot


def test_shard_size_follows_slots_budget_and_measured_time():
    # An equal share per slot, never more than the per-process budget.
    assert shard_size(1000, 4) == 250
    assert shard_size(1000, 8) == 125
    assert shard_size(3, 8) == 1
    assert shard_size(1000, 2, max_pairs=40) == 40
    # With a time target: about target / seconds-per-image images, the assumed figure first.
    assert shard_size(1000, 1, target_shard_s=180.0) == 12
    assert shard_size(1000, 1, target_shard_s=180.0, seconds_per_image=0.5) == 250
    assert shard_size(1000, 1, target_shard_s=180.0, seconds_per_image=3.0) == 60
    assert shard_size(1000, 1, target_shard_s=1.0, seconds_per_image=30.0) == 1


def test_manifest_needs_entry_files_and_same_fingerprint(tmp_path):
    key = fingerprint({"settings": 1})
    m = Manifest.load(tmp_path, key)
    m.mark_done(3, "cam", {"render_s": 1.0, "post_s": 0.1})
    m.save()
    assert not Manifest.load(tmp_path, key).is_done(3, "cam")  # files missing
    for path in (layout.image_path(tmp_path, "cam", 3), layout.mask_path(tmp_path, "cam", 3)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"png")
    assert Manifest.load(tmp_path, key).is_done(3, "cam")
    assert not Manifest.load(tmp_path, fingerprint({"settings": 2})).is_done(3, "cam")
    (tmp_path / layout.MANIFEST_FILE).write_text("{not json")
    assert Manifest.load(tmp_path, key).done == {}
    assert fingerprint({"a": 1, "b": 2}) == fingerprint({"b": 2, "a": 1})


@pytest.mark.usd
def test_stage_reader_reports_every_bad_object(tmp_path):
    from pxr import Sdf, Usd

    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    cam = Camera("c", Intrinsics(LensModel.PERSPECTIVE, 64, 48, 50.0, 50.0, 31.5, 23.5))
    spheres = (SphereSpec("a", (0, 0, 0), 0.1, (1, 0, 0), 1), SphereSpec("b", (0, 0, 1), 0.1, (1, 0, 0), 1),
               SphereSpec("c", (0, 1, 0), 0.1, (1, 0, 0), 2, frames=(1,)))
    path = write_synthetic_stage(SyntheticScene(cameras=(cam,), spheres=spheres, frame_end=2), tmp_path)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/World/Cameras/c").GetAttribute("usdscene:lens:model").Set("pinhole")
    stage.GetPrimAtPath("/World/Objects/sphere_c").CreateAttribute("usdscene:maskId", Sdf.ValueTypeNames.Int).Set(70000)
    stage.Save()
    with pytest.raises(RenderError) as err:
        read_stage_plan(path)
    where = {p.where for p in err.value.problems}
    assert where == {"/World/Cameras/c", "/World/Objects/sphere_b", "/World/Objects/sphere_c"}
    assert "'pinhole'" in str(err.value) and "70000" in str(err.value) and "also used by" in str(err.value)


@pytest.mark.usd
def test_stage_reader_reads_presence_poses_and_settings(tmp_path):
    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    moving = tuple((f, Pose.from_rotation_translation(r, [f * 0.5, 0.0, 1.0])) for f in range(3))
    intr = Intrinsics(LensModel.FISHEYE_EQUISOLID, 64, 48, 20.0, 20.0, 31.5, 23.5, fov_deg=150.0)
    cam = Camera("fish", intr, moving[0][1], frame_poses=moving, clip_near_m=0.2, clip_far_m=40.0)
    spheres = (SphereSpec("a", (0, 0, 0), 0.1, (1, 0, 0), 5, frames=(0, 2)),)
    settings = RenderSettings(samples=3, max_bounces=2, caustics=True, seed=7)
    path = write_synthetic_stage(SyntheticScene(cameras=(cam,), spheres=spheres, frame_end=2, render=settings),
                                 tmp_path)
    plan = read_stage_plan(path)
    assert plan.settings == settings
    got = plan.cameras[0]
    assert got.intrinsics == intr
    assert [f for f, _ in got.frame_poses] == [0, 1, 2]
    np.testing.assert_allclose(got.pose_at(2).as_array(), moving[2][1].as_array(), atol=1e-9)
    assert (got.clip_near_m, got.clip_far_m) == pytest.approx((0.2, 40.0))
    assert plan.objects[0].visible_frames == (0, 2) and plan.objects[0].mask_id == 5
    assert json.loads(json.dumps(plan.shared_prims)) == ["/World/Environment"]
