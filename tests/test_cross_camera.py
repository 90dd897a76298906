"""Cross-camera table: which cameras see each object per frame, at what px/m and DORI class; on
hand-made labels and on a real tiny two-camera Cycles render, and in `usdscene stats OUT`."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from usdscene.labels.cross_camera import camera_for_image, cross_camera_table, object_centre
from usdscene.labels.image_labels import ImageLabels, ObjectLabel, PixelBox, label_images
from usdscene.document.model import Camera, FrameInterval, Intrinsics, LensModel, Pose, SceneObject, SceneSpec

W, H, F = 64, 48, 100.0
# Top camera 4 m above z = 1 looking down; side camera 5 m in front (-y) of the origin at z = 1.
TOP = Camera("top", Intrinsics(LensModel.PERSPECTIVE, W, H, F, F, (W - 1) / 2, (H - 1) / 2),
             pose=Pose.from_rotation_translation(np.diag([1.0, -1.0, -1.0]), (0.0, 0.0, 4.0)))
SIDE = Camera("side", Intrinsics(LensModel.PERSPECTIVE, W, H, F, F, (W - 1) / 2, (H - 1) / 2),
              pose=Pose.from_rotation_translation(np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]), (0.0, -5.0, 1.0)))


def _label(uid: str, pixels: int, fraction: float | None = None) -> ObjectLabel:
    box = PixelBox(0, 0, 3, 3) if pixels else None
    return ObjectLabel(uid=uid, class_name="ball", mask_id=int(uid), box=box, pixel_count=pixels,
                       amodal_box=PixelBox(0, 0, 3, 3), amodal_pixel_count=16, visible_fraction=fraction)


def test_table_from_labels_counts_present_objects_no_camera_sees():
    scene = SceneSpec(name="s", frame_start=0, frame_end=1, cameras=(TOP, SIDE), objects=(
        SceneObject(uid="1", name="a", class_name="ball"),
        SceneObject(uid="2", name="b", class_name="ball"),
        SceneObject(uid="3", name="c", class_name="ball", frame_intervals=(FrameInterval(1, 1),))))
    images = [ImageLabels("top", 0, W, H, (_label("1", 10, 1.0), _label("2", 0, 0.0))),
              ImageLabels("side", 0, W, H, (_label("1", 4, 0.25),)),
              ImageLabels("top", 1, W, H, (_label("3", 8, 0.5),))]
    densities = {(0, "top", "1"): 30.0, (0, "side", "1"): 130.0, (1, "top", "3"): 5.0}
    rows = {(r.frame, r.uid): r for r in cross_camera_table(label_images(images), scene, densities=densities)}
    # Object 3 is absent at frame 0; 2 is present but only hidden (no visible pixel) there.
    assert sorted(rows) == [(0, "1"), (0, "2"), (1, "1"), (1, "2"), (1, "3")]
    a = rows[0, "1"]
    assert [s.camera for s in a.sightings] == ["side", "top"] and a.camera_count == 2
    assert [s.visible_fraction for s in a.sightings] == [0.25, 1.0]
    assert [s.dori for s in a.sightings] == ["recognise", "detect"]
    assert a.best().camera == "side" and a.best().px_per_m == 130.0
    assert rows[0, "2"].camera_count == 0 and rows[0, "2"].best() is None
    assert rows[1, "3"].sightings[0].dori == ""  # 5 px/m is below "monitor"
    unknown = cross_camera_table(label_images(images), scene)
    assert all(s.px_per_m is None and s.dori is None for r in unknown for s in r.sightings)


def test_density_follows_the_image_size_and_the_frame_pose():
    moving = Camera("m", TOP.intrinsics, pose=TOP.pose,
                    frame_poses=((1, Pose.from_rotation_translation(np.diag([1.0, -1.0, -1.0]), (0.0, 0.0, 3.0))),))
    from usdscene.labels.pixel_density import pixel_density

    centre = np.array([[0.0, 0.0, 1.0]])
    assert pixel_density(camera_for_image(moving, 0, W, H), centre)[0] == pytest.approx(F / 3, rel=1e-6)
    assert pixel_density(camera_for_image(moving, 1, W, H), centre)[0] == pytest.approx(F / 2, rel=1e-6)
    # Rendered at twice the calibrated resolution: twice the pixels per metre.
    assert pixel_density(camera_for_image(moving, 0, 2 * W, 2 * H), centre)[0] == pytest.approx(2 * F / 3, rel=1e-6)
    triangles = np.array([[[-1.0, 2.0, 0.0], [1.0, 2.0, 0.0], [0.0, 4.0, 6.0]]])
    assert object_centre(triangles).tolist() == [0.0, 3.0, 3.0]


# ---------------------------------------------------------------------------------------------
# A real render: "a" seen by both cameras, "b" behind "a" for the side camera (top only), "c"
# far away at frame 0 (no camera) and beside "a" at frame 1 (both cameras).


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from usdscene.dataset.annotation import LabelsWhileRendering, annotate_output
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    root = tmp_path_factory.mktemp("cross_camera")
    spheres = (SphereSpec("1", (0.0, 0.0, 1.0), 0.4, (1.0, 0.3, 0.3), 1, class_name="ball"),
               SphereSpec("2", (0.0, 0.6, 1.0), 0.2, (0.3, 1.0, 0.3), 2, class_name="ball"),
               SphereSpec("3", (20.0, 20.0, 1.0), 0.2, (0.3, 0.3, 1.0), 3, class_name="cube",
                          frame_centres=((0, (20.0, 20.0, 1.0)), (1, (-0.7, 0.0, 1.0)))))
    out = root / "out"
    stage = write_synthetic_stage(SyntheticScene(cameras=(TOP, SIDE), spheres=spheres, frame_end=1), out / "stage")
    render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False,
           on_event=LabelsWhileRendering(out))
    document, _ = annotate_output(out)
    return out, json.loads(json.dumps(document))


def test_rendered_table_is_in_the_document_and_valid(rendered, openlabel_schema_path):
    from usdscene.converters.openlabel import schema_problems
    from usdscene.converters.openlabel.annotations import cross_camera_rows

    _, document = rendered
    assert schema_problems(document, openlabel_schema_path) == []
    rows = {(r["frame"], r["uid"]): r for r in cross_camera_rows(document)}
    assert {k: r["cameras"] for k, r in rows.items()} == {
        (0, "1"): ["side", "top"], (0, "2"): ["top"], (0, "3"): [],
        (1, "1"): ["side", "top"], (1, "2"): ["top"], (1, "3"): ["side", "top"]}
    # px/m = f / depth on the optical axis: 100 / 5 from the side, 100 / 3 from the top.
    a = rows[0, "1"]
    assert a["px_per_m"] == pytest.approx([F / 5, F / 3], rel=0.01)
    assert a["dori"] == ["monitor", "detect"] and a["best_dori"] == "detect"
    assert a["best_px_per_m"] == pytest.approx(F / 3, rel=0.01)
    assert a["visible_fractions"][0] == pytest.approx(1.0, abs=0.1)
    assert rows[0, "3"]["best_dori"] is None and rows[0, "3"]["px_per_m"] == []  # parallel to no camera
    # The moving object's centre is read per frame: at frame 1 it is 3 m below the top camera.
    assert rows[1, "3"]["px_per_m"][1] == pytest.approx(F / 3, rel=0.05)
    pointer = document["openlabel"]["objects"]["3"]["object_data_pointers"]["usdscene_cameras"]
    assert pointer["type"] == "vec" and pointer["attribute_pointers"]["best_dori"] == "text"
    classes = document["openlabel"]["metadata"]["usdscene_annotations"]["dori_classes"]
    assert [c["name"] for c in classes][:2] == ["monitor", "detect"]


def test_table_is_the_same_when_labelled_afterwards(rendered, tmp_path):
    from usdscene.document import output_layout as layout
    from usdscene.dataset.annotation import annotate_output

    out, during = rendered
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    shutil.rmtree(copy / layout.LABELS_DIR)
    after, _ = annotate_output(copy)
    assert json.dumps(json.loads(json.dumps(after)), sort_keys=True) == json.dumps(during, sort_keys=True)


def test_stats_shows_the_cross_camera_summary(rendered, tmp_path, capsys):
    import cv2

    from usdscene.document import output_layout as layout
    from usdscene.cli import main
    from usdscene.files import write_json_atomic
    from usdscene.dataset.statistics import cross_camera_statistics

    out, document = rendered
    summary = cross_camera_statistics(document)
    assert summary["object_frames"] == 6 and summary["by_camera_count"] == {0: 1, 1: 2, 2: 3}
    assert summary["classes"]["ball"]["median_cameras"] == 1.5
    assert summary["classes"]["ball"]["best_dori"] == "detect"
    cube = dict(summary["classes"]["cube"])
    assert cube.pop("best_dori") == "detect"
    assert cube == pytest.approx({"object_frames": 2, "unseen": 1, "median_cameras": 1.0,
                                  "median_best_px_per_m": F / 3, "best_px_per_m": F / 3}, rel=0.05)

    write_json_atomic(out / layout.ANNOTATIONS_FILE, document)
    chart = tmp_path / "stats.png"
    assert main(["stats", str(out), "--chart", str(chart)]) == 0
    text = capsys.readouterr().out
    assert "6 object-frames" in text and "median cameras" in text
    assert "IEC 62676-4:2015" in text  # the standard of the annotations' classes is named
    assert "2 cameras" in text and "detect" in text
    image = cv2.imread(str(chart))
    assert image is not None and image.shape[1] == 720 and image.shape[0] > 400
