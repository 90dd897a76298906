"""compose_stage: golden layers, determinism, stage metadata, composed vs flattened stage,
camera/light conventions, atomicity and the ``usdscene compose`` command."""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
from pathlib import Path

import numpy as np
import pytest

from test_compose_support import build_test_catalog, load_test_catalog, look_at_cv, small_scene
from usdscene.document import model as m
from usdscene.document import stage_schema as ss
from usdscene.scene.compose import compose_stage, light_intensity
from usdscene.errors import CompositionError

pytestmark = pytest.mark.usd

GOLDEN = Path(__file__).parent / "golden" / "compose_small"
REGENERATE = os.environ.get("USDSCENE_REGENERATE_GOLDEN") == "1"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("compose")
    build_test_catalog(root / "cat")
    return root


@pytest.fixture(scope="module")
def catalog(workdir):
    return load_test_catalog(workdir / "cat")


@pytest.fixture(scope="module")
def composed(workdir, catalog):
    return compose_stage(small_scene(), catalog, workdir / "stage")


def test_golden_layers(composed):
    """Set USDSCENE_REGENERATE_GOLDEN=1 to rewrite tests/golden/compose_small/ after an
    intended change (then review the diff)."""
    names = (ss.ROOT_LAYER, *ss.SUBLAYERS)
    assert [p.name for p in composed.layers] == list(names)
    if REGENERATE:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        for name in names:
            (GOLDEN / name).write_text((composed.stage_dir / name).read_text())
    problems = []
    for name in names:
        expected = (GOLDEN / name).read_text()
        got = (composed.stage_dir / name).read_text()
        if got != expected:
            diff = "".join(list(difflib.unified_diff(expected.splitlines(True), got.splitlines(True),
                                                     f"golden/{name}", f"composed/{name}"))[:40])
            problems.append(diff)
    assert not problems, "\n".join(problems)


def test_same_scene_and_seed_give_byte_identical_layers(workdir, catalog, composed):
    again = compose_stage(small_scene(), catalog, workdir / "again")
    for a, b in zip(composed.layers, again.layers):
        assert a.read_bytes() == b.read_bytes(), a.name
    other = compose_stage(small_scene(seed=8), catalog, workdir / "other")
    assert (other.stage_dir / "objects.usda").read_bytes() != (composed.stage_dir / "objects.usda").read_bytes()
    # An explicit generator replaces the document's seed.
    explicit = compose_stage(small_scene(seed=8), catalog, workdir / "explicit", rng=np.random.default_rng(7))
    assert (explicit.stage_dir / "objects.usda").read_bytes() == (composed.stage_dir / "objects.usda").read_bytes()


def test_root_layer_metadata(composed):
    from pxr import Sdf, Usd, UsdGeom

    layer = Sdf.Layer.FindOrOpen(str(composed.root_layer))
    assert layer.pseudoRoot.GetInfo("upAxis") == "Z"
    assert layer.pseudoRoot.GetInfo("metersPerUnit") == 1.0
    assert (layer.startTimeCode, layer.endTimeCode) == (0.0, 5.0)
    assert [p.lstrip("./") for p in layer.subLayerPaths] == list(ss.SUBLAYERS)
    data = layer.customLayerData[ss.LAYER_DATA_KEY]
    assert data["sourceSha256"] == "0" * 64 and data["seed"] == 7 and data["toolkitVersion"]
    stage = Usd.Stage.Open(str(composed.root_layer))
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert composed.frame_count == 6
    assert composed.objects_per_class == {"bag": 1, "box": 1, "cup": 2}


def _queries(stage, frames) -> dict:
    """Object world transforms, visibility and colour per frame, camera parameters."""
    from pxr import Usd, UsdGeom

    out = {}
    for prim in stage.Traverse():
        path = prim.GetPath().pathString
        if path.startswith(ss.OBJECTS + "/") and prim.GetParent().GetPath().pathString == ss.OBJECTS:
            img = UsdGeom.Imageable(prim)
            for f in frames:
                xf = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(f))
                out[(path, f, "xf")] = tuple(v for row in xf for v in row)
                out[(path, f, "vis")] = img.ComputeVisibility(Usd.TimeCode(f))
            shader = stage.GetPrimAtPath(path + "/Looks/Body/Surface")
            out[(path, "colour")] = tuple(shader.GetAttribute("inputs:diffuseColor").Get()) if shader else None
        if prim.IsA(UsdGeom.Camera):
            for f in frames:
                cam = UsdGeom.Camera(prim).GetCamera(Usd.TimeCode(f))
                out[(path, f, "cam")] = (tuple(v for row in cam.transform for v in row), cam.focalLength,
                                         cam.horizontalAperture, cam.verticalAperture,
                                         cam.horizontalApertureOffset, cam.verticalApertureOffset,
                                         (cam.clippingRange.GetMin(), cam.clippingRange.GetMax()), cam.projection)
            out[(path, "lens")] = tuple(str(prim.GetAttribute(n).Get()) for n in (
                ss.ATTR_LENS_MODEL, ss.ATTR_LENS_FX, ss.ATTR_LENS_CX, ss.ATTR_LENS_DISTORTION))
    return out


def test_composed_and_flattened_stage_answer_the_same(composed, workdir):
    from pxr import Usd

    stage = Usd.Stage.Open(str(composed.root_layer))
    flat_path = workdir / "flat.usda"
    stage.Flatten().Export(str(flat_path))
    flat = Usd.Stage.Open(str(flat_path))
    frames = range(composed.frame_start, composed.frame_end + 1)
    a, b = _queries(stage, frames), _queries(flat, frames)
    assert len(a) > 50
    assert a == b
    # The answers are the composition's, not vacuous: presence and appearance come through.
    assert a[("/World/Objects/cup_o3", 0, "vis")] == "invisible"
    assert a[("/World/Objects/cup_o3", 1, "vis")] == "inherited"
    # (Flattening bakes variant selections away, so the selection is asked of the composed stage.)
    assert stage.GetPrimAtPath("/World/Objects/box_o2").GetVariantSets().GetVariantSelection("appearance") == "striped"
    assert a[("/World/Objects/box_o2", "colour")] == pytest.approx((0.8, 0.2, 0.2))  # the variant's colour
    assert a[("/World/Objects/cup_o3", "colour")] == pytest.approx((0.9, 0.1, 0.1))  # the colour opinion


def test_objects_layer_identity_and_time_samples(composed):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(composed.root_layer))
    bag = stage.GetPrimAtPath(ss.object_prim_path("bag", "o1"))
    assert bag.GetCustomDataByKey(ss.CUSTOM_UID) == "o1"
    assert bag.GetCustomDataByKey(ss.CUSTOM_CLASS) == "bag"
    assert bag.GetAttribute(ss.ATTR_USER_UID).Get() == "o1"
    assert bag.GetAttribute(ss.ATTR_USER_CLASS).Get() == "bag"
    assert bag.GetAttribute(ss.ATTR_MASK_ID).Get() == 1
    assert not bag.IsInstanceable()
    # Relation changes at frame 3 (seat_01A below → seat_01B on): samples at run ends only.
    op = bag.GetAttribute("xformOp:transform")
    assert op.GetTimeSamples() == [0.0, 2.0, 3.0, 5.0]
    # The box never moves: no time samples at all.
    assert stage.GetPrimAtPath(ss.object_prim_path("box", "o2")).GetAttribute("xformOp:transform").GetTimeSamples() == []
    # Placed objects rest on their support: the bag's bottom at the seat's top (z 0.45) from frame 3.
    box = UsdGeom.Imageable(bag).ComputeWorldBound(Usd.TimeCode(4), "default").ComputeAlignedRange()
    assert box.GetMin()[2] == pytest.approx(0.45, abs=1e-6)
    # The cup on the box: bottom at the box top.
    cup = stage.GetPrimAtPath(ss.object_prim_path("cup", "o3"))
    box = UsdGeom.Imageable(cup).ComputeWorldBound(Usd.TimeCode(2), "default").ComputeAlignedRange()
    assert box.GetMin()[2] == pytest.approx(0.3, abs=1e-6)
    vis = cup.GetAttribute("visibility")
    assert vis.GetTimeSamples() == [0.0, 1.0, 5.0]


def _project_with_usd(stage, camera_path: str, point, width: int, height: int, frame: int = 0):
    """Pixel (OpenCV convention) of a world point through USD's own camera frustum."""
    from pxr import Gf, Usd, UsdGeom

    cam = UsdGeom.Camera(stage.GetPrimAtPath(camera_path)).GetCamera(Usd.TimeCode(frame))
    frustum = cam.frustum
    ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
    p = ndc.Transform(Gf.Vec3d(*point))
    return ((p[0] + 1) / 2 * width - 0.5, (1 - p[1]) / 2 * height - 0.5)


@pytest.mark.parametrize("lens", [m.LensModel.PERSPECTIVE, m.LensModel.ORTHOGRAPHIC])
def test_camera_attributes_project_like_the_intrinsics(tmp_path, catalog, lens):
    """USD's own frustum (focal length, apertures, offsets in tenths of a unit) puts points on
    the same pixels as the OpenCV intrinsics, principal point off centre included."""
    from pxr import Usd

    f = 70.0 if lens == m.LensModel.PERSPECTIVE else 40.0  # ortho: pixels per metre
    intr = m.Intrinsics(lens, 80, 60, f, f * 1.1, 35.0, 33.0, sensor_width_mm=6.4)
    pose = look_at_cv((0.3, -2.0, 1.5), (0.0, 0.0, 0.5))
    scene = m.SceneSpec(cameras=(m.Camera("cam", intr, pose, clip_near_m=0.1, clip_far_m=100),))
    result = compose_stage(scene, catalog, tmp_path / "stage")
    stage = Usd.Stage.Open(str(result.root_layer))
    rng = np.random.default_rng(0)
    for point in rng.uniform(-0.5, 0.5, (5, 3)) + (0, 0, 0.5):
        x_cam = pose.inverse().transform_points(point)[0]
        if lens == m.LensModel.PERSPECTIVE:
            expected = (f * x_cam[0] / x_cam[2] + 35.0, 1.1 * f * x_cam[1] / x_cam[2] + 33.0)
        else:
            expected = (f * x_cam[0] + 35.0, 1.1 * f * x_cam[1] + 33.0)
        got = _project_with_usd(stage, "/World/Cameras/cam", point, 80, 60)
        assert got == pytest.approx(expected, abs=1e-3)
    cam = stage.GetPrimAtPath("/World/Cameras/cam")
    if lens == m.LensModel.PERSPECTIVE:
        # 70 px at 80 px over 6.4 mm = 5.6 mm = 0.056 tenths of a metre.
        assert cam.GetAttribute("focalLength").Get() == pytest.approx(0.056)
        assert cam.GetAttribute("projection").Get() == "perspective"
    else:
        assert cam.GetAttribute("horizontalAperture").Get() == pytest.approx(10 * 80 / 40.0)
        assert cam.GetAttribute("projection").Get() == "orthographic"


def test_moving_camera_has_samples_only_where_it_changes(composed):
    from pxr import Usd

    stage = Usd.Stage.Open(str(composed.root_layer))
    op = stage.GetPrimAtPath("/World/Cameras/cam_aisle").GetAttribute("xformOp:transform")
    assert op.GetTimeSamples() == [0.0, 2.0, 3.0, 4.0, 5.0]
    assert stage.GetPrimAtPath("/World/Cameras/cam_fish").GetAttribute("xformOp:transform").GetTimeSamples() == []
    lens = stage.GetPrimAtPath("/World/Cameras/cam_fish")
    assert lens.GetAttribute(ss.ATTR_LENS_MODEL).Get() == "opencv_fisheye"
    assert list(lens.GetAttribute(ss.ATTR_LENS_DISTORTION).Get()) == [0.01, -0.002, 0.0, 0.0]
    assert lens.GetAttribute(ss.ATTR_LENS_FOV).Get() == 180.0


def test_lights_units_and_shapes(composed):
    from pxr import Usd, UsdLux

    stage = Usd.Stage.Open(str(composed.root_layer))
    area = stage.GetPrimAtPath("/World/Lights/cabin_light")
    assert area.IsA(UsdLux.RectLight)
    assert area.GetAttribute("inputs:intensity").Get() == pytest.approx(150.0 / math.pi)
    assert (area.GetAttribute("inputs:width").Get(), area.GetAttribute("inputs:height").Get()) == pytest.approx((1.5, 0.2))
    spot = stage.GetPrimAtPath("/World/Lights/reading_spot")
    assert spot.IsA(UsdLux.SphereLight) and spot.HasAPI(UsdLux.ShapingAPI)
    assert spot.GetAttribute("inputs:shaping:cone:angle").Get() == pytest.approx(20.0)
    assert spot.GetAttribute("inputs:shaping:cone:softness").Get() == pytest.approx(0.3)
    assert spot.GetAttribute(ss.ATTR_LIGHT_POWER_W).Get() == 20.0
    assert spot.GetAttribute("visibility").GetTimeSamples() == [0.0, 2.0, 5.0]
    sun = stage.GetPrimAtPath("/World/Lights/sun")
    assert sun.IsA(UsdLux.DistantLight)
    assert sun.GetAttribute("inputs:intensity").Get() == pytest.approx(0.75)
    assert light_intensity(m.Light("x", "x", m.LightKind.POINT, power_w=math.pi)) == pytest.approx(1.0)


def test_lighting_rigs_are_a_variant_set(composed, tmp_path):
    from pxr import Usd, UsdLux

    from usdscene.converters.stage.usd_stage import scene_from_stage

    stage = Usd.Stage.Open(str(composed.root_layer))
    rigs = stage.GetPrimAtPath(ss.LIGHTS).GetVariantSets().GetVariantSet(ss.VARIANT_SET_LIGHTING)
    assert rigs.GetVariantNames() == ["document", "off"] and rigs.GetVariantSelection() == "document"
    assert len([p for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)]) == 3
    stage.SetEditTarget(stage.GetSessionLayer())  # leave the files (and their loaded layers) alone
    rigs.SetVariantSelection("off")
    assert [p for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)] == []
    assert scene_from_stage(stage).lights == ()


def test_render_layer(composed):
    from pxr import Usd, UsdRender

    stage = Usd.Stage.Open(str(composed.root_layer))
    settings = UsdRender.Settings(stage.GetPrimAtPath(ss.RENDER_SETTINGS))
    assert settings and tuple(settings.GetResolutionAttr().Get()) == (64, 48)
    assert settings.GetPrim().GetAttribute(ss.ATTR_RENDER_SAMPLES).Get() == 2
    products = settings.GetProductsRel().GetTargets()
    assert [p.name for p in products] == ["cam_aisle", "cam_fish"]
    product = UsdRender.Product(stage.GetPrimAtPath(products[0]))
    assert product.GetCameraRel().GetTargets()[0].pathString == "/World/Cameras/cam_aisle"
    assert UsdRender.Settings.GetStageRenderSettings(stage).GetPath().pathString == ss.RENDER_SETTINGS


def test_interrupted_compose_leaves_no_valid_looking_stage(tmp_path, catalog, monkeypatch):
    import usdscene.scene.compose as compose_module

    stage_dir = tmp_path / "stage"
    compose_stage(small_scene(), catalog, stage_dir)
    assert (stage_dir / "scene.usda").is_file()
    real = compose_module.write_text_atomic

    def failing(path, text):
        if Path(path).name == "objects.usda":
            raise KeyboardInterrupt
        return real(path, text)

    monkeypatch.setattr(compose_module, "write_text_atomic", failing)
    with pytest.raises(KeyboardInterrupt):
        compose_stage(small_scene(seed=9), catalog, stage_dir)
    assert not (stage_dir / "scene.usda").exists()
    assert not [p for p in stage_dir.iterdir() if p.name.endswith(".tmp")]


def test_bad_input_raises_composition_error_before_writing(tmp_path, catalog):
    scene = small_scene()
    bad = dataclasses.replace(scene, objects=scene.objects + (m.SceneObject("o99", "x", "unicorn"),))
    with pytest.raises(CompositionError, match="o99"):
        compose_stage(bad, catalog, tmp_path / "stage")
    assert not (tmp_path / "stage" / "scene.usda").exists()
    clash = dataclasses.replace(scene, cameras=scene.cameras + (dataclasses.replace(scene.cameras[0], name="cam-aisle"),))
    with pytest.raises(CompositionError, match="cam-aisle"):
        compose_stage(clash, catalog, tmp_path / "stage")


# --------------------------------------------------------------------------------------------
# The command


def _write_document(path: Path, scene: m.SceneSpec) -> None:
    from usdscene.converters.openlabel import write_document, write_openlabel

    write_document(path, write_openlabel(scene))


def test_compose_command_prints_a_summary(tmp_path, workdir, capsys):
    from usdscene.cli import main

    scene = dataclasses.replace(small_scene(), asset_paths=(str(workdir / "cat"),))
    _write_document(tmp_path / "doc.json", scene)
    assert main(["compose", str(tmp_path / "doc.json"), "-o", str(tmp_path / "out"),
                 "--asset-path", str(workdir)]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "out" / "stage" / "scene.usda").is_file()
    assert "frames:  6" in out and "bag 1" in out and "cup 2" in out and "objects.usda" in out


@pytest.mark.parametrize("change, expected", [
    (lambda s: dataclasses.replace(s, places=(m.PlaceRef("p1", "seat_99Z"),) + s.places[1:]),
     lambda doc: ("seat_99Z", next(r.uid for r in doc.relations if r.type == "is_below"))),
    (lambda s: dataclasses.replace(s, objects=s.objects + (m.SceneObject("o9", "u", "unicorn"),)),
     lambda doc: ("unicorn", next(o.uid for o in doc.objects if o.class_name == "unicorn"))),
    (lambda s: dataclasses.replace(s, relations=s.relations + (m.Relation("r9", "is_on", "o2", "o3"),)),
     lambda doc: ("cyclic", next(o.uid for o in doc.objects if o.class_name == "box"))),
])
def test_compose_command_exits_1_naming_the_element(tmp_path, workdir, capsys, change, expected):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.cli import main

    scene = change(dataclasses.replace(small_scene(), asset_paths=(str(workdir / "cat"),)))
    _write_document(tmp_path / "doc.json", scene)
    word, uid = expected(read_openlabel(tmp_path / "doc.json"))  # uids as the document spells them
    assert main(["compose", str(tmp_path / "doc.json"), "-o", str(tmp_path / "out"),
                 "--asset-path", str(workdir)]) == 1
    err = capsys.readouterr().err
    assert "usdscene: error:" in err and word in err and repr(uid) in err, err
    assert not (tmp_path / "out" / "stage" / "scene.usda").exists()
