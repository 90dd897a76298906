"""Typed worker jobs (``usdscene.render.job``): built from a real stage plan, through JSON and
back unchanged, and a job file of another version refused with one message naming the field,
also by the worker process itself."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
from usdscene.errors import RenderError
from usdscene.render.job import (
    BakeWorldJob,
    BlendJob,
    BlendToUsdJob,
    InspectBlendJob,
    JobObject,
    RenderJob,
    from_json,
    to_json,
)

pytestmark = pytest.mark.usd

FISHEYE = Intrinsics(LensModel.FISHEYE_EQUIDISTANT, 64, 48, 20.0, 20.0, 31.5, 23.5, fov_deg=180.0)


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    r = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    intr = Intrinsics(LensModel.OPENCV_PINHOLE, 64, 48, 50.0, 50.0, 31.5, 23.5, distortion=(-0.2, 0.05, 0.0, 0.0))
    cams = (Camera("still", intr, Pose.from_rotation_translation(r, [-4.0, 0.0, 1.0])),
            Camera("moving", FISHEYE, Pose.from_rotation_translation(r, [-4.0, 0.5, 1.0]),
                   frame_poses=tuple((f, Pose.from_rotation_translation(r, [-4.0, 0.5 - 0.1 * f, 1.0]))
                                     for f in range(4))))
    spheres = (SphereSpec("a", (0.0, 0.0, 1.0), 0.5, (0.9, 0.2, 0.1), 1),
               SphereSpec("b", (0.0, 1.0, 1.0), 0.3, (0.1, 0.8, 0.2), 2, frames=(2, 3)))
    stage = write_synthetic_stage(SyntheticScene(cameras=cams, spheres=spheres, frame_start=0, frame_end=3),
                                  tmp_path_factory.mktemp("job") / "stage")
    return read_stage_plan(stage)


def render_job(plan, pairs) -> RenderJob:
    from usdscene.render.driver import camera_jobs, resolve_settings
    from usdscene.render.shards import shard_job

    settings = resolve_settings(plan.settings, {"samples": 1})
    cameras = camera_jobs(plan, [c.name for c in plan.cameras], list(plan.frames))
    return shard_job(plan, settings, cameras, 2, False, pairs)


def test_a_shard_holds_the_objects_and_cameras_of_its_pairs(plan):
    job = render_job(plan, [(0, "still"), (1, "still")])
    assert [o.uid for o in job.objects] == ["a"]  # b is absent on frames 0 and 1
    assert job.objects[0].visible_frames == (0, 1) and job.objects[0].visible == {0, 1}
    assert list(job.cameras) == ["still"] and job.cameras["still"].remapped  # OpenCV: rendered undistorted
    assert job.pairs == ((0, "still"), (1, "still")) and job.threads == 2
    assert job.out_dir is None and job.scratch_dir is None  # the executor sets them
    moving = render_job(plan, [(2, "moving"), (3, "moving")])
    assert [o.uid for o in moving.objects] == ["a", "b"]
    camera = moving.cameras["moving"]
    assert not camera.remapped and camera.pose_at(3) != camera.pose_at(2)
    assert camera.pose_at(2) == camera.poses[2]


def test_every_kind_of_job_goes_through_json_unchanged(plan):
    job = dataclasses.replace(render_job(plan, [(2, "moving"), (3, "still")]), out_dir="/out", scratch_dir="/s",
                              parent_pid=7, keep_clean=True, world={"world": {"color_rgb": [0.1, 0.2, 0.3]}})
    posed = JobObject("p", 3, "/World/Objects/p", (0, 1, 2), {"sit": frozenset({0, 2}), "stand": frozenset({1})})
    jobs = [job, dataclasses.replace(job, objects=(posed,), keep_clean=False, world=None),
            BlendJob(stage="/s.usda", prim_path_mask="/World", settings={"samples": 2}, objects=(posed,),
                     cameras=dict(job.cameras), blend="/x.blend", frame_start=0, frame_end=3, document='{"a":1}'),
            BlendToUsdJob(blend="/x.blend", usd="/x.usda"),
            InspectBlendJob(blend="/x.blend", usd="/x.usda", json="/x.json"),
            BakeWorldJob(world={"world": {}, "sun": None}, frame=4, size_px=(64, 32), samples=4, out="/w.hdr")]
    for original in jobs:
        text = to_json(original)
        back = from_json(text)
        assert type(back) is type(original) and back == original, type(original).__name__
        assert to_json(back) == text
    data = json.loads(to_json(jobs[1]))
    # left out when unset, as the job dicts before them did
    assert data["mode"] == "render" and "world" not in data and "keep_clean" not in data
    assert "pose_frames" in data["objects"][0] and data["objects"][0]["pose_frames"]["sit"] == [0, 2]


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(samples_per_pixel=4), "unknown field 'samples_per_pixel' in a RenderJob"),
    (lambda d: d.pop("pairs"), "a RenderJob needs the field 'pairs'"),
    (lambda d: d["objects"][0].update(velocity=[1, 0]), "objects[0]: unknown field 'velocity' in a JobObject"),
    (lambda d: d["cameras"]["still"].pop("clip_m"), "cameras.still: a JobCamera needs the field 'clip_m'"),
    (lambda d: d.update(mode="render_video"), "unknown job mode 'render_video'"),
])
def test_a_job_file_of_another_version_is_refused_naming_the_field(plan, edit, message):
    data = json.loads(to_json(render_job(plan, [(0, "still")])))
    edit(data)
    with pytest.raises(RenderError) as caught:
        from_json(json.dumps(data), where="job-1.json")
    text = str(caught.value)
    assert text.startswith("job-1.json") and message in text, text
    if "mode" not in message:
        assert "another usdscene version" in text


def test_the_worker_reports_a_job_file_of_another_version_in_one_line(plan, tmp_path):
    from usdscene.render.worker_process import describe_exit, iter_worker_events

    data = json.loads(to_json(render_job(plan, [(0, "still")])))
    data["denoise_twice"] = True
    job_path = tmp_path / "job.json"
    job_path.write_text(json.dumps(data))
    events = list(iter_worker_events(job_path, tmp_path / "job.log"))
    exit_event = events[-1]
    outcome = describe_exit(exit_event["code"], exit_event["error"], exit_event["log_tail"])
    assert not outcome.ok and not outcome.retryable
    assert outcome.message == (f"render worker failed: {job_path}: unknown field 'denoise_twice' in a RenderJob; "
                               "the job was written by another usdscene version than the worker's?")
    assert [e["event"] for e in events] == ["error", "exit"]  # nothing rendered, nothing written


def test_render_takes_an_options_object_and_the_older_keywords_alike(plan, tmp_path):
    # Checked before anything renders or is written: the same messages in both call forms.
    from usdscene.render.driver import RenderOptions, render

    messages = []
    for options, keywords in ((RenderOptions(workers=0, frames=[9]), {}), (None, {"workers": 0, "frames": [9]}),
                              (RenderOptions(workers=0, frames=[1]), {"frames": [9]})):
        with pytest.raises(RenderError) as caught:
            render(plan.stage_path, tmp_path / "out", options, **keywords)
        messages.append(str(caught.value))
    assert messages[0] == messages[1] == messages[2]
    assert "workers 0 must be at least 1" in messages[0] and "frame 9 is outside the stage's range 0..3" in messages[0]
    assert not (tmp_path / "out").exists()
