"""Scenes from other people's files: every way of writing a Y-up scene, variant sets whose
variants differ in size, orientation rules, colour slots, forward axes, implausible units,
unreachable variants, files outside the working folder, place kinds and the catalog listing.

Every input is built inside the test, the way an exporter or a script writes it: Y-up GLBs
with the Z-up → Y-up turn in the node transforms or baked into the vertices (Blender's
exporter), a USD file with a ``rotateX -90`` root, multi-variant vehicles in centimetres.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from usdscene.assetgen.asset_import import ImportOptions, import_asset
from usdscene.cli import main
from usdscene.document import model as m
from usdscene.errors import AssetError
from usdscene.scene.catalog import load_catalog

pytestmark = pytest.mark.usd

# Z-up → Y-up: (x, y, z) → (x, z, -y), as glTF exporters turn a Z-up scene.
Z_TO_Y = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
# Bays in Z-up metres: (name, centre x, centre y, yaw deg); 2.4 x 5.0 m, 2.2 m clearance.
BAYS = (("bay_A1", -3.0, 4.0, 0.0), ("bay_A2", 0.0, 4.0, 0.0), ("bay_B1", 3.0, -4.0, 30.0))
BAY_SIZE = (2.4, 5.0, 2.2)


@pytest.fixture()
def workdir(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "assets").mkdir()
    return tmp_path


def _placed(x: float, y: float, z: float, yaw_deg: float = 0.0) -> np.ndarray:
    a = math.radians(yaw_deg)
    out = np.eye(4)
    out[:3, :3] = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]
    out[:3, 3] = (x, y, z)
    return out


def _lot_parts():
    """(floor mesh, [(place node name, box mesh, placement)]) in Z-up metres; each box is
    centred on its node, which stands on the floor."""
    import trimesh

    floor = trimesh.creation.box([14.0, 14.0, 0.2])
    floor.apply_translation([0.0, 0.0, -0.1])
    floor.visual.face_colors = [120, 120, 118, 255]
    boxes = [(f"place.{name}.on", trimesh.creation.box(BAY_SIZE), _placed(x, y, BAY_SIZE[2] / 2, yaw))
             for name, x, y, yaw in BAYS]
    return floor, boxes


def glb_turned_nodes(path: Path) -> Path:
    """Y-up glTF whose nodes carry the turn (Sketchfab, 3ds Max, trimesh scenes): every mesh
    is Z up in its own frame, every node is ``Z_TO_Y @ placement``."""
    import trimesh

    floor, boxes = _lot_parts()
    scene = trimesh.Scene()
    scene.add_geometry(floor, node_name="floor", geom_name="floor", transform=Z_TO_Y)
    for name, box, placed in boxes:
        scene.add_geometry(box, node_name=name, geom_name=name, transform=Z_TO_Y @ placed)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def glb_baked(path: Path) -> Path:
    """Y-up glTF as Blender's exporter writes it: the turn baked into the vertices, node
    transforms expressed in Y-up axes."""
    import trimesh

    floor, boxes = _lot_parts()
    scene = trimesh.Scene()
    scene.add_geometry(floor.copy().apply_transform(Z_TO_Y), node_name="floor", geom_name="floor")
    for name, box, placed in boxes:
        scene.add_geometry(box.copy().apply_transform(Z_TO_Y), node_name=name, geom_name=name,
                           transform=Z_TO_Y @ placed @ Z_TO_Y.T)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def usd_rotated_root(path: Path) -> Path:
    """Y-up USD file whose root prim is ``rotateX -90`` over a Z-up modelled scene."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Lot")
    root.AddRotateXOp().Set(-90.0)
    stage.SetDefaultPrim(root.GetPrim())
    floor, boxes = _lot_parts()
    _usd_mesh(stage, "/Lot/floor", floor)
    for name, box, placed in boxes:
        prim = _usd_mesh(stage, f"/Lot/{name.replace('.', '_')}", box)
        UsdGeom.Xformable(prim).AddTransformOp().Set(Gf.Matrix4d(placed.T.tolist()))
    stage.Save()
    return path


def _usd_mesh(stage, path: str, mesh):
    from pxr import UsdGeom

    usd = UsdGeom.Mesh.Define(stage, path)
    usd.CreatePointsAttr(np.asarray(mesh.vertices, dtype=np.float32).tolist())
    usd.CreateFaceVertexCountsAttr([3] * len(mesh.faces))
    usd.CreateFaceVertexIndicesAttr(np.asarray(mesh.faces).reshape(-1).tolist())
    usd.CreateExtentAttr([mesh.vertices.min(axis=0).tolist(), mesh.vertices.max(axis=0).tolist()])
    return usd


def _crate_obj(path: Path, size=(1.2, 2.0, 1.0)) -> Path:
    """A Z-up box object in metres (a stand-in for a small vehicle)."""
    import trimesh

    box = trimesh.creation.box(size)
    box.apply_translation([0.0, 0.0, size[2] / 2])
    box.export(str(path))
    return path


def _scene_on(places: list[str], environment: str, classes: list[str], seed: int = 4) -> m.SceneSpec:
    objects, refs, relations = [], [], []
    for i, (place, class_name) in enumerate(zip(places, classes)):
        objects.append(m.SceneObject(uid=str(i), name=f"{class_name}_{i}", class_name=class_name,
                                     randomization=m.Randomization(position_noise_m=0.2, rotation_noise_deg=5.0)))
        refs.append(m.PlaceRef(uid=str(100 + i), name=place))
        relations.append(m.Relation(uid=str(i), type="is_on", subject_uid=str(i), object_uid=str(100 + i)))
    return m.SceneSpec(name="lot", environment=environment, objects=tuple(objects), places=tuple(refs),
                       relations=tuple(relations), seed=seed, asset_paths=("assets",))


# --------------------------------------------------------------------------------------------
# 1. Place boxes under rotated nodes


def test_every_way_of_writing_a_y_up_scene_gives_the_same_regions_and_poses(workdir):
    from usdscene.scene.compose import compose_stage

    glb_turned_nodes(workdir / "turned.glb")
    glb_baked(workdir / "baked.glb")
    usd_rotated_root(workdir / "rotated.usda")
    _crate_obj(workdir / "crate.obj")
    import_asset("crate.obj", "crate", "assets", ImportOptions(up_axis="Z"))
    regions, poses = {}, {}
    for source, name in (("turned.glb", "lot_turned"), ("baked.glb", "lot_baked"), ("rotated.usda", "lot_usd")):
        entry = import_asset(source, name, "assets", ImportOptions(kind="environment"))
        regions[name] = {p: (place.regions["is_on"].pose.as_array(), place.regions["is_on"].size_m)
                         for p, place in entry.places.items()}
    catalog = load_catalog(["assets"], base_dir=workdir)
    for name in regions:
        scene = _scene_on(["bay_A1", "bay_B1"], name, ["crate", "crate"])
        result = compose_stage(scene, catalog, workdir / name / "stage")
        poses[name] = {uid: p.spans[0].pose.as_array() for uid, p in result.placements.items()}
    # The modelled truth: each bay's region is the box's bottom face, Z up, its x along the bay.
    for place, x, y, yaw in BAYS:
        expected = _placed(x, y, 0.0, yaw)
        for name in regions:
            pose, size = regions[name][place]
            np.testing.assert_allclose(pose, expected, atol=1e-6, err_msg=f"{name} {place}")
            assert size == BAY_SIZE, (name, place, size)
    for name in ("lot_baked", "lot_usd"):
        for place in regions["lot_turned"]:
            assert np.array_equal(regions[name][place][0], regions["lot_turned"][place][0]), (name, place)
        for uid in poses["lot_turned"]:
            np.testing.assert_allclose(poses[name][uid], poses["lot_turned"][uid], atol=1e-12)
    # The crate stands upright on the asphalt: its up axis is world Z, its base at z = 0.
    for pose in poses["lot_turned"].values():
        assert pose[2, 2] == pytest.approx(1.0) and pose[2, 3] == pytest.approx(0.0, abs=1e-9)


def test_a_place_box_with_no_vertical_axis_is_refused_with_its_node(workdir):
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box([8.0, 0.1, 8.0]), node_name="floor", geom_name="floor")
    tilted = np.eye(4)
    tilted[:3, :3] = trimesh.transformations.rotation_matrix(math.radians(20.0), [1, 0, 0])[:3, :3]
    scene.add_geometry(trimesh.creation.box([2.0, 2.0, 5.0]), node_name="place.ramp_1.on", geom_name="ramp",
                       transform=tilted)
    (workdir / "ramp.glb").write_bytes(scene.export(file_type="glb"))
    with pytest.raises(AssetError) as info:
        import_asset("ramp.glb", "ramp", "assets", ImportOptions(kind="environment"))
    assert "place.ramp_1.on" in str(info.value) and "vertical" in str(info.value)
    assert not (workdir / "assets" / "catalog.json").exists()
