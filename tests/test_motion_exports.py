"""MOT and multi-view exports of a tiny rendered moving car park, read by real clients:
motmetrics scores the MOT ground truth, OpenCV reads and projects through the calibrations."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from usdscene.cli import main

pytestmark = pytest.mark.blender

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"
CAMERAS = ("pole_north", "entrance_wide", "ceiling_fisheye")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A moving sequence (8 frames at 5 fps, walkers, standing people, vehicles) rendered at
    128x96 with 1 sample by three cameras of three lens models, then exported."""
    folder = tmp_path_factory.mktemp("moving_car_park")
    for name in ("assets", "source"):
        shutil.copytree(CAR_PARK / name, folder / name)
    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    for stream in setup["openlabel"]["streams"].values():
        stream["stream_properties"]["usdscene"]["resolution_px"] = [128, 96]
    setup["openlabel"]["metadata"]["usdscene"]["render"].update(samples=1, denoise=False, max_bounces=1)
    (folder / "setup.json").write_text(json.dumps(setup))
    doc, out = folder / "doc.json", folder / "out"
    assert main(["generate", "tracks", "--setup", str(folder / "setup.json"), "-o", str(doc), "--frames", "8",
                 "--fps", "5", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "1"]) == 0
    assert main(["run", str(doc), "-o", str(out), "--cameras", *CAMERAS, "--export", "--no-progress"]) == 0
    assert main(["export", "mot", "multiview", str(out)]) == 0
    return out


def _mover_classes() -> set[str]:
    """The classes ``generate tracks`` draws movers from (no ``--person-classes`` or
    ``--vehicle-classes`` given): the code's own rule over the setup's catalog."""
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.generate.motion import person_classes, vehicle_classes
    from usdscene.scene.catalog import load_catalog

    scene = read_openlabel(CAR_PARK / "setup_moving.openlabel.json")
    catalog = load_catalog(scene.asset_paths, base_dir=CAR_PARK)
    return {*person_classes(catalog), *vehicle_classes(catalog)}


def _document(out: Path) -> dict:
    return json.loads((out / "annotations.openlabel.json").read_text())


def test_mot_layout_and_one_id_per_uid_in_every_camera(run):
    from usdscene.converters.exports.tracks import track_ids

    document = _document(run)
    tracks = json.loads((run / "exports" / "mot" / "tracks.json").read_text())
    assert tracks["ids"] == track_ids(document)
    objects = document["openlabel"]["objects"]
    movers = {uid for uid, o in objects.items() if o["type"] in _mover_classes()}
    assert set(tracks["ids"]) == movers and sorted(tracks["ids"].values()) == list(range(1, len(movers) + 1))
    seen_ids = set()
    for camera in CAMERAS:
        seq = run / "exports" / "mot" / camera
        info = (seq / "seqinfo.ini").read_text()
        assert "frameRate=5\n" in info and "seqLength=8\n" in info and "imWidth=128\n" in info
        assert sorted(p.name for p in (seq / "img1").iterdir()) == [f"{k:06d}.png" for k in range(1, 9)]
        rows = np.loadtxt(seq / "gt" / "gt.txt", delimiter=",", ndmin=2)
        assert rows.shape[1] == 9 and len(rows)
        # each row's id is the uid labelled with that box in the document
        by_id = {v: k for k, v in tracks["ids"].items()}
        for frame, ident, left, top, width, height, conf, cls, vis in rows:
            uid = by_id[int(ident)]
            labels = document["openlabel"]["frames"][str(int(frame) - 1)]["objects"][uid]["object_data"]["bbox"]
            # the amodal box, or the visible box where no amodal one is known (mot.py's rule)
            boxes = {b["name"]: b["val"] for b in labels}
            box = boxes.get(f"{camera}_amodal_bbox") or boxes[f"{camera}_bbox"]
            assert left == pytest.approx(box[0] - box[2] / 2 + 1.5) and width == pytest.approx(box[2])
            assert 0.0 <= vis <= 1.0 and conf == 1
            seen_ids.add(int(ident))
    assert len(seen_ids) >= 5


def test_coco_annotations_carry_the_same_track_ids(run):
    assert main(["export", "coco", str(run), "--document-classes"]) == 0
    coco = json.loads((run / "exports" / "coco" / "annotations.json").read_text())
    ids = json.loads((run / "exports" / "mot" / "tracks.json").read_text())["ids"]
    assert coco["annotations"] and all(a["track_id"] == ids[a["uid"]] for a in coco["annotations"])


def _mot_accumulator(gt: np.ndarray, hyp: np.ndarray):
    import motmetrics as mm

    acc = mm.MOTAccumulator(auto_id=False)
    for frame in np.unique(gt[:, 0]).astype(int):
        g, h = gt[gt[:, 0] == frame], hyp[hyp[:, 0] == frame]
        distances = mm.distances.iou_matrix(g[:, 2:6], h[:, 2:6], max_iou=0.5)
        acc.update(g[:, 1].astype(int), h[:, 1].astype(int), distances, frameid=int(frame))
    return acc


def test_motmetrics_scores_the_ground_truth_against_itself(run):
    import motmetrics as mm

    for camera in CAMERAS:
        path = run / "exports" / "mot" / camera / "gt" / "gt.txt"
        gt = mm.io.loadtxt(str(path), fmt="mot15-2D", min_confidence=1)
        acc = mm.utils.compare_to_groundtruth(gt, gt, "iou", distth=0.5)
        summary = mm.metrics.create().compute(acc, metrics=["mota", "idf1", "num_switches", "num_objects"])
        assert summary["num_objects"].iloc[0] > 0
        assert summary["mota"].iloc[0] == 1.0 and summary["idf1"].iloc[0] == 1.0
        assert summary["num_switches"].iloc[0] == 0


def test_two_ids_swapped_from_frame_k_give_two_switches(run):
    import motmetrics as mm

    camera = "entrance_wide"
    gt = np.loadtxt(run / "exports" / "mot" / camera / "gt" / "gt.txt", delimiter=",", ndmin=2)
    k = 4
    # two tracks present in frames k-1 and k whose boxes do not overlap (matching is by IoU)
    before, at = gt[gt[:, 0] == k - 1], gt[gt[:, 0] == k]
    both = sorted(set(before[:, 1].astype(int)) & set(at[:, 1].astype(int)))
    a, b = both[0], both[-1]
    hyp = gt.copy()
    late = hyp[:, 0] >= k
    ia, ib = late & (hyp[:, 1] == a), late & (hyp[:, 1] == b)
    hyp[ia, 1], hyp[ib, 1] = b, a
    summary = mm.metrics.create().compute(_mot_accumulator(gt, hyp),
                                          metrics=["num_switches", "mota", "idf1", "num_objects"])
    assert summary["num_switches"].iloc[0] == 2
    assert summary["mota"].iloc[0] == pytest.approx(1.0 - 2.0 / summary["num_objects"].iloc[0])
    assert summary["idf1"].iloc[0] < 1.0
    clean = mm.metrics.create().compute(_mot_accumulator(gt, gt), metrics=["num_switches"])
    assert clean["num_switches"].iloc[0] == 0


def test_position_ids_round_trip_exactly(run):
    from usdscene.converters.exports.multiview import GroundGrid

    info = json.loads((run / "exports" / "multiview" / "grid.json").read_text())
    g = info["grid"]
    grid = GroundGrid(tuple(g["origin_m"]), g["cell_m"], tuple(g["size"]))
    rng = np.random.default_rng(0)
    ids = np.concatenate([[0, grid.size[0] - 1, grid.size[0] * grid.size[1] - 1],
                          rng.integers(0, grid.size[0] * grid.size[1], 10000)])
    assert np.array_equal(grid.position_ids(grid.world(ids)), ids)
    wildtrack = GroundGrid((-3.0, -9.0), 0.025, (480, 1440))
    assert np.array_equal(wildtrack.position_ids(wildtrack.world(np.arange(480 * 1440))), np.arange(480 * 1440))
    assert np.allclose(wildtrack.world([481]), [[-2.975, -8.975]])
    assert wildtrack.position_ids([[100.0, 0.0]])[0] == -1


def test_every_position_projects_into_its_boxes_through_the_written_calibration(run):
    import cv2

    from usdscene.converters.exports.multiview import GroundGrid, ground_positions, project_with_calibration

    root = run / "exports" / "multiview"
    info = json.loads((root / "grid.json").read_text())
    g = info["grid"]
    grid = GroundGrid(tuple(g["origin_m"]), g["cell_m"], tuple(g["size"]))
    calib = {}
    for view in info["views"]:
        intr = cv2.FileStorage(str(root / view["intrinsic"]), cv2.FILE_STORAGE_READ)
        extr = cv2.FileStorage(str(root / view["extrinsic"]), cv2.FILE_STORAGE_READ)
        calib[view["viewNum"]] = (intr.getNode("distortion_model").string(), intr.getNode("camera_matrix").mat(),
                                  intr.getNode("distortion_coefficients").mat().reshape(-1),
                                  extr.getNode("rvec").mat().reshape(3), extr.getNode("tvec").mat().reshape(3),
                                  int(intr.getNode("image_width").real()), int(intr.getNode("image_height").real()))
    assert {c[0] for c in calib.values()} == {"pinhole", "fisheye"}
    truth = ground_positions(_document(run))
    ids = info["ids"]
    uid_of = {v: k for k, v in ids.items()}
    checked = 0
    for path in sorted((root / "annotations_positions").iterdir()):
        frame = int(path.stem)
        for person in json.loads(path.read_text()):
            uid = uid_of[person["personID"]]
            exact = truth[frame][uid]
            pid = person["positionID"]
            assert pid == grid.position_ids(exact[None, :2])[0] >= 0
            xy = grid.world([pid])[0]
            assert np.all(np.abs(xy - exact[:2]) <= grid.cell_m / 2 + 1e-9)
            point = np.array([[xy[0], xy[1], exact[2]]])  # the grid point at the person's ground height
            for view in person["views"]:
                # -1: not seen. Under 3 px wide or tall (a person 40 m away at 128x96) the pixels
                # whose centres a sub-pixel sliver covers say nothing about where its feet are.
                if view["xmin"] == -1 or min(view["xmax"] - view["xmin"], view["ymax"] - view["ymin"]) < 3:
                    continue
                model, K, D, rvec, tvec, width, height = calib[view["viewNum"]]
                u, v = project_with_calibration(model, K, D, rvec, tvec, point)[0]
                if not (-0.5 <= u < width - 0.5 and -0.5 <= v < height - 0.5):
                    continue  # feet outside the image (a truncated person)
                # The box holds the pixels whose centres the projection covers. A part at least a
                # pixel thick reaches at most one pixel beyond its edges, but a part thinner than
                # a pixel can fall between the pixel centres and be left out whole: legs (about
                # 0.1 m across, under a pixel at 128x96 beyond a few metres) end at the feet and
                # are up to half a body's length, as long as the rest of the body, which the box
                # holds (seed 1: feet 3.1 px beyond a 3 px box of pole_north, the legs missed).
                slack = 1.0 + max(view["xmax"] - view["xmin"], view["ymax"] - view["ymin"])
                assert view["xmin"] - slack <= u + 0.5 <= view["xmax"] + slack, (path.name, person, u)
                assert view["ymin"] - slack <= v + 0.5 <= view["ymax"] + slack, (path.name, person, v)
                checked += 1
    assert checked >= 15


def test_annotations_carry_time_and_ground_positions(run):
    body = _document(run)["openlabel"]
    assert body["metadata"]["usdscene"]["fps"] == 5.0
    for key, frame in body["frames"].items():
        assert frame["frame_properties"]["timestamp"] == pytest.approx(int(key) / 5.0)
    walker = next(uid for uid, o in body["objects"].items() if o["name"].startswith("walking_"))
    data = body["frames"]["3"]["objects"][walker]["object_data"]
    assert any(v["name"] == "ground_position_m" for v in data["vec"])
    assert any(b["name"].endswith("_bbox") for b in data.get("bbox", []))


def test_export_mot_without_tracks_is_one_error_and_writes_nothing(run, tmp_path, capsys):
    out = tmp_path / "still"
    shutil.copytree(run, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
    document = _document(out)
    del document["openlabel"]["metadata"]["usdscene"]["fps"]
    (out / "annotations.openlabel.json").write_text(json.dumps(document))
    assert main(["export", "mot", str(out)]) == 1
    err = capsys.readouterr().err
    assert "metadata.usdscene.fps" in err and err.count("error:") == 1
    assert not (out / "exports").exists()
    assert main(["export", "coco", "multiview", str(out)]) == 1
    assert not (out / "exports").exists()  # not even the COCO part


def test_mot_and_multiview_read_each_frame_once_for_every_camera(run, tmp_path):
    """With an index that holds two frames, MOT (three cameras) and multi-view each read every
    frame's labels once, and write the same bytes as with an index that holds every frame."""
    from usdscene.converters.exports.mot import MotClasses, export_mot
    from usdscene.converters.exports.multiview import export_multiview
    from usdscene.converters.openlabel.annotations import LabelIndex

    movers = _mover_classes()
    numbers = MotClasses(class_map={name: 1 for name in movers})
    written = {}
    for held in (2, 8):
        out = tmp_path / f"held_{held}"
        shutil.copytree(run, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
        document = _document(out)
        index = LabelIndex(document, max_frames=held)
        export_mot(document, out, mot_classes=numbers, index=index)
        assert index.frames_read == 8  # not 8 per camera
        export_multiview(document, out, index=index, classes=movers)
        assert index.frames_read == (16 if held == 2 else 8) and index.most_frames_held == held
        written[held] = {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted((out / "exports").rglob("*"))
                         if p.is_file() and not p.is_symlink() and p.suffix != ".png"}
    assert written[2] == written[8]
    assert sum(name.endswith("gt/gt.txt") for name in written[2]) == len(CAMERAS)
    assert all(len(rows) for name, rows in written[2].items() if name.endswith("gt/gt.txt"))


def test_projection_through_a_calibration_reads_strided_points():
    """The first three columns of homogeneous points (a strided view) project like a copy."""
    from usdscene.converters.exports.multiview import project_with_calibration

    K = np.array([[40.0, 0.0, 63.5], [0.0, 40.0, 47.5], [0.0, 0.0, 1.0]])
    rvec, tvec = np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.0, 5.0])
    homogeneous = np.c_[np.random.default_rng(0).normal(size=(50, 3)), np.ones(50)]
    for model, D in (("fisheye", np.array([0.01, -0.002, 0.0, 0.0])), ("pinhole", np.zeros(5))):
        packed = project_with_calibration(model, K, D, rvec, tvec, homogeneous[:, :3].copy())
        assert np.array_equal(project_with_calibration(model, K, D, rvec, tvec, homogeneous[:, :3]), packed)
