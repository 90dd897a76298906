"""``usdscene assets add --kind person`` refuses a person file it cannot pose, naming the file
and every reason; nothing is registered (never rigid without a word)."""

from __future__ import annotations

import json
import struct

import pytest

from usdscene.assetgen.person_rig import missing_keypoint_joints

pytestmark = pytest.mark.usd

FULL_RIG = ["Hips", "Hips/Spine", "Hips/Spine/Neck", "Hips/Spine/Neck/Head",
            "Hips/Spine/LeftArm", "Hips/Spine/LeftArm/LeftForeArm", "Hips/Spine/LeftArm/LeftForeArm/LeftHand",
            "Hips/Spine/RightArm", "Hips/Spine/RightArm/RightForeArm", "Hips/Spine/RightArm/RightForeArm/RightHand",
            "Hips/LeftUpLeg", "Hips/LeftUpLeg/LeftLeg", "Hips/LeftUpLeg/LeftLeg/LeftFoot",
            "Hips/RightUpLeg", "Hips/RightUpLeg/RightLeg", "Hips/RightUpLeg/RightLeg/RightFoot"]


def _usd_person(path, joints, *, skinned=True, method=None):
    from pxr import Sdf, Usd, UsdGeom, UsdSkel, Vt

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    root = UsdSkel.Root.Define(stage, "/Person")
    stage.SetDefaultPrim(root.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/Person/Body")
    mesh.CreatePointsAttr([(0, 0, 0), (0.3, 0, 0), (0, 0, 1.7)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    if joints is not None:
        skel = UsdSkel.Skeleton.Define(stage, "/Person/Skel")
        skel.CreateJointsAttr(Vt.TokenArray(joints))
        if skinned:
            binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
            binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
            binding.CreateJointIndicesPrimvar(False, 1).Set([0, 0, 0])
            binding.CreateJointWeightsPrimvar(False, 1).Set([1.0, 1.0, 1.0])
            if method:
                mesh.GetPrim().CreateAttribute("primvars:skel:skinningMethod", Sdf.ValueTypeNames.Token).Set(method)
    stage.GetRootLayer().Save()
    return path


def _glb_without_skin(path):
    doc = json.dumps({"asset": {"version": "2.0"}, "nodes": [{"name": "body", "mesh": 0}],
                      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}).encode()
    doc += b" " * (-len(doc) % 4)
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + 8 + len(doc)) + struct.pack("<I4s", len(doc), b"JSON") + doc)
    return path


def _add(tmp_path, path, capsys):
    from usdscene.cli import main

    code = main(["assets", "add", str(path), "--class", "walker", "--kind", "person", "--catalog", str(tmp_path / "cat")])
    return code, capsys.readouterr().err


def test_no_skeleton_is_refused_naming_the_file(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _usd_person(tmp_path / "statue.usda", None)
    code, err = _add(tmp_path, path, capsys)
    assert code == 1 and "Traceback" not in err
    assert f"usdscene: error: {path}: no skeleton" in err
    assert not (tmp_path / "cat" / "catalog.json").exists()


def test_unsupported_skinning_and_missing_joints_are_all_named(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _usd_person(tmp_path / "dq.usda", ["Hips", "Hips/Spine", "Hips/Spine/Head"], method="dualQuaternion")
    code, err = _add(tmp_path, path, capsys)
    assert code == 1
    assert "skinningMethod 'dualQuaternion'" in err and "only linear blend skinning" in err
    assert "lacks joints the keypoints need: left shoulder, right shoulder" in err and "right ankle" in err
    unbound = _usd_person(tmp_path / "unbound.usda", FULL_RIG, skinned=False)
    code, err = _add(tmp_path, unbound, capsys)
    assert code == 1 and "no mesh is bound to the skeleton" in err and "lacks joints" not in err


def test_gltf_without_skin_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = _add(tmp_path, _glb_without_skin(tmp_path / "person.glb"), capsys)
    assert code == 1 and "person.glb: no skeleton: the glTF file has no skin" in err


def test_a_posable_rig_is_still_refused_with_the_reason(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = _add(tmp_path, _usd_person(tmp_path / "rigged.usda", FULL_RIG), capsys)
    assert code == 1 and "posing a rigged person of one's own is not supported yet" in err
    assert not (tmp_path / "cat" / "catalog.json").exists()


def test_joint_names_found_by_side_and_stem():
    assert missing_keypoint_joints(FULL_RIG) == []
    assert missing_keypoint_joints(["head", "upperarm_l", "lowerarm_l", "hand_l", "thigh_l", "calf_l", "foot_l"]) == [
        "right shoulder", "right elbow", "right wrist", "right hip", "right knee", "right ankle"]
    assert missing_keypoint_joints(["upper_arm.L", "upper_arm.R"])[:1] == ["head"]
