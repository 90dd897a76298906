"""A walker's walk-cycle pose per frame (text object data ``walk_pose_variant``) is what the
stage shows, the renderer draws and the labels follow.

- composition gives the object one child per shown pose, visible on its frames; objects without
  per-frame poses keep their one referenced prim;
- stage geometry (amodal labels) and keypoints change with the pose between frames;
- a tiny two-frame render draws different masks per frame and the keypoints flagged visible
  fall on the walker's own mask pixels in each frame;
- an unknown per-frame pose is one error naming the frame and the object.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from usdscene.document import model as m
from usdscene.document import stage_schema as ss

W, H = 64, 48
POSES = {0: "walk_0", 1: "walk_4"}  # opposite legs forward


def _look_at(eye, target) -> m.Pose:
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return m.Pose.from_rotation_translation(np.stack([x, np.cross(z, x), z], axis=1), eye)


def _frame_pose(variant: str) -> str:
    return m.canonical_json({"object_data": {"text": [{"name": ss.FRAME_POSE_DATA, "val": variant}]}})


def _scene(poses=POSES) -> m.SceneSpec:
    # Seen from the side (camera on -X, the walker faces +Y): the legs swing across the image.
    intr = m.Intrinsics(lens=m.LensModel.PERSPECTIVE, width_px=W, height_px=H, fx_px=40.0, fy_px=40.0,
                        cx_px=(W - 1) / 2, cy_px=(H - 1) / 2, sensor_width_mm=6.4)
    camera = m.Camera("side", intr, pose=_look_at((-3.2, 0.0, 1.0), (0.0, 0.0, 0.9)))
    walker = m.SceneObject("1", "walker", "person", pose=m.Pose(), pose_variant="walk_0",
                           appearance="m_35_192_average_tone1",
                           frame_extra=tuple((f, _frame_pose(v)) for f, v in poses.items()))
    standing = m.SceneObject("2", "still", "person", pose=m.Pose.from_rotation_translation(np.eye(3), [0.0, 1.2, 0.0]),
                             pose_variant="standing", appearance="f_57_175_average_tone2")
    sun = m.Light("10", "sun", m.LightKind("sun"), pose=_look_at((-2.0, -3.0, 4.0), (0.0, 0.0, 0.0)), power_w=4.0)
    return m.SceneSpec(name="walk", seed=3, frame_start=0, frame_end=1, cameras=(camera,),
                       objects=(walker, standing), lights=(sun,),
                       render=m.RenderSettings(samples=1, denoise=False))


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage

    return compose_stage(_scene(), load_catalog(), tmp_path_factory.mktemp("walk") / "stage")


@pytest.mark.usd
def test_each_shown_pose_is_a_child_visible_on_its_frames(stage):
    from usdscene.render.stage_reader import read_stage_plan

    plan = {o.uid: o for o in read_stage_plan(stage.root_layer).objects}
    assert plan["1"].pose_frames == (("walk_0", (0,)), ("walk_4", (1,)))
    assert plan["2"].pose_frames == ()  # one pose for the whole sequence: one referenced prim
    text = (stage.stage_dir / "objects.usda").read_text()
    assert text.count("prepend references") == 3  # two poses of the walker, the standing person


@pytest.mark.usd
def test_geometry_and_keypoints_follow_the_pose(stage):
    from usdscene.labels.keypoints import COCO_KEYPOINTS
    from usdscene.scene.stage_geometry import StageGeometry

    geometry = StageGeometry(stage.root_layer)
    k0, k1 = geometry.keypoints(0), geometry.keypoints(1)
    t0, t1 = geometry.triangles(0), geometry.triangles(1)
    assert np.abs(t0["1"] - t1["1"]).max() > 0.3 and np.array_equal(t0["2"], t1["2"])
    ankle = [COCO_KEYPOINTS.index("left_ankle"), COCO_KEYPOINTS.index("right_ankle")]
    # walk_4 is walk_0 with the legs swapped: the ankles trade places along the walk (+Y).
    assert np.allclose(k0["1"][ankle][:, 1], k1["1"][ankle][::-1, 1], atol=1e-6)
    assert abs(k0["1"][ankle[0], 1] - k1["1"][ankle[0], 1]) > 0.5
    assert np.array_equal(k0["1"][0], k1["1"][0]) and np.array_equal(k0["2"], k1["2"])


@pytest.mark.usd
def test_an_unknown_frame_pose_names_frame_and_object(tmp_path):
    from usdscene.errors import CompositionError
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage

    with pytest.raises(CompositionError) as info:
        compose_stage(_scene({0: "walk_0", 1: "walk_99"}), load_catalog(), tmp_path / "stage")
    assert "frames.1.objects.1" in str(info.value) and "'walk_99'" in str(info.value)
    assert not (tmp_path / "stage" / ss.ROOT_LAYER).exists()


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from usdscene.cli import main
    from usdscene.converters.openlabel import write_openlabel

    root = tmp_path_factory.mktemp("walk_render")
    doc = root / "walk.openlabel.json"
    doc.write_text(json.dumps(write_openlabel(_scene())))
    out = root / "out"
    assert main(["render", str(doc), "-o", str(out), "--no-progress"]) == 0
    assert main(["annotate", str(out), "--no-progress"]) == 0
    return out


@pytest.mark.usd
@pytest.mark.blender
def test_render_draws_the_pose_of_each_frame(rendered):
    import cv2

    from usdscene.document import output_layout as layout

    masks = [cv2.imread(str(layout.mask_path(rendered, "side", f)), cv2.IMREAD_UNCHANGED) for f in (0, 1)]
    walker = [mask == 1 for mask in masks]
    still = [mask == 2 for mask in masks]
    assert walker[0].sum() > 50 and walker[1].sum() > 50
    assert (walker[0] ^ walker[1]).sum() > 20  # the legs moved
    assert np.array_equal(still[0], still[1])  # the standing person did not
    document = json.loads((rendered / "annotations.openlabel.json").read_text())
    seen = {}
    for f, mask in zip((0, 1), masks):
        items = document["openlabel"]["frames"][str(f)]["objects"]["1"]["object_data"]["point2d"]
        rows = np.array([[*i["val"], i["attributes"]["num"][0]["val"]] for i in items], dtype=float)
        seen[f] = rows
        for x, y, v in rows:  # flagged visible: on the walker's own pixels of that frame
            if v == 2:
                col, row = int(np.floor(x + 0.5)), int(np.floor(y + 0.5))
                assert 1 in mask[max(row - 1, 0):row + 2, max(col - 1, 0):col + 2], (f, x, y)
    assert seen[0].shape == seen[1].shape and np.abs(seen[0][:, :2] - seen[1][:, :2]).max() > 3.0


@pytest.mark.usd
def test_stage_to_document_keeps_the_pose_per_frame(stage, tmp_path):
    from usdscene.converters.stage.usd_stage import scene_from_stage
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage, frame_pose_data

    back = {o.uid: o for o in scene_from_stage(stage.root_layer).objects}
    assert frame_pose_data(back["1"]) == POSES and back["1"].appearance == "m_35_192_average_tone1"
    assert back["2"].frame_extra == () and back["2"].pose_variant == "standing"
    again = compose_stage(scene_from_stage(stage.root_layer), load_catalog(), tmp_path / "stage")
    assert (again.stage_dir / "objects.usda").read_bytes() == (stage.stage_dir / "objects.usda").read_bytes()


_SHOWN_POSES = """
import json, sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
scene = bpy.context.scene
shown = {}
for f in (0, 1):
    scene.frame_set(f)
    poses = set()
    for ob in scene.objects:
        if ob.type != "MESH" or ob.hide_render:
            continue
        while ob.parent is not None and ob.get("usdscene_pose") is None:
            ob = ob.parent
        poses.add(ob.get("usdscene_pose", "-"))
    shown[f] = sorted(poses)
print(json.dumps(shown))
"""


@pytest.mark.usd
@pytest.mark.blender
def test_blender_project_keyframes_the_pose_of_each_frame(tmp_path):
    import subprocess
    import sys

    from usdscene.cli import main
    from usdscene.converters.openlabel import write_openlabel

    doc = tmp_path / "walk.openlabel.json"
    doc.write_text(json.dumps(write_openlabel(_scene())))
    assert main(["blend", str(doc), "-o", str(tmp_path / "walk.blend")]) == 0
    done = subprocess.run([sys.executable, "-c", _SHOWN_POSES, str(tmp_path / "walk.blend")],
                          capture_output=True, text=True, check=True)
    shown = json.loads(done.stdout.strip().splitlines()[-1])
    # "-": the standing person's body, one referenced prim without pose children.
    assert shown == {"0": ["-", "walk_0"], "1": ["-", "walk_4"]}


@pytest.mark.usd
def test_a_late_walker_gets_children_only_for_the_poses_it_shows(tmp_path):
    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage

    scene = _scene({1: "walk_2", 2: "walk_6"})
    walker = dataclasses.replace(scene.objects[0], frame_intervals=(m.FrameInterval(1, 2),))
    scene = dataclasses.replace(scene, frame_end=2, objects=(walker, *scene.objects[1:]))
    result = compose_stage(scene, load_catalog(), tmp_path / "stage")
    plan = {o.uid: o for o in read_stage_plan(result.root_layer).objects}
    assert plan["1"].visible_frames == (1, 2)
    assert plan["1"].pose_frames == (("walk_2", (1,)), ("walk_6", (2,)))
    # One pose all along, other than the object's own: one child, still that pose.
    result = compose_stage(_scene({0: "walk_3", 1: "walk_3"}), load_catalog(), tmp_path / "one")
    assert {o.uid: o.pose_frames for o in read_stage_plan(result.root_layer).objects}["1"] == (
        ("walk_3", (0, 1)),)
