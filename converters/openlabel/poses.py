"""Coordinate systems, transforms and poses of an OpenLABEL document. Pure module.

* ``coordinate_systems`` form a forest: each system has a parent ("" for a root) and a static
  ``pose_wrt_parent``; ``frames[f].frame_properties.transforms`` override a system's pose in
  one frame. :func:`read_coordinate_systems` reads them into :class:`CoordinateSystems`, which
  gives the pose of a system in the root of its tree, statically or frame by frame.
* The friendly camera form places a camera with ``position_m`` and ``orientation_deg`` (yaw,
  pitch, roll) or ``target_m``: :func:`read_friendly_pose`, :func:`friendly_camera_rotation`.
* Lights and objects carry their pose as object data (``pose_matrix4x4``, or ``position_m``
  with ``rotation_xyz_deg`` or ``rotation_quaternion_xyzw``): :func:`pose_from_object_data`.

Every ``Pose`` maps child → parent coordinates (``usdscene.document.model`` conventions).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, Mapping

from usdscene.errors import ProblemCollector
from usdscene.document.model import Pose, euler_zyx_to_rotation, quaternion_to_rotation

from usdscene.converters.openlabel.load import DocumentBody
from usdscene.converters.openlabel.values import (
    INVALID,
    axis_rotation,
    describe,
    pose_from_rotation,
    read_matrix4x4,
    read_numbers,
    read_transform,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CoordinateSystems:
    """The coordinate-system forest of a document.

    Attributes:
        parents: name → parent name ("" for a root).
        static: name → Pose of the system in its parent (identity where none is given).
        per_frame: frame → {name: Pose in parent} from the frame's transforms.
    """

    parents: dict[str, str]
    static: dict[str, Pose]
    per_frame: dict[int, dict[str, Pose]]

    def world_pose(self, name: str, overrides: Mapping[str, Pose] | None = None) -> Pose:
        """Pose of coordinate system ``name`` in the root of its tree.

        Args:
            name: an existing coordinate system.
            overrides: name → pose in parent that replaces the static pose (one frame's).
        """
        overrides = overrides or {}
        chain = []
        current = name
        while self.parents.get(current):
            chain.append(overrides.get(current, self.static[current]))
            current = self.parents[current]
        if not chain:
            return Pose()
        pose = chain[-1]
        for child in reversed(chain[:-1]):
            pose = pose.compose(child)
        return pose

    def ancestors(self, name: str) -> list[str]:
        """The parent of ``name``, its parent, ... up to the root of its tree."""
        out = []
        current = self.parents.get(name, "")
        while current:
            out.append(current)
            current = self.parents.get(current, "")
        return out

    def root_of(self, name: str) -> str:
        """The root of the tree that holds ``name`` (``name`` itself for a root)."""
        chain = self.ancestors(name)
        return chain[-1] if chain else name

    def track(self, name: str) -> tuple[Pose, tuple[tuple[int, Pose], ...]]:
        """The static world pose of ``name`` and its world pose in every frame whose
        transforms move ``name`` or one of its ancestors, in frame order."""
        chain = set()
        current = name
        while self.parents.get(current):
            chain.add(current)
            current = self.parents[current]
        frames = tuple((number, self.world_pose(name, self.per_frame[number]))
                       for number in sorted(self.per_frame) if chain & self.per_frame[number].keys())
        return self.world_pose(name), frames


def _break_parent_loops(parents: dict[str, str], report) -> None:
    """Make a root of every system whose parent chain loops, reporting each one.

    Systems are walked in document order; ``report(name, through)`` is called for a system
    whose chain comes back to ``through``, and that system becomes a root. Linear in the number
    of systems: a walk stops at the first system already known to reach a root, so a chain
    20,000 deep is walked once, not once per system.
    """
    reaches_root: set[str] = set()
    for name in parents:
        if name in reaches_root:
            continue
        path: list[str] = []
        on_path: set[str] = set()
        current = name
        while current and current not in reaches_root:
            if current in on_path:
                report(name, current)
                parents[name] = ""
                # only `name` is known to be a root now; the others are walked again later
                path = [name]
                break
            path.append(current)
            on_path.add(current)
            current = parents.get(current, "")
        reaches_root.update(path)


def read_coordinate_systems(doc: DocumentBody) -> CoordinateSystems:
    """``coordinate_systems`` and the per-frame ``transforms`` of ``doc``.

    A missing parent or a parent loop is reported and the system treated as a root, so that the
    rest of the document is still read.
    """
    R = doc.root
    parents: dict[str, str] = {}
    static: dict[str, Pose] = {}
    systems = doc.section("coordinate_systems")
    for name, cs in systems.items():
        where = f"{R}.coordinate_systems.{name}"
        if not isinstance(cs, dict):
            doc.add(where, f"expected a JSON object, got {describe(cs)}")
            continue
        parent = cs.get("parent")
        if not isinstance(parent, str):
            doc.add(f"{where}.parent", f"expected the parent's name ('' for a root), got {describe(parent)}")
            parent = ""
        if parent and parent not in systems:
            doc.add(f"{where}.parent", f"parent coordinate system {parent!r} does not exist")
            parent = ""
        if not isinstance(cs.get("type"), str):
            doc.add(f"{where}.type", f"expected a string such as 'scene_cs', 'local_cs', 'sensor_cs', "
                                     f"got {describe(cs.get('type'))}")
        parents[name] = parent
        pose = Pose()
        given = cs.get("pose_wrt_parent")
        if isinstance(given, dict) and given.get("matrix4x4") == [] and len(given) == 1:
            # The VCD library writes an empty matrix for a pose nobody gave; a root needs none.
            if parent:
                log.warning("%s.pose_wrt_parent: empty matrix4x4, read as the identity", where)
        elif "pose_wrt_parent" in cs:
            read = read_transform(cs["pose_wrt_parent"], f"{where}.pose_wrt_parent", doc.problems)
            pose = read if read is not None else pose
        static[name] = pose
    _break_parent_loops(parents, lambda name, through: doc.add(
        f"{R}.coordinate_systems.{name}.parent", f"the parent chain of {name!r} loops through {through!r}"))
    per_frame: dict[int, dict[str, Pose]] = {}
    indirect: list[tuple[int, str, str, str, Pose]] = []
    for number, frame in doc.frames().items():
        props = frame.get("frame_properties")
        if props is None:
            continue
        where = f"{R}.frames.{number}.frame_properties"
        if not isinstance(props, dict):
            doc.add(where, f"expected a JSON object, got {describe(props)}")
            continue
        transforms = props.get("transforms")
        if transforms is None:
            continue
        if not isinstance(transforms, dict):
            doc.add(f"{where}.transforms", f"expected a JSON object, got {describe(transforms)}")
            continue
        for tname, t in transforms.items():
            here = f"{where}.transforms.{tname}"
            if not isinstance(t, dict):
                doc.add(here, f"expected a JSON object, got {describe(t)}")
                continue
            src, dst = t.get("src"), t.get("dst")
            bad = False
            for key, value in (("src", src), ("dst", dst)):
                if not isinstance(value, str) or value not in parents:
                    doc.add(f"{here}.{key}", f"coordinate system {describe(value)} does not exist")
                    bad = True
            if "transform_src_to_dst" not in t:
                doc.add(f"{here}.transform_src_to_dst", "missing 'transform_src_to_dst'")
                continue
            pose = read_transform(t["transform_src_to_dst"], f"{here}.transform_src_to_dst", doc.problems)
            if bad or pose is None:
                continue
            # transform_src_to_dst maps points from src to dst coordinates
            # (X_dst = M · X_src, as the schema states), so a child → parent transform is
            # the child's pose in its parent, and parent → child its inverse.
            if parents.get(src) == dst:
                per_frame.setdefault(number, {})[src] = pose
            elif parents.get(dst) == src:
                per_frame.setdefault(number, {})[dst] = pose.inverse()
            else:
                indirect.append((number, here, src, dst, pose))
    systems = CoordinateSystems(parents, static, per_frame)
    # After the parent/child transforms of every frame, so that a transform between distant
    # systems is resolved against the poses of its own frame.
    streams = doc.section("streams")
    cameras = {name for name, st in streams.items() if isinstance(st, dict) and st.get("type") == "camera"}
    camera_roots = {systems.root_of(name) for name in cameras if name in parents}
    for number, here, src, dst, pose in indirect:
        if systems.root_of(src) != systems.root_of(dst) and not (
                {systems.root_of(src), systems.root_of(dst)} & camera_roots):
            # Two trees without a camera: nothing usdscene places depends on the link.
            log.warning("%s: transform between the separate trees of %r and %r is not used "
                        "(no camera in either)", here, src, dst)
            continue
        problem = _resolve_through_graph(systems, number, src, dst, pose)
        if problem:
            doc.add(here, problem)
    return systems


def _resolve_through_graph(systems: CoordinateSystems, number: int, src: str, dst: str,
                           pose: Pose) -> str | None:
    """Turn a per-frame ``src → dst`` transform between systems that are not parent and child
    into a pose in parent for one of them, in ``systems.per_frame[number]``.

    The moved system is ``src`` (its pose in its parent becomes the one that puts it at
    ``world(dst) · M``), unless ``src`` is a root or an ancestor of ``dst``: then ``dst`` moves
    to ``world(src) · M⁻¹``. Returns why it cannot be resolved, or None.
    """
    if src == dst:
        return f"a transform from coordinate system {src!r} to itself"
    if systems.root_of(src) != systems.root_of(dst):
        return (f"coordinate systems {src!r} and {dst!r} are in different trees (roots "
                f"{systems.root_of(src)!r} and {systems.root_of(dst)!r}); no transform can connect them")
    overrides = systems.per_frame.setdefault(number, {})
    moved, anchor, anchor_to_moved = src, dst, pose
    if not systems.parents[src] or src in systems.ancestors(dst):
        moved, anchor, anchor_to_moved = dst, src, pose.inverse()
    parent_world = systems.world_pose(systems.parents[moved], overrides)
    overrides[moved] = parent_world.inverse().compose(systems.world_pose(anchor, overrides).compose(anchor_to_moved))
    return None


def read_friendly_pose(friendly: Mapping, where: str, problems: ProblemCollector):
    """Camera → world pose of the friendly form, from ``position_m`` + ``orientation_deg`` or
    ``target_m`` (see :func:`friendly_camera_rotation`); None if absent, INVALID if bad."""
    if not any(k in friendly for k in ("position_m", "orientation_deg", "target_m")):
        return None
    if "position_m" not in friendly:
        problems.add(f"{where}.position_m", "orientation_deg/target_m need a position_m [x, y, z] (metres)")
        return INVALID
    position = read_numbers(friendly["position_m"], f"{where}.position_m", problems, lengths=(3,))
    if "orientation_deg" in friendly and "target_m" in friendly:
        problems.add(f"{where}.target_m", "give orientation_deg or target_m, not both")
        return INVALID
    yaw = pitch = roll = 0.0
    if "orientation_deg" in friendly:
        angles = read_numbers(friendly["orientation_deg"], f"{where}.orientation_deg", problems,
                              lengths=(3,), what="angles [yaw, pitch, roll] in degrees")
        if angles is None:
            return INVALID
        yaw, pitch, roll = (math.radians(a) for a in angles)
    elif "target_m" in friendly:
        target = read_numbers(friendly["target_m"], f"{where}.target_m", problems, lengths=(3,))
        if target is None or position is None:
            return INVALID
        d = [t - p for t, p in zip(target, position)]
        if math.sqrt(sum(v * v for v in d)) < 1e-9:
            problems.add(f"{where}.target_m", f"target_m {list(target)} equals position_m")
            return INVALID
        yaw = math.atan2(d[1], d[0])
        pitch = math.atan2(d[2], math.hypot(d[0], d[1]))
    else:
        problems.add(f"{where}.orientation_deg", "position_m needs orientation_deg [yaw, pitch, roll] or target_m")
        return INVALID
    if position is None:
        return INVALID
    return pose_from_rotation(friendly_camera_rotation(yaw, pitch, roll), position)


def friendly_camera_rotation(yaw_rad: float, pitch_rad: float, roll_rad: float):
    """Camera → world rotation (OpenCV camera axes) of the friendly ``orientation_deg``.

    At yaw = pitch = roll = 0 the camera looks along world +X with the image up along world +Z
    (image right = world -Y). Yaw turns the view about world +Z (counter-clockwise seen from
    above, +90° looks along +Y), pitch raises it (+ looks up), roll turns the camera about
    its optical axis (+ turns the image content counter-clockwise, i.e. the camera clockwise
    as seen from behind it).

    Returns:
        (3, 3) float64 array whose columns are the camera x (right), y (down), z (forward)
        axes in world coordinates.
    """
    import numpy as np

    base = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return (np.asarray(axis_rotation("Z", yaw_rad)) @ np.asarray(axis_rotation("Y", -pitch_rad))
            @ base @ np.asarray(axis_rotation("Z", roll_rad)))


def pose_from_object_data(items: Mapping[str, tuple[str, Any, str]], problems: ProblemCollector):
    """Pose from the object data ``pose_matrix4x4`` or ``position_m`` [+ ``rotation_xyz_deg``
    | ``rotation_quaternion_xyzw``]; None if absent, INVALID if invalid.

    Args:
        items: name → (kind, value, JSON path of the value), as
            :func:`usdscene.converters.openlabel.objects.read_object_data` returns them.
    """
    P = problems
    if "pose_matrix4x4" in items:
        clash = [k for k in ("position_m", "rotation_xyz_deg", "rotation_quaternion_xyzw") if k in items]
        if clash:
            problems.add(items[clash[0]][2], f"give pose_matrix4x4 or {clash[0]}, not both")
            return INVALID
        pose = read_matrix4x4(items["pose_matrix4x4"][1], items["pose_matrix4x4"][2], P)
        return INVALID if pose is None else pose
    rotations = [k for k in ("rotation_xyz_deg", "rotation_quaternion_xyzw") if k in items]
    if "position_m" not in items:
        if rotations:
            problems.add(items[rotations[0]][2], f"{rotations[0]} needs a position_m vec [x, y, z] (metres)")
            return INVALID
        return None
    position = read_numbers(items["position_m"][1], items["position_m"][2], P, lengths=(3,))
    if len(rotations) > 1:
        problems.add(items[rotations[1]][2], "give rotation_xyz_deg or rotation_quaternion_xyzw, not both")
        return INVALID
    rotation: Any = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    if rotations == ["rotation_xyz_deg"]:
        angles = read_numbers(items["rotation_xyz_deg"][1], items["rotation_xyz_deg"][2], P, lengths=(3,),
                              what="angles [rx, ry, rz] in degrees")
        if angles is None:
            return INVALID
        rotation = euler_zyx_to_rotation(math.radians(angles[2]), math.radians(angles[1]),
                                         math.radians(angles[0]))
    elif rotations:
        quaternion = read_numbers(items["rotation_quaternion_xyzw"][1], items["rotation_quaternion_xyzw"][2],
                                  P, lengths=(4,))
        if quaternion is None:
            return INVALID
        if math.sqrt(sum(q * q for q in quaternion)) < 1e-9:
            problems.add(items["rotation_quaternion_xyzw"][2], f"quaternion {list(quaternion)} has zero length")
            return INVALID
        rotation = quaternion_to_rotation(quaternion)
    if position is None:
        return INVALID
    return pose_from_rotation(rotation, position)
