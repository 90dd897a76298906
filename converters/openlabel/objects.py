"""Objects of an OpenLABEL document: lights, places and dynamic objects. Pure module.

An object's ``type`` decides what it is: ``light`` (kind, power, colour and pose as object
data), ``place`` (a named target inside the environment asset, e.g. ``seat_03A``) or else a
dynamic object whose type is an asset class, with presence (``frame_intervals``), an optional
pose (static, and per frame from ``frames[f].objects``) and randomization knobs.

Object data are read by name (:func:`read_object_data`); names outside usdscene's vocabulary
are somebody else's annotations and pass (repeated or not), except on lights, which are
usdscene's own type, and lower-case near misses of a known name, which are typos. An object
with an empty ``type`` is valid OpenLABEL; only a catalog check refuses it.
"""

from __future__ import annotations

import difflib
import functools
import math
import re
from typing import Any, Mapping

from usdscene.errors import ProblemCollector
from usdscene.document.model import (
    PLACEMENT_RELATIONS,
    DeclaredRegion,
    FrameInterval,
    Light,
    LightKind,
    PlaceRef,
    Randomization,
    RelationType,
    SceneObject,
)

from usdscene.converters.openlabel.carry import OBJECT_KEYS, element_residue, frame_residues
from usdscene.converters.openlabel.load import DocumentBody
from usdscene.converters.openlabel.poses import pose_from_object_data
from usdscene.converters.openlabel.values import (
    INVALID,
    describe,
    read_bool,
    read_intervals,
    read_number,
    read_numbers,
    read_text,
    suggest,
)

LIGHT_TYPE = "light"
PLACE_TYPE = "place"
UID_PATTERN = re.compile(r"^(-?[0-9]+|[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12})$")

# Object data names (``object_data.<kind>[i].name``).
POSE_DATA = {"position_m": "vec", "rotation_xyz_deg": "vec", "rotation_quaternion_xyzw": "vec",
             "pose_matrix4x4": "vec"}
LIGHT_DATA = {"kind": "text", "power_w": "num", "color_rgb": "vec", "radius_m": "num",
              "spot_angle_deg": "num", "spot_blend": "num", "size_m": "vec", "sun_angle_deg": "num",
              **POSE_DATA}
OBJECT_DATA = {"appearance": "text", "pose_variant": "text", "color_rgb": "vec", "position_noise_m": "num",
               "rotation_noise_deg": "num", "random_color": "boolean", "random_appearance": "boolean",
               **POSE_DATA}
DATA_KINDS = ("text", "num", "vec", "boolean")


# A place's object data usdscene reads: one cuboid per placement relation (declared regions).
PLACE_DATA = {relation.value: "cuboid" for relation in RelationType}


def _declared_regions(obj: Mapping, where: str, problems: ProblemCollector) -> tuple[DeclaredRegion, ...]:
    """Regions a place object declares as OpenLABEL ``cuboid`` object data: name = placement
    relation, val = ``[x, y, z, qx, qy, qz, qw, sx, sy, sz]`` (centre in world metres, rotation
    quaternion, full sizes in metres); the region's support surface is the cuboid's bottom face."""
    data = obj.get("object_data")
    cuboids = data.get("cuboid", []) if isinstance(data, dict) else []
    if not isinstance(cuboids, list):
        problems.add(f"{where}.object_data.cuboid", f"expected a list, got {describe(cuboids)}")
        return ()
    regions: list[DeclaredRegion] = []
    for k, item in enumerate(cuboids):
        at = f"{where}.object_data.cuboid[{k}]"
        if not isinstance(item, dict):
            problems.add(at, f"expected a JSON object, got {describe(item)}")
            continue
        relation = item.get("name")
        if relation not in PLACEMENT_RELATIONS:
            continue  # another cuboid of the place (someone's 3D box): carried, not a region
        if any(r.relation == relation for r in regions):
            problems.add(f"{at}.name", f"place has two {relation!r} cuboids")
            continue
        val = read_numbers(item.get("val"), f"{at}.val", problems, lengths=(10,),
                           what="numbers (x, y, z, qx, qy, qz, qw, sx, sy, sz)")
        if val is None:
            continue
        quaternion, size = val[3:7], val[7:10]
        if min(size) <= 0:
            problems.add(f"{at}.val", f"cuboid sizes must be positive, got {list(size)}")
            continue
        if abs(math.sqrt(sum(q * q for q in quaternion)) - 1.0) > 1e-3:
            problems.add(f"{at}.val", f"the rotation quaternion {list(quaternion)} is not of unit length")
            continue
        regions.append(DeclaredRegion.from_cuboid(relation, val))
    return tuple(regions)


def read_objects(doc: DocumentBody) -> tuple[list[Light], list[PlaceRef], list[SceneObject], dict[str, str]]:
    """Lights, places and dynamic objects of ``objects`` (with their per-frame poses).

    Returns:
        (lights, places, objects, uids): the elements that could be read, in document order,
        and uid → ``"light"``, ``"place"``, ``"object"`` or ``"other"`` (not readable) for every
        uid of ``objects``, to resolve relations against.
    """
    R = doc.root
    lights: list[Light] = []
    places: list[PlaceRef] = []
    objects: list[SceneObject] = []
    uids: dict[str, str] = {}  # uid → "light" | "place" | "object" (| "other" for bad ones)
    place_names: dict[str, str] = {}
    light_names: dict[str, str] = {}
    frame_poses, frame_entries = _frame_object_poses(doc)
    for uid, obj in doc.section("objects").items():
        where = f"{R}.objects.{uid}"
        uids[uid] = "other"
        if not UID_PATTERN.match(uid):
            doc.add(where, f"object uid {uid!r} must be an integer string or a UUID")
        if not isinstance(obj, dict):
            doc.add(where, f"expected a JSON object, got {describe(obj)}")
            continue
        name = obj.get("name")
        if not isinstance(name, str):
            doc.add(f"{where}.name", f"expected the object's name (a string), got {describe(name)}")
            name = ""
        otype = obj.get("type")
        if not isinstance(otype, str):  # "" is valid OpenLABEL; only a catalog can refuse it
            doc.add(f"{where}.type", f"expected the object's type (class name), got {describe(otype)}")
            continue
        intervals: tuple[FrameInterval, ...] = ()
        if "frame_intervals" in obj:
            intervals = read_intervals(obj["frame_intervals"], f"{where}.frame_intervals", doc.problems) or ()
        if otype == PLACE_TYPE:
            uids[uid] = "place"
            if not name:
                doc.add(f"{where}.name", "a place needs its name in the environment (e.g. 'seat_03A')")
                continue
            if name in place_names:
                doc.add(f"{where}.name", f"place {name!r} is already object {place_names[name]}")
                continue
            place_names[name] = uid
            places.append(PlaceRef(uid=uid, name=name, regions=_declared_regions(obj, where, doc.problems),
                                   extra=element_residue(obj, PLACE_DATA, OBJECT_KEYS)))
            if uid in frame_poses:
                doc.add(frame_poses[uid][0][2], "places have no per-frame poses (their geometry is "
                                                "in the environment asset)")
        elif otype == LIGHT_TYPE:
            uids[uid] = "light"
            if name in light_names:
                doc.add(f"{where}.name", f"light name {name!r} is already used by object {light_names[name]}")
            light_names[name] = uid
            light = _read_light(doc, uid, name, obj, where, intervals)
            if light is not None:
                lights.append(light)
            if uid in frame_poses:
                doc.add(frame_poses[uid][0][2], "lights have no per-frame poses")
        else:
            uids[uid] = "object"
            scene_object = _read_scene_object(doc, uid, name, otype, obj, where, intervals,
                                              tuple((f, p) for f, p, _ in frame_poses.get(uid, ())),
                                              frame_entries.get(uid, ()))
            if scene_object is not None:
                objects.append(scene_object)
    return lights, places, objects, uids


def _frame_object_poses(doc: DocumentBody) -> tuple[dict[str, list], dict[str, list]]:
    """(uid → [(frame, Pose, where)] from ``frames[f].objects[uid].object_data``, uid →
    [(frame, entry)] of every JSON object entry); frame entries of uids that are not objects
    are reported as dangling."""
    out: dict[str, list] = {}
    entries: dict[str, list] = {}
    R = doc.root
    known = doc.body.get("objects", {})
    known = known if isinstance(known, dict) else {}
    dangling: set = set()
    for number, where, objs in doc.frame_sections("objects"):
        for uid, entry in objs.items():
            if uid not in known:
                if uid not in dangling:
                    dangling.add(uid)
                    doc.add(f"{where}.{uid}", f"object {uid!r} does not exist in {R}.objects")
                continue
            if not entry:
                continue
            if not isinstance(entry, dict):
                doc.add(f"{where}.{uid}", f"expected a JSON object, got {describe(entry)}")
                continue
            entries.setdefault(uid, []).append((number, entry))
            items = read_object_data(entry.get("object_data"), f"{where}.{uid}.object_data", POSE_DATA,
                                     strict=False, problems=doc.problems)
            if not items:
                continue
            pose = pose_from_object_data(items, doc.problems)
            if pose is not None and pose is not INVALID:
                out.setdefault(uid, []).append((number, pose, f"{where}.{uid}"))
    return out, entries


def _read_light(doc: DocumentBody, uid: str, name: str, obj: Mapping, where: str,
                intervals: tuple[FrameInterval, ...]) -> Light | None:
    P = doc.problems
    items = read_object_data(obj.get("object_data"), f"{where}.object_data", LIGHT_DATA,
                             strict=True, problems=P)
    if items is None:
        return None
    kwargs: dict = {}
    if "kind" not in items:
        doc.add(f"{where}.object_data", "a light needs a text 'kind': point, spot, sun or area")
        return None
    kind_text = read_text(items["kind"][1], items["kind"][2], P)
    if kind_text is None:
        return None
    try:
        kind = LightKind(kind_text)
    except ValueError:
        doc.add(items["kind"][2], f"unknown light kind {describe(kind_text)}; expected point, spot, sun or area")
        return None
    for key, opts in (("power_w", dict(non_negative=True)), ("radius_m", dict(non_negative=True)),
                      ("spot_angle_deg", dict(positive=True)), ("spot_blend", dict(non_negative=True)),
                      ("sun_angle_deg", dict(non_negative=True))):
        if key in items:
            value = read_number(items[key][1], items[key][2], P, **opts)
            if value is not None:
                if key == "spot_angle_deg" and value > 180:
                    doc.add(items[key][2], f"spot_angle_deg is the full cone angle, at most 180, got {value:g}")
                elif key == "spot_blend" and value > 1:
                    doc.add(items[key][2], f"spot_blend is in [0, 1], got {value:g}")
                else:
                    kwargs[key] = value
    if "color_rgb" in items:
        color = _read_color(items["color_rgb"], P)
        if color is not None:
            kwargs["color_rgb"] = color
    if "size_m" in items:
        size = read_numbers(items["size_m"][1], items["size_m"][2], P, lengths=(2,), what="[width, height] in metres")
        if size is not None:
            if min(size) <= 0:
                doc.add(items["size_m"][2], f"area light size must be positive, got {list(size)}")
            else:
                kwargs["size_m"] = size
    pose = pose_from_object_data(items, P)
    if pose is INVALID:
        return None
    if pose is None:
        doc.add(f"{where}.object_data", "a light needs a pose: vec 'position_m' (+ 'rotation_xyz_deg' or "
                                        "'rotation_quaternion_xyzw') or vec 'pose_matrix4x4'")
        return None
    if kind is LightKind.SUN and "power_w" not in items:
        # Light's 100 W default would be a sun of 100 W/m²: most of an outdoor image clipped.
        from usdscene.document.imaging import DEFAULT_SUN_IRRADIANCE_W_M2

        kwargs["power_w"] = DEFAULT_SUN_IRRADIANCE_W_M2
    return Light(uid=uid, name=name, kind=kind, pose=pose, frame_intervals=intervals, **kwargs)


def _read_scene_object(doc: DocumentBody, uid: str, name: str, otype: str, obj: Mapping, where: str,
                       intervals: tuple[FrameInterval, ...], frame_poses: tuple,
                       frame_entries: tuple | list = ()) -> SceneObject | None:
    P = doc.problems
    items = read_object_data(obj.get("object_data"), f"{where}.object_data", OBJECT_DATA,
                             strict=False, problems=P)
    if items is None:
        return None
    kwargs: dict = {}
    if "appearance" in items:
        kwargs["appearance"] = read_text(items["appearance"][1], items["appearance"][2], P, non_empty=True)
    if "pose_variant" in items:
        kwargs["pose_variant"] = read_text(items["pose_variant"][1], items["pose_variant"][2], P, non_empty=True)
    if "color_rgb" in items:
        kwargs["color_rgb"] = _read_color(items["color_rgb"], P)
    knobs: dict = {}
    for key in ("position_noise_m", "rotation_noise_deg"):
        if key in items:
            value = read_number(items[key][1], items[key][2], P, non_negative=True)
            if value is not None:
                knobs[key] = value
    for key in ("random_color", "random_appearance"):
        if key in items:
            value = read_bool(items[key][1], items[key][2], P)
            if value is not None:
                knobs[key] = value
    pose = pose_from_object_data(items, P)
    if pose is INVALID:
        return None
    return SceneObject(uid=uid, name=name, class_name=otype, frame_intervals=intervals, pose=pose,
                       frame_poses=frame_poses, randomization=Randomization(**knobs),
                       extra=element_residue(obj, OBJECT_DATA, OBJECT_KEYS),
                       frame_extra=frame_residues(frame_entries, POSE_DATA), **kwargs)


def _read_color(item: tuple[str, Any, str], problems: ProblemCollector) -> tuple[float, float, float] | None:
    """A linear RGB colour in [0, 1] from an object data item (kind, value, where)."""
    color = read_numbers(item[1], item[2], problems, lengths=(3,), what="linear RGB values")
    if color is None:
        return None
    if min(color) < 0 or max(color) > 1:
        problems.add(item[2], f"colour components are linear RGB in [0, 1], got {list(color)}")
        return None
    return color  # type: ignore[return-value]


@functools.lru_cache(maxsize=4096)
def _close_names(name: str, known: tuple[str, ...]) -> list[str]:
    """The known name nearest ``name`` (or none): asked once per name, not per frame, since a
    moving sequence repeats its per-frame object data names in every frame."""
    return difflib.get_close_matches(name, list(known), n=1, cutoff=0.75)


def read_object_data(data: Any, where: str, known: Mapping[str, str], *, strict: bool,
                     problems: ProblemCollector) -> dict | None:
    """``object_data`` → {name: (kind, val, where)} for the names in ``known``.

    Unknown names are errors when ``strict`` (lights: our own type); otherwise they are
    somebody else's annotations and pass, unless they look like a misspelt known name.
    """
    if data is None:
        return {}
    if not isinstance(data, dict):
        problems.add(where, f"expected a JSON object, got {describe(data)}")
        return None
    out: dict = {}
    seen: set = set()
    for kind, items in data.items():
        if not isinstance(items, list):
            problems.add(f"{where}.{kind}", f"expected a list, got {describe(items)}")
            continue
        for index, item in enumerate(items):
            here = f"{where}.{kind}[{index}]"
            if not isinstance(item, dict):
                problems.add(here, f"expected a JSON object, got {describe(item)}")
                continue
            name = item.get("name")
            if not isinstance(name, str):
                if kind in DATA_KINDS and (strict or name is not None):
                    problems.add(f"{here}.name", f"expected a name, got {describe(name)}")
                continue
            if name not in known:
                close = _close_names(name, tuple(known))
                # A near miss of a known name of the same kind, written in usdscene's lower-case
                # style, is a typo; anything else ("Position") is somebody else's data.
                typo = close and known[close[0]] == kind and name == name.lower()
                if kind in DATA_KINDS and (strict or typo):
                    problems.add(f"{here}.name", f"unknown {kind} {name!r}{suggest(name, known)}; known: "
                                                 f"{', '.join(known)}")
                continue
            # repeated names only matter where usdscene reads them (datasets repeat their own)
            if name in seen:
                problems.add(f"{here}.name", f"duplicate object data name {name!r} in one element")
                continue
            seen.add(name)
            if known[name] != kind:
                problems.add(here, f"{name!r} must be a {known[name]!r} entry, not {kind!r}")
                continue
            if "val" not in item:
                problems.add(f"{here}.val", f"{name!r} has no 'val'")
                continue
            out[name] = (kind, item["val"], f"{here}.val")
    return out
