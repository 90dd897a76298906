"""The AI City Challenge export of a tiny rendered moving car park, read back by the rules of the
published readers (NVIDIA's ground-truth converter and calibration tools, the Metropolis
multi-camera tracker's calibrator, participants' loaders): field names, the required attributes,
one scale and translation for every camera, camera ids that match the ground truth, at most
5 m/s between frames; then the geometry: 3D locations project into their boxes, foot points
through the homography, cameras on the map; the videos decode to the rendered images."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from usdscene.cli import main

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"
CAMERAS = ("pole_north", "pole_east")
SENSOR_FIELDS = ("type", "id", "origin", "geoLocation", "coordinates", "scaleFactor",
                 "translationToGlobalCoordinates", "attributes", "place", "imageCoordinates", "globalCoordinates",
                 "intrinsicMatrix", "extrinsicMatrix", "cameraMatrix", "homography")
REQUIRED_ATTRIBUTES = ("fps", "direction", "direction3d", "frameWidth", "frameHeight")
OBJECT_FIELDS = ("object type", "object id", "object name", "3d location", "3d bounding box scale",
                 "3d bounding box rotation", "2d bounding box", "2d bounding box visible")


# --------------------------------------------------------------------------------------------
# Pure parts: the map frame, the speed rule, the streamed writer


def test_map_pixels_follow_the_published_rule():
    from usdscene.converters.exports.aicity import map_frame

    frame = map_frame((-20.0, -10.0, 20.0, 14.0), 0.05)
    assert (frame.width_px, frame.height_px) == (800, 480)
    assert frame.translation_m == (20.0, 10.0) and frame.scale_px_per_m == pytest.approx(20.0)
    # px = (x + tx) s, py = H - (y + ty) s: the map's corners and centre
    assert np.allclose(frame.pixels([[-20.0, -10.0], [20.0, 14.0], [0.0, 2.0]]), [[0, 480], [800, 0], [400, 240]])
    assert frame.bounds_m == pytest.approx((-20.0, -10.0, 20.0, 14.0))


def test_rotation_is_pitch_roll_yaw_of_z_y_x():
    from scipy.spatial.transform import Rotation

    from usdscene.converters.exports.aicity import pitch_roll_yaw

    r = Rotation.from_euler("ZYX", [0.7, -0.2, 0.1]).as_matrix()  # yaw, pitch, roll
    assert np.allclose(pitch_roll_yaw(r), [-0.2, 0.1, 0.7])


def _object(uid: str, x: float, frame_boxes=None):
    from usdscene.converters.exports.aicity import AicObject

    return AicObject(uid, int(uid), f"walker_{uid}", "Person", np.array([x, 0.0, 0.9]), np.array([0.5, 0.3, 1.8]),
                     np.zeros(3), np.array([x, 0.0, 0.0]), frame_boxes or {"Camera_0000": [1, 2, 11, 32]},
                     frame_boxes or {"Camera_0000": [1, 2, 11, 20]})


def test_streamed_ground_truth_and_its_twin(tmp_path):
    from usdscene.converters.exports.aicity import write_ground_truth

    frames = [(f, [_object("1", 0.1 * f), _object("2", -0.1 * f)]) for f in range(4)]
    counts = write_ground_truth(iter(frames), tmp_path, edition="2025", scene_id=7, fps=30.0,
                                camera_numbers={"Camera_0000": 0})
    assert counts == {"frames": 4, "objects": 8, "boxes": 8}
    gt = json.loads((tmp_path / "ground_truth.json").read_text())
    assert list(gt) == ["0", "1", "2", "3"]
    assert gt["2"][0]["3d location"] == pytest.approx([0.2, 0.0, 0.9])
    assert set(gt["2"][0]) == set(OBJECT_FIELDS)
    rows = [line.split() for line in (tmp_path / "track1.txt").read_text().splitlines()]
    assert rows[2] == ["7", "0", "1", "1", "0.1", "0", "0.9", "0.5", "0.3", "1.8", "0"]


def test_an_object_faster_than_5_m_s_is_named_with_its_frame(tmp_path):
    from usdscene.converters.exports.aicity import write_ground_truth
    from usdscene.errors import DocumentError

    frames = [(0, [_object("3", 0.0)]), (1, [_object("3", 0.1)]), (2, [_object("3", 0.4)])]  # 9 m/s at 30 fps
    with pytest.raises(DocumentError) as error:
        write_ground_truth(iter(frames), tmp_path, edition="2025", scene_id=0, fps=30.0,
                           camera_numbers={"Camera_0000": 0})
    problem = error.value.problems[0]
    assert "object 3" in problem.where and "frames 1 and 2" in problem.message and "9.00 m/s" in problem.message


def test_depth_maps_hold_one_png_per_frame(tmp_path):
    import h5py

    from usdscene.converters.exports.aicity import write_depth_h5

    pngs = []
    for f in range(3):
        depth = np.full((6, 8), 1000 * (f + 1), dtype=np.uint16)
        path = tmp_path / f"{f:06d}.png"
        cv2.imwrite(str(path), depth)
        pngs.append((f, path))
    assert write_depth_h5(tmp_path / "Camera_0000.h5", pngs) == 3
    with h5py.File(tmp_path / "Camera_0000.h5", "r") as h5:
        assert sorted(h5) == [f"distance_to_image_plane_{f:05d}.png" for f in range(3)]
        decoded = cv2.imdecode(np.asarray(h5["distance_to_image_plane_00002.png"]), cv2.IMREAD_UNCHANGED)
    assert decoded.dtype == np.uint16 and np.all(decoded == 3000)


@pytest.mark.parametrize("lens, distortion, expressible", [
    ("perspective", (), True), ("opencv_pinhole", (0.0, 0.0, 0.0, 0.0, 0.0), True),
    ("opencv_pinhole", (-0.2, 0.04, 0.0, 0.0, 0.0), False), ("fisheye_equidistant", (), False),
    ("opencv_fisheye", (0.0, 0.0, 0.0, 0.0), False), ("orthographic", (), False)])
def test_only_ideal_pinhole_lenses_are_expressible(lens, distortion, expressible):
    from usdscene.converters.exports.aicity import pinhole_problem
    from usdscene.document.model import Camera, Intrinsics, LensModel

    camera = Camera("c", Intrinsics(LensModel(lens), 64, 48, 40.0, 40.0, 31.5, 23.5, distortion=distortion))
    problem = pinhole_problem(camera)
    assert (problem is None) == expressible
    if not expressible:
        assert f"its {lens} lens cannot be written" in problem and "no distortion" in problem


def test_an_unknown_aic_class_is_refused():
    from usdscene.converters.exports.aicity import check_class_map
    from usdscene.errors import DocumentError

    with pytest.raises(DocumentError) as error:
        check_class_map({"person": "Person", "vehicle": "Car"})
    assert [p.where for p in error.value.problems] == ["--aic-class vehicle=Car"]


# --------------------------------------------------------------------------------------------
# A rendered run, exported and read back


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """8 frames at 5 fps of walkers and vehicles, two pinhole cameras at 128x96, 1 sample; the
    AIC export with a 0.25 m/px map."""
    folder = tmp_path_factory.mktemp("aicity_car_park")
    for name in ("assets", "source"):
        shutil.copytree(CAR_PARK / name, folder / name)
    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    for stream in setup["openlabel"]["streams"].values():
        stream["stream_properties"]["usdscene"]["resolution_px"] = [128, 96]
    setup["openlabel"]["metadata"]["usdscene"]["render"].update(samples=1, denoise=False, max_bounces=1,
                                                                depth="png16")
    (folder / "setup.json").write_text(json.dumps(setup))
    doc, out = folder / "doc.json", folder / "out"
    assert main(["generate", "tracks", "--setup", str(folder / "setup.json"), "-o", str(doc), "--frames", "8",
                 "--fps", "5", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "1"]) == 0
    assert main(["run", str(doc), "-o", str(out), "--cameras", *CAMERAS, "--no-progress"]) == 0
    assert main(["export", "aicity", str(out), "--map-m-per-px", "0.25", "--map-samples", "1"]) == 0
    return out


def _scene(out: Path) -> Path:
    return out / "exports" / "aicity" / "Scene_000"


def _attributes(sensor: dict) -> dict:
    return {a["name"]: a["value"] for a in sensor["attributes"]}


@pytest.mark.blender
def test_the_readers_rules_hold(run):
    scene = _scene(run)
    calibration = json.loads((scene / "calibration.json").read_text())
    assert {"version", "osmURL", "calibrationType", "sensors"} <= set(calibration)
    assert calibration["calibrationType"] == "cartesian"
    sensors = calibration["sensors"]
    assert [s["id"] for s in sensors] == [f"Camera_{k:04d}" for k in range(len(list((run / "images").iterdir())))]
    for sensor in sensors:
        assert set(SENSOR_FIELDS) <= set(sensor), set(SENSOR_FIELDS) - set(sensor)
        attributes = _attributes(sensor)
        assert all(name in attributes for name in REQUIRED_ATTRIBUTES)
        assert len(attributes["direction3d"].split(",")) == 3
        assert np.array(sensor["intrinsicMatrix"]).shape == (3, 3)
        assert np.array(sensor["extrinsicMatrix"]).shape == (3, 4)
        assert np.allclose(np.array(sensor["intrinsicMatrix"]) @ np.array(sensor["extrinsicMatrix"]),
                           sensor["cameraMatrix"])
        assert len(sensor["imageCoordinates"]) == len(sensor["globalCoordinates"]) >= 4
    # one map: the same scale and translation for every camera (the tracker's calibrator exits otherwise)
    assert len({s["scaleFactor"] for s in sensors}) == 1
    assert len({json.dumps(s["translationToGlobalCoordinates"], sort_keys=True) for s in sensors}) == 1
    fps = float(_attributes(sensors[0])["fps"])
    document = json.loads((run / "annotations.openlabel.json").read_text())["openlabel"]
    assert fps == document["metadata"]["usdscene"]["fps"]
    rendered = sorted(p.name for p in (run / "images").iterdir())
    frames = len(list((run / "images" / rendered[0]).glob("*.png")))
    gt = json.loads((scene / "ground_truth.json").read_text())
    assert list(gt) == [str(f) for f in range(frames)]
    ids = {s["id"] for s in sensors}
    last: dict[int, tuple[int, np.ndarray]] = {}
    seen_cameras, boxes = set(), 0
    for key, objects in gt.items():
        for obj in objects:
            assert set(OBJECT_FIELDS) <= set(obj)
            assert obj["object type"] == "Person"
            seen_cameras |= set(obj["2d bounding box"]) | set(obj["2d bounding box visible"])
            for camera, visible in obj["2d bounding box visible"].items():
                full = obj["2d bounding box"][camera]
                area = lambda b: max(b[2] - b[0], 0) * max(b[3] - b[1], 0)  # noqa: E731
                assert 0 < area(visible) <= area(full)
                boxes += 1
            here = np.array(obj["3d location"])
            if obj["object id"] in last:
                frame, there = last[obj["object id"]]
                assert np.linalg.norm(here - there) * fps / (int(key) - frame) <= 5.0
            last[obj["object id"]] = (int(key), here)
    assert seen_cameras <= ids and seen_cameras
    assert boxes >= 10
    twin = (scene / "track1.txt").read_text().splitlines()
    assert len(twin) == sum(len(v) for v in gt.values())
    mapping = json.loads((scene / "usdscene_aicity.json").read_text())
    assert [c["usdscene_camera"] for c in mapping["cameras"]] == rendered


@pytest.mark.blender
def test_locations_project_into_boxes_and_feet_through_the_homography(run):
    scene = _scene(run)
    sensors = {s["id"]: s for s in json.loads((scene / "calibration.json").read_text())["sensors"]}
    gt = json.loads((scene / "ground_truth.json").read_text())
    projected = feet = 0
    for objects in gt.values():
        for obj in objects:
            x, y, z = obj["3d location"]
            for camera, (x0, y0, x1, y1) in obj["2d bounding box"].items():
                P, H = np.array(sensors[camera]["cameraMatrix"]), np.array(sensors[camera]["homography"])
                u, v, w = P @ [x, y, z, 1.0]
                attributes = _attributes(sensors[camera])
                width, height = int(attributes["frameWidth"]), int(attributes["frameHeight"])
                if w <= 0 or not (-0.5 <= u / w < width - 0.5 and -0.5 <= v / w < height - 0.5):
                    continue  # a truncated object: its centre is outside the image, its box clipped to it
                # pixel centres at integers, box edges: pixel i covers [i, i + 1)
                assert x0 - 1 <= u / w + 0.5 <= x1 + 1 and y0 - 1 <= v / w + 0.5 <= y1 + 1, (camera, obj)
                projected += 1
                # the foot below the box centre, on the ground, through the homography (ground -> image)
                fu, fv, fw = P @ [x, y, 0.0, 1.0]
                g = np.linalg.solve(H, [fu / fw, fv / fw, 1.0])
                assert np.hypot(g[0] / g[2] - x, g[1] / g[2] - y) <= 0.05
                feet += 1
    assert projected >= 10 and feet == projected


@pytest.mark.blender
def test_cameras_and_people_lie_on_the_map(run):
    scene = _scene(run)
    sensors = json.loads((scene / "calibration.json").read_text())["sensors"]
    picture = cv2.imread(str(scene / "map.png"))
    height, width = picture.shape[:2]
    s = sensors[0]["scaleFactor"]
    t = sensors[0]["translationToGlobalCoordinates"]
    assert (width, height) == tuple(json.loads((scene / "usdscene_aicity.json").read_text())["map"]["size_px"])
    assert picture.std() > 5  # a render of the deck, not an empty picture

    def pixel(x, y):
        return (x + t["x"]) * s, height - (y + t["y"]) * s

    for sensor in sensors:
        px, py = pixel(sensor["coordinates"]["x"], sensor["coordinates"]["y"])
        assert 0 <= px < width and 0 <= py < height
    # The car park deck spans x -18..18, y -12..12 m (its catalog extent): every camera stands on it.
    from usdscene.scene.catalog import load_catalog

    deck = load_catalog(["assets"], base_dir=CAR_PARK)["car_park"]
    for sensor in sensors:
        x, y = sensor["coordinates"]["x"], sensor["coordinates"]["y"]
        assert deck.extent_min_m[0] - 1 <= x <= deck.extent_max_m[0] + 1
        assert deck.extent_min_m[1] - 1 <= y <= deck.extent_max_m[1] + 1
    for objects in json.loads((scene / "ground_truth.json").read_text()).values():
        for obj in objects:
            px, py = pixel(*obj["3d location"][:2])
            assert 0 <= px < width and 0 <= py < height


@pytest.mark.blender
def test_videos_hold_the_rendered_images_in_order(run):
    import av

    scene = _scene(run)
    mapping = json.loads((scene / "usdscene_aicity.json").read_text())
    for camera in mapping["cameras"]:
        rendered = [cv2.imread(str(p)) for p in sorted((run / "images" / camera["usdscene_camera"]).glob("*.png"))]
        with av.open(str(scene / "videos" / f"{camera['id']}.mp4")) as container:
            decoded = [f.to_ndarray(format="bgr24") for f in container.decode(video=0)]
        assert len(decoded) == len(rendered) == len(json.loads((scene / "ground_truth.json").read_text()))
        h, w = decoded[0].shape[:2]
        for k, frame in enumerate(decoded):
            errors = [np.abs(frame.astype(int) - r[:h, :w].astype(int)).mean() for r in rendered]
            assert int(np.argmin(errors)) == k and errors[k] < 8.0, (camera, k, errors)


@pytest.mark.blender
def test_depth_maps_hold_the_rendered_depth_of_every_frame(run):
    import h5py

    scene = _scene(run)
    for camera in json.loads((scene / "usdscene_aicity.json").read_text())["cameras"]:
        pngs = sorted((run / "depth" / camera["usdscene_camera"]).glob("*.png"))
        assert len(pngs) == 8
        with h5py.File(scene / "depth_maps" / f"{camera['id']}.h5", "r") as h5:
            assert sorted(h5) == [f"distance_to_image_plane_{k:05d}.png" for k in range(8)]
            for k, png in enumerate(pngs):
                decoded = cv2.imdecode(np.asarray(h5[f"distance_to_image_plane_{k:05d}.png"]), cv2.IMREAD_UNCHANGED)
                assert np.array_equal(decoded, cv2.imread(str(png), cv2.IMREAD_UNCHANGED))
                assert decoded.dtype == np.uint16 and decoded.max() > 0


@pytest.mark.blender
def test_edition_2024_layout(run, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(run, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
    assert main(["export", "aicity", str(out), "--edition", "2024", "--no-videos", "--aic-scene", "scene_001"]) == 0
    scene = out / "exports" / "aicity" / "scene_001"
    for k in range(2):
        calibration = json.loads((scene / f"camera_{k:04d}" / "calibration.json").read_text())
        assert np.array(calibration["camera projection matrix"]).shape == (3, 4)
        assert np.array(calibration["homography matrix"]).shape == (3, 3)
    rows = np.loadtxt(scene / "ground_truth.txt", ndmin=2)
    assert rows.shape[1] == 9 and set(rows[:, 0].astype(int)) <= {0, 1} and len(rows) >= 10
    assert np.all(rows[:, 5] > 0) and np.all(rows[:, 6] > 0)


def _copy(run: Path, tmp_path: Path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(run, out, symlinks=True, ignore=shutil.ignore_patterns("exports"))
    return out


def _edit(out: Path, change) -> None:
    path = out / "annotations.openlabel.json"
    document = json.loads(path.read_text())
    change(document["openlabel"])
    path.write_text(json.dumps(document))


@pytest.mark.blender
@pytest.mark.parametrize("case", ["still", "distorted", "class", "scene", "speed"])
def test_bad_input_is_one_line_and_writes_nothing(run, tmp_path, capsys, case):
    out = _copy(run, tmp_path)
    args = ["export", "aicity", str(out), "--no-map", "--no-videos"]
    if case == "still":
        _edit(out, lambda root: root["metadata"]["usdscene"].pop("fps"))
        expected = "metadata.usdscene.fps"
    elif case == "distorted":
        def distorted(root):  # the entrance camera's barrel distortion: AIC's schema has no distortion
            props = root["streams"]["pole_east"]["stream_properties"]
            props["intrinsics_pinhole"]["distortion_coeffs"] = [-0.2, 0.04, 0.0, 0.0, 0.0]
            props["usdscene"]["model"] = "opencv_pinhole"
        _edit(out, distorted)
        expected = "camera 'pole_east': its opencv_pinhole lens cannot be written"
    elif case == "class":
        args += ["--aic-class", "vehicle=Car"]
        expected = "--aic-class vehicle=Car"
    elif case == "scene":
        args += ["--aic-scene", "../elsewhere"]
        expected = "--aic-scene"
    else:
        def jump(root):
            frame = root["frames"]["4"]["objects"]
            uid = next(u for u, e in frame.items() if root["objects"][u]["name"].startswith("walking_"))
            data = frame[uid]["object_data"]
            for item in data["vec"]:
                if item["name"] == "pose_matrix4x4":
                    item["val"][3] += 10.0  # 10 m in 0.2 s
            for item in data.get("cuboid", []):
                if item["name"] == "box3d":
                    item["val"][0] += 10.0
        _edit(out, jump)
        expected = "frames 3 and 4"
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and expected in err, err
    assert "Traceback" not in err
    assert not (out / "exports").exists() or not any((out / "exports").rglob("*"))
