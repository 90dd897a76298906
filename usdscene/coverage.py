"""Camera-system design maths: targets, candidate cameras, visibility, smallest covering set.

Pure module (numpy, scipy, trimesh/embreex; no pxr, no bpy): it works on world triangles and
catalog places handed in by :mod:`usdscene.camera_design`, which reads them from a composed
stage. The pieces, each a function ``input -> result``:

* :func:`load_lenses` / :func:`lens_intrinsics`: the lens catalog (shipped
  ``usdscene/data/lenses.json``, extended or overridden by a user file).
* :func:`load_dori` / :func:`dori_class`: image-detail classes as pixel density at the target
  (IEC 62676-4:2015 by default, ``usdscene/data/dori.json``; a user file replaces it).
* :func:`targets_from_places`: sample points in the regions of catalog places
  (``seat_*:on,below,in_front``) or in explicit boxes.
* :class:`Occluders`: ray casting against the scene's triangles (Embree through ``embreex``
  when it is installed, trimesh's own ray-triangle test otherwise).
* :func:`candidate_mounts` / :func:`candidate_cameras`: positions on the ceiling and the walls
  found by casting rays in the environment, aimed at clusters of targets, times every lens.
* :func:`evaluate_visibility`: per (camera, target) the fraction of the target's points inside
  the image, the fraction seen (inside and unoccluded), the pixel density and its class.
* :func:`select_cameras`: the smallest set giving every target ≥ K cameras, as an integer
  program (``scipy.optimize.milp``, HiGHS) with a greedy fallback and its gap to the LP bound.

Pixel density (px/m) of a point is the image-space length, in pixels, of one metre laid at the
point perpendicular to the viewing ray, taken in the worse of the two perpendicular
directions (the local Jacobian of the exact lens model from :mod:`usdscene.projection`), so a
fisheye's squeezed radial direction at the edge of its image is what counts.
"""

from __future__ import annotations

import fnmatch
import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.catalog import REGION_RELATIONS, Place
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.model import Camera, Intrinsics, LensModel, Pose
from usdscene.projection import project_points

log = logging.getLogger(__name__)

DATA_DIR = Path(__file__).resolve().parent / "data"
LENSES_FILE = DATA_DIR / "lenses.json"
DORI_FILE = DATA_DIR / "dori.json"

# Points of a target lie this far inside its region, so that a point on a support surface is
# not hidden by that surface itself.
SURFACE_LIFT_M = 0.03
# A ray stops this short of its target point (the marker radius of verification renders).
RAY_MARGIN_M = 0.02


# --------------------------------------------------------------------------------------------
# Lens catalog and DORI table


@dataclass(frozen=True)
class Lens:
    """A lens + sensor entry of the lens catalog.

    Attributes:
        name: catalog key.
        model: projection model (``perspective``, ``fisheye_equisolid``, ...).
        focal_length_mm: focal length in millimetres.
        sensor_width_mm: sensor width in millimetres.
        fov_deg: fisheye image-circle field of view (degrees); None for pinhole lenses.
        resolution_px: (width, height) of the camera's image in pixels.
        description: free text.
    """

    name: str
    model: LensModel
    focal_length_mm: float
    sensor_width_mm: float
    resolution_px: tuple[int, int]
    fov_deg: float | None = None
    description: str = ""


def load_lenses(extra: str | os.PathLike | None = None) -> dict[str, Lens]:
    """The shipped lens catalog, extended (same name: replaced) by a user file.

    Args:
        extra: a JSON file of the same format as ``usdscene/data/lenses.json``.

    Returns:
        name → :class:`Lens`, in file order.

    Raises:
        DocumentError: a file is unreadable or an entry malformed (every problem at once).
    """
    problems = ProblemCollector()
    lenses = _read_lenses(LENSES_FILE, problems)
    if extra is not None:
        lenses.update(_read_lenses(Path(extra), problems))
    problems.raise_if_any(DocumentError)
    return lenses


def _read_json(path: Path, problems: ProblemCollector) -> dict | None:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        problems.add(str(path), f"cannot read: {exc}")
        return None
    if not isinstance(data, dict):
        problems.add(str(path), "expected a JSON object")
        return None
    return data


def _read_lenses(path: Path, problems: ProblemCollector) -> dict[str, Lens]:
    data = _read_json(path, problems)
    if data is None:
        return {}
    entries = data.get("lenses")
    if not isinstance(entries, dict) or not entries:
        problems.add(f"{path}:lenses", "expected a non-empty object of lens entries")
        return {}
    lenses = {}
    for name, raw in entries.items():
        where = f"{path}:lenses.{name}"
        if not isinstance(raw, dict):
            problems.add(where, f"expected an object, got {raw!r}")
            continue
        try:
            model = LensModel(raw.get("model"))
        except ValueError:
            problems.add(f"{where}.model", f"unknown lens model {raw.get('model')!r}; expected one of "
                                           f"{', '.join(m.value for m in LensModel)}")
            continue
        if model in (LensModel.ORTHOGRAPHIC, LensModel.OPENCV_PINHOLE, LensModel.OPENCV_FISHEYE):
            problems.add(f"{where}.model", f"lens model {model.value!r} is not a catalog lens; use perspective, "
                                           "fisheye_equidistant or fisheye_equisolid")
            continue
        numbers = {}
        for key in ("focal_length_mm", "sensor_width_mm"):
            value = raw.get(key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                problems.add(f"{where}.{key}", f"expected a positive number, got {value!r}")
            else:
                numbers[key] = float(value)
        fov = raw.get("fov_deg")
        if model is not LensModel.PERSPECTIVE and (not isinstance(fov, (int, float)) or not 0 < fov < 360):
            problems.add(f"{where}.fov_deg", f"a fisheye lens needs fov_deg in (0, 360), got {fov!r}")
            continue
        res = raw.get("resolution_px")
        if (not isinstance(res, list) or len(res) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in res)):
            problems.add(f"{where}.resolution_px", f"expected [width, height] in pixels, got {res!r}")
            continue
        if len(numbers) < 2:
            continue
        lenses[name] = Lens(name=name, model=model, focal_length_mm=numbers["focal_length_mm"],
                            sensor_width_mm=numbers["sensor_width_mm"], resolution_px=(res[0], res[1]),
                            fov_deg=None if model is LensModel.PERSPECTIVE else float(fov),
                            description=str(raw.get("description", "")))
    return lenses


def lens_intrinsics(lens: Lens) -> Intrinsics:
    """Intrinsics of a catalog lens: square pixels, centred principal point.

    ``f_px = focal_length_mm · width_px / sensor_width_mm`` for every model (the same reading
    as the friendly camera form of the document for pinhole and equisolid lenses).
    """
    w, h = lens.resolution_px
    f = lens.focal_length_mm * w / lens.sensor_width_mm
    return Intrinsics(lens=lens.model, width_px=w, height_px=h, fx_px=f, fy_px=f,
                      cx_px=(w - 1) / 2.0, cy_px=(h - 1) / 2.0, fov_deg=lens.fov_deg,
                      sensor_width_mm=lens.sensor_width_mm)


@dataclass(frozen=True)
class DoriClass:
    """An image-detail class: name and the pixel density it needs at the target (px/m)."""

    name: str
    px_per_m: float


def load_dori(path: str | os.PathLike | None = None) -> tuple[DoriClass, ...]:
    """The DORI table, ascending in pixel density.

    Args:
        path: a JSON file replacing the shipped IEC 62676-4:2015 table
            (``{"classes": [{"name": ..., "px_per_m": ...}, ...]}``).

    Raises:
        DocumentError: unreadable file, malformed entries, repeated names.
    """
    file = Path(path) if path is not None else DORI_FILE
    problems = ProblemCollector()
    data = _read_json(file, problems)
    classes: list[DoriClass] = []
    if data is not None:
        raw = data.get("classes")
        if not isinstance(raw, list) or not raw:
            problems.add(f"{file}:classes", "expected a non-empty list of {name, px_per_m}")
            raw = []
        for i, item in enumerate(raw):
            where = f"{file}:classes[{i}]"
            if not isinstance(item, dict) or not isinstance(item.get("name"), str):
                problems.add(where, f"expected an object with a 'name' string, got {item!r}")
                continue
            value = item.get("px_per_m")
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                problems.add(f"{where}.px_per_m", f"expected a positive number, got {value!r}")
                continue
            classes.append(DoriClass(item["name"], float(value)))
        names = [c.name for c in classes]
        for name in sorted({n for n in names if names.count(n) > 1}):
            problems.add(f"{file}:classes", f"class name {name!r} appears more than once")
    problems.raise_if_any(DocumentError)
    return tuple(sorted(classes, key=lambda c: c.px_per_m))


def dori_index(px_per_m: np.ndarray, table: Sequence[DoriClass]) -> np.ndarray:
    """Index into ``table`` of the best class each density reaches; -1 = below the lowest.

    Args:
        px_per_m: any-shaped array of pixel densities.
        table: ascending classes (:func:`load_dori`).

    Returns:
        int array of the same shape.
    """
    thresholds = np.array([c.px_per_m for c in table])
    values = np.nan_to_num(np.asarray(px_per_m, dtype=np.float64), nan=0.0)
    return np.searchsorted(thresholds, values, side="right") - 1


def dori_class(px_per_m: float, table: Sequence[DoriClass]) -> str | None:
    """Name of the best class ``px_per_m`` reaches, None below the lowest."""
    i = int(dori_index(np.array([px_per_m]), table)[0])
    return table[i].name if i >= 0 else None


def class_index(name: str, table: Sequence[DoriClass], where: str = "dori") -> int:
    """Index of a class by name; DocumentError naming the known classes otherwise."""
    for i, c in enumerate(table):
        if c.name == name:
            return i
    raise DocumentError(f"unknown image-detail class {name!r}; the table has {', '.join(c.name for c in table)}",
                        where=where)


# --------------------------------------------------------------------------------------------
# Targets


@dataclass(frozen=True)
class Target:
    """Something the camera system must see, as sample points.

    Attributes:
        name: ``<place>:<region>`` (``seat_05C:on``) or the box's name.
        place: place name ("" for a box).
        region: region short name (``on``, ``below``, ``in_front``, ...) or "box".
        points_m: (N, 3) float64 world points, metres.
    """

    name: str
    place: str
    region: str
    points_m: np.ndarray

    @property
    def centre_m(self) -> np.ndarray:
        """(3,) mean of the points."""
        return self.points_m.mean(axis=0)


@dataclass(frozen=True)
class TargetSpec:
    """A parsed ``--targets`` argument: places matching ``pattern`` with ``regions``, or a box.

    Attributes:
        pattern: glob on place names (``seat_*``); "" for a box.
        regions: region short names (keys of :data:`usdscene.catalog.REGION_RELATIONS`).
        box_name: name of an explicit box target.
        box_min_m, box_max_m: its corners in world metres.
    """

    pattern: str = ""
    regions: tuple[str, ...] = ()
    box_name: str = ""
    box_min_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    box_max_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


def parse_target_spec(text: str, where: str = "--targets") -> TargetSpec:
    """Parse ``GLOB:REGION,REGION`` (``seat_*:on,below,in_front``) or
    ``box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`` (metres).

    Raises:
        DocumentError: unknown region name, malformed box.
    """
    parts = text.split(":")
    if parts[0] == "box":
        try:
            if len(parts) != 3 or not parts[1]:
                raise ValueError
            values = [float(v) for v in parts[2].split(",")]
            if len(values) != 6 or not all(math.isfinite(v) for v in values):
                raise ValueError
        except ValueError:
            raise DocumentError(f"expected box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (metres), got {text!r}",
                                where=where) from None
        lo, hi = values[:3], values[3:]
        if any(h <= l for l, h in zip(lo, hi)):
            raise DocumentError(f"box {parts[1]!r} has a max corner not above its min corner: {text!r}", where=where)
        return TargetSpec(box_name=parts[1], box_min_m=tuple(lo), box_max_m=tuple(hi))  # type: ignore[arg-type]
    if len(parts) != 2 or not parts[0] or not parts[1]:
        raise DocumentError(f"expected PLACE_GLOB:REGION[,REGION...] (e.g. 'seat_*:on,below') or "
                            f"box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX, got {text!r}", where=where)
    regions = tuple(r.strip() for r in parts[1].split(","))
    bad = [r for r in regions if r not in REGION_RELATIONS]
    if bad:
        raise DocumentError(f"unknown region {bad[0]!r} in {text!r}; regions: {', '.join(REGION_RELATIONS)}",
                            where=where)
    return TargetSpec(pattern=parts[0], regions=regions)


def box_points(size_m: Sequence[float], spacing_m: float) -> np.ndarray:
    """Sample points of a box ``[-sx/2, sx/2] × [-sy/2, sy/2] × [0, sz]`` (a region frame):
    a grid on its support surface (lifted by :data:`SURFACE_LIFT_M`) and, for boxes taller than
    two lifts, a second layer at half height.

    Args:
        size_m: (3,) box size, metres.
        spacing_m: grid spacing; at least 2 points per horizontal axis.

    Returns:
        (N, 3) float64 points in the box frame.
    """
    sx, sy, sz = (float(v) for v in size_m)
    axes = []
    for s in (sx, sy):
        n = max(2, int(math.ceil(s / spacing_m - 1e-9)) + 1)
        inset = min(SURFACE_LIFT_M, s / 4)
        axes.append(np.linspace(-s / 2 + inset, s / 2 - inset, n))
    heights = [min(SURFACE_LIFT_M, sz / 2)]
    if sz > 4 * SURFACE_LIFT_M:
        heights.append(sz / 2)
    gx, gy, gz = np.meshgrid(axes[0], axes[1], heights, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)


def targets_from_places(places: Mapping[str, Place], specs: Sequence[TargetSpec], *,
                        spacing_m: float = 0.2) -> list[Target]:
    """Targets of the places and boxes ``specs`` name, in spec order then place-name order.

    Args:
        places: the environment's places (:meth:`usdscene.catalog.Catalog.places`).
        specs: parsed ``--targets`` arguments.
        spacing_m: spacing of the sample grid in each region (metres).

    Returns:
        One :class:`Target` per (place, region) that exists, and one per box.

    Raises:
        DocumentError: a pattern matches no place, or no matched place has a named region.
    """
    problems = ProblemCollector()
    targets: list[Target] = []
    seen: set[str] = set()
    for spec in specs:
        if spec.box_name:
            lo, hi = np.array(spec.box_min_m), np.array(spec.box_max_m)
            local = box_points(hi - lo, spacing_m)
            pts = local + np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
            targets.append(Target(spec.box_name, "", "box", pts))
            continue
        names = sorted(n for n in places if fnmatch.fnmatchcase(n, spec.pattern))
        if not names:
            problems.add("--targets", f"place pattern {spec.pattern!r} matches no place of the environment "
                                      f"(places look like {', '.join(sorted(places)[:3])}, ...)")
            continue
        found = 0
        for name in names:
            for region in spec.regions:
                r = places[name].regions.get(REGION_RELATIONS[region])
                # 'in' and 'back_pocket' both serve is_in; keep the name the user asked for.
                key = f"{name}:{region}"
                if r is None or key in seen:
                    continue
                seen.add(key)
                found += 1
                pts = r.pose.transform_points(box_points(r.size_m, spacing_m))
                targets.append(Target(key, name, region, pts))
        if not found:
            problems.add("--targets", f"no place matching {spec.pattern!r} has a region "
                                      f"{', '.join(spec.regions)}")
    problems.raise_if_any(DocumentError)
    return targets


# --------------------------------------------------------------------------------------------
# Ray casting


class Occluders:
    """The scene's triangles as a ray-casting structure (built once, queried many times).

    Embree (``embreex``) when it imports, else trimesh's pure ray-triangle intersector.

    Args:
        triangles_m: (T, 3, 3) world triangle vertices, metres.
    """

    def __init__(self, triangles_m: np.ndarray) -> None:
        tris = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3, 3)
        self.triangle_count = len(tris)
        self.bounds_m = (tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)) if len(tris) else \
            (np.zeros(3), np.zeros(3))
        vertices = tris.reshape(-1, 3)
        faces = np.arange(len(vertices)).reshape(-1, 3)
        self._embree = None
        self._trimesh = None
        if not len(tris):
            return
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
        except ImportError:
            import trimesh

            log.info("embreex not installed: pure-Python ray casting (slower)")
            self._trimesh = trimesh.ray.ray_triangle.RayMeshIntersector(
                trimesh.Trimesh(vertices=vertices, faces=faces, process=False))
            return
        # Embree is single precision: rays start near the origin of their own geometry, so
        # shift everything by the scene's centre.
        self._offset = (self.bounds_m[0] + self.bounds_m[1]) / 2
        scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene=scene, vertices=(vertices - self._offset).astype(np.float32),
                     indices=faces.astype(np.int32))
        self._embree = scene

    @property
    def backend(self) -> str:
        """``embree`` or ``trimesh``."""
        return "embree" if self._embree is not None else "trimesh"

    def blocked(self, origins_m: np.ndarray, points_m: np.ndarray, margin_m: float = RAY_MARGIN_M) -> np.ndarray:
        """Whether a triangle lies on the segment from each origin to its point.

        Args:
            origins_m: (N, 3) or (3,) ray origins, metres.
            points_m: (N, 3) end points, metres.
            margin_m: the segment stops this short of the point.

        Returns:
            (N,) bool.
        """
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        origins = np.broadcast_to(np.asarray(origins_m, dtype=np.float64), pts.shape)
        if len(pts) == 0 or (self._embree is None and self._trimesh is None):
            return np.zeros(len(pts), dtype=bool)
        delta = pts - origins
        dist = np.linalg.norm(delta, axis=1)
        dirs = delta / np.where(dist > 0, dist, 1.0)[:, None]
        far = np.maximum(dist - margin_m, 0.0)
        if self._embree is not None:
            hits = self._embree.run((origins - self._offset).astype(np.float32), dirs.astype(np.float32),
                                    dists=far.astype(np.float32), query="OCCLUDED")
            return (np.asarray(hits) != -1) & (far > 0)
        index_tri, index_ray, locations = self._trimesh.intersects_id(
            origins, dirs, multiple_hits=True, return_locations=True)
        out = np.zeros(len(pts), dtype=bool)
        if len(index_ray):
            t = np.einsum("ij,ij->i", locations - origins[index_ray], dirs[index_ray])
            close = (t > 1e-9) & (t < far[index_ray])
            out[np.unique(index_ray[close])] = True
        return out

    def first_hit(self, origins_m: np.ndarray, directions: np.ndarray, max_m: float = 1e3) -> np.ndarray:
        """Distance along each ray to the first triangle; ``inf`` where none within ``max_m``.

        Args:
            origins_m: (N, 3) ray origins, metres.
            directions: (N, 3) unit directions.

        Returns:
            (N,) float64 metres.
        """
        origins = np.asarray(origins_m, dtype=np.float64).reshape(-1, 3)
        dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(origins), np.inf)
        if self._embree is not None:
            result = self._embree.run((origins - self._offset).astype(np.float32), dirs.astype(np.float32),
                                      dists=np.full(len(origins), max_m, np.float32), output=1)
            hit = np.asarray(result["geomID"]) != -1
            out[hit] = np.asarray(result["tfar"], dtype=np.float64)[hit]
            return out
        if self._trimesh is None:
            return out
        _, index_ray, locations = self._trimesh.intersects_id(origins, dirs, multiple_hits=False,
                                                              return_locations=True)
        if len(index_ray):
            d = np.linalg.norm(locations - origins[index_ray], axis=1)
            out[index_ray] = np.where(d <= max_m, d, np.inf)
        return out


# --------------------------------------------------------------------------------------------
# Candidate cameras


@dataclass(frozen=True)
class Mount:
    """A place a camera can be fixed.

    Attributes:
        position_m: (3,) camera centre, metres (a little off the surface).
        surface: ``ceiling`` or ``wall``.
        normal: (3,) unit normal of the surface, pointing into the room.
    """

    position_m: tuple[float, float, float]
    surface: str
    normal: tuple[float, float, float]


def candidate_mounts(occluders: Occluders, region_min_m: Sequence[float], region_max_m: Sequence[float], *,
                     spacing_m: float = 0.8, offset_m: float = 0.05, walls: bool = True) -> list[Mount]:
    """Ceiling and wall positions of the environment inside an axis-aligned region.

    A grid of probe points at the region's mid-height (``spacing_m`` apart in X and Y) casts
    rays up (ceiling) and, with ``walls``, sideways in ±X and ±Y at 80 % of the ceiling height
    (walls). A probe counts only when a ray down also hits something (it is inside the
    environment, not above an open floor). Mounts sit ``offset_m`` off the surface hit.

    Args:
        occluders: the environment (and objects) to cast against.
        region_min_m, region_max_m: (3,) corners of the space to look in, metres.
        spacing_m: grid spacing.
        offset_m: distance of the camera centre from its surface.
        walls: add wall mounts.

    Returns:
        Mounts, deduplicated to a ``spacing_m / 2`` grid, in a deterministic order.
    """
    lo, hi = np.asarray(region_min_m, float), np.asarray(region_max_m, float)
    xs = np.arange(lo[0] + spacing_m / 2, hi[0], spacing_m)
    ys = np.arange(lo[1] + spacing_m / 2, hi[1], spacing_m)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    z_mid = lo[2] + 0.5 * (hi[2] - lo[2])
    probes = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, z_mid)], axis=1)
    span = float(np.linalg.norm(hi - lo))
    down = occluders.first_hit(probes, np.tile([0.0, 0.0, -1.0], (len(probes), 1)), span)
    up = occluders.first_hit(probes, np.tile([0.0, 0.0, 1.0], (len(probes), 1)), span)
    inside = np.isfinite(down) & np.isfinite(up)
    mounts: list[Mount] = []
    keys: set[tuple[int, int, int]] = set()

    def add(p: np.ndarray, surface: str, normal: Sequence[float]) -> None:
        key = tuple(int(round(v / (spacing_m / 2))) for v in p)
        if key not in keys and np.all(p >= lo - 1e-9) and np.all(p <= hi + 1e-9):
            keys.add(key)  # type: ignore[arg-type]
            mounts.append(Mount(tuple(float(v) for v in p), surface, tuple(float(v) for v in normal)))  # type: ignore[arg-type]

    for p, d in zip(probes[inside], up[inside]):
        add(p + np.array([0.0, 0.0, d - offset_m]), "ceiling", (0.0, 0.0, -1.0))
    if walls and inside.any():
        ceiling = probes[inside, 2] + up[inside]
        wall_probes = probes[inside].copy()
        wall_probes[:, 2] = lo[2] + 0.8 * (ceiling - lo[2])
        for direction in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)):
            dirs = np.tile(direction, (len(wall_probes), 1))
            dist = occluders.first_hit(wall_probes, dirs, span)
            # Only the outermost probe of each line sees the wall directly, the others hit it
            # too but land on the same dedup key.
            for p, d in zip(wall_probes, dist):
                if np.isfinite(d) and d > offset_m:
                    add(p + np.asarray(direction) * (d - offset_m), "wall", tuple(-v for v in direction))
    return mounts


def look_rotation(forward: Sequence[float]) -> np.ndarray:
    """Camera → world rotation (OpenCV axes: x right, y down, z forward) looking along
    ``forward`` with the image's up towards world +Z (straight down: image up = world +Y).

    Returns:
        (3, 3) float64.
    """
    z = np.asarray(forward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0]) if z[2] < 0 else np.array([-1.0, 0.0, 0.0])
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def target_clusters(targets: Sequence[Target], cell_m: float) -> np.ndarray:
    """Centroids of targets grouped on an XY grid of ``cell_m`` cells (deterministic).

    Returns:
        (K, 3) float64 centroids in metres, sorted by cell.
    """
    centres = np.array([t.centre_m for t in targets]).reshape(-1, 3)
    cells = np.floor(centres[:, :2] / cell_m).astype(np.int64)
    groups: dict[tuple[int, int], list[int]] = {}
    for i, c in enumerate(map(tuple, cells)):
        groups.setdefault(c, []).append(i)
    return np.array([centres[groups[k]].mean(axis=0) for k in sorted(groups)]).reshape(-1, 3)


def candidate_cameras(mounts: Sequence[Mount], targets: Sequence[Target], lenses: Sequence[Lens], *,
                      aims: int = 4, cluster_m: float = 1.6, max_range_m: float = 8.0) -> list[Camera]:
    """Cameras at every mount, aimed along the surface normal and at the ``aims`` nearest target
    clusters (within ``max_range_m``), with every lens.

    Camera names are ``cand_<mount>_<aim>_<lens>``; ``custom`` records the lens name, mount
    surface and aim, which the plan writes back into the document.

    Returns:
        Cameras in mount, aim, lens order.
    """
    clusters = target_clusters(targets, cluster_m)
    cameras = []
    for m_index, mount in enumerate(mounts):
        p = np.asarray(mount.position_m)
        normal = np.asarray(mount.normal)
        # A wall camera along its normal looks at the opposite wall; tilt it down 35°.
        base = normal if mount.surface == "ceiling" else normal * math.cos(math.radians(35)) + \
            np.array([0.0, 0.0, -math.sin(math.radians(35))])
        directions = [base]
        if len(clusters):
            d = np.linalg.norm(clusters - p, axis=1)
            order = [i for i in np.argsort(d, kind="stable") if 0.3 < d[i] <= max_range_m]
            for i in order[:aims]:
                v = (clusters[i] - p) / d[i]
                if float(v @ normal) > 0.05:  # not into the surface the camera hangs on
                    directions.append(v)
        for a_index, forward in enumerate(directions):
            rotation = look_rotation(forward)
            for lens in lenses:
                cameras.append(Camera(
                    name=f"cand_{m_index:04d}_{a_index}_{lens.name}",
                    intrinsics=lens_intrinsics(lens),
                    pose=Pose.from_rotation_translation(rotation, p),
                    model_name=lens.name,
                    custom={"lens": lens.name, "mount": mount.surface, "aim": "normal" if a_index == 0 else "target"}))
    return cameras


# --------------------------------------------------------------------------------------------
# Visibility


@dataclass(frozen=True)
class Visibility:
    """Visibility of every target from every camera.

    Attributes:
        in_image: (C, T) float64 fraction of each target's points inside the image.
        visible: (C, T) float64 fraction of each target's points inside the image and
            unoccluded.
        px_per_m: (C, T) float64 median pixel density over the visible points (0 where none).
        dori: (C, T) int index of the best DORI class reached (-1 = none or not visible).
        point_visible: per target, (C, N_t) bool of its points (for verification).
    """

    in_image: np.ndarray
    visible: np.ndarray
    px_per_m: np.ndarray
    dori: np.ndarray
    point_visible: tuple[np.ndarray, ...] = field(repr=False, default=())


def pixel_density(camera: Camera, points_m: np.ndarray, step_m: float = 0.01) -> np.ndarray:
    """Pixels per metre at each point, across the viewing ray, in the worse direction.

    Two small steps perpendicular to the viewing ray are projected with the camera's exact
    lens model; the smaller of their image lengths per metre is returned.

    Args:
        camera: the camera.
        points_m: (N, 3) world points, metres.
        step_m: finite-difference step (metres).

    Returns:
        (N,) float64 px/m; 0 where the point or its neighbours do not project.
    """
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    if not len(pts):
        return np.zeros(0)
    pose = camera.pose.as_array()
    r, t = pose[:3, :3], pose[:3, 3]
    ray = pts - t
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    # Perpendicular directions: the camera's x axis and y axis made orthogonal to each ray.
    densities = []
    uv0, ok0 = project_points(camera, pts)
    for axis in (r[:, 0], r[:, 1]):
        e = axis - (ray @ axis)[:, None] * ray
        e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
        uv1, ok1 = project_points(camera, pts + step_m * e)
        d = np.linalg.norm(uv1 - uv0, axis=1) / step_m
        densities.append(np.where(ok0 & ok1, d, 0.0))
    return np.minimum(densities[0], densities[1])


def evaluate_visibility(cameras: Sequence[Camera], targets: Sequence[Target], occluders: Occluders,
                        dori_table: Sequence[DoriClass], *, max_range_m: float = 30.0) -> Visibility:
    """Visibility of every target from every camera by ray casting.

    A point is *visible* when it projects inside the image rectangle through the camera's exact
    lens model (:func:`usdscene.projection.project_points`) and no triangle lies between the
    camera centre and the point (stopping :data:`RAY_MARGIN_M` short of it).

    Args:
        cameras: C cameras.
        targets: T targets.
        occluders: the scene's triangles.
        dori_table: ascending image-detail classes.
        max_range_m: points farther than this from a camera count as outside its image.

    Returns:
        A :class:`Visibility`.
    """
    n_c, n_t = len(cameras), len(targets)
    counts = np.array([len(t.points_m) for t in targets], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    all_pts = np.concatenate([t.points_m for t in targets]) if n_t else np.zeros((0, 3))
    owner = np.repeat(np.arange(n_t), counts)
    in_image = np.zeros((n_c, n_t))
    visible = np.zeros((n_c, n_t))
    density = np.zeros((n_c, n_t))
    per_point = np.zeros((n_c, len(all_pts)), dtype=bool)
    for c, camera in enumerate(cameras):
        intr = camera.intrinsics
        centre = camera.pose.translation_m
        near = np.linalg.norm(all_pts - centre, axis=1) <= max_range_m
        idx = np.flatnonzero(near)
        uv, ok = project_points(camera, all_pts[idx])
        inside = ok & (uv[:, 0] >= -0.5) & (uv[:, 0] <= intr.width_px - 0.5) & \
            (uv[:, 1] >= -0.5) & (uv[:, 1] <= intr.height_px - 0.5)
        idx = idx[inside]
        if not len(idx):
            continue
        seen = ~occluders.blocked(centre, all_pts[idx])
        in_image[c] = np.bincount(owner[idx], minlength=n_t) / counts
        vis_idx = idx[seen]
        per_point[c, vis_idx] = True
        visible[c] = np.bincount(owner[vis_idx], minlength=n_t) / counts
        if len(vis_idx):
            d = pixel_density(camera, all_pts[vis_idx])
            for t in np.unique(owner[vis_idx]):
                density[c, t] = float(np.median(d[owner[vis_idx] == t]))
    dori = np.where(visible > 0, dori_index(density, dori_table), -1)
    return Visibility(in_image=in_image, visible=visible, px_per_m=density, dori=dori,
                      point_visible=tuple(per_point[:, offsets[t]:offsets[t + 1]] for t in range(n_t)))


def coverage_matrix(visibility: Visibility, *, min_visible: float, min_dori: int) -> np.ndarray:
    """(C, T) bool: camera c covers target t (visible fraction ≥ ``min_visible`` and DORI
    index ≥ ``min_dori``)."""
    return (visibility.visible >= min_visible - 1e-12) & (visibility.dori >= min_dori) & (visibility.visible > 0)


# --------------------------------------------------------------------------------------------
# Selection


@dataclass(frozen=True)
class Selection:
    """The chosen camera set.

    Attributes:
        chosen: indices of the chosen cameras, ascending.
        method: ``milp`` (optimal, or the best found within the time limit) or ``greedy``.
        optimal: the MILP proved optimality.
        lower_bound: a lower bound on the smallest set (LP relaxation, rounded up; or the
            MILP's dual bound when it is higher).
        greedy_size: size of the greedy set (always computed, for comparison).
        demand: (T,) cameras asked of each target: min(K, cameras that can cover it).
        uncoverable: indices of targets no candidate covers at all.
        short: indices of targets with fewer than K covering candidates (but some).
        seconds: solver wall time.
    """

    chosen: tuple[int, ...]
    method: str
    optimal: bool
    lower_bound: int
    greedy_size: int
    demand: np.ndarray
    uncoverable: tuple[int, ...]
    short: tuple[int, ...]
    seconds: float = 0.0

    @property
    def gap(self) -> float:
        """Relative gap of the chosen set to the lower bound: (n - bound) / n."""
        n = len(self.chosen)
        return 0.0 if n == 0 else (n - self.lower_bound) / n


def greedy_cover(cover: np.ndarray, demand: np.ndarray, weights: np.ndarray | None = None) -> list[int]:
    """Greedy multi-cover: repeatedly take the camera that meets the most remaining demand
    (ties: larger weight, then lower index). Then drop cameras that became redundant.

    Args:
        cover: (C, T) bool.
        demand: (T,) int cameras asked of each target (must be achievable).
        weights: (C,) tie-breaking scores (larger preferred).

    Returns:
        Chosen camera indices, ascending.
    """
    cover = np.asarray(cover, dtype=bool)
    remaining = np.asarray(demand, dtype=np.int64).copy()
    w = np.zeros(len(cover)) if weights is None else np.asarray(weights, dtype=np.float64)
    chosen: list[int] = []
    available = np.ones(len(cover), dtype=bool)
    while remaining.max(initial=0) > 0:
        gain = (cover & (remaining > 0)).sum(axis=1).astype(np.float64)
        gain[~available] = -1
        best = np.flatnonzero(gain == gain.max())
        c = int(best[np.argmax(w[best])])
        if gain[c] <= 0:
            break
        chosen.append(c)
        available[c] = False
        remaining -= cover[c]
    # Reverse-delete: a camera whose targets keep their demand without it is redundant.
    counts = cover[chosen].sum(axis=0) if chosen else np.zeros(cover.shape[1], int)
    for c in sorted(chosen, key=lambda i: (w[i], -i)):
        if np.all(counts - cover[c] >= demand):
            counts = counts - cover[c]
            chosen.remove(c)
    return sorted(chosen)


def _useful_columns(cover: np.ndarray, weights: np.ndarray, *, prune_dominated: bool) -> np.ndarray:
    """Indices of cameras that cover something, without dominated ones when asked.

    Args:
        cover: (C, R) bool over the targets with demand.
        weights: (C,) preference among cameras with equal target sets.
        prune_dominated: drop a camera whose targets are a strict subset of another's, or
            equal to a better-weighted (then lower-index) camera's.

    Returns:
        Ascending int indices.
    """
    size = cover.sum(axis=1)
    useful = np.flatnonzero(size > 0)
    if not prune_dominated or not len(useful):
        return useful
    a = cover[useful].astype(np.float32)
    inter = a @ a.T  # exact: counts far below 2**24
    s, w = size[useful], weights[useful]
    order = np.arange(len(useful))
    keep = []
    for i in range(len(useful)):
        subset_of = inter[i] == s[i]
        subset_of[i] = False
        better = (s > s[i]) | ((s == s[i]) & ((w > w[i]) | ((w == w[i]) & (order < i))))
        if not (subset_of & better).any():
            keep.append(useful[i])
    return np.asarray(keep, dtype=np.int64)


def select_cameras(cover: np.ndarray, k: int = 1, *, time_limit_s: float = 60.0,
                   weights: np.ndarray | None = None) -> Selection:
    """The smallest camera set giving every target ``min(k, coverable)`` covering cameras.

    Integer program ``min Σ x_c  s.t.  Σ_c cover[c, t] x_c ≥ demand_t,  x ∈ {0, 1}`` solved by
    HiGHS through ``scipy.optimize.milp`` with ``time_limit_s``. For K = 1 a camera whose
    targets are a subset of another's is dropped first (among equal sets the one with the
    larger weight stays), which shrinks the cabin's 2880 candidates to about 400 without
    changing the optimum; weights are not in the objective (a tie-breaking term makes HiGHS
    several times slower). The greedy set is computed too and returned when the MILP finds
    nothing better (or fails); the LP relaxation gives the lower bound that the reported gap
    refers to.

    Args:
        cover: (C, T) bool from :func:`coverage_matrix`.
        k: cameras each target needs.
        time_limit_s: MILP wall-time limit, seconds.
        weights: (C,) preference among equal-size sets (e.g. summed px/m), larger better.

    Returns:
        A :class:`Selection`.
    """
    import time

    from scipy.optimize import Bounds, LinearConstraint, linprog, milp

    started = time.perf_counter()
    cover = np.asarray(cover, dtype=bool)
    n_c, n_t = cover.shape
    able = cover.sum(axis=0)
    demand = np.minimum(able, k).astype(np.int64)
    uncoverable = tuple(int(t) for t in np.flatnonzero(able == 0))
    short = tuple(int(t) for t in np.flatnonzero((able > 0) & (able < k)))
    w = np.zeros(n_c) if weights is None else np.asarray(weights, dtype=np.float64)
    greedy = greedy_cover(cover, demand, w)
    rows = np.flatnonzero(demand > 0)
    if not len(rows):
        return Selection((), "greedy", True, 0, 0, demand, uncoverable, short, time.perf_counter() - started)
    useful = _useful_columns(cover[:, rows], w, prune_dominated=k == 1)
    a = cover[np.ix_(useful, rows)].T.astype(np.float64)
    cost = np.ones(len(useful))
    lp = linprog(cost, A_ub=-a, b_ub=-demand[rows], bounds=(0, 1), method="highs")
    bound = int(math.ceil(lp.fun - 1e-6)) if lp.status == 0 else 0
    chosen, method, optimal = greedy, "greedy", False
    res = milp(cost, integrality=np.ones(len(useful)), bounds=Bounds(0, 1),
               constraints=LinearConstraint(a, lb=demand[rows], ub=np.inf),
               options={"time_limit": float(time_limit_s), "disp": False})
    if res.x is not None:
        picked = sorted(int(useful[i]) for i in np.flatnonzero(res.x > 0.5))
        if len(picked) <= len(greedy):
            chosen, method = picked, "milp"
            optimal = res.status == 0
            if optimal:
                bound = max(bound, len(picked))
            elif getattr(res, "mip_dual_bound", None) is not None and np.isfinite(res.mip_dual_bound):
                bound = max(bound, int(math.ceil(res.mip_dual_bound - 1e-6)))
    else:
        log.warning("MILP found no solution within %.0f s (%s); using the greedy set", time_limit_s, res.message)
    return Selection(tuple(chosen), method, optimal, bound, len(greedy), demand, uncoverable, short,
                     time.perf_counter() - started)


# --------------------------------------------------------------------------------------------
# Top-down plan picture

# BGR colours of coverage counts 0, 1, 2, ≥3 and of the camera wedges.
_COUNT_COLOURS = ((60, 60, 230), (60, 200, 250), (90, 200, 90), (200, 150, 60))
_WEDGE_COLOUR = (180, 90, 200)


def _border_rays(intrinsics: Intrinsics, per_side: int = 12) -> np.ndarray:
    from usdscene.projection import pixel_rays

    w, h = intrinsics.width_px, intrinsics.height_px
    s = np.linspace(0.0, 1.0, per_side, endpoint=False)
    uv = np.concatenate([np.stack([s * (w - 1), np.zeros_like(s)], 1),
                         np.stack([np.full_like(s, w - 1), s * (h - 1)], 1),
                         np.stack([(1 - s) * (w - 1), np.full_like(s, h - 1)], 1),
                         np.stack([np.zeros_like(s), (1 - s) * (h - 1)], 1)])
    rays, ok = pixel_rays(intrinsics, uv)
    return rays[ok]


def plan_picture(triangles_m: np.ndarray, targets: Sequence[Target], cameras: Sequence[Camera],
                 counts: np.ndarray, best_dori: np.ndarray, dori_table: Sequence[DoriClass],
                 occluders: Occluders, *, max_width_px: int = 1600, max_height_px: int = 900,
                 title: str = "") -> np.ndarray:
    """Top-down plan, one panel per target region (``on``, ``below``, ...; targets of different
    regions overlap from above): the scene shaded by height, each target's footprint filled by
    how many chosen cameras cover it and dotted by its best DORI class (darker = finer), and the
    cameras with the outline of their view (where their image border rays first hit the scene).

    Args:
        triangles_m: (T, 3, 3) world triangles of the scene.
        targets: the targets.
        cameras: the chosen cameras.
        counts: (len(targets),) int covering cameras per target.
        best_dori: (len(targets),) int best DORI index per target (-1 = none).
        dori_table: ascending DORI classes (for the legend).
        occluders: for the view outlines.
        max_width_px, max_height_px: size limit of one panel.
        title: text in the legend rows.

    Returns:
        (H, W, 3) uint8 BGR image (x of the world to the right, y of the world up).
    """
    import cv2

    tris = np.asarray(triangles_m, dtype=np.float64).reshape(-1, 3, 3)
    pts = [tris.reshape(-1, 3)] + [t.points_m for t in targets] + [c.pose.translation_m[None] for c in cameras]
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0) - 0.3, allp.max(axis=0) + 0.3
    scale = min(max_width_px / (hi[0] - lo[0]), max_height_px / (hi[1] - lo[1]))
    width = int(math.ceil((hi[0] - lo[0]) * scale))
    height = int(math.ceil((hi[1] - lo[1]) * scale))

    def to_px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([(xy[:, 0] - lo[0]) * scale, (hi[1] - xy[:, 1]) * scale], 1)

    def shift(xy: np.ndarray) -> np.ndarray:
        return np.round(to_px(xy) * 16).astype(np.int32)  # 4 fractional bits for cv2

    base = np.full((height, width, 3), 255, np.uint8)
    if len(tris):
        # Painter's order by height: what is seen from above is drawn last.
        top = tris[:, :, 2].max(axis=1)
        zlo, zhi = float(top.min()), float(top.max())
        levels = np.clip(((top - zlo) / max(zhi - zlo, 1e-9) * 10).astype(int), 0, 9)
        for level in range(10):
            sel = tris[levels == level]
            if len(sel):
                shade = int(235 - 10 * level)
                polys = shift(sel[:, :, :2].reshape(-1, 2)).reshape(-1, 3, 2)
                cv2.fillPoly(base, list(polys), (shade, shade, shade), lineType=cv2.LINE_8, shift=4)
    outlines = []
    for camera in cameras:
        rays = _border_rays(camera.intrinsics)
        if not len(rays):
            continue
        world = rays @ camera.pose.rotation.T
        origin = camera.pose.translation_m
        dist = occluders.first_hit(np.tile(origin, (len(world), 1)), world, 30.0)
        dist = np.where(np.isfinite(dist), dist, 5.0)
        outlines.append(shift((origin + world * dist[:, None])[:, :2]))
    n_classes = max(len(dori_table), 1)
    regions = list(dict.fromkeys(t.region for t in targets)) or [""]
    panels = []
    for region in regions:
        image = base.copy()
        cv2.polylines(image, outlines, True, _WEDGE_COLOUR, 1, cv2.LINE_AA, shift=4)
        for t, target in enumerate(targets):
            if target.region != region:
                continue
            hull = np.round(cv2.convexHull(to_px(target.points_m[:, :2]).astype(np.float32)).reshape(-1, 2) * 16)
            hull = hull.astype(np.int32)
            cv2.fillPoly(image, [hull], _COUNT_COLOURS[min(int(counts[t]), 3)], lineType=cv2.LINE_AA, shift=4)
            cv2.polylines(image, [hull], True, (40, 40, 40), 1, cv2.LINE_AA, shift=4)
            c = to_px(target.centre_m[None, :2])[0]
            d = int(best_dori[t])
            grey = 255 - int(255 * (d + 1) / n_classes) if d >= 0 else 255
            cv2.circle(image, (int(round(c[0])), int(round(c[1]))), max(2, int(scale * 0.04)),
                       (grey, grey, grey), -1, cv2.LINE_AA)
        for camera in cameras:
            p = to_px(camera.pose.translation_m[None, :2])[0]
            forward = camera.pose.rotation[:, 2]
            centre = (int(round(p[0])), int(round(p[1])))
            cv2.circle(image, centre, max(3, int(scale * 0.07)), (120, 30, 150), -1, cv2.LINE_AA)
            if np.hypot(forward[0], forward[1]) > 0.1:
                tip = to_px((camera.pose.translation_m[:2] + 0.35 * forward[:2] / np.hypot(*forward[:2]))[None])[0]
                cv2.line(image, centre, (int(round(tip[0])), int(round(tip[1]))), (120, 30, 150), 2, cv2.LINE_AA)
        label = np.full((22, width, 3), 255, np.uint8)
        cv2.putText(label, f"targets: {region}", (8, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        panels += [label, image]
    legend = np.full((56, width, 3), 255, np.uint8)
    y, x = 20, 8
    for i, text in enumerate(("0 cameras", "1", "2", ">=3")):
        cv2.rectangle(legend, (x, y - 12), (x + 16, y + 2), _COUNT_COLOURS[i], -1)
        cv2.putText(legend, text, (x + 20, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        x += 40 + 9 * len(text)
    x += 10
    for i, dori in enumerate(dori_table):
        grey = 255 - int(255 * (i + 1) / n_classes)
        cv2.circle(legend, (x + 6, y - 5), 6, (grey, grey, grey), -1, cv2.LINE_AA)
        cv2.circle(legend, (x + 6, y - 5), 6, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(legend, dori.name, (x + 16, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        x += 26 + 9 * len(dori.name)
    cv2.putText(legend, "camera (dot, aim) and view outline", (x + 10, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                _WEDGE_COLOUR, 1, cv2.LINE_AA)
    if title:
        cv2.putText(legend, title, (8, y + 24), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate(panels + [legend], axis=0)
