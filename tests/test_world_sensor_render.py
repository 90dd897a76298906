"""World and sensor through the real renderer (Blender Cycles at 64x48, 2 samples) on the
shipped car park example: noise, compression and IR change the image and not the mask; IR
images are one channel; a physical sky is not black; an HDRI lights the background; what validate accepts
renders. And a document without world and sensor renders the bytes it rendered before they
existed (the minimal example without its passenger, against golden images)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout

pytestmark = [pytest.mark.usd, pytest.mark.blender]

REPO = Path(__file__).resolve().parents[1]
CAR_PARK = REPO / "examples" / "car_park"
GOLDEN = Path(__file__).resolve().parent / "golden" / "render_minimal_plain"


def car_park_document(*, world=None, sensors=None, cameras=("pole_north",), sun_power=True) -> dict:
    """The shipped car park document at 64x48, 2 samples, frame 0; ``sensors``: camera name → sensor block
    (a camera of that name that is not in the setup is a copy of pole_north)."""
    doc = json.loads((CAR_PARK / "car_park.openlabel.json").read_text())
    body = doc["openlabel"]
    # the setup's friendly cameras (the generated document holds them calibrated at 640x480)
    body["streams"] = json.loads((CAR_PARK / "setup.openlabel.json").read_text())["openlabel"]["streams"]
    del body["coordinate_systems"]
    block = body["metadata"]["usdscene"]
    block["asset_paths"] = [str(CAR_PARK / "assets")]
    block["render"] = {"samples": 2, "denoise": False, "max_bounces": 2, "resolution_px": [64, 48]}
    block["frame_range"] = {"frame_start": 0, "frame_end": 0}
    block.pop("exports", None)
    block.pop("world", None)  # the example's sky
    if world is not None:
        block["world"] = world
    streams = {}
    for name in cameras:
        stream = copy.deepcopy(body["streams"].get(name, body["streams"]["pole_north"]))
        stream["stream_properties"]["usdscene"]["resolution_px"] = [64, 48]
        stream["stream_properties"]["usdscene"].pop("sensor", None)  # the example's camera profile
        if sensors and name in sensors:
            stream["stream_properties"]["usdscene"]["sensor"] = sensors[name]
        streams[name] = stream
    body["streams"] = streams
    data = body["objects"]["0"]["object_data"]  # the sun, stated: so that usdscene before the
    data["num"] = [n for n in data["num"] if n["name"] != "power_w"]  # daylight default renders it alike
    if sun_power:
        data["num"].append({"name": "power_w", "val": 4.0})
    return doc


def run_document(tmp_path: Path, doc: dict, monkeypatch, **kwargs) -> Path:
    from usdscene.pipeline import RunOptions, run_pipeline

    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(CAR_PARK))  # its assets and their DCC sources
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(doc))
    out = tmp_path / "out"
    run_pipeline(path, out, RunOptions(exports=[], **kwargs), progress=False)
    return out


def image(out: Path, camera: str) -> np.ndarray:
    return cv2.imread(str(layout.image_path(out, camera, 0)), cv2.IMREAD_UNCHANGED)


def mask(out: Path, camera: str) -> np.ndarray:
    return cv2.imread(str(layout.mask_path(out, camera, 0)), cv2.IMREAD_UNCHANGED)


@pytest.fixture(scope="module")
def sensor_run(tmp_path_factory):
    monkeypatch = pytest.MonkeyPatch()
    try:
        doc = car_park_document(cameras=("pole_north", "noisy", "jpeg", "ir"), sensors={
            "noisy": {"iso": 6400, "vignetting": 0.4},
            "jpeg": {"compression": "jpeg", "quality": 20},
            "ir": {"ir_night": True, "iso": 800, "ir_range_m": 30}})
        yield run_document(tmp_path_factory.mktemp("sensor"), doc, monkeypatch, keep_clean=True)
    finally:
        monkeypatch.undo()


def test_without_world_and_sensor_the_images_are_the_ones_rendered_before(tmp_path):
    # The golden images were rendered from this document (the minimal example without its
    # passenger, frame 0) by usdscene before world and sensor existed (main at b6baf99, bpy 5.0.1,
    # x86-64 CPU). It uses only shipped assets that world and sensor work left alone.
    from usdscene.pipeline import RunOptions, run_pipeline

    out = tmp_path / "out"
    run_pipeline(GOLDEN / "scene.openlabel.json", out, RunOptions(exports=[], report=False), progress=False)
    for camera in ("cam_01", "cam_02"):
        assert layout.image_path(out, camera, 0).read_bytes() == (GOLDEN / f"{camera}_image.png").read_bytes()
        assert layout.mask_path(out, camera, 0).read_bytes() == (GOLDEN / f"{camera}_mask.png").read_bytes()
        assert not layout.clean_image_path(out, camera, 0).exists()  # no sensor, nothing to keep


def test_a_camera_without_sensor_renders_its_clean_image(sensor_run):
    """Beside sensor cameras, a camera without one keeps no clean copy."""
    assert layout.image_path(sensor_run, "pole_north", 0).is_file()
    assert not layout.clean_image_path(sensor_run, "pole_north", 0).exists()


@pytest.mark.parametrize("camera", ["noisy", "jpeg", "ir"])
def test_sensor_changes_the_image_not_the_mask(sensor_run, camera):
    assert np.array_equal(mask(sensor_run, camera), mask(sensor_run, "pole_north"))
    assert np.count_nonzero(mask(sensor_run, camera)) > 0
    assert not np.array_equal(image(sensor_run, camera), image(sensor_run, "pole_north"))
    # --keep-clean: the image before the sensor
    clean = cv2.imread(str(layout.clean_image_path(sensor_run, camera, 0)), cv2.IMREAD_UNCHANGED)
    assert clean.shape == image(sensor_run, camera).shape
    if camera != "ir":  # the IR camera's clean image holds its illuminator's light
        assert np.array_equal(clean, image(sensor_run, "pole_north"))


def test_ir_image_is_single_channel_in_content(sensor_run):
    ir = image(sensor_run, "ir")
    assert ir.shape == (48, 64, 3)
    assert np.array_equal(ir[..., 0], ir[..., 1]) and np.array_equal(ir[..., 1], ir[..., 2])
    assert ir.std() > 5  # an image, not a flat field
    colour = image(sensor_run, "pole_north")
    assert np.abs(colour[..., 0].astype(int) - colour[..., 2]).max() > 10  # the colour one is not grey


def test_sensor_provenance_in_the_annotations(sensor_run):
    doc = json.loads((sensor_run / "annotations.openlabel.json").read_text())
    streams = doc["openlabel"]["frames"]["0"]["frame_properties"]["usdscene"]["streams"]
    assert "sensor" not in streams["pole_north"]
    assert streams["noisy"]["sensor"]["iso"] == 6400 and streams["noisy"]["sensor"]["vignetting"] == 0.4
    assert streams["jpeg"]["sensor"]["quality"] == 20 and streams["jpeg"]["sensor"]["compression"] == "jpeg"
    assert streams["ir"]["sensor"]["ir_night"] is True
    assert len(streams["noisy"]["sensor"]["seed"]) == 3
    assert streams["noisy"]["clean_uri"] == "images_clean/noisy/000000.png"


def test_physical_sky_lights_the_background_and_agx_renders(tmp_path, monkeypatch):
    doc = car_park_document(world={"sky": "nishita", "view_transform": "agx", "exposure_ev": -0.5},
                            cameras=("pole_north", "blurred"),
                            sensors={"blurred": {"shutter_frames": 0.5, "compression": "h264_like", "quality": 30}})
    out = run_document(tmp_path, doc, monkeypatch)
    for camera in ("pole_north", "blurred"):
        top = image(out, camera)[:4].astype(float)  # above the horizon: sky, no geometry
        assert np.all(mask(out, camera)[:4] == 0)
        assert top.mean() > 60, f"{camera}: the sky is dark ({top.mean():.1f})"
        # cv2 reads BGR: a clear sky is bluer than it is red
        assert top[..., 0].mean() > top[..., 2].mean()


def test_hdri_from_the_document_folder_lights_the_background(tmp_path, monkeypatch):
    hdri = np.zeros((16, 32, 3), np.float32)
    hdri[:8] = (0.1, 0.8, 0.2)  # BGR: a green upper hemisphere
    hdri[8:] = (0.2, 0.2, 0.2)
    assert cv2.imwrite(str(tmp_path / "green.hdr"), hdri)
    doc = car_park_document(world={"hdri": "green.hdr", "strength": 1.0})
    out = run_document(tmp_path, doc, monkeypatch)
    blue, green, red = image(out, "pole_north")[:4].astype(float).mean(axis=(0, 1))  # cv2 reads BGR
    assert green > 200 and green > red + 60 and green > blue + 60


def test_a_sun_without_power_gives_a_daylight_picture(tmp_path, monkeypatch):
    # the car park as shipped: a sun without a stated power under the physical sky
    doc = car_park_document(world={"sky": "nishita"}, sun_power=False, cameras=("pole_north", "pole_east"))
    out = run_document(tmp_path, doc, monkeypatch)
    for camera in ("pole_north", "pole_east"):
        picture = image(out, camera)
        clipped = float((picture == 255).any(axis=-1).mean())
        assert clipped <= 0.01, f"{camera}: {100 * clipped:.1f} % of the pixels clipped"
        assert picture.mean() > 70, f"{camera}: a dark picture ({picture.mean():.0f})"


def test_the_sky_is_brightest_towards_the_sun_light(tmp_path, monkeypatch):
    # Blender's sky rotation convention (about the zenith, from +Y towards +X) checked by the
    # picture: a camera facing the sun light's azimuth sees the bright forward-scattering glow,
    # one facing away does not. Both look 20 degrees up from 40 m above the deck: sky only.
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.document.imaging import sun_sky_angles

    doc = car_park_document(world={"sky": "nishita"}, cameras=("towards", "away"))
    # the sun 50 degrees up in the east (+X): a convention that took x for y would put the sky's
    # sun in the north, 90 degrees off both cameras
    data = doc["openlabel"]["objects"]["0"]["object_data"]
    data["vec"] = [v for v in data["vec"] if v["name"] == "color_rgb"] + [
        {"name": "position_m", "val": [0.0, 0.0, 20.0]}, {"name": "rotation_xyz_deg", "val": [40.0, 0.0, 90.0]}]
    sun = next(light for light in read_openlabel(copy.deepcopy(doc)).lights if light.kind.value == "sun")
    elevation, _ = sun_sky_angles(sun.pose.rotation)
    assert 0.2 < elevation < 1.2  # the example's sun stands between 11 and 69 degrees up
    # towards the sun: the light shines along its -Z, so the sun lies along its +Z
    to_sun = sun.pose.rotation[:2, 2] / np.linalg.norm(sun.pose.rotation[:2, 2])
    for name, horizontal in (("towards", to_sun), ("away", -to_sun)):
        friendly = doc["openlabel"]["streams"][name]["stream_properties"]["usdscene"]
        direction = [horizontal[0] * np.cos(0.35), horizontal[1] * np.cos(0.35), np.sin(0.35)]
        friendly["position_m"] = [0.0, 0.0, 40.0]
        friendly["target_m"] = [float(d * 10.0 + p) for d, p in zip(direction, (0.0, 0.0, 40.0))]
    out = run_document(tmp_path, doc, monkeypatch)
    towards, away = image(out, "towards").astype(float), image(out, "away").astype(float)
    assert np.all(mask(out, "towards") == 0) and np.all(mask(out, "away") == 0)
    assert towards.mean() > away.mean() + 15, (towards.mean(), away.mean())


def test_bake_world_lays_out_the_world_as_an_hdri_is_read(tmp_path):
    # A world baked from an HDRI gives that HDRI back (same orientation, same values): so the
    # sky baked by benchmarks/world_render_cost.py is the sky, as an environment image.
    from usdscene.render.driver import run_job
    from usdscene.render.job import BakeWorldJob

    height, width = 32, 64
    lon = (np.arange(width) + 0.5) / width * 2 * np.pi
    rows = (np.arange(height) + 0.5) / height
    rgb = np.zeros((height, width, 3), np.float32)
    rgb[..., 0] = 0.5 + 0.4 * np.cos(lon)[None, :]
    rgb[..., 1] = 0.5 + 0.4 * np.sin(lon)[None, :]
    rgb[..., 2] = 0.2 + 0.6 * rows[:, None]
    assert cv2.imwrite(str(tmp_path / "pattern.hdr"), rgb[..., ::-1])
    world = {"world": {"hdri": "pattern.hdr"}, "hdri_path": str(tmp_path / "pattern.hdr"), "sun": None}
    run_job(BakeWorldJob(world=world, frame=0, size_px=(width, height), samples=4, out=str(tmp_path / "baked.hdr")),
            "bake")
    baked = cv2.imread(str(tmp_path / "baked.hdr"), cv2.IMREAD_UNCHANGED)[..., ::-1]
    assert baked.shape == rgb.shape
    # 0.004 measured (a smooth pattern, linearly interpolated); the layout one pixel off in
    # longitude would be 0.017 off, mirrored 0.17, upside down 0.10
    assert np.abs(baked - rgb).mean() < 0.01, np.abs(baked - rgb).mean()
