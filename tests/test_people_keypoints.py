"""People keypoints end to end: a tiny rendered run with every lens model, standing, walking and
seated people from the shipped family, one of them half hidden by a suitcase.

- keypoints flagged 2 fall on the person's own mask pixels (within 1 px), those flagged 1 do
  not, those flagged 0 are outside the image or behind the camera;
- the OpenLABEL document carries them as named ``point2d`` and validates;
- pycocotools loads the COCO export's ``keypoints`` / ``num_keypoints`` and the person
  categories' keypoint names and skeleton.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.document import model as m
from usdscene.labels.keypoints import COCO_KEYPOINTS, COCO_SKELETON

pytestmark = [pytest.mark.usd, pytest.mark.blender]

W, H = 96, 72


def _intrinsics(lens: m.LensModel, f: float, distortion=(), fov_deg=None) -> m.Intrinsics:
    return m.Intrinsics(lens=lens, width_px=W, height_px=H, fx_px=f, fy_px=f, cx_px=(W - 1) / 2,
                        cy_px=(H - 1) / 2, distortion=tuple(distortion), fov_deg=fov_deg, sensor_width_mm=6.4)


LENSES = {
    "persp": _intrinsics(m.LensModel.PERSPECTIVE, 70.0),
    "brown": _intrinsics(m.LensModel.OPENCV_PINHOLE, 70.0, (-0.22, 0.05, 0.001, -0.0015, -0.004)),
    "equidistant": _intrinsics(m.LensModel.FISHEYE_EQUIDISTANT, 30.0, fov_deg=170.0),
    "equisolid": _intrinsics(m.LensModel.FISHEYE_EQUISOLID, 31.0, fov_deg=170.0),
    "kannala": _intrinsics(m.LensModel.OPENCV_FISHEYE, 30.0, (0.03, -0.01, 0.002, -0.0005)),
    "vcd_kannala": _intrinsics(m.LensModel.KANNALA, 30.0, (-0.02, 0.003, -0.0002, 0.00001)),
    "radial_poly": _intrinsics(m.LensModel.RADIAL_POLY, 30.0, (0.03, -0.02, 0.002), fov_deg=180.0),
    "ortho": _intrinsics(m.LensModel.ORTHOGRAPHIC, 28.0),
}


def _look_at(eye, target) -> m.Pose:
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return m.Pose.from_rotation_translation(np.stack([x, np.cross(z, x), z], axis=1), eye)


def _yaw(x: float, y: float, z: float, deg: float) -> m.Pose:
    a = np.radians(deg)
    rot = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return m.Pose.from_rotation_translation(rot, [x, y, z])


def _scene() -> m.SceneSpec:
    # The people stand along world X around the origin, facing the cameras at -Y.
    eye, target = (0.3, -3.2, 1.4), (0.0, 0.0, 0.9)
    cameras = tuple(m.Camera(name, intr, pose=_look_at(eye, target)) for name, intr in LENSES.items())
    objects = (
        m.SceneObject("1", "walker", "person", pose=_yaw(-0.8, 0.0, 0.0, 0.0), pose_variant="walk_2",
                      appearance="m_35_192_average_tone1"),
        m.SceneObject("2", "phone", "person", pose=_yaw(0.0, 0.3, 0.0, 30.0), pose_variant="phone",
                      appearance="f_57_175_average_tone2"),
        m.SceneObject("3", "sitter", "passenger", pose=_yaw(0.8, 0.0, 0.45, 0.0), pose_variant="reading",
                      appearance="f_41_150_average_tone5"),
        # Hides the walker's legs from the cameras.
        m.SceneObject("4", "case", "trolley_suitcase", pose=_yaw(-0.8, -0.9, 0.0, 0.0)),
    )
    lights = (m.Light("10", "sun", m.LightKind("sun"), pose=_look_at((2.0, -3.0, 4.0), (0.0, 0.0, 0.0)),
                      power_w=4.0),)
    return m.SceneSpec(name="people", seed=5, frame_start=0, frame_end=0, cameras=cameras, objects=objects,
                       lights=lights, render=m.RenderSettings(samples=1, denoise=False))


@pytest.fixture(scope="module")
def output(tmp_path_factory):
    from usdscene.cli import main
    from usdscene.converters.openlabel import write_openlabel

    root = tmp_path_factory.mktemp("people")
    doc = root / "people.openlabel.json"
    doc.write_text(json.dumps(write_openlabel(_scene())))
    out = root / "out"
    assert main(["render", str(doc), "-o", str(out), "--no-progress"]) == 0
    assert main(["annotate", str(out), "--no-progress"]) == 0
    assert main(["export", "coco", str(out)]) == 0
    return out


def _keypoints_by_camera(document: dict) -> dict[str, dict[str, np.ndarray]]:
    """camera → uid → (17, 3) from the OpenLABEL document's point2d."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for uid, entry in document["openlabel"]["frames"]["0"]["objects"].items():
        for item in entry.get("object_data", {}).get("point2d", []):
            camera, name = item["name"].split("_kp_")
            v = item["attributes"]["num"][0]["val"]
            rows = out.setdefault(camera, {}).setdefault(uid, np.zeros((17, 3)))
            rows[COCO_KEYPOINTS.index(name)] = (*item["val"], v)
    return out


def test_flags_agree_with_the_masks_on_every_lens(output):
    import cv2

    from usdscene.document import output_layout as layout

    document = json.loads((output / "annotations.openlabel.json").read_text())
    ids = {v["uid"]: int(k) for k, v in json.loads((output / layout.ID_MAP_FILE).read_text()).items()}
    by_camera = _keypoints_by_camera(document)
    assert set(by_camera) == set(LENSES)
    totals = np.zeros(3, dtype=int)
    for camera, people in by_camera.items():
        mask = cv2.imread(str(layout.mask_path(output, camera, 0)), cv2.IMREAD_UNCHANGED)
        assert set(people) <= {"1", "2", "3"}, camera  # the suitcase has no keypoints
        assert len(people) >= 2, camera
        for uid, rows in people.items():
            for x, y, v in rows:
                if v == 0:
                    assert x == 0 and y == 0
                    continue
                col, row = int(np.floor(x + 0.5)), int(np.floor(y + 0.5))
                assert 0 <= col < W and 0 <= row < H, (camera, uid)
                near = mask[max(row - 1, 0):row + 2, max(col - 1, 0):col + 2]
                assert (ids[uid] in near) == (v == 2), (camera, uid, x, y, v)
            totals += np.bincount(rows[:, 2].astype(int), minlength=3)
    # Seen, hidden (legs behind the suitcase, the far side of bodies) and outside all occur.
    assert totals[2] > 100 and totals[1] > 5, totals


def test_openlabel_document_validates_with_keypoints(output, openlabel_schema_path):
    import jsonschema

    document = json.loads((output / "annotations.openlabel.json").read_text())
    jsonschema.validate(document, json.loads(openlabel_schema_path.read_text()))
    assert any("point2d" in e.get("object_data", {})
               for e in document["openlabel"]["frames"]["0"]["objects"].values())


def test_pycocotools_loads_the_keypoints(output):
    from pycocotools.coco import COCO

    path = output / "exports" / "coco" / "annotations.json"
    coco = COCO(str(path))
    people = [c for c in coco.loadCats(coco.getCatIds()) if "keypoints" in c]
    assert {c["name"] for c in people} == {"person", "passenger"}
    for c in people:
        assert c["keypoints"] == list(COCO_KEYPOINTS) and c["skeleton"] == [list(p) for p in COCO_SKELETON]
    anns = coco.loadAnns(coco.getAnnIds(catIds=[c["id"] for c in people]))
    assert len(anns) >= 2 * len(LENSES) - 2
    for ann in anns:
        kp = np.asarray(ann["keypoints"]).reshape(17, 3)
        assert ann["num_keypoints"] == int((kp[:, 2] > 0).sum())
        x, y, w, h = ann["bbox"]
        seen = kp[kp[:, 2] == 2]
        # COCO convention: visible keypoints lie in (or within a pixel of) the visible box.
        assert np.all((seen[:, 0] >= x - 1.5) & (seen[:, 0] <= x + w + 1.5)), ann["id"]
        assert np.all((seen[:, 1] >= y - 1.5) & (seen[:, 1] <= y + h + 1.5)), ann["id"]
    suitcase = coco.loadAnns(coco.getAnnIds(catIds=coco.getCatIds(catNms=["trolley_suitcase"])))
    # objects without keypoints: num_keypoints 0 and zero triples (COCOeval's defaults read them)
    assert suitcase and all(a["num_keypoints"] == 0 and a["keypoints"] == [0] * 51 for a in suitcase)
    assert "keypoints" not in coco.loadCats(coco.getCatIds(catNms=["trolley_suitcase"]))[0]


def test_visibility_flags_on_a_synthetic_mask():
    """Pure: flags from a mask built in the test (no render)."""
    from usdscene.labels.keypoints import keypoint_visibility

    mask = np.zeros((10, 12), dtype=np.uint16)
    mask[2:6, 3:7] = 5          # the person
    mask[6:9, 3:7] = 9          # something else below it
    uv = np.array([[4.0, 3.0],   # on its own pixel → 2
                   [7.4, 3.0],   # one pixel right of it (x 7 px) → within 1 px → 2
                   [4.0, 7.6],   # on the other object, 2 rows below → 1
                   [-0.6, 3.0],  # left of the image → 0
                   [11.4, 9.4],  # last pixel, background → 1
                   [4.0, 3.0]])  # behind the camera → 0
    valid = np.array([True, True, True, True, True, False])
    flags = keypoint_visibility(uv, valid, mask, 5)
    assert flags[:, 2].tolist() == [2, 2, 1, 0, 1, 0]
    assert flags[3, :2].tolist() == [0, 0] and flags[5, :2].tolist() == [0, 0]
    assert flags[0, :2].tolist() == [4.0, 3.0]
    # Two people flagged in one call, an id per keypoint: as if each were flagged alone.
    both = keypoint_visibility(np.concatenate([uv, uv]), np.concatenate([valid, valid]), mask,
                               np.repeat([5, 9], len(uv)))
    assert np.array_equal(both[:len(uv)], flags)
    assert np.array_equal(both[len(uv):], keypoint_visibility(uv, valid, mask, 9))
    assert both[len(uv) + 2, 2] == 2  # on the other object's pixels: seen for that one
