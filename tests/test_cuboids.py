"""3D boxes: the upright box around each object's posed geometry, its OpenLABEL form, and its
projection containing the object's amodal box through every lens model."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel
from usdscene.labels.cuboids import Cuboid, document_cuboids, fit_cuboid, frame_cuboids, object_yaw

CAR_PARK = Path(__file__).resolve().parents[1] / "examples" / "car_park"


def _box_triangles(size, yaw, centre) -> np.ndarray:
    return Cuboid(tuple(centre), tuple(size), yaw).triangles()


def test_fit_recovers_a_turned_box_and_its_yaw():
    tris = _box_triangles((0.6, 4.2, 1.5), 0.7, (3.0, -2.0, 0.75))
    box = fit_cuboid(tris, 0.7)
    assert box.size_m == pytest.approx((0.6, 4.2, 1.5), abs=1e-12)
    assert box.center_m == pytest.approx((3.0, -2.0, 0.75), abs=1e-12)
    # a box fitted at another yaw is larger: the size is measured along the object's axes
    assert np.prod(fit_cuboid(tris, 0.0).size_m) > np.prod(box.size_m) * 1.5


def test_box_triangles_face_outwards_and_cover_the_corners():
    box = Cuboid((1.0, 2.0, 3.0), (2.0, 3.0, 4.0), -2.0)
    tris = box.triangles()
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    outwards = tris.mean(axis=1) - np.asarray(box.center_m)
    assert np.all(np.einsum("ij,ij->i", normals, outwards) > 0)
    assert {tuple(np.round(p, 9)) for p in tris.reshape(-1, 3)} == {tuple(np.round(p, 9)) for p in box.corners()}


def test_yaw_from_the_object_matrix_and_the_openlabel_round_trip():
    c, s = math.cos(2.5), math.sin(2.5)
    rz = np.array([[c, s, 0, 0], [-s, c, 0, 0], [0, 0, 1, 0], [5, 6, 0, 1]], dtype=float)  # USD row vectors
    assert object_yaw(rz) == pytest.approx(2.5)
    # x pointing straight up (a lying object): the yaw comes from its y axis
    up = np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]], dtype=float)
    assert object_yaw(up) == pytest.approx(0.0)
    box = Cuboid((1.0, -2.0, 0.9), (0.5, 0.4, 1.8), -3.0)
    val = box.openlabel_val()
    assert len(val) == 10 and val[3:5] == [0.0, 0.0] and math.hypot(val[5], val[6]) == pytest.approx(1.0)
    back = Cuboid.from_openlabel_val(val)
    assert back.center_m == box.center_m and back.size_m == box.size_m
    assert back.yaw_rad == pytest.approx(box.yaw_rad, abs=1e-12)
    with pytest.raises(ValueError):
        Cuboid.from_openlabel_val(val[:9])
    tris = {"a": _box_triangles((1, 1, 1), 0.0, (0, 0, 0)), "b": np.zeros((0, 3, 3))}
    assert set(frame_cuboids(tris, {"a": np.eye(4), "b": np.eye(4)})) == {"a"}


def test_document_cuboids_reads_every_frame_in_one_pass():
    box = Cuboid((1.0, 2.0, 0.5), (1.0, 2.0, 1.0), 0.25)
    doc = {"openlabel": {"frames": {
        "3": {"objects": {"7": {"object_data": {"cuboid": [{"name": "box3d", "val": box.openlabel_val()}]}}}},
        "1": {"objects": {"7": {"object_data": {"bbox": []}}}}}}}
    read = document_cuboids(doc)
    assert list(read) == [3] and read[3]["7"].yaw_rad == pytest.approx(0.25)


# ------------------------------------------------------------------------------------------
# On the moving car park: every lens model


def _lens_variants(camera: Camera) -> list[Camera]:
    """The camera with each lens model of the project at its pose and image size."""
    i = camera.intrinsics
    w, h, cx, cy = i.width_px, i.height_px, (i.width_px - 1) / 2, (i.height_px - 1) / 2
    f = i.fx_px
    wide = 0.3 * w  # fisheye focal length that fits ~160° into the image
    lenses = [
        (LensModel.PERSPECTIVE, f, (), None),
        (LensModel.ORTHOGRAPHIC, w / 30.0, (), None),  # 30 m across
        (LensModel.OPENCV_PINHOLE, f, (-0.25, 0.05, 0.001, -0.001, 0.0), None),
        (LensModel.FISHEYE_EQUIDISTANT, wide, (), 170.0),
        (LensModel.FISHEYE_EQUISOLID, wide, (), 170.0),
        (LensModel.OPENCV_FISHEYE, wide, (0.05, -0.01, 0.002, 0.0), 170.0),
        (LensModel.KANNALA, wide, (0.04, -0.008, 0.001, 0.0), 170.0),
        (LensModel.RADIAL_POLY, wide, (0.02, -0.01, 0.001), 170.0),
    ]
    return [dataclasses.replace(camera, name=f"{camera.name}_{lens.value}",
                                intrinsics=Intrinsics(lens, w, h, fx, fx, cx, cy, distortion, fov))
            for lens, fx, distortion, fov in lenses]


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    """The moving car park (4 frames, walkers, a standing person, vehicles) composed."""
    from usdscene.cli import main
    from usdscene.pipeline import compose_document

    folder = tmp_path_factory.mktemp("cuboid_car_park")
    for name in ("assets", "source"):
        shutil.copytree(CAR_PARK / name, folder / name)
    shutil.copy(CAR_PARK / "setup_moving.openlabel.json", folder / "setup.json")
    doc = folder / "doc.json"
    assert main(["generate", "tracks", "--setup", str(folder / "setup.json"), "-o", str(doc), "--frames", "12",
                 "--fps", "2", "--people", "6", "--standing", "1", "--vehicles", "2", "--seed", "3"]) == 0
    scene, _ = compose_document(doc, folder / "stage")
    return scene, folder / "stage" / "scene.usda"


@pytest.mark.usd
def test_box_projection_contains_the_amodal_box_on_every_lens_model(stage):
    from usdscene.labels.amodal import amodal_projection, amodal_projections
    from usdscene.scene.stage_geometry import StageGeometry

    scene, stage_path = stage
    geometry = StageGeometry(stage_path)
    movers = {o.uid for o in scene.objects if o.frame_poses}
    assert movers
    checked, classes, worst = 0, set(), 0
    cameras = [c for base in scene.cameras for c in _lens_variants(base)]
    for frame in (0, 5, 11):
        triangles = geometry.triangles(frame)
        boxes = frame_cuboids(triangles, geometry.transforms(frame))
        assert movers & set(boxes)
        for camera in cameras:
            amodal = amodal_projections(camera, triangles, frame)
            for uid, projection in amodal.items():
                inner = projection.box
                if inner is None:
                    continue
                outer = amodal_projection(camera, boxes[uid].triangles(), frame).box
                assert outer is not None, (camera.name, uid)
                miss = max(outer.x_min - inner.x_min, outer.y_min - inner.y_min,
                           inner.x_max - outer.x_max, inner.y_max - outer.y_max)
                assert miss <= 2, (frame, camera.name, uid, inner, outer)
                worst = max(worst, miss)
                checked += 1
                classes.add(next(o.class_name for o in scene.objects if o.uid == uid) if uid in movers else "")
    lenses = {c.intrinsics.lens for c in cameras}
    assert lenses == set(LensModel) and checked > 100 and len(classes) >= 3


def test_a_striding_body_keeps_its_box_centred_on_its_origin():
    """A walker's leg swung forward grows its box, not moves it: the box is centred on the
    object's origin (inside its footprint), so its centre moves with the track (the tight box's
    centre jumped 0.17 m in a frame at 30 fps, 5 m/s, which the AI City export refuses)."""
    yaw, origin = 0.4, np.array([2.0, -1.0, 0.0])
    c, s = math.cos(yaw), math.sin(yaw)
    pose = np.array([[c, s, 0, 0], [-s, c, 0, 0], [0, 0, 1, 0], [*origin, 1]], dtype=float)  # USD row vectors
    body = _box_triangles((0.4, 0.25, 1.7), 0.0, (0.0, 0.0, 0.85))
    centres = []
    for stride in (0.0, 0.35, -0.2):
        leg = _box_triangles((0.12, 0.12, 0.8), 0.0, (0.1, stride, 0.4))  # along the body's y
        local = np.concatenate([body, leg]).reshape(-1, 3)
        world = (local @ pose[:3, :3] + pose[3, :3]).reshape(-1, 3, 3)
        box = frame_cuboids({"w": world}, {"w": pose})["w"]
        tight = fit_cuboid(world, object_yaw(pose))
        assert box.center_m[:2] == pytest.approx(tuple(origin[:2]), abs=1e-12)
        assert box.center_m[2] == pytest.approx(tight.center_m[2]) and box.size_m[2] == pytest.approx(tight.size_m[2])
        # it holds every point: in the box's axes, within half its size of its centre
        inside = (world.reshape(-1, 3) - np.asarray(box.center_m)) @ box.rotation()
        assert np.all(np.abs(inside) <= np.asarray(box.size_m) / 2 + 1e-12)
        centres.append(tight.center_m[:2])
    assert max(np.linalg.norm(np.subtract(a, centres[0])) for a in centres) > 0.1  # the tight box moved
    # an origin outside the footprint (a model placed off its origin) keeps the tight box
    far = pose.copy()
    far[3, :3] = [10.0, 10.0, 0.0]
    assert frame_cuboids({"w": world}, {"w": far})["w"] == fit_cuboid(world, object_yaw(far))
