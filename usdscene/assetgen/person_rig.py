"""What ``usdscene assets add --kind person`` checks in a person file of one's own.

A person class must be posable (its mesh follows a skeleton) and must carry the joints the 17
COCO keypoints come from. :func:`person_rig_problems` reads a USD file (UsdSkel) or a glTF/GLB
file (``skins``) and lists every reason it cannot be posed:

- no skeleton (no ``UsdSkel.Skeleton`` / no glTF ``skin``);
- skinning it does not support: no mesh bound to the skeleton with joint indices and weights,
  or a skinning method other than linear blend (UsdSkel ``dualQuaternion``);
- joints the keypoints need that the skeleton lacks (found by name: head, both shoulders /
  upper arms, elbows / forearms, wrists / hands, hips / thighs, knees / shins, ankles / feet).

Even a file that passes is refused today, with the reason: the people the pipeline poses are
baked from the MakeHuman data (``usdscene.assetgen.people``); posing a user's own rig per frame
is not implemented. Nothing is ever registered rigid without a word.
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

KEYPOINT_JOINTS = {
    "head": ("head",),
    "left shoulder": ("upperarm", "upper_arm", "shoulder", "arm"),
    "right shoulder": ("upperarm", "upper_arm", "shoulder", "arm"),
    "left elbow": ("lowerarm", "forearm", "lower_arm", "elbow"),
    "right elbow": ("lowerarm", "forearm", "lower_arm", "elbow"),
    "left wrist": ("hand", "wrist"),
    "right wrist": ("hand", "wrist"),
    "left hip": ("thigh", "upleg", "upperleg", "upper_leg", "hip"),
    "right hip": ("thigh", "upleg", "upperleg", "upper_leg", "hip"),
    "left knee": ("calf", "shin", "lowerleg", "lower_leg", "leg", "knee"),
    "right knee": ("calf", "shin", "lowerleg", "lower_leg", "leg", "knee"),
    "left ankle": ("foot", "ankle"),
    "right ankle": ("foot", "ankle"),
}
"""Keypoint joint → name stems that count as it (case-insensitive; sides by l/left, r/right)."""
_LEFT = re.compile(r"(^|[^a-z])(l|left)([^a-z]|$)|left", re.I)
_RIGHT = re.compile(r"(^|[^a-z])(r|right)([^a-z]|$)|right", re.I)


def missing_keypoint_joints(joint_names: list[str]) -> list[str]:
    """The keypoint joints (keys of :data:`KEYPOINT_JOINTS`) no joint name stands for."""
    leaves = [name.split("/")[-1] for name in joint_names]
    missing = []
    for role, stems in KEYPOINT_JOINTS.items():
        side = role.split(" ")[0] if " " in role else None
        found = False
        for name in leaves:
            low = name.lower().replace(".", "_").replace("-", "_")
            if side == "left" and not _LEFT.search(name.replace(".", "_")):
                continue
            if side == "right" and not _RIGHT.search(name.replace(".", "_")):
                continue
            if any(stem in low for stem in stems):
                found = True
                break
        if not found:
            missing.append(role)
    return missing


def _usd_problems(path: Path) -> list[str]:
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(path))
    skeletons = [p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)]
    if not skeletons:
        return ["no skeleton: the file has no UsdSkel.Skeleton prim, so nothing can pose it"]
    problems = []
    joints = [str(j) for s in skeletons for j in (UsdSkel.Skeleton(s).GetJointsAttr().Get() or [])]
    skinned = []
    for prim in stage.Traverse():
        binding = UsdSkel.BindingAPI(prim)
        if prim.HasAPI(UsdSkel.BindingAPI) and binding.GetJointIndicesPrimvar().IsDefined() \
                and binding.GetJointWeightsPrimvar().IsDefined():
            skinned.append(prim)
            method = prim.GetAttribute("primvars:skel:skinningMethod")
            value = method.Get() if method and method.HasValue() else "classicLinear"
            if value != "classicLinear":
                problems.append(f"skinning it does not support: {prim.GetPath()} uses skinningMethod "
                                f"{value!r}; only linear blend skinning (classicLinear) is supported")
    if not skinned:
        problems.append("skinning it does not support: no mesh is bound to the skeleton with "
                        "primvars:skel:jointIndices and primvars:skel:jointWeights")
    missing = missing_keypoint_joints(joints)
    if missing:
        problems.append(f"the skeleton lacks joints the keypoints need: {', '.join(missing)} "
                        f"(joints: {', '.join(j.split('/')[-1] for j in joints[:12])}{' ...' if len(joints) > 12 else ''})")
    return problems


def _gltf_json(path: Path) -> dict:
    data = path.read_bytes()
    if path.suffix.lower() == ".glb":
        if data[:4] != b"glTF":
            raise ValueError("not a GLB file (no glTF magic)")
        length, kind = struct.unpack_from("<I4s", data, 12)
        if kind != b"JSON":
            raise ValueError("GLB without a JSON chunk first")
        return json.loads(data[20:20 + length])
    return json.loads(data)


def _gltf_problems(path: Path) -> list[str]:
    doc = _gltf_json(path)
    skins = doc.get("skins") or []
    if not skins:
        return ["no skeleton: the glTF file has no skin"]
    problems = []
    skinned = [m for m in doc.get("meshes", []) for prim in m.get("primitives", [])
               if {"JOINTS_0", "WEIGHTS_0"} <= set(prim.get("attributes", {}))]
    if not skinned:
        problems.append("skinning it does not support: no mesh primitive has JOINTS_0 and WEIGHTS_0")
    nodes = doc.get("nodes", [])
    joints = [nodes[j].get("name", f"node{j}") for skin in skins for j in skin.get("joints", []) if j < len(nodes)]
    missing = missing_keypoint_joints(joints)
    if missing:
        problems.append(f"the skeleton lacks joints the keypoints need: {', '.join(missing)}")
    return problems


def person_rig_problems(path: str | Path) -> list[str]:
    """Every reason the person file ``path`` cannot be posed (empty = a posable rig).

    Raises:
        ValueError: unreadable file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in (".usd", ".usda", ".usdc", ".usdz"):
        return _usd_problems(path)
    if suffix in (".gltf", ".glb"):
        return _gltf_problems(path)
    return [f"no skeleton: {suffix or 'this'} files carry no rig; use USD (UsdSkel) or glTF/GLB with a skin"]


NOT_YET = ("posing a rigged person of one's own is not supported yet: the people the pipeline poses and "
           "labels with keypoints are the shipped person and passenger classes (docs/adapting.md)")
