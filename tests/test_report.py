"""The browsable report built from synthetic output folders (no renderer, no browser: the page
itself is driven in Chromium by tests/test_report_browser.py)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from usdscene.labels.amodal import AmodalProjection
from usdscene.cli import main
from usdscene.converters.openlabel.annotations import add_annotations, labels_in
from usdscene.labels.image_labels import image_labels_to_json, label_image, label_images
from usdscene.document.model import Camera, Intrinsics, LensModel, SceneObject, SceneSpec
from usdscene.dataset.report import build_report
from usdscene.dataset.report_pictures import THUMB_WIDTH_PX, picture_paths

W, H = 400, 240  # wider than THUMB_ABOVE_PX: thumbnails are drawn
CAMERAS = ("cam_a", "cam_b")
FRAMES = (0, 1, 2)
OBJECTS = {"0": ("bag_0", "backpack"), "1": ("case_1", "suitcase")}
IDS = {1: "0", 2: "1"}
CLASSES = {uid: cls for uid, (_, cls) in OBJECTS.items()}


def _scene() -> SceneSpec:
    intr = Intrinsics(LensModel.PERSPECTIVE, W, H, 200.0, 200.0, (W - 1) / 2, (H - 1) / 2)
    return SceneSpec(name="synthetic", frame_start=0, frame_end=2,
                     cameras=tuple(Camera(name, intr) for name in CAMERAS),
                     objects=tuple(SceneObject(uid, name, cls) for uid, (name, cls) in OBJECTS.items()))


def _document() -> dict:
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "synthetic_report"},
        "streams": {name: {"type": "camera", "stream_properties": {"intrinsics_pinhole": {
            "width_px": W, "height_px": H,
            "camera_matrix_3x4": [200.0, 0, (W - 1) / 2, 0, 0, 200.0, (H - 1) / 2, 0, 0, 0, 1, 0],
            "distortion_coeffs_1xN": []}}} for name in CAMERAS},
        "objects": {uid: {"name": name, "type": cls, "frame_intervals": [{"frame_start": 0, "frame_end": 2}]}
                    for uid, (name, cls) in OBJECTS.items()}}}


def _mask(frame: int, camera: str) -> np.ndarray:
    """The bag moves right with the frame; the suitcase is only in cam_b."""
    mask = np.zeros((H, W), np.uint16)
    mask[40:90, 30 + 20 * frame:80 + 20 * frame] = 1
    if camera == "cam_b":
        mask[120:200, 150:260] = 2
    return mask


def _amodal(frame: int, camera: str) -> dict:
    """The bag's whole projection is twice its visible part (visible fraction 0.5)."""
    bag = np.zeros((H, W), bool)
    bag[40:90, 30 + 20 * frame:130 + 20 * frame] = True
    projections = {"0": AmodalProjection.from_mask(bag, False)}
    if camera == "cam_b":
        projections["1"] = AmodalProjection.from_mask(_mask(frame, camera) == 2, False)
    return projections


@pytest.fixture()
def output(tmp_path) -> Path:
    """A finished output folder: images, masks, kept labels and the annotations document with
    one keypoint added by hand (the format the report reads)."""
    out = tmp_path / "out"
    images = []
    for frame in FRAMES:
        for camera in CAMERAS:
            mask = _mask(frame, camera)
            labels = label_image(mask, IDS, _amodal(frame, camera), classes=CLASSES, camera=camera, frame=frame)
            images.append(labels)
            picture = np.full((H, W, 3), 40 * frame, np.uint8)
            picture[mask > 0] = (0, 200, 255)
            for folder, pixels in (("images", picture), ("masks", mask)):
                path = out / folder / camera / f"{frame:06d}.png"
                path.parent.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(path), pixels)
            kept = out / "labels" / camera / f"{frame:06d}.json"
            kept.parent.mkdir(parents=True, exist_ok=True)
            kept.write_text(json.dumps({"key": {}, "labels": image_labels_to_json(labels)}))
    document = add_annotations(_document(), _scene(), label_images(images), out)
    bag = document["openlabel"]["frames"]["1"]["objects"]["0"]["object_data"]
    bag["point2d"] = [{"name": "cam_a_kp_nose", "val": [55.0, 50.0],
                       "attributes": {"num": [{"name": "visibility", "val": 1}]}}]
    (out / "annotations.openlabel.json").write_text(json.dumps(document))
    return out


def _script_data(path: Path, call: str):
    text = path.read_text(encoding="utf-8")
    assert text.startswith(call + "(") and text.endswith(");\n")
    body = text[len(call) + 1:-3]
    if call == "usdsceneReportPage":
        body = "[" + body + "]"
    return json.loads(body)


def test_report_holds_every_image_and_label(output):
    summary = build_report(output)
    report = output / "report"
    assert summary.index == report / "index.html" and summary.complete
    assert (summary.images, summary.labels) == (6, 9)
    assert summary.note() == "6 images, 9 labels"
    for name in ("index.html", "report.js", "report.css"):
        assert (report / name).stat().st_size > 500
    index = _script_data(report / "data" / "index.js", "usdsceneReportIndex")
    assert index["title"] == "synthetic_report"
    assert index["cameras"] == list(CAMERAS) and index["classes"] == ["backpack", "suitcase"]
    assert index["frames"] == list(FRAMES) and index["imageRoot"] == ".."
    assert index["thumb"] == [1] * 6
    # (frame, camera) order; codes: (class · 11 + visibility bin) · 2 + visible
    assert index["camera"] == [0, 1, 0, 1, 0, 1]
    assert index["codes"][1] == [(0 * 11 + 5) * 2 + 1, (1 * 11 + 9) * 2 + 1]
    k, page = _script_data(report / "data" / "labels_00000.js", "usdsceneReportPage")
    assert k == 0 and len(page) == 6
    document = json.loads((output / "annotations.openlabel.json").read_text())
    for number, entry in enumerate(page):
        frame, camera = FRAMES[number // 2], CAMERAS[number % 2]
        assert entry["uri"] == f"images/{camera}/{frame:06d}.png" and (entry["w"], entry["h"]) == (W, H)
        expected = labels_in(document, frame, camera)
        assert [o["u"] for o in entry["o"]] == [o["uid"] for o in expected]
        assert [o["b"] for o in entry["o"]] == [o["bbox"] for o in expected]
        assert [o["v"] for o in entry["o"]] == [0.5, 1.0][:len(expected)]
        assert all(o["p"] and o["a"] for o in entry["o"])
    assert page[2]["o"][0]["kp"] == [["nose", 55.0, 50.0, 1]]  # frame 1, cam_a
    thumb, tint = picture_paths(report, "cam_b", 2)
    assert cv2.imread(str(thumb)).shape == (H * THUMB_WIDTH_PX // W, THUMB_WIDTH_PX, 3)
    indices = cv2.imread(str(tint), cv2.IMREAD_UNCHANGED)
    assert indices.dtype == np.uint8 and indices.tolist() == _mask(2, "cam_b").tolist()  # ids 1, 2 → 1, 2


def test_tint_indices_wrap_past_255():
    from usdscene.dataset.report_pictures import tint_indices

    ids = np.array([[0, 1, 255, 256, 511, 65535]], np.uint16)
    assert tint_indices(ids).tolist() == [[0, 1, 255, 1, 1, 255]]


def test_grey_png_decodes_to_its_pixels_and_is_stable():
    from usdscene.dataset.report_pictures import grey_png

    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, (37, 53), dtype=np.uint8)
    pixels[:10] = 0  # runs, as in a tint
    encoded = grey_png(pixels)
    decoded = cv2.imdecode(np.frombuffer(encoded, np.uint8), cv2.IMREAD_UNCHANGED)
    assert decoded.dtype == np.uint8 and decoded.shape == (37, 53) and (decoded == pixels).all()
    assert grey_png(pixels.copy()) == encoded


def test_no_tint_for_an_image_labelled_with_nothing(output):
    document = json.loads((output / "annotations.openlabel.json").read_text())
    # frame 2 of cam_a: the bag leaves the picture, its mask is all background
    cv2.imwrite(str(output / "masks" / "cam_a" / "000002.png"), np.zeros((H, W), np.uint16))
    for entry in document["openlabel"]["frames"]["2"]["objects"].values():
        data = entry["object_data"]
        for kind in ("bbox", "poly2d", "rbbox", "vec"):
            if kind in data:
                data[kind] = [item for item in data[kind] if not item["name"].startswith("cam_a_")]
    (output / "annotations.openlabel.json").write_text(json.dumps(document))
    summary = build_report(output)
    page = _script_data(output / "report" / "data" / "labels_00000.js", "usdsceneReportPage")[1]
    assert page[4]["uri"] == "images/cam_a/000002.png" and page[4]["o"] == []
    assert not picture_paths(output / "report", "cam_a", 2)[1].exists()
    assert picture_paths(output / "report", "cam_b", 2)[1].is_file()
    assert summary.pictures_drawn == 11  # 6 thumbnails + 5 tints


def test_rebuild_redraws_only_changed_pictures(output):
    assert build_report(output).pictures_drawn == 12  # 6 thumbnails + 6 tints
    assert build_report(output).pictures_drawn == 0
    image = output / "images" / "cam_a" / "000001.png"
    later = image.stat().st_mtime_ns + 5_000_000_000
    os.utime(image, ns=(later, later))
    assert build_report(output).pictures_drawn == 1


def test_pictures_drawn_while_rendering_are_kept_by_the_report(output):
    from usdscene.dataset.report_pictures import PicturesWhileRendering

    pictures = PicturesWhileRendering(output)
    for frame in FRAMES:
        for camera in CAMERAS:
            pictures({"event": "done", "frame": frame, "camera": camera})
    pictures({"event": "started", "frame": 0, "camera": "cam_a"})  # other events: nothing
    assert pictures.pictures == 12
    assert build_report(output).pictures_drawn == 0


def test_half_finished_run_reports_what_is_there(output, capsys):
    (output / "annotations.openlabel.json").unlink()
    for frame in (1, 2):
        (output / "labels" / "cam_b" / f"{frame:06d}.json").unlink()
    assert main(["report", str(output)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1
    assert "half-finished run" in lines[0] and "6 images rendered so far, 4 of them labelled" in lines[0]
    index = _script_data(output / "report" / "data" / "index.js", "usdsceneReportIndex")
    assert index["complete"] is False and "half-finished" in index["note"]
    assert index["labelled"] == [1, 1, 1, 0, 1, 0]
    _, page = _script_data(output / "report" / "data" / "labels_00000.js", "usdsceneReportPage")
    assert page[3]["o"] == [] and (page[3]["w"], page[3]["h"]) == (W, H)
    assert [o["b"] for o in page[1]["o"]] == [[54.5, 64.5, 50.0, 50.0], [204.5, 159.5, 110.0, 80.0]]


def test_small_images_are_their_own_thumbnails_and_sizes_come_from_the_png(output):
    (output / "annotations.openlabel.json").unlink()
    cv2.imwrite(str(output / "images" / "cam_a" / "000000.png"), np.zeros((48, 64, 3), np.uint8))
    (output / "labels" / "cam_a" / "000000.json").unlink()
    build_report(output)
    index = _script_data(output / "report" / "data" / "index.js", "usdsceneReportIndex")
    assert index["thumb"] == [2, 1, 1, 1, 1, 1]
    assert not picture_paths(output / "report", "cam_a", 0)[0].exists()
    _, page = _script_data(output / "report" / "data" / "labels_00000.js", "usdsceneReportPage")
    assert (page[0]["w"], page[0]["h"]) == (64, 48)  # unlabelled: read from the PNG header


def test_unreadable_annotations_is_a_one_line_error(output, capsys):
    (output / "annotations.openlabel.json").write_text('{"openlabel": {"frames": ')
    assert main(["report", str(output)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unreadable annotations document" in err[0]


def test_folder_without_annotations_is_a_one_line_error(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing to report" in err[0] and str(tmp_path) in err[0]
    assert main(["report", str(tmp_path / "missing")]) == 1
    assert "no such output folder" in capsys.readouterr().err


def test_balance_chart_and_coverage_map(output, tmp_path, capsys):
    document = tmp_path / "plan" / "generated.openlabel.json"
    document.parent.mkdir()
    document.write_text(json.dumps(_document()))
    Path(f"{document}.report.json").write_text(json.dumps({
        "frames": 3, "classes": {"backpack": {"objects": 1, "instance_frames": 3}},
        "relations": {"is_on": 3}, "places": {"seat_01A": 3}, "place_kinds": {"seat": 3}}))
    cv2.imwrite(str(document.parent / "coverage.png"), np.full((20, 30, 3), 128, np.uint8))
    (document.parent / "coverage.json").write_text("{}")
    assert main(["report", str(output), "-o", str(tmp_path / "elsewhere"), "--document", str(document)]) == 0
    report = tmp_path / "elsewhere"
    index = _script_data(report / "data" / "index.js", "usdsceneReportIndex")
    assert index["pictures"] == {"balance": "balance.png", "coverage": "coverage.png"}
    assert cv2.imread(str(report / "balance.png")).shape[1] == 720
    assert (report / "coverage.png").read_bytes() == (document.parent / "coverage.png").read_bytes()
    assert index["imageRoot"] == os.path.relpath(output, report)
    assert str(report / "index.html") in capsys.readouterr().out


def test_a_tracks_report_draws_no_balance_chart_and_warns_nothing(output, tmp_path, caplog):
    """``generate tracks`` writes a report of tracks beside its document: not a balance report."""
    document = tmp_path / "moving.openlabel.json"
    document.write_text(json.dumps(_document()))
    Path(f"{document}.report.json").write_text(json.dumps({
        "strategy": "tracks", "frames": 3, "fps": 5.0, "tracks": {"1": {"frames": 3}}}))
    with caplog.at_level("WARNING"):
        assert main(["report", str(output), "-o", str(tmp_path / "report"), "--document", str(document)]) == 0
    index = _script_data(tmp_path / "report" / "data" / "index.js", "usdsceneReportIndex")
    assert "balance" not in index["pictures"]
    assert not (tmp_path / "report" / "balance.png").exists()
    assert not [r for r in caplog.records if "balance" in r.getMessage()]
