"""3D ground truth of a rendered moving car park: box3d cuboids in the annotated document and in
COCO, depth images checked against ray casts of the meshes the mask names, and the H.264
video export decoded by PyAV and compared with the PNGs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from usdscene.cli import main
from usdscene.document.model import LensModel

pytestmark = pytest.mark.blender

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"
# perspective (native), equidistant fisheye (native panoramic: Cycles' Z is the ray length) and
# OpenCV pinhole (rendered wider and remapped) of the car park, and the other five lens models
# added at the poses of two of them: every lens model of the project.
CAMERAS = ("pole_north", "ceiling_fisheye", "entrance_wide", "pole_ortho", "ceiling_equisolid",
           "ceiling_opencv_fisheye", "ceiling_kannala", "ceiling_radial_poly")
ADDED_LENSES = {  # name → (camera whose pose it takes, its lens)
    "pole_ortho": ("pole_north", {"model": "orthographic", "ortho_width_m": 30.0}),
    "ceiling_equisolid": ("ceiling_fisheye", {"model": "fisheye_equisolid", "focal_length_mm": 1.2}),
    "ceiling_opencv_fisheye": ("ceiling_fisheye", {"model": "opencv_fisheye", "focal_length_mm": 1.4,
                                                   "distortion": [0.05, -0.01, 0.002, 0.0]}),
    "ceiling_kannala": ("ceiling_fisheye", {"model": "kannala", "focal_length_mm": 1.4,
                                            "distortion": [0.04, -0.008, 0.001, 0.0]}),
    "ceiling_radial_poly": ("ceiling_fisheye", {"model": "radial_poly", "focal_length_mm": 1.4,
                                                "distortion": [0.02, -0.01, 0.001]}),
}
FRAMES = 4
VIDEO_PSNR_DB = 30.0


def _setup(folder: Path, depth) -> Path:
    for name in ("assets", "source"):
        if not (folder / name).exists():
            shutil.copytree(CAR_PARK / name, folder / name)
    setup = json.loads((CAR_PARK / "setup_moving.openlabel.json").read_text())
    streams = setup["openlabel"]["streams"]
    for name, (base, lens) in ADDED_LENSES.items():
        block = {key: value for key, value in streams[base]["stream_properties"]["usdscene"].items()
                 if key in ("sensor", "sensor_size_mm", "position_m", "target_m")}
        if lens["model"] != "orthographic":
            block["fov_deg"] = 170.0
        streams[name] = {"type": "camera", "description": f"{lens['model']} at the pose of {base}",
                         "stream_properties": {"usdscene": {**block, **lens}}}
    for stream in streams.values():
        stream["stream_properties"]["usdscene"]["resolution_px"] = [160, 120]
    render = setup["openlabel"]["metadata"]["usdscene"]["render"]
    render.update(samples=1, denoise=False, max_bounces=1, depth=depth)
    path = folder / f"setup_{depth}.json"
    path.write_text(json.dumps(setup))
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """4 frames at 5 fps (walkers, a standing person, vehicles), eight cameras of the eight lens
    models at 160x120, 1 sample, depth as EXR; annotated; COCO and video exported."""
    folder = tmp_path_factory.mktemp("gt3d_car_park")
    setup = _setup(folder, "exr")
    doc, out = folder / "doc.json", folder / "out"
    assert main(["generate", "tracks", "--setup", str(setup), "-o", str(doc), "--frames", str(FRAMES),
                 "--fps", "5", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "1"]) == 0
    assert main(["run", str(doc), "-o", str(out), "--cameras", *CAMERAS, "--no-progress"]) == 0
    assert main(["export", "coco", "video", str(out), "--document-classes"]) == 0
    return doc, out


def _document(out: Path) -> dict:
    return json.loads((out / "annotations.openlabel.json").read_text())


def test_every_object_of_every_labelled_frame_has_a_schema_valid_box3d(run):
    import jsonschema

    from usdscene.labels.cuboids import CUBOID_NAME, document_cuboids
    from usdscene.validation import resolve_schema

    _, out = run
    document = _document(out)
    schema = json.loads(Path(resolve_schema("default")).read_text())
    jsonschema.validate(document, schema)  # the official schema accepts the 10-value cuboids
    boxes = document_cuboids(document)
    assert sorted(boxes) == list(range(FRAMES))
    objects = document["openlabel"]["objects"]
    movers = [uid for uid, o in objects.items() if o["type"] not in ("light", "place")
              and all(uid in boxes[f] for f in range(FRAMES))]
    assert len(movers) >= 9  # 6 walkers, 1 standing, 2 vehicles
    for uid in movers:
        pointer = objects[uid]["object_data_pointers"][CUBOID_NAME]
        assert pointer["type"] == "cuboid"
    for frame, per_object in boxes.items():
        for uid, box in per_object.items():
            item = next(c for c in document["openlabel"]["frames"][str(frame)]["objects"][uid]["object_data"]["cuboid"]
                        if c["name"] == CUBOID_NAME)
            assert item["coordinate_system"] == "world" and len(item["val"]) == 10
            assert all(s > 0 for s in box.size_m)
    # the size is along the object's own axes: a vehicle (facing -Y) is longer than wide and
    # than high, whichever way it drives
    vehicles = [uid for uid in movers if objects[uid]["type"] == "vehicle"]
    assert vehicles
    for uid in vehicles:
        for frame in range(FRAMES):
            width, length, height = boxes[frame][uid].size_m
            assert length > 1.5 * width and length > height, (uid, frame, boxes[frame][uid])


def test_boxes_of_the_document_contain_its_amodal_boxes_and_coco_carries_them(run):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.labels.amodal import amodal_projection
    from usdscene.labels.cross_camera import camera_for_image
    from usdscene.labels.cuboids import document_cuboids
    from usdscene.labels.pixel_box import PixelBox

    _, out = run
    document = _document(out)
    boxes = document_cuboids(document)
    scene = read_openlabel(out / "annotations.openlabel.json")
    cameras = {c.name: c for c in scene.cameras}
    checked = 0
    for frame, per_object in boxes.items():
        for uid, entry in document["openlabel"]["frames"][str(frame)]["objects"].items():
            for item in entry.get("object_data", {}).get("bbox", []):
                if not item["name"].endswith("_amodal_bbox") or uid not in per_object:
                    continue
                camera = camera_for_image(cameras[item["name"][:-len("_amodal_bbox")]], frame, 160, 120)
                inner = PixelBox.from_center_size(item["val"])
                outer = amodal_projection(camera, per_object[uid].triangles(), frame).box
                assert outer is not None
                assert max(outer.x_min - inner.x_min, outer.y_min - inner.y_min,
                           inner.x_max - outer.x_max, inner.y_max - outer.y_max) <= 2, (frame, item["name"], uid)
                checked += 1
    assert checked >= 20
    coco = json.loads((out / "exports" / "coco" / "annotations.json").read_text())
    assert coco["annotations"]
    images = {i["id"]: i for i in coco["images"]}
    for annotation in coco["annotations"]:
        frame = images[annotation["image_id"]]["frame"]
        assert annotation["box3d"] == pytest.approx(boxes[frame][annotation["uid"]].openlabel_val())


def _source_pixels(camera) -> tuple:
    """``(intrinsics rendered, (H, W) int index of the rendered pixel each output pixel takes)``:
    the output's own pixels for a lens Blender renders, else the nearest pixel of the remap, found
    with the worker's maps and ``cv2.remap`` of an index image (-1: none)."""
    import cv2

    from usdscene.labels.projection import remap_grids, undistorted_render_intrinsics

    intrinsics = camera.intrinsics
    render = undistorted_render_intrinsics(intrinsics)
    index = np.arange(render.height_px * render.width_px, dtype=np.float32).reshape(render.height_px, -1)
    if render == intrinsics:
        return render, index.astype(np.int64)
    map_x, map_y = remap_grids(intrinsics, render)
    taken = cv2.remap(index, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
    return render, taken.astype(np.int64)


def _mesh_depths(render, pose: np.ndarray, mesh, uv: np.ndarray) -> np.ndarray:
    """(N,) image-plane distance (metres) of the first hit of each pixel position's ray of
    ``render`` on ``mesh`` (an :class:`~usdscene.design.occluders.Occluders`); inf: no hit."""
    from usdscene.labels.projection import pixel_rays

    rays, valid = pixel_rays(render, uv)
    assert valid.all()
    origins = np.zeros_like(rays)
    if LensModel(render.lens) is LensModel.ORTHOGRAPHIC:  # parallel rays off the image plane
        origins[:, 0] = (uv[:, 0] - render.cx_px) / render.fx_px
        origins[:, 1] = (uv[:, 1] - render.cy_px) / render.fy_px
    t = mesh.first_hit(origins @ pose[:3, :3].T + pose[:3, 3], rays @ pose[:3, :3].T)
    return np.where(np.isfinite(t), origins[:, 2] + t * rays[:, 2], np.inf)


# How far (pixels of the render) the reference ray may lie from the pixel's centre ray. Cycles'
# ray and this test's, or Blender's triangles and the stage's, differ by a few hundredths of a
# pixel (the 0.01 px pixel filter, float32 in Blender's camera, or a quad split along its other
# diagonal): where the ray crosses a step of the surface (a car's edge) or a silhouette, that
# moves the hit. 7 of 8,274 object pixels needed it when measured.
RAY_SLACK_PX = 0.05


def test_depth_is_the_image_plane_distance_of_the_mesh_the_mask_names(run):
    """Every object pixel of the mask, on every lens model: its depth is the image-plane distance
    of the mesh point, of the object the mask names, on the ray the mask pixel was rendered
    through, within 1 %. That ray is the pixel's own centre ray, and for a remapped lens the
    centre ray of the native pixel that the mask and the depth both take; where the centre ray
    does not agree, a ray within :data:`RAY_SLACK_PX` of it must (a handful of pixels)."""
    import cv2

    from usdscene.design.occluders import Occluders
    from usdscene.render.depth import read_depth
    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.scene.stage_geometry import StageGeometry

    _, out = run
    stage = out / "stage" / "scene.usda"
    cameras = {c.name: c for c in read_stage_plan(stage).cameras}
    assert {cameras[name].intrinsics.lens for name in CAMERAS} == set(LensModel)
    geometry = StageGeometry(stage)
    ids = {int(k): v["uid"] for k, v in json.loads((out / "masks" / "ids.json").read_text()).items()}
    slack = np.array([(du, dv) for du in (-RAY_SLACK_PX, 0, RAY_SLACK_PX)
                      for dv in (-RAY_SLACK_PX, 0, RAY_SLACK_PX) if du or dv])
    report = []  # per camera: object pixels, those the centre ray misses or disagrees on, errors
    for name in CAMERAS:
        camera = cameras[name]
        render, taken = _source_pixels(camera)
        pixels = off_centre = errors = 0
        for frame in range(FRAMES):
            depth = read_depth(out / "depth" / name / f"{frame:06d}.exr")
            mask = cv2.imread(str(out / "masks" / name / f"{frame:06d}.png"), cv2.IMREAD_UNCHANGED)
            assert depth.shape == mask.shape == (120, 160) and depth.dtype == np.float32
            # every pixel the mask gives an object has a depth
            assert np.all(depth[mask > 0] > 0)
            pose = camera.pose_at(frame).as_array()
            triangles = geometry.triangles(frame)
            for mask_id in np.unique(mask[mask > 0]):
                vs, us = np.nonzero(mask == mask_id)
                source = taken[vs, us]
                assert np.all(source >= 0), (name, frame)
                uv = np.stack([source % render.width_px, source // render.width_px], 1).astype(float)
                mesh = Occluders(np.asarray(triangles[ids[int(mask_id)]]))
                values = depth[vs, us].astype(np.float64)
                error = np.abs(values - _mesh_depths(render, pose, mesh, uv)) / values
                for k in np.nonzero(~(error < 0.01))[0]:
                    off_centre += 1
                    near = _mesh_depths(render, pose, mesh, uv[k] + slack)
                    error[k] = np.min(np.abs(values[k] - near) / values[k])
                pixels += len(error)
                errors += int(np.sum(~(error < 0.01)))
        report.append((name, pixels, off_centre, errors))
    assert all(pixels > 100 for _, pixels, _, _ in report), report
    # the slack is for a few pixels on edges, not a blur
    assert all(off_centre <= 0.005 * pixels for _, pixels, off_centre, _ in report), report
    assert all(errors == 0 for *_, errors in report), report


def test_depth_resumes_like_the_masks_and_renders_the_same_bytes(run):
    doc, out = run
    path = out / "depth" / "ceiling_fisheye" / "000002.exr"
    before = path.read_bytes()
    path.unlink()
    assert main(["run", str(doc), "-o", str(out), "--cameras", *CAMERAS, "--no-progress"]) == 0
    assert path.read_bytes() == before


def test_png16_depth_is_millimetres(tmp_path):
    from usdscene.render.depth import encode_depth, read_depth

    depth = np.array([[0.0, 1.2344, 12.3456], [65.5, 70.0, 0.0006]], np.float32)
    path = tmp_path / "d.png"
    path.write_bytes(encode_depth(depth, "png16"))
    back = read_depth(path)
    np.testing.assert_allclose(back, [[0.0, 1.234, 12.346], [65.5, 65.535, 0.001]], atol=1e-6)
    exr = tmp_path / "d.exr"
    exr.write_bytes(encode_depth(depth, "exr"))
    assert np.array_equal(read_depth(exr), depth)


def test_an_unknown_depth_format_is_one_line_and_writes_nothing(tmp_path, capsys):
    setup = _setup(tmp_path, "tiff")
    out = tmp_path / "out"
    assert main(["run", str(setup), "-o", str(out), "--no-progress"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(err) == 1 and "metadata.usdscene.render.depth" in err[0] and "'tiff'" in err[0]
    assert not out.exists()


def test_the_video_decodes_to_the_frames_and_matches_the_pngs(run):
    import av
    import cv2

    _, out = run
    index = json.loads((out / "exports" / "video" / "videos.json").read_text())
    assert index["fps"] == 5 and set(index["cameras"]) == set(CAMERAS)
    worst = np.inf
    for name in CAMERAS:
        with av.open(str(out / "exports" / "video" / f"{name}.mp4")) as container:
            stream = container.streams.video[0]
            assert stream.codec_context.name == "h264" and stream.average_rate == 5
            frames = [f.to_ndarray(format="bgr24") for f in container.decode(stream)]
        assert len(frames) == FRAMES == len(index["cameras"][name]["frames"])
        for k, decoded in enumerate(frames):
            png = cv2.imread(str(out / "images" / name / f"{k:06d}.png"), cv2.IMREAD_COLOR)
            assert decoded.shape == png.shape
            worst = min(worst, cv2.PSNR(png, decoded))
    assert worst >= VIDEO_PSNR_DB, worst


def test_video_of_a_still_document_is_one_line_and_writes_nothing(run, tmp_path, capsys):
    _, out = run
    document = _document(out)
    del document["openlabel"]["metadata"]["usdscene"]["fps"]
    still = tmp_path / "still"
    still.mkdir()
    (still / "annotations.openlabel.json").write_text(json.dumps(document))
    assert main(["export", "video", str(still), "--document-classes"]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(err) == 1 and "metadata.usdscene.fps" in err[0] and "video" in err[0]
    assert not (still / "exports").exists()
