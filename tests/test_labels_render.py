"""Labels of a real tiny Cycles render: occlusion and visible fractions against known geometry."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel, Pose

pytestmark = [pytest.mark.usd, pytest.mark.blender]

W, H = 64, 48
PX_PER_M = 14.0
# Orthographic camera 10 m above the floor looking straight down, centred on x = 0.8 m: a
# sphere of radius r projects to a disc of r * 14 px whatever its depth.
CAMERA = Camera("top", Intrinsics(LensModel.ORTHOGRAPHIC, W, H, PX_PER_M, PX_PER_M, (W - 1) / 2, (H - 1) / 2),
                pose=Pose.from_rotation_translation(np.diag([1.0, -1.0, -1.0]), (0.8, 0.0, 10.0)))
# uid: (centre, radius). "1" hides behind "2" completely; "4" in front covers part of "3".
SPHERES = {"1": ((-0.3, 0.0, 0.0), 0.5), "2": ((-0.3, 0.0, 3.0), 1.0),
           "3": ((1.5, 0.0, 0.0), 0.7), "4": ((2.2, 0.0, 3.0), 0.7)}


def _lens_fraction(d: float, r: float) -> float:
    """Visible part of a disc of radius r behind an equal disc at centre distance d."""
    overlap = 2 * r * r * math.acos(d / (2 * r)) - d / 2 * math.sqrt(4 * r * r - d * d)
    return 1.0 - overlap / (math.pi * r * r)


@pytest.fixture(scope="module")
def annotated(tmp_path_factory):
    from usdscene.dataset.annotation import annotate_output
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    root = tmp_path_factory.mktemp("render_labels")
    spheres = tuple(SphereSpec(uid, centre, radius, (0.2 * k, 0.5, 1.0 - 0.2 * k), k + 1, class_name="ball")
                    for k, (uid, (centre, radius)) in enumerate(SPHERES.items()))
    stage = write_synthetic_stage(SyntheticScene(cameras=(CAMERA,), spheres=spheres), root / "out" / "stage")
    out = root / "out"
    render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False)
    document, annotations = annotate_output(out, epsilon_px=0)
    return out, document, annotations


def test_fully_hidden_sphere_has_amodal_box_only(annotated):
    _, _, annotations = annotated
    labels = {o.uid: o for o in annotations.images[0].objects}
    hidden = labels["1"]
    assert hidden.box is None and hidden.pixel_count == 0 and hidden.visible_fraction == 0.0
    # Amodal disc of 0.5 m * 14 px/m = 7 px radius around x = (W-1)/2 + (-0.3 - 0.8) * 14.
    cx = (W - 1) / 2 + (-0.3 - 0.8) * PX_PER_M
    acx, acy, aw, ah = hidden.amodal_box.center_size()
    assert acx == pytest.approx(cx, abs=1.0) and aw == pytest.approx(14, abs=2)


def test_partly_hidden_sphere_visible_fraction_matches_geometry(annotated):
    _, _, annotations = annotated
    labels = {o.uid: o for o in annotations.images[0].objects}
    expected = _lens_fraction(0.7, 0.7)  # ≈ 0.609
    assert labels["3"].visible_fraction == pytest.approx(expected, abs=0.05)
    assert labels["4"].visible_fraction == pytest.approx(1.0, abs=0.05)
    assert labels["2"].visible_fraction == pytest.approx(1.0, abs=0.05)
    assert not any(o.truncated for o in labels.values())


def test_rendered_labels_reach_the_document_and_exports(annotated, openlabel_schema_path):
    from usdscene.converters.exports.coco import coco_dataset
    from usdscene.converters.openlabel import schema_problems
    from usdscene.converters.openlabel.annotations import labels_in

    out, document, _ = annotated
    document = json.loads(json.dumps(document))
    assert schema_problems(document, openlabel_schema_path) == []
    labels = labels_in(document, 0, "top")
    assert len(labels) == 4 and sum(1 for lab in labels if lab["bbox"] is None) == 1
    coco = coco_dataset(document)
    assert len(coco["annotations"]) == 3 and coco["images"][0]["file_name"] == "images/top/000000.png"
    assert (out / coco["images"][0]["file_name"]).is_file()


def test_cli_annotate_export_stats(annotated, capsys):
    from usdscene.cli import main

    out, _, _ = annotated
    assert main(["annotate", str(out), "--no-progress"]) == 0
    document = json.loads((out / "annotations.openlabel.json").read_text())
    assert "usdscene_annotations" in document["openlabel"]["metadata"]
    assert main(["export", "coco", "yolo", "rois", str(out), "--document-classes"]) == 0
    coco = json.loads((out / "exports" / "coco" / "annotations.json").read_text())
    assert [c["name"] for c in coco["categories"]] == ["ball"] and len(coco["annotations"]) == 3
    assert len((out / "exports" / "yolo" / "detect" / "labels" / "top" / "000000.txt").read_text().splitlines()) == 3
    assert (out / "exports" / "rois" / "index.csv").read_text().startswith("path,label")
    assert main(["stats", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "ball" in printed and "top" in printed
    import cv2

    chart = cv2.imread(str(out / "stats.png"))
    assert chart is not None and chart.shape[1] == 720
    assert main(["stats", str(out / "missing")]) == 1
