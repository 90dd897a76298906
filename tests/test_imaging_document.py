"""World and sensor in the document: what validate refuses (naming field and value), the HDRI's
containment, the daylight sun default, round trips, per-frame overrides and the draws of
usdscene generate. Pure tier except where a test validates a file against the catalog."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from usdscene.errors import DocumentError
from usdscene.document.imaging import (DEFAULT_SUN_IRRADIANCE_W_M2, Sensor, World, draw_per_frame, randomize_scene,
                              sun_sky_angles)
from usdscene.document.model import euler_zyx_to_rotation

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"


def minimal(world=None, sensor=None, sun=None, drop_sun=False) -> dict:
    """The minimal example (its light "1" is a sun of 4 W/m²); ``sun``: that sun's ``num``
    entries instead; ``drop_sun``: without it."""
    doc = json.loads(MINIMAL.read_text())
    if world is not None:
        doc["openlabel"]["metadata"]["usdscene"]["world"] = world
    if sensor is not None:
        doc["openlabel"]["streams"]["cam_01"]["stream_properties"]["usdscene"]["sensor"] = sensor
    if sun is not None:
        doc["openlabel"]["objects"]["1"]["object_data"]["num"] = sun
    if drop_sun:
        del doc["openlabel"]["objects"]["1"]
    return doc


def problems_of(doc: dict) -> list[str]:
    from usdscene.converters.openlabel import read_openlabel

    with pytest.raises(DocumentError) as info:
        read_openlabel(doc)
    return [str(p) for p in info.value.problems]


def test_out_of_range_sensor_values_are_refused_by_field_and_value():
    found = problems_of(minimal(sensor={"read_noise_e": -1, "quality": 0, "iso": -100}))
    where = "openlabel.streams.cam_01.stream_properties.usdscene.sensor"
    assert any(f"{where}.read_noise_e" in p and "-1" in p for p in found)
    assert any(f"{where}.quality" in p and "quality 0 " in p for p in found)
    assert any(f"{where}.iso" in p and "-100" in p for p in found)
    found = problems_of(minimal(sensor={"quality": 101, "compression": "webp", "vignetting": 1.5}))
    assert any(f"{where}.quality" in p and "101" in p for p in found)
    assert any(f"{where}.compression" in p and "'webp'" in p for p in found)
    assert any(f"{where}.vignetting" in p and "1.5" in p for p in found)
    found = problems_of(minimal(sensor={"randomize": {"quality": [0, 50], "ir_night": [0, 1]}, "per_frame": {"x": {}}}))
    assert any(f"{where}.randomize.quality[0]" in p for p in found)
    assert any(f"{where}.randomize.ir_night" in p for p in found)
    assert any(f"{where}.per_frame.x" in p for p in found)


def test_unknown_sky_kind_and_sky_without_sun_are_refused():
    found = problems_of(minimal(world={"sky": "preetham"}, sun=[]))
    assert any("metadata.usdscene.world.sky" in p and "unknown sky kind 'preetham'" in p for p in found)
    found = problems_of(minimal(world={"sky": "nishita"}, drop_sun=True))
    assert any("world.sky" in p and "no light of kind 'sun'" in p for p in found)
    found = problems_of(minimal(world={"sky": "nishita", "hdri": "x.hdr"}))
    assert any("'sky' or 'hdri'" in p for p in found)
    found = problems_of(minimal(world={"view_transform": "log", "exposure_ev": 40}))
    assert any("world.view_transform" in p and "'log'" in p for p in found)
    assert any("world.exposure_ev" in p and "40" in p for p in found)


def test_world_and_sensor_round_trip_through_the_writer():
    from usdscene.converters.openlabel import read_openlabel, write_openlabel

    doc = minimal(world={"color_rgb": [0.1, 0.2, 0.3], "strength": 2.0, "view_transform": "filmic",
                         "per_frame": {"1": {"exposure_ev": -1.0}}},
                  sensor={"iso": 800, "quality": 60, "ir_night": True, "randomize": {"iso": [100, 1600]}})
    scene = read_openlabel(doc)
    assert scene.cameras[0].sensor.compression == "jpeg"  # a quality alone means JPEG
    again = read_openlabel(write_openlabel(scene))
    assert again.world == scene.world and again.cameras[0].sensor == scene.cameras[0].sensor
    assert scene.world.at_frame(1).exposure_ev == -1.0 and scene.world.at_frame(0).exposure_ev == 0.0
    assert scene.cameras[1].sensor is None


def test_a_sun_without_power_gets_daylight_irradiance():
    from usdscene.converters.openlabel import read_openlabel

    scene = read_openlabel(minimal(sun=[]))
    sun = [light for light in scene.lights if light.kind.value == "sun"][0]
    assert sun.power_w == DEFAULT_SUN_IRRADIANCE_W_M2 == 4.0
    point = [light for light in scene.lights if light.kind.value != "sun"][0]
    assert point.power_w != DEFAULT_SUN_IRRADIANCE_W_M2  # other lights keep what they had
    stated = read_openlabel(minimal(sun=[{"name": "power_w", "val": 2.5}]))
    assert [light.power_w for light in stated.lights if light.kind.value == "sun"] == [2.5]


def test_sky_sun_follows_the_sun_light():
    # a light with no rotation shines straight down: the sun at the zenith
    assert sun_sky_angles(np.eye(3))[0] == pytest.approx(np.pi / 2)
    # tilted 60 degrees about x (shining towards +y and down): the sun stands 30 degrees above
    # the horizon towards -y, Blender's sky rotation of pi (measured from +y towards +x)
    elevation, rotation = sun_sky_angles(euler_zyx_to_rotation(0.0, 0.0, np.radians(60.0)))
    assert elevation == pytest.approx(np.radians(30.0))
    assert abs(rotation) == pytest.approx(np.pi)
    # turned 90 degrees about z: the sun towards +x, rotation +pi/2
    elevation, rotation = sun_sky_angles(euler_zyx_to_rotation(np.radians(90.0), 0.0, np.radians(60.0)))
    assert rotation == pytest.approx(np.pi / 2)


def write_doc(folder: Path, doc: dict) -> Path:
    path = folder / "scene.openlabel.json"
    path.write_text(json.dumps(doc))
    return path


def test_hdri_outside_the_asset_folders_is_refused_with_its_path(tmp_path, monkeypatch):
    from usdscene.validation import validate_document

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "sky.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n\x80\x80\x80\x80")
    inside = tmp_path / "doc"
    inside.mkdir()
    monkeypatch.chdir(inside)  # the working folder is a reading root too
    path = write_doc(inside, minimal(world={"hdri": str(outside / "sky.hdr")}))
    with pytest.raises(DocumentError) as info:
        validate_document(path, schema=None, use_catalog=False)
    text = str(info.value)
    assert "metadata.usdscene.world.hdri" in text and str(outside / "sky.hdr") in text
    assert "outside the document's folder" in text
    # consented with the asset path, it passes
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(outside))
    assert validate_document(path, schema=None, use_catalog=False).scene.world.hdri == str(outside / "sky.hdr")


def test_hdri_that_is_not_an_image_or_missing_is_refused(tmp_path, monkeypatch):
    from usdscene.validation import validate_document

    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.hdr").write_text("not an image")
    with pytest.raises(DocumentError) as info:
        validate_document(write_doc(tmp_path, minimal(world={"hdri": "notes.hdr"})), schema=None, use_catalog=False)
    assert "'notes.hdr' is not an image" in str(info.value)
    with pytest.raises(DocumentError) as info:
        validate_document(write_doc(tmp_path, minimal(world={"hdri": "missing.exr"})), schema=None, use_catalog=False)
    assert "'missing.exr'" in str(info.value) and "does not exist" in str(info.value)


def test_the_cli_refuses_bad_world_and_sensor_with_exit_1(tmp_path, monkeypatch, capsys):
    from usdscene.cli import main

    monkeypatch.chdir(tmp_path)
    path = write_doc(tmp_path, minimal(world={"sky": "cloudy"}, sensor={"quality": 0}))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert "unknown sky kind 'cloudy'" in err and "sensor.quality: quality 0" in err
    assert "Traceback" not in err


def test_draws_are_per_frame_deterministic_and_in_range():
    sensor = Sensor(iso=400.0, randomize=(("iso", (100.0, 3200.0)), ("quality", (30.0, 90.0))))
    a = draw_per_frame(sensor, [0, 1, 2], np.random.default_rng(5))
    b = draw_per_frame(sensor, [0, 1, 2], np.random.default_rng(5))
    assert a == b and not a.randomize
    values = [a.at_frame(f) for f in (0, 1, 2)]
    assert all(100 <= v.iso <= 3200 and 30 <= v.quality <= 90 and isinstance(v.quality, int) for v in values)
    assert len({v.iso for v in values}) == 3
    assert a.at_frame(7).iso == 400.0  # a frame without a draw keeps the base value


def test_randomize_scene_reports_what_it_drew():
    from usdscene.converters.openlabel import read_openlabel

    scene = read_openlabel(minimal(world={"randomize": {"strength": [0.5, 2.0]}},
                                   sensor={"randomize": {"exposure_bias_ev": [-1.0, 1.0]}}))
    drawn_scene, drawn = randomize_scene(scene, np.random.default_rng(3))
    assert set(drawn["world"]) == {str(f) for f in scene.frames}
    assert set(drawn["sensors"]) == {"cam_01"}
    for frame, values in drawn["sensors"]["cam_01"].items():
        assert drawn_scene.cameras[0].sensor.at_frame(int(frame)).exposure_bias_ev == values["exposure_bias_ev"]
    assert drawn_scene.world.randomize == () and isinstance(drawn_scene.world, World)


@pytest.mark.usd
def test_generate_draws_world_and_sensor_per_frame_and_reports_them(tmp_path, monkeypatch):
    from usdscene.generate.sequences import GenerateOptions, generate_document

    car_park = REPO / "examples" / "car_park"
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(car_park))
    setup = json.loads((car_park / "setup.openlabel.json").read_text())
    setup["openlabel"]["metadata"]["usdscene"]["asset_paths"] = [str(car_park / "assets")]
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps(setup))
    block = setup["openlabel"]["metadata"]["usdscene"]
    block["world"] = {"sky": "nishita", "randomize": {"strength": [0.5, 1.5]}}
    for stream in setup["openlabel"]["streams"].values():
        stream["stream_properties"]["usdscene"]["sensor"] = {"iso": 400, "randomize": {"iso": [100, 3200],
                                                                                       "quality": [30, 90]}}
    ranged = tmp_path / "ranged.json"
    ranged.write_text(json.dumps(setup))
    options = GenerateOptions(strategy="appearance", frames=3, seed=11, classes=("vehicle", "backpack"),
                              objects_per_frame=3)
    without = generate_document(plain, tmp_path / "without.json", options)
    with_ranges = generate_document(ranged, tmp_path / "with.json", options)
    drawn = with_ranges.report["domain_randomization"]
    assert set(drawn["world"]) == {"0", "1", "2"}
    assert all(0.5 <= v["strength"] <= 1.5 for v in drawn["world"].values())
    assert set(drawn["sensors"]) == set(setup["openlabel"]["streams"])
    isos = [v["iso"] for frames in drawn["sensors"].values() for v in frames.values()]
    assert len(set(isos)) == len(isos) == 12 and all(100 <= iso <= 3200 for iso in isos)
    # the document holds the draws, not the ranges, and the objects are those drawn without ranges
    written = json.loads((tmp_path / "with.json").read_text())["openlabel"]
    sensor = written["streams"]["pole_north"]["stream_properties"]["usdscene"]["sensor"]
    assert "randomize" not in sensor and sensor["per_frame"]["1"] == drawn["sensors"]["pole_north"]["1"]
    assert written["metadata"]["usdscene"]["world"]["per_frame"]["2"] == drawn["world"]["2"]
    assert with_ranges.scene.objects == without.scene.objects
    assert "domain_randomization" not in without.report
    again = generate_document(ranged, tmp_path / "again.json", options)
    assert again.report["domain_randomization"] == drawn


@pytest.mark.parametrize("command", ["run", "render"])
def test_keep_clean_is_an_option_of_run_and_render(command, capsys):
    from usdscene.cli import main

    assert main([command, "--help"]) == 0
    assert "--keep-clean" in capsys.readouterr().out
