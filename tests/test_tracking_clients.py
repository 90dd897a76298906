"""The 2D tracking exports read by the clients the field scores with, on exact labels of a moving
car park at 640x480 without a render: TrackEval (HOTA, CLEAR, Identity) on the MOT export, an
MVDet-style reader on both multi-view flavours, pycocotools' keypoint evaluation on COCO.

The labels are computed as the annotate step computes them (amodal projections and keypoints of
the composed stage's posed meshes through each camera) on instance masks painted from those
projections far to near: the amodal boxes, which the exports write, are exact; only the visible
pixels are the painter's (no renderer is needed for what these clients read)."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from usdscene.cli import main

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"
CAMERAS = ("pole_east", "pole_north")  # the car park's two perspective (pinhole) cameras
W, H = 640, 480
FIXED_NAME = "waiting_at_the_barrier"


def _label_without_render(doc_path: Path, out: Path) -> None:
    """Compose the stage of ``doc_path`` and write ``out/annotations.openlabel.json`` with exact
    amodal boxes and keypoints (see the module docstring), plus placeholder images."""
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.converters.openlabel.annotations import add_annotations, image_records
    from usdscene.document import output_layout as layout
    from usdscene.labels.amodal import amodal_projections
    from usdscene.labels.cross_camera import camera_for_image
    from usdscene.labels.image_labels import label_image, label_images
    from usdscene.labels.projection import project_points
    from usdscene.pipeline import compose_document
    from usdscene.scene.stage_geometry import StageGeometry

    scene, result = compose_document(doc_path, out / layout.STAGE_DIR)
    geometry = StageGeometry(result.root_layer)
    tracked = [o for o in scene.objects]
    ids = {k + 1: o.uid for k, o in enumerate(tracked)}
    classes = {o.uid: o.class_name for o in tracked}
    images = []
    for frame in range(scene.frame_start, scene.frame_end + 1):
        triangles = geometry.triangles(frame, set(ids.values()))
        people = geometry.keypoints(frame, set(ids.values()))
        for base in scene.cameras:
            camera = camera_for_image(base, frame, W, H)
            amodal = {u: a for u, a in amodal_projections(camera, triangles, frame).items() if a.pixel_count}
            eye = camera.pose_at(frame).as_array()[:3, 3]
            far_to_near = sorted(amodal, key=lambda u: -np.linalg.norm(triangles[u].reshape(-1, 3).mean(0) - eye))
            mask = np.zeros((H, W), np.uint16)
            number = {u: k for k, u in ids.items()}
            for uid in far_to_near:
                mask[amodal[uid].mask] = number[uid]
            keypoints = {}
            if people:
                uv, valid = project_points(camera, np.concatenate(list(people.values())), frame)
                starts = np.cumsum([0] + [len(p) for p in people.values()])
                keypoints = {u: (uv[a:b], valid[a:b]) for u, a, b in zip(people, starts[:-1], starts[1:])}
            images.append(label_image(mask, ids, amodal, classes=classes, camera=base.name, frame=frame,
                                      keypoints=keypoints))
    source = json.loads(doc_path.read_text())
    document = add_annotations(source, scene, label_images(images), out)
    (out / layout.ANNOTATIONS_FILE).write_text(json.dumps(document))
    for record in image_records(document):
        path = out / record["uri"]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"png")  # the exports link images; no client here opens them


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """6 frames at 5 fps of walkers, a standing person, vehicles and a person fixed in the
    document, seen by the car park's two perspective cameras at 640x480."""
    folder = tmp_path_factory.mktemp("tracking_car_park")
    for name in ("assets", "source"):
        shutil.copytree(CAR_PARK / name, folder / name)
    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    streams = setup["openlabel"]["streams"]
    for name in list(streams):
        if name not in CAMERAS:
            del streams[name]
        else:
            streams[name]["stream_properties"]["usdscene"]["resolution_px"] = [W, H]
    (folder / "setup.json").write_text(json.dumps(setup))
    doc = folder / "doc.json"
    assert main(["generate", "tracks", "--setup", str(folder / "setup.json"), "-o", str(doc), "--frames", "6",
                 "--fps", "5", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "3"]) == 0
    document = json.loads(doc.read_text())
    objects = document["openlabel"]["objects"]
    walker = next(o for o in objects.values() if o["name"].startswith("walking_"))
    # a person standing as a fixed object of the document, with an explicit pose (no ground_position_m)
    uid = str(max(int(u) for u in objects) + 1)
    objects[uid] = {"name": FIXED_NAME, "type": walker["type"],
                    "frame_intervals": [{"frame_start": 0, "frame_end": 5}],
                    "object_data": {"vec": [{"name": "position_m", "val": [0.0, -2.0, 0.0]},
                                            {"name": "rotation_xyz_deg", "val": [0.0, 0.0, 30.0]}]}}
    doc.write_text(json.dumps(document))
    out = folder / "out"
    _label_without_render(doc, out)
    return out


def _document(out: Path) -> dict:
    return json.loads((out / "annotations.openlabel.json").read_text())


# ------------------------------------------------------------------------------------------
# MOT through TrackEval


def _trackeval(gt_folder: Path, trackers: Path, benchmark: str = "MOT17") -> dict:
    import trackeval

    config = trackeval.datasets.MotChallenge2DBox.get_default_dataset_config()
    config.update(GT_FOLDER=str(gt_folder), TRACKERS_FOLDER=str(trackers), BENCHMARK=benchmark,
                  SPLIT_TO_EVAL="train", TRACKERS_TO_EVAL=["gt"], PRINT_CONFIG=False)
    eval_config = trackeval.Evaluator.get_default_eval_config()
    eval_config.update(USE_PARALLEL=False, PRINT_RESULTS=False, PRINT_CONFIG=False, OUTPUT_SUMMARY=False,
                       OUTPUT_DETAILED=False, PLOT_CURVES=False, TIME_PROGRESS=False, DISPLAY_LESS_PROGRESS=True)
    metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR(), trackeval.metrics.Identity()]
    results, messages = trackeval.Evaluator(eval_config).evaluate(
        [trackeval.datasets.MotChallenge2DBox(config)], metrics)
    combined = results["MotChallenge2DBox"]["gt"]["COMBINED_SEQ"]["pedestrian"]
    return {"HOTA": float(np.mean(combined["HOTA"]["HOTA"])), "MOTA": float(combined["CLEAR"]["MOTA"]),
            "IDF1": float(combined["Identity"]["IDF1"]), "IDSW": int(combined["CLEAR"]["IDSW"]),
            "GT": int(combined["CLEAR"]["CLR_TP"] + combined["CLEAR"]["CLR_FN"])}


def _tracker_from_gt(mot: Path, trackers: Path, benchmark: str, swap: tuple[int, int, int] | None = None) -> None:
    """A tracker's output from the ground truth: its people's rows in MOTChallenge's tracker
    format; ``swap = (a, b, k)`` exchanges ids a and b from MOT frame k on in the first sequence."""
    data = trackers / f"{benchmark}-train" / "gt" / "data"
    data.mkdir(parents=True)
    for seq in sorted((mot / f"{benchmark}-train").iterdir()):
        gt = np.loadtxt(seq / "gt" / "gt.txt", delimiter=",", ndmin=2)
        rows = gt[np.isin(gt[:, 7], (1, 7))].copy()
        if swap is not None and seq.name.endswith("-01"):
            a, b, k = swap
            late = rows[:, 0] >= k
            ia, ib = late & (rows[:, 1] == a), late & (rows[:, 1] == b)
            rows[ia, 1], rows[ib, 1] = b, a
        lines = [f"{int(r[0])},{int(r[1])},{r[2]:.4f},{r[3]:.4f},{r[4]:.4f},{r[5]:.4f},1,-1,-1,-1" for r in rows]
        (data / f"{seq.name}.txt").write_text("".join(f"{line}\n" for line in lines))


def test_trackeval_scores_the_ground_truth_against_itself_one(labelled, tmp_path):
    assert main(["export", "mot", str(labelled), "--mot-layout", "mot17"]) == 0
    mot = labelled / "exports" / "mot"
    tracks = json.loads((mot / "tracks.json").read_text())
    assert tracks["sequences"] == {"MOT17-train/MOT17-01": "pole_east", "MOT17-train/MOT17-02": "pole_north"}
    assert (mot / "seqmaps" / "MOT17-train.txt").read_text() == "name\nMOT17-01\nMOT17-02\n"
    info = (mot / "MOT17-train" / "MOT17-01" / "seqinfo.ini").read_text()
    for line in ("[Sequence]", "name=MOT17-01", "imDir=img1", "frameRate=5", "seqLength=6", f"imWidth={W}",
                 f"imHeight={H}", "imExt=.png"):
        assert line in info.splitlines()
    classes = set()
    for seq in ("MOT17-01", "MOT17-02"):
        gt = np.loadtxt(mot / "MOT17-train" / seq / "gt" / "gt.txt", delimiter=",", ndmin=2)
        classes |= set(gt[:, 7].astype(int))
    assert classes == {1, 3}  # people 1, vehicles 3: MOTChallenge's numbers
    _tracker_from_gt(mot, tmp_path / "trackers", "MOT17")
    scores = _trackeval(mot, tmp_path / "trackers")
    assert scores["GT"] > 20
    assert scores["HOTA"] == pytest.approx(1.0) and scores["MOTA"] == 1.0 and scores["IDF1"] == 1.0


def test_trackeval_idf1_drops_when_two_ids_are_swapped(labelled, tmp_path):
    assert main(["export", "mot", str(labelled), "--mot-layout", "mot20"]) == 0
    mot = labelled / "exports" / "mot"
    gt = np.loadtxt(mot / "MOT20-train" / "MOT20-01" / "gt" / "gt.txt", delimiter=",", ndmin=2)
    people = gt[gt[:, 7] == 1]
    k = 3
    both = sorted(set(people[people[:, 0] == k - 1, 1].astype(int)) & set(people[people[:, 0] == k, 1].astype(int)))
    assert len(both) >= 2
    _tracker_from_gt(mot, tmp_path / "clean", "MOT20")
    _tracker_from_gt(mot, tmp_path / "swapped", "MOT20", swap=(both[0], both[-1], k))
    clean, swapped = _trackeval(mot, tmp_path / "clean", "MOT20"), _trackeval(mot, tmp_path / "swapped", "MOT20")
    assert clean["IDF1"] == 1.0 and clean["IDSW"] == 0
    assert swapped["IDF1"] < clean["IDF1"] and swapped["IDSW"] == 2 and swapped["HOTA"] < clean["HOTA"]


def test_mot_options_static_people_ignore_and_mapping(labelled):
    from usdscene.converters.exports.mot import still_objects

    document = _document(labelled)
    objects = document["openlabel"]["objects"]
    still = still_objects(document)
    standing = {u for u, o in objects.items() if o["name"].startswith("standing_") or o["name"] == FIXED_NAME}
    assert standing and standing <= still
    vehicle = next(o["type"] for o in objects.values() if o["name"].startswith(("arriving_", "leaving_")))
    assert main(["export", "mot", str(labelled), "--mot-static-people", "--mot-ignore-occluded",
                 "--mot-class", f"{vehicle}=none"]) == 0
    mot = labelled / "exports" / "mot"
    tracks = json.loads((mot / "tracks.json").read_text())
    assert vehicle not in tracks["classes"]
    ids = tracks["ids"]
    for camera in CAMERAS:
        gt = np.loadtxt(mot / camera / "gt" / "gt.txt", delimiter=",", ndmin=2)
        assert set(gt[:, 7].astype(int)) <= {1, 7}
        for row in gt:
            uid = next(u for u, i in ids.items() if i == int(row[1]))
            assert int(row[7]) == (7 if uid in still else 1)
            assert int(row[6]) == (0 if row[8] == 0 else 1)  # conf 0: no visible pixel


def test_mot_class_mapping_of_an_unknown_class_is_one_error_and_writes_nothing(labelled, tmp_path, capsys):
    out = tmp_path / "copy"
    shutil.copytree(labelled, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
    assert main(["export", "coco", "mot", str(out), "--mot-class", "unicycle=4"]) == 1
    err = capsys.readouterr().err
    assert err.count("error") == 1 and "--mot-class" in err and "'unicycle'" in err and "Traceback" not in err
    assert not (out / "exports").exists()
    assert main(["export", "mot", str(out), "--mot-class", f"{_document(out)['openlabel']['objects']['5']['type']}=42"]) == 1
    assert "'42'" in capsys.readouterr().err and not (out / "exports").exists()


# ------------------------------------------------------------------------------------------
# Multi-view through an MVDet-style reader


class MvdetStyleReader:
    """A multi-view dataset read by MVDet's published rules (its ``Wildtrack`` and ``MultiviewX``
    dataset classes and ``frameDataset``): camera index = last digit of the ``Image_subsets/``
    folder - 1, calibrations opened by fixed names, intrinsics = ``camera_matrix`` only
    (``cv2.FileStorage``), WILDTRACK extrinsics as ElementTree text split on spaces and
    MultiviewX extrinsics with ``cv2.FileStorage``, frame = int(file name before the dot),
    position id → grid → world by the dataset's ``worldgrid2worldcoord_mat``. The numbers a
    user would type into such a class come from ``dataset.json``."""

    def __init__(self, root: Path):
        import cv2

        self.root = root
        numbers = json.loads((root / "dataset.json").read_text())
        self.flavour, self.num_cam = numbers["flavour"], numbers["num_cam"]
        self.img_shape, self.worldgrid_shape = numbers["img_shape"], numbers["worldgrid_shape"]
        self.nx = numbers["grid_size_xy"][0]
        self.indexing = numbers["indexing"]
        self.mat = np.array(numbers["worldgrid2worldcoord_mat"])
        self.unit_m = numbers["unit_m"]
        name = "CVLab" if self.flavour == "wildtrack" else "Camera"
        intrinsic = "intrinsic_zero" if self.flavour == "wildtrack" else "intrinsic"
        self.K, self.Rt = [], []
        for cam in range(self.num_cam):
            fs = cv2.FileStorage(str(root / "calibrations" / intrinsic / f"intr_{name}{cam + 1}.xml"),
                                 cv2.FILE_STORAGE_READ)
            self.K.append(fs.getNode("camera_matrix").mat())
            fs.release()
            path = root / "calibrations" / "extrinsic" / f"extr_{name}{cam + 1}.xml"
            if self.flavour == "wildtrack":
                tree = ET.parse(path).getroot()
                rvec = np.array([float(v) for v in tree.findall("rvec")[0].text.strip().split(" ")])
                tvec = np.array([float(v) for v in tree.findall("tvec")[0].text.strip().split(" ")])
            else:
                fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
                rvec, tvec = fs.getNode("rvec").mat().squeeze(), fs.getNode("tvec").mat().squeeze()
                fs.release()
            rotation, _ = cv2.Rodrigues(rvec)
            self.Rt.append(np.hstack([rotation, tvec.reshape(3, 1)]))
        self.images = {cam: {} for cam in range(self.num_cam)}
        for folder in sorted((root / "Image_subsets").iterdir()):
            cam = int(folder.name[-1]) - 1
            for image in sorted(folder.iterdir()):
                self.images[cam][int(image.name.split(".")[0])] = image
        self.frames = {}
        for path in sorted((root / "annotations_positions").iterdir()):
            self.frames[int(path.name.split(".")[0])] = json.loads(path.read_text())

    def world(self, position_id: int) -> np.ndarray:
        """World (x, y) in the dataset's unit of a position id (MVDet's rules)."""
        grid_x, grid_y = position_id % self.nx, position_id // self.nx
        # ij: (row, col) = (grid_x, grid_y); xy: (row, col) = (grid_y, grid_x)
        row_col = (grid_x, grid_y) if self.indexing == "ij" else (grid_y, grid_x)
        return (self.mat @ np.array([*row_col, 1.0]))[:2]

    def project(self, cam: int, xy: np.ndarray, z: float = 0.0) -> np.ndarray:
        """Image point of a ground point (MVDet's ``get_imagecoord_from_worldcoord``: z = 0)."""
        p = self.K[cam] @ self.Rt[cam] @ np.array([xy[0], xy[1], z, 1.0])
        return p[:2] / p[2]


def test_an_mvdet_style_reader_loads_both_flavours_and_ground_points_lie_in_the_boxes(labelled):
    from usdscene.converters.exports.tracks import ground_positions

    document = _document(labelled)
    objects = document["openlabel"]["objects"]
    heights = {(frame, uid): float(p[2]) for frame, by_uid in ground_positions(document).items()
               for uid, p in by_uid.items()}
    results = {}
    for flavour in ("wildtrack", "multiviewx"):
        assert main(["export", "multiview", str(labelled), "--multiview-flavour", flavour]) == 0
        root = labelled / "exports" / "multiview"
        reader = MvdetStyleReader(root)
        info = json.loads((root / "grid.json").read_text())
        uid_of = {v: k for k, v in info["ids"].items()}
        first = info["first_frame"]
        assert reader.num_cam == 2 and reader.img_shape == [H, W]
        assert sorted(reader.frames) == list(range(6)) and all(sorted(v) == list(range(6)) for v in reader.images.values())
        assert [v["camera"] for v in info["views"]] == list(CAMERAS)
        fixed = next(u for u, o in objects.items() if o["name"] == FIXED_NAME)
        assert info["fixed"] == [fixed]
        inside = raised = checked = 0
        people = set()
        for frame, persons in reader.frames.items():
            for person in persons:
                uid = uid_of[person["personID"]]
                people.add(uid)
                xy = reader.world(person["positionID"])
                for view in person["views"]:
                    if view["xmin"] == -1:
                        continue
                    u, v = reader.project(view["viewNum"], xy)
                    if not (0 <= u < W and 0 <= v < H) or min(view["xmax"] - view["xmin"], view["ymax"] - view["ymin"]) < 3:
                        continue  # the feet outside the image (a truncated person), or a sliver
                    # A person's box holds its feet: the grid point (within half a cell) in the
                    # box's pixel edges. The box holds the pixels whose centres the projection
                    # covers: a pixel of slack for that, and a tenth of the box's height more for
                    # feet and ankles under a pixel thick (9 cm a pixel for a person 20 px tall),
                    # which can fall between the pixel centres and be left out of the box.
                    slack = 1.0 + max(1.0, 0.1 * (view["ymax"] - view["ymin"]))
                    def in_box(u, v):
                        return (view["xmin"] - slack <= u + 0.5 <= view["xmax"] + slack
                                and view["ymin"] - slack <= v + 0.5 <= view["ymax"] + slack)

                    checked += 1
                    if in_box(u, v):
                        inside += 1
                        continue
                    # The only misses allowed: people standing above z = 0 (on the 15 cm kerb),
                    # whose ground point a 2D grid puts at z = 0, below their feet in the image;
                    # at their height the same grid point lies in the box.
                    height = heights.get((frame + first, uid), 0.0)
                    assert height > 0.01, (flavour, frame, objects[uid]["name"], view, u, v)
                    assert in_box(*reader.project(view["viewNum"], xy, height / reader.unit_m)), (flavour, frame, uid, view["ymin"], view["ymax"], (u, v), reader.project(view["viewNum"], xy, height / reader.unit_m), objects[uid]["name"])
                    raised += 1
        assert fixed in people and checked >= 50 and inside > raised
        results[flavour] = (inside, raised, checked)
    # both flavours describe the same positions and boxes: the same counts
    assert results["wildtrack"] == results["multiviewx"], results


def test_wildtrack_extrinsics_are_centimetres_of_the_same_camera(labelled):
    import cv2

    assert main(["export", "multiview", str(labelled), "--multiview-flavour", "multiviewx"]) == 0
    storage = cv2.FileStorage(str(labelled / "exports/multiview/calibrations/extrinsic/extr_Camera1.xml"),
                              cv2.FILE_STORAGE_READ)
    metres = storage.getNode("tvec").mat().reshape(3)
    storage.release()
    assert main(["export", "multiview", str(labelled), "--multiview-flavour", "wildtrack"]) == 0
    tree = ET.parse(labelled / "exports/multiview/calibrations/extrinsic/extr_CVLab1.xml").getroot()
    centimetres = np.array([float(v) for v in tree.findall("tvec")[0].text.split(" ")])
    assert np.allclose(centimetres, 100.0 * metres)
    numbers = json.loads((labelled / "exports/multiview/dataset.json").read_text())
    assert numbers["cell_size"] == pytest.approx(2.5) and numbers["indexing"] == "ij"


def test_a_flavour_asked_for_more_cameras_than_it_names_is_one_error(labelled, tmp_path, capsys):
    out = tmp_path / "ten"
    shutil.copytree(labelled, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
    document = _document(out)
    root = document["openlabel"]
    base = CAMERAS[0]
    for k in range(8):  # 2 + 8 = 10 labelled cameras
        name = f"copy_{k}"
        root["streams"][name] = json.loads(json.dumps(root["streams"][base]))
        for key in list(root.get("coordinate_systems", {}) or {}):
            if key == base:
                root["coordinate_systems"][name] = json.loads(json.dumps(root["coordinate_systems"][key]))
                root["coordinate_systems"][name]["children"] = []
        for frame in root["frames"].values():
            streams = frame["frame_properties"]["streams"]
            streams[name] = json.loads(json.dumps(streams[base]))
    (out / "annotations.openlabel.json").write_text(json.dumps(document))
    assert main(["export", "multiview", str(out), "--multiview-flavour", "multiviewx"]) == 1
    err = capsys.readouterr().err
    assert err.count("error") == 1 and "--multiview-flavour" in err and "10 views" in err and "last digit" in err
    assert not (out / "exports").exists()


# ------------------------------------------------------------------------------------------
# COCO keypoints


def test_cocoeval_keypoints_runs_with_defaults(labelled, tmp_path):
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    assert main(["export", "coco", str(labelled)]) == 0
    path = labelled / "exports" / "coco" / "annotations.json"
    data = json.loads(path.read_text())
    assert all("num_keypoints" in a and len(a["keypoints"]) == 51 for a in data["annotations"])
    people = [a for a in data["annotations"] if a["num_keypoints"] > 0]
    assert people and any(a["num_keypoints"] == 0 for a in data["annotations"])
    gt = COCO(str(path))
    detections = [dict(a, score=1.0) for a in data["annotations"]]
    evaluation = COCOeval(gt, gt.loadRes(detections), "keypoints")
    evaluation.evaluate()
    evaluation.accumulate()
    evaluation.summarize()
    assert evaluation.stats[0] == pytest.approx(1.0)


def test_the_report_shows_the_exports_track_ids(labelled):
    from usdscene.converters.exports.tracks import track_ids
    from usdscene.dataset.report import _images_from_document, _page_entry

    document = _document(labelled)
    ids = track_ids(document)
    images = _images_from_document(labelled, labelled / "annotations.openlabel.json")
    classes = {c: k for k, c in enumerate(sorted({o["class"] for im in images for o in im["objects"]}))}
    entries = [o for im in images for o in _page_entry(im, classes)["o"]]
    assert entries and all(o["id"] == ids[o["u"]] for o in entries)
    assert any(o["id"] != int(o["u"]) for o in entries)  # uids are not the ids


# ------------------------------------------------------------------------------------------
# Pieces without a scene


def test_class_mapping_reads_numbers_names_and_none_and_names_the_bad_value():
    from usdscene.converters.exports.mot import MotClasses, parse_class_map
    from usdscene.errors import OutputError

    known = {"person", "van", "bicycle", "bench"}
    mapping = parse_class_map(["bicycle=4", "bench=Occluder", "van=none"], known)
    assert mapping == {"bicycle": 4, "bench": 9, "van": None}
    classes = MotClasses(people=("person",), vehicles=("van",), class_map=mapping, static_people=True)
    assert [classes.number(c, False) for c in ("person", "van", "bicycle", "bench", "cone")] == [1, None, 4, 9, None]
    assert classes.number("person", True) == 7 and MotClasses(people=("person",)).number("person", True) == 1
    for item, words in (("unicycle=4", ("unknown class 'unicycle'",)), ("bicycle=14", ("'14'", "1..13")),
                        ("bicycle", ("CLASS=NUMBER",)), ("bicycle=wheelchair", ("'wheelchair'",))):
        with pytest.raises(OutputError) as error:
            parse_class_map([item], known)
        text = str(error.value)
        assert "--mot-class" in text and all(w in text for w in words), text


def test_the_equisolid_fisheye_goes_through_the_writers_opencv_fisheye_fit():
    import cv2

    from usdscene.converters.exports.multiview import equisolid_fit_error_px, opencv_calibration
    from usdscene.converters.openlabel import EQUISOLID_KB_COEFFS
    from usdscene.document.model import Camera, Intrinsics, LensModel
    from usdscene.labels.projection import project_camera_points

    errors = {}
    for fov in (120.0, 180.0):
        intr = Intrinsics(LensModel.FISHEYE_EQUISOLID, 640, 480, 160.0, 160.0, 319.5, 239.5, fov_deg=fov)
        camera = Camera("fish", intr)
        model, K, D = opencv_calibration(camera)
        assert model == "fisheye" and np.array_equal(D, EQUISOLID_KB_COEFFS)
        theta = np.radians(np.linspace(0.0, fov / 2, 200))
        points = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
        ours = project_camera_points(intr, points)[0]
        theirs, _ = cv2.fisheye.projectPoints(points.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
        measured = float(np.abs(ours - theirs.reshape(-1, 2)).max())
        errors[fov] = equisolid_fit_error_px(camera)
        assert measured <= errors[fov] + 1e-6  # the stated accuracy holds
    assert errors[120.0] < errors[180.0] < 1e-3  # f = 160 px: a thousandth of a pixel even at 180 degrees


def test_unknown_flavour_is_named():
    from usdscene.converters.exports.multiview import flavour_of
    from usdscene.errors import OutputError

    with pytest.raises(OutputError, match="--multiview-flavour.*'mvdet'"):
        flavour_of("mvdet")
