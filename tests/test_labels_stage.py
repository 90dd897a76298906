"""World triangles from a small composed-style USD stage built here."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.document import stage_schema

pytestmark = pytest.mark.usd


def _stage():
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.Xform.Define(stage, stage_schema.WORLD)
    UsdGeom.Xform.Define(stage, stage_schema.OBJECTS)
    for uid, cls in (("0", "backpack"), ("1", "suitcase")):
        path = stage_schema.object_prim_path(cls, uid)
        xform = UsdGeom.Xform.Define(stage, path)
        xform.GetPrim().SetCustomDataByKey(stage_schema.CUSTOM_UID, uid)
        op = xform.AddTranslateOp()
        if uid == "0":  # moves along x: frame 0 at x=0, frame 1 at x=1, frame 2 and 3 at x=2
            for frame, x in ((0, 0.0), (1, 1.0), (2, 2.0), (3, 2.0)):
                op.Set(Gf.Vec3d(x, 0, 0), Usd.TimeCode(frame))
            vis = xform.GetVisibilityAttr()
            vis.Set(UsdGeom.Tokens.inherited, Usd.TimeCode(0))
            vis.Set(UsdGeom.Tokens.invisible, Usd.TimeCode(4))
        else:
            op.Set(Gf.Vec3d(0, 5, 0))
        body = UsdGeom.Xform.Define(stage, f"{path}/Geom")
        body.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
        mesh = UsdGeom.Mesh.Define(stage, f"{path}/Geom/Box")
        # A unit cube from six quads (12 triangles) plus one pentagon face (3 triangles).
        pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1),
               (0.5, -0.5, 0.5)]
        mesh.CreatePointsAttr(pts)
        mesh.CreateFaceVertexCountsAttr([4, 4, 4, 4, 4, 4, 5])
        mesh.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5,
                                          2, 3, 7, 6, 3, 0, 4, 7, 0, 1, 8, 5, 4])
        guide = UsdGeom.Mesh.Define(stage, f"{path}/Guide")
        guide.CreatePointsAttr([(0, 0, 0), (9, 0, 0), (0, 9, 0)])
        guide.CreateFaceVertexCountsAttr([3])
        guide.CreateFaceVertexIndicesAttr([0, 1, 2])
        guide.CreatePurposeAttr(UsdGeom.Tokens.guide)
    return stage


def test_triangulate_fans():
    from usdscene.scene.stage_geometry import triangulate

    tris = triangulate(np.array([3, 4, 2, 5]), np.arange(14))
    assert tris.tolist() == [[0, 1, 2], [3, 4, 5], [3, 5, 6], [9, 10, 11], [9, 11, 12], [9, 12, 13]]


def test_world_triangles_follow_time_samples_and_visibility():
    from usdscene.scene.stage_geometry import StageGeometry

    geometry = StageGeometry(_stage())
    assert set(geometry.uids) == {"0", "1"}
    f0 = geometry.triangles(0)
    assert f0["0"].shape == (15, 3, 3)  # 6 quads + 1 pentagon; the guide mesh is skipped
    # Scale 2 then translate: the cube spans [0, 2] at frame 0, [1, 3] in x at frame 1.
    assert f0["0"][..., 0].min() == 0 and f0["0"][..., 0].max() == 2
    f1 = geometry.triangles(1)
    assert f1["0"][..., 0].min() == 1 and f1["0"][..., 0].max() == 3
    assert f1["1"][..., 1].min() == 4 and f1["1"][..., 1].max() == 7  # apex at y = -0.5 · 2 + 5
    # Static object and repeated transform come from the cache (same array object).
    assert f1["1"] is f0["1"]
    assert geometry.triangles(3)["0"] is geometry.triangles(2)["0"]
    assert "0" not in geometry.triangles(4)  # invisible
    assert set(geometry.triangles(1, uids={"1"})) == {"1"}


def test_stage_triangles_give_amodal_masks():
    from usdscene.labels.amodal import amodal_projection
    from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
    from usdscene.scene.stage_geometry import StageGeometry

    # Camera 10 m above the origin looking straight down (OpenCV z forward = world -Z).
    rotation = np.diag([1.0, -1.0, -1.0])
    camera = Camera("top", Intrinsics(LensModel.PERSPECTIVE, 64, 48, 20.0, 20.0, 31.5, 23.5),
                    pose=Pose.from_rotation_translation(rotation, (0.0, 0.0, 10.0)))
    triangles = StageGeometry(_stage()).triangles(0)
    proj = amodal_projection(camera, triangles["0"], 0)
    ys, xs = np.nonzero(proj.mask)
    # The cube's top face (z = 2, 8 m from the camera) spans x, y ∈ [0, 2] m → 5 px from the
    # centre; the -0.5 m apex of the pentagon adds a sliver towards -y (image down).
    assert xs.min() == 32 and xs.max() == 36
    assert ys.min() == 19 and ys.max() >= 24
