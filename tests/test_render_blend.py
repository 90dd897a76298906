""".blend camera-design round trip: stage → .blend → SceneSpec keeps exact calibrations and
presence; a camera moved and re-lensed in Blender comes back moved and re-lensed. Also the
preview contact sheet and the render command's input checks."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import cv2
import numpy as np
import pytest

from usdscene.document.model import Camera, FrameInterval, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    cams = (
        Camera("ortho_top", Intrinsics(LensModel.ORTHOGRAPHIC, 64, 48, 10.0, 10.0, 30.0, 25.0),
               Pose.from_rotation_translation(R, [-5.0, 0.0, 1.0])),
        Camera("brown", Intrinsics(LensModel.OPENCV_PINHOLE, 64, 48, 50.0, 50.0, 32.2, 23.1,
                                   distortion=(-0.2, 0.03, 0.001, 0.0, 0.0)),
               Pose.from_rotation_translation(R, [-3.0, 0.2, 1.2]), clip_near_m=0.05, clip_far_m=50.0),
        Camera("equisolid", Intrinsics(LensModel.FISHEYE_EQUISOLID, 64, 48, 20.0, 20.0, 31.5, 23.5, fov_deg=160.0),
               Pose.from_rotation_translation(R, [-2.0, 0.0, 1.0])),
    )
    spheres = (SphereSpec("a", (0.0, 0.0, 1.0), 0.4, (1.0, 0.0, 0.0), 1),
               SphereSpec("b", (0.0, 1.0, 1.2), 0.3, (0.0, 1.0, 0.0), 2, frames=(1, 2)))
    return write_synthetic_stage(SyntheticScene(cameras=cams, spheres=spheres, frame_start=0, frame_end=3),
                                 tmp_path_factory.mktemp("blend") / "stage"), cams


@pytest.fixture(scope="module")
def blend(stage, tmp_path_factory):
    from usdscene.cli import main

    path = tmp_path_factory.mktemp("project") / "design.blend"
    assert main(["blend", str(stage[0]), "-o", str(path)]) == 0
    return path


def test_blend_round_trip_keeps_exact_calibration_and_presence(stage, blend):
    from usdscene.render.blend_io import scene_from_blend

    _, cams = stage
    scene = scene_from_blend(blend)
    got = {c.name: c for c in scene.cameras}
    assert set(got) == {c.name for c in cams}
    for cam in cams:
        assert got[cam.name].intrinsics == cam.intrinsics
        np.testing.assert_allclose(got[cam.name].pose.as_array(), cam.pose.as_array(), atol=1e-5)
    assert got["brown"].clip_near_m == pytest.approx(0.05) and got["brown"].clip_far_m == pytest.approx(50.0)
    objects = {o.uid: o for o in scene.objects}
    assert objects["a"].frame_intervals == (FrameInterval(0, 3),)
    assert objects["b"].frame_intervals == (FrameInterval(1, 2),)
    np.testing.assert_allclose(objects["b"].pose.translation_m, [0.0, 1.0, 1.2], atol=1e-6)
    assert scene.provenance.source_format == "blend"


def test_camera_edited_in_blender_comes_back(blend, tmp_path):
    from usdscene.render.blend_io import scene_from_blend

    edited = tmp_path / "edited.blend"
    script = textwrap.dedent(f"""
        import bpy
        bpy.ops.wm.open_mainfile(filepath={str(blend)!r})
        cam = bpy.data.objects["brown"]
        cam.location.z += 0.5
        bpy.data.objects["ortho_top"].data.ortho_scale = 8.0
        bpy.ops.wm.save_as_mainfile(filepath={str(edited)!r})
    """)
    subprocess.run([sys.executable, "-c", script], check=True, capture_output=True)
    scene = scene_from_blend(edited)
    got = {c.name: c for c in scene.cameras}
    assert got["brown"].pose.translation_m[2] == pytest.approx(1.7, abs=1e-5)
    assert got["brown"].intrinsics.distortion == (-0.2, 0.03, 0.001, 0.0, 0.0)  # lens untouched: exact
    ortho = got["ortho_top"].intrinsics
    assert ortho.lens is LensModel.ORTHOGRAPHIC
    assert ortho.fx_px == pytest.approx(64 / 8.0)
    assert ortho.cx_px == pytest.approx(30.0, abs=1e-4)  # the shift survives


def test_preview_contact_sheet(stage, tmp_path):
    from usdscene.cli import main

    sheet = tmp_path / "sheet.png"
    assert main(["preview", str(stage[0]), "-o", str(sheet), "--tile-width", "64", "--samples", "1"]) == 0
    image = cv2.imread(str(sheet))
    assert image is not None and image.shape[1] >= 2 * 64  # three tiles: two columns
    assert image.std() > 5  # tiles are not blank


def test_render_command_rejects_bad_input(stage, tmp_path, capsys):
    from usdscene.cli import main

    assert main(["render", str(stage[0]), "-o", str(tmp_path), "--cameras", "nope"]) == 1
    assert "camera 'nope' is not in the stage" in capsys.readouterr().err
    assert main(["render", str(stage[0]), "-o", str(tmp_path), "--frames", "2:1"]) == 1
    assert main(["render", str(stage[0]), "-o", str(tmp_path), "--frames", "7"]) == 1
    assert "outside the stage's range 0..3" in capsys.readouterr().err
