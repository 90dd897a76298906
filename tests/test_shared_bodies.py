"""Shared bodies: people of the same body and pose share one Blender mesh in a render (linked
duplicates, blender/mesh_sharing.py), each keeping its own instance id and its own colour."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.document import model as m
from usdscene.document import stage_schema as ss

W, H = 96, 48
LOOK = "m_35_192_average_tone1"
RED, BLUE = (0.8, 0.05, 0.05), (0.05, 0.05, 0.8)


def _look_at(eye, target) -> m.Pose:
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return m.Pose.from_rotation_translation(np.stack([x, np.cross(z, x), z], axis=1), eye)


def _scene() -> m.SceneSpec:
    """Six people of one body in a row along +X, seen from -Y: four walk (walk_0 at frame 0,
    walk_4 at frame 1), two stand; two walkers are painted red and blue."""
    intr = m.Intrinsics(lens=m.LensModel.PERSPECTIVE, width_px=W, height_px=H, fx_px=40.0, fy_px=40.0,
                        cx_px=(W - 1) / 2, cy_px=(H - 1) / 2, sensor_width_mm=6.4)
    camera = m.Camera("front", intr, pose=_look_at((0.0, -6.0, 1.0), (0.0, 0.0, 0.9)))
    walk = m.canonical_json({"object_data": {"text": [{"name": ss.FRAME_POSE_DATA, "val": "walk_0"}]}})
    stride = m.canonical_json({"object_data": {"text": [{"name": ss.FRAME_POSE_DATA, "val": "walk_4"}]}})
    people = []
    for k in range(6):
        pose = m.Pose.from_rotation_translation(np.eye(3), [-3.75 + 1.5 * k, 0.0, 0.0])
        colour = RED if k == 1 else BLUE if k == 2 else None
        if k < 4:
            people.append(m.SceneObject(str(k + 1), f"walker_{k}", "person", pose=pose, pose_variant="walk_0",
                                        appearance=LOOK, color_rgb=colour, frame_extra=((0, walk), (1, stride))))
        else:
            people.append(m.SceneObject(str(k + 1), f"still_{k}", "person", pose=pose, pose_variant="standing",
                                        appearance=LOOK))
    sun = m.Light("10", "sun", m.LightKind("sun"), pose=_look_at((-2.0, -6.0, 5.0), (0.0, 0.0, 0.0)), power_w=4.0)
    return m.SceneSpec(name="shared", seed=3, frame_start=0, frame_end=1, cameras=(camera,),
                       objects=tuple(people), lights=(sun,), render=m.RenderSettings(samples=16, denoise=False))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from usdscene.render.driver import render
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage

    root = tmp_path_factory.mktemp("shared")
    stage = compose_stage(_scene(), load_catalog(), root / "stage")
    events = []
    render(stage.root_layer, root / "out", progress=False, on_event=events.append)
    return root / "out", [e for e in events if e.get("event") == "imported"]


@pytest.mark.usd
@pytest.mark.blender
def test_people_of_one_body_and_pose_share_meshes(rendered):
    _, imported = rendered
    assert len(imported) == 1
    event = imported[0]
    # 4 walkers x 2 poses + 2 standing: 10 references of the body; 3 distinct (body, pose).
    assert event["object_meshes"] >= 10
    assert event["shared_meshes"] * 10 <= event["object_meshes"] * 3


@pytest.mark.usd
@pytest.mark.blender
def test_each_person_keeps_its_own_instance_id_and_colour(rendered):
    import cv2

    from usdscene.document import output_layout as layout

    out, _ = rendered
    for frame in (0, 1):
        mask = cv2.imread(str(layout.mask_path(out, "front", frame)), cv2.IMREAD_UNCHANGED)
        image = cv2.imread(str(layout.image_path(out, "front", frame)))[:, :, ::-1].astype(float)
        ids = [int(i) for i in np.unique(mask) if i]
        assert len(ids) == 6
        centres = [np.flatnonzero((mask == i).any(axis=0)).mean() for i in ids]
        assert sorted(centres) == centres  # ids in the row's order, left to right
        red, blue = (image[mask == ids[k]] for k in (1, 2))  # (N, 3) pixels of each
        # Each its own material: the red shirt shows red, the blue one blue (a shared mesh's
        # materials would paint both alike).
        assert (red[:, 0] - red[:, 2]).max() > 40 and (blue[:, 2] - blue[:, 0]).max() > 40
        assert (red[:, 0] - red[:, 2]).mean() > (blue[:, 0] - blue[:, 2]).mean() + 5.0


@pytest.mark.usd
@pytest.mark.blender
def test_a_shard_imports_only_the_poses_of_its_frames(rendered, tmp_path):
    """Frame 1 alone: each walker's walk_4 child only (6 references of the body, not 10)."""
    from usdscene.render.driver import render

    out, both = rendered
    events = []
    render(out.parent / "stage" / ss.ROOT_LAYER, tmp_path / "out", frames=[1], progress=False, on_event=events.append)
    one = next(e for e in events if e.get("event") == "imported")
    assert one["object_meshes"] * 10 == both[0]["object_meshes"] * 6
    assert one["shared_meshes"] * 3 == both[0]["shared_meshes"] * 2  # (body, walk_4) and (body, standing)
