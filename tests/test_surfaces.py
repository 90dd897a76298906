"""Procedural surfaces: names, the route from a DCC material to the stage, and a real render."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
from usdscene.document.surfaces import SURFACES, surface_from_material_name, surface_recipe
from usdscene.errors import AssetError


def test_every_recipe_is_in_range():
    for name, recipe in SURFACES.items():
        assert recipe.name == name and recipe.space in ("world", "object")
        assert 0 <= recipe.roughness <= 1 and recipe.grain_m > 0 and recipe.blotch_m > recipe.grain_m


def test_unknown_surface_names_the_field_and_value():
    with pytest.raises(AssetError) as err:
        surface_recipe("asphlt", where="floor: material")
    text = str(err.value)
    assert "floor: material" in text and "'asphlt'" in text and "asphalt" in text
    assert len(err.value.problems) == 1


def test_material_names_map_to_surfaces():
    assert surface_from_material_name("surface.concrete", where="x") == "concrete"
    assert surface_from_material_name("Concrete", where="x") is None
    assert surface_from_material_name(None, where="x") is None
    with pytest.raises(AssetError, match="'glas'"):
        surface_from_material_name("surface.glas", where="window: material")


def _glb(path, material_name):
    import trimesh

    box = trimesh.creation.box(extents=(4.0, 4.0, 0.2))
    box.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name=material_name, baseColorFactor=[90, 90, 90, 255]))
    post = trimesh.creation.box(extents=(0.2, 0.2, 2.0))
    post.visual.face_colors = [200, 10, 10, 255]
    scene = trimesh.Scene()
    scene.add_geometry(box, node_name="floor", geom_name="floor")
    scene.add_geometry(post, node_name="post", geom_name="post")
    path.write_bytes(scene.export(file_type="glb"))
    return path


@pytest.mark.usd
def test_environment_import_keeps_the_surface_of_a_material(tmp_path):
    from pxr import Usd

    from usdscene.cli import main

    source = _glb(tmp_path / "yard.glb", "surface.asphalt")
    assert main(["assets", "add", str(source), "--class", "yard", "--kind", "environment",
                 "--catalog", str(tmp_path / "cat")]) == 0
    stage = Usd.Stage.Open(str(tmp_path / "cat" / "imported" / "yard.usda"))
    kinds = {}
    for prim in stage.Traverse():
        attr = prim.GetAttribute("userProperties:usdscene_surface")
        if prim.GetTypeName() == "Mesh":
            kinds[str(prim.GetPath())] = attr.Get() if attr else None
    assert sorted(kinds.values(), key=str) == [None, "asphalt"]  # the floor; the post has no surface


@pytest.mark.usd
def test_environment_import_refuses_an_unknown_surface(tmp_path, capsys):
    from usdscene.cli import main

    source = _glb(tmp_path / "yard.glb", "surface.asphlt")
    assert main(["assets", "add", str(source), "--class", "yard", "--kind", "environment",
                 "--catalog", str(tmp_path / "cat")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'asphlt'" in err[0] and "floor" in err[0]
    assert not (tmp_path / "cat" / "imported" / "yard.usda").exists()


@pytest.mark.usd
def test_backdrop_is_drawn_but_no_obstacle_and_outside_the_extent(tmp_path):
    import json

    import trimesh
    from pxr import Usd, UsdGeom

    from usdscene.cli import main
    from usdscene.document import stage_schema
    from usdscene.scene.stage_geometry import environment_triangles

    scene = trimesh.Scene()
    floor = trimesh.creation.box(extents=(4.0, 0.2, 4.0))  # Y up, as glTF
    scene.add_geometry(floor, node_name="floor", geom_name="floor")
    ground = trimesh.creation.box(extents=(500.0, 0.1, 500.0))
    ground.visual.face_colors = [60, 80, 40, 255]
    scene.add_geometry(ground, node_name="backdrop.ground", geom_name="ground")
    (tmp_path / "yard.glb").write_bytes(scene.export(file_type="glb"))
    assert main(["assets", "add", str(tmp_path / "yard.glb"), "--class", "yard", "--kind", "environment",
                 "--catalog", str(tmp_path / "cat")]) == 0
    entry = json.loads((tmp_path / "cat" / "catalog.json").read_text())["classes"]["yard"]
    assert entry["extent_m"][0][0] == pytest.approx(-2.0) and entry["extent_m"][1][0] == pytest.approx(2.0)
    asset = tmp_path / "cat" / "imported" / "yard.usda"
    opened = Usd.Stage.Open(str(asset))
    purposes = sorted(UsdGeom.Imageable(p).ComputePurpose() for p in opened.Traverse() if p.GetTypeName() == "Mesh")
    assert purposes == ["default", "render"]
    stage = Usd.Stage.CreateNew(str(tmp_path / "scene.usda"))
    stage.DefinePrim(stage_schema.ENVIRONMENT).GetReferences().AddReference(str(asset))
    stage.Save()
    triangles = environment_triangles(tmp_path / "scene.usda")
    assert len(triangles) == 12 and np.abs(triangles).max() <= 2.0 + 1e-6  # the floor's box alone


W, H = 64, 48
# 45 degrees down onto a floor 6 m away: the surface's detail at a camera's working distance.
# Columns: the OpenCV camera axes in the world (x right, y down the image, z forward).
_TILT = np.array([[1.0, 0.0, 0.0], [0.0, -np.sqrt(0.5), np.sqrt(0.5)], [0.0, -np.sqrt(0.5), -np.sqrt(0.5)]])
CAMERA = Camera("cam", Intrinsics(LensModel.PERSPECTIVE, W, H, 60.0, 60.0, (W - 1) / 2, (H - 1) / 2),
                pose=Pose.from_rotation_translation(_TILT, (0.0, -4.0, 4.0)))


def _render(tmp_path, surface):
    import cv2

    from usdscene.document import output_layout as layout
    from usdscene.render.driver import render
    from usdscene.render.synthetic import BoxSpec, PointLightSpec, SphereSpec, SyntheticScene, write_synthetic_stage

    scene = SyntheticScene(cameras=(CAMERA,),
                           spheres=(SphereSpec("1", (0.0, 0.5, 0.5), 0.5, (0.6, 0.2, 0.2), 1, emissive=False),),
                           boxes=(BoxSpec("floor", (0.0, 0.0, -0.05), (30.0, 30.0, 0.1), (0.3, 0.3, 0.3),
                                          surface=surface),),
                           lights=(PointLightSpec("lamp", (0.0, -2.0, 6.0), intensity=200.0, radius_m=0.5),))
    out = tmp_path / (surface or "plain")
    stage = write_synthetic_stage(scene, out / "stage")
    # The examples' default: 2 samples with OpenImageDenoise on its albedo and normal passes.
    render(stage, out, settings_override={"samples": 2, "denoise": True}, progress=False)
    image = cv2.imread(str(layout.image_path(out, "cam", 0)), cv2.IMREAD_GRAYSCALE).astype(float)
    mask = cv2.imread(str(layout.mask_path(out, "cam", 0)), cv2.IMREAD_UNCHANGED)
    return image, mask


@pytest.mark.usd
@pytest.mark.blender
def test_asphalt_keeps_its_detail_through_the_denoiser(tmp_path):
    plain, plain_mask = _render(tmp_path, None)
    asphalt, asphalt_mask = _render(tmp_path, "asphalt")
    # The material changes what the floor looks like, never the masks.
    assert np.array_equal(plain_mask, asphalt_mask) and (asphalt_mask == 1).sum() > 20
    import cv2

    # The floor away from the ball's outline and shadow edge.
    floor = cv2.erode((asphalt_mask == 0).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0

    def detail(image):
        """Mean high-pass (image minus its 3 px blur) of the floor: a flat colour leaves only
        what noise the denoiser kept; a texture the denoiser smeared would leave as little."""
        return float(np.abs(image - cv2.GaussianBlur(image, (0, 0), 3))[floor].mean())

    assert detail(asphalt) > 1.5 * detail(plain)
