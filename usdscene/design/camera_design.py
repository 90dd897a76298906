"""``usdscene plan-cameras``: design a camera system on the composed scene, then prove it.

:func:`plan_cameras` reads a setup document, composes the scene that blocks the views
(the environment plus a passenger in every seat, or the setup's own objects) with
:func:`usdscene.scene.compose.compose_stage`, reads its triangles, builds targets and candidate
cameras and hands them to :mod:`usdscene.design.visibility` and :mod:`usdscene.design.selection`. It writes::

    PLAN_DIR/cameras.openlabel.json   the setup with the chosen cameras (for generate / run)
    PLAN_DIR/coverage.json            per target: cameras, px/m, DORI, visible fraction;
                                      per camera: targets; the request and the solver summary
    PLAN_DIR/coverage.png             top-down plan (coverage count, best DORI, view wedges)
    PLAN_DIR/occluders/               the composed occluder stage the rays were cast against

:func:`usdscene.design.plan_verify.verify_plan` proves the plan by a render.

Outputs are deterministic for the same inputs (no timings in the files) as long as the MILP
finishes inside its time limit.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from usdscene.design.candidates import (Aiming, Mount, PoleGrid, RoomGrid, candidate_cameras, candidate_mounts,
                                        open_air_mounts)
from usdscene.design.coverage_file import Coverage, coverage_report
from usdscene.design.mount_surfaces import mount_surfaces
from usdscene.design.user_mounts import load_mounts
from usdscene.design.lenses import Lens, load_lenses
from usdscene.design.occluders import Occluders
from usdscene.design.plan_picture import plan_picture
from usdscene.design.plan_request import DEFAULT_TARGETS, OCCLUDER_MODES, PlanRequest  # noqa: F401 (DEFAULT_TARGETS re-exported)
from usdscene.design.selection import Selection, select_cameras
from usdscene.design.targets import Target, parse_target_spec, targets_from_places
from usdscene.design.zones import select_by_zones, zone_index
from usdscene.design.visibility import (PAIR_BYTES, Uncovered, Visibility, coverage_matrix, covering_pairs,
                                        evaluate_visibility, pairs_in_range, why_uncovered)
from usdscene.labels.pixel_density import STANDARD_FILES, class_index, load_dori, standard_file, table_standard
from usdscene.errors import DocumentError
from usdscene.document.model import Camera, Relation, SceneObject, SceneSpec, PlaceRef

log = logging.getLogger(__name__)

CAMERAS_FILE = "cameras.openlabel.json"
COVERAGE_FILE = "coverage.json"
PLAN_PICTURE = "coverage.png"
OCCLUDER_STAGE_DIR = "occluders"


def plan_picture_for(document: str | os.PathLike) -> Path | None:
    """The coverage map of the camera plan a scene document comes from: the plan picture of the
    folder it sits in when that folder is a plan folder (``coverage.json`` beside it), else None."""
    folder = Path(document).resolve().parent
    picture = folder / PLAN_PICTURE
    return picture if picture.is_file() and (folder / COVERAGE_FILE).is_file() else None


@dataclass(frozen=True)
class PlanResult:
    """What :func:`plan_cameras` computed and wrote.

    Attributes:
        out_dir: the plan folder.
        scene: the setup with the chosen cameras (what ``cameras.openlabel.json`` holds).
        chosen: the chosen cameras (as named in ``scene``).
        candidates: number of candidate cameras scored.
        targets: the targets.
        selection: the solver's answer (indices into the candidates).
        coverage: the ``coverage.json`` content.
        seconds: step → wall seconds (targets, compose, candidates, visibility, select, write).
        backend: ray-casting backend (``embree`` or ``trimesh``).
    """

    out_dir: Path
    scene: SceneSpec
    chosen: tuple[Camera, ...]
    candidates: int
    targets: tuple[Target, ...]
    selection: Selection
    coverage: Mapping
    seconds: Mapping[str, float] = field(default_factory=dict)
    backend: str = ""


def occluder_scene(setup: SceneSpec, catalog, mode: str) -> SceneSpec:
    """The scene whose geometry blocks the views.

    ``setup``: the setup document's own objects. ``worst-case``: no setup objects, a passenger
    (the catalog's first class of kind ``passenger``, default appearance and pose) ``is_on``
    every place of kind ``seat``.

    Raises:
        DocumentError: unknown mode, no environment, or worst-case without a passenger class.
    """
    if mode not in OCCLUDER_MODES:
        raise DocumentError(f"unknown occluders {mode!r}; expected one of {', '.join(OCCLUDER_MODES)}",
                            where="--occluders")
    if setup.environment is None:
        raise DocumentError("the setup document names no environment (metadata.usdscene.environment); "
                            "plan-cameras needs one", where="metadata.usdscene.environment")
    if mode == "setup":
        return setup
    passengers = catalog.classes("passenger")
    if not passengers:
        raise DocumentError("--occluders worst-case needs an asset class of kind 'passenger' in the catalog",
                            where="--occluders")
    seats = [name for name, place in sorted(catalog.places(setup.environment).items()) if place.kind == "seat"]
    objects, relations, places = [], [], []
    for name in seats:
        uid = f"occluder_{name}"
        objects.append(SceneObject(uid=uid, name=uid, class_name=passengers[0]))
        places.append(PlaceRef(uid=f"place_{name}", name=name))
        relations.append(Relation(uid=f"rel_{uid}", type="is_on", subject_uid=uid, object_uid=f"place_{name}"))
    return dataclasses.replace(setup, objects=tuple(objects), relations=tuple(relations), places=tuple(places),
                               frame_end=setup.frame_start)


def stage_triangles(stage_path: Path, frame: int) -> np.ndarray:
    """(T, 3, 3) world triangles of the environment and every object of a composed stage."""
    from usdscene.scene.stage_geometry import StageGeometry, environment_triangles

    geometry = StageGeometry(stage_path)
    parts = [environment_triangles(geometry.stage, frame)] + list(geometry.triangles(frame).values())
    return np.concatenate(parts)


def scene_geometry(stage_path: Path, frame: int):
    """The composed stage's world triangles (as :func:`stage_triangles`), their mountability
    (:func:`usdscene.design.mount_surfaces.mount_surfaces`) and the environment's mount nodes.

    Returns:
        ((T, 3, 3) float64 triangles in metres, MountSurfaces, list of (name, (3,) position m,
        (3,) facing)).
    """
    from usdscene.scene.stage_geometry import StageGeometry, environment_meshes, mount_nodes

    geometry = StageGeometry(stage_path)
    meshes = environment_meshes(geometry.stage, frame)
    objects = list(geometry.triangles(frame).values())
    parts = [m.triangles_m for m in meshes] + objects
    triangles = np.concatenate(parts) if parts else np.zeros((0, 3, 3))
    surfaces = mount_surfaces(meshes, sum(len(o) for o in objects))
    return triangles, surfaces, mount_nodes(geometry.stage, frame)


def read_setup(document: Path):
    from usdscene.scene.catalog import load_catalog, scene_catalog
    from usdscene.converters.openlabel import read_openlabel

    setup = read_openlabel(document)
    catalog = load_catalog(setup.asset_paths, base_dir=document.resolve().parent)
    return setup, scene_catalog(catalog, setup)


def check_pair_memory(pairs: int, targets: int, candidates: int, limit_gb: float) -> None:
    """Refuse, before any ray is cast, a request whose kept pairs would pass ``limit_gb``.

    Raises:
        DocumentError: one line naming the targets, candidates and pairs, and what to change.
    """
    need = pairs * PAIR_BYTES / 1e9
    if need > limit_gb:
        raise DocumentError(
            f"{targets} targets x {candidates} candidate cameras give up to {pairs} (camera, target) pairs in range, "
            f"about {need:.1f} GB, over the {limit_gb:g} GB limit: use a coarser --cell, a larger --spacing, fewer "
            f"--lens, or plan the floor in zones (--targets box:...), or raise --max-memory", where="--max-memory")


def plan_cameras(request: PlanRequest, out_dir: str | Path,
                 progress: Callable[[str, int, int], None] | None = None) -> PlanResult:
    """Plan the smallest camera set that covers the targets, and write the plan folder.

    Args:
        request: what to plan (:class:`usdscene.design.plan_request.PlanRequest`).
        out_dir: plan folder (created).
        progress: called with (stage, done, total) during long steps (``visibility``:
            candidate cameras scored).

    Returns:
        A :class:`PlanResult`.

    Raises:
        DocumentError: bad document, request, lens or DORI file (every problem at once
            where possible).
        OutputError: the output document fails the official OpenLABEL schema.
    """
    from usdscene.scene.compose import compose_stage
    from usdscene.converters.openlabel import default_schema_path, write_document, write_openlabel
    from usdscene.files import write_json_atomic, write_png_atomic

    seconds: dict[str, float] = {}
    started = time.perf_counter()
    document, out = Path(request.setup_document), Path(out_dir)
    request.check()
    mounts, k, dori = request.mounts, request.k, request.level
    specs = [parse_target_spec(s) for s in request.targets]
    table_file = request.dori_table_file or standard_file(request.standard)
    table = load_dori(table_file)
    standard_name = table_standard(table_file)
    required = _required_class(dori, table, standard_name, request.dori_table_file is None)
    user_mounts = load_mounts(mounts) if mounts not in ("auto", "setup") else []
    setup, catalog = read_setup(document)
    lenses = _pick_lenses(load_lenses(request.lenses_file), request.lens_names) if mounts != "setup" else []
    if mounts == "setup" and not setup.cameras:
        raise DocumentError("--mounts setup re-scores the setup's cameras, but the document has none",
                            where=str(document))
    scene = occluder_scene(setup, catalog, request.occluders)
    target_list = targets_from_places(catalog.places(setup.environment), specs,
                                      spacing_m=request.target_spacing_m, cell_m=request.cell_m)
    seconds["targets"] = time.perf_counter() - started

    t = time.perf_counter()
    # No cameras in the occluder stage: they do not block anything and the planner adds its own.
    existed = out.exists()
    composed = compose_stage(dataclasses.replace(scene, cameras=()), catalog, out / OCCLUDER_STAGE_DIR)
    triangles, surfaces, nodes = scene_geometry(composed.root_layer, scene.frame_start)
    occ = Occluders(triangles)
    seconds["compose"] = time.perf_counter() - t

    t = time.perf_counter()
    left_out: dict[str, int] = {}
    if mounts == "setup":
        candidates = list(setup.cameras)
        mount_count = len(candidates)
    else:
        if mounts == "auto":
            structure = Occluders(triangles[surfaces.mountable])
            mount_list = candidate_mounts(occ, occ.bounds_m, grid=RoomGrid(spacing_m=request.spacing_m),
                                          surfaces=surfaces, structure=structure, left_out=left_out)
            if request.pole_heights_m:
                poles = PoleGrid(heights_m=tuple(request.pole_heights_m), spacing_m=request.pole_spacing_m)
                mount_list += open_air_mounts(occ, triangles, surfaces, occ.bounds_m, grid=poles, left_out=left_out)
            mount_list += [Mount(tuple(float(v) for v in p), "node", tuple(float(v) for v in f), (), name)
                           for name, p, f in nodes]
        else:
            mount_list = user_mounts
        candidates = candidate_cameras(mount_list, target_list, lenses, aiming=Aiming(aims=request.aims))
        mount_count = len(mount_list)
    seconds["candidates"] = time.perf_counter() - t

    try:
        check_pair_memory(pairs_in_range(candidates, target_list), len(target_list), len(candidates),
                          request.max_memory_gb)
    except DocumentError:
        # Refused before the work: leave nothing behind (the occluder stage was only a means).
        if not existed:
            shutil.rmtree(out, ignore_errors=True)
        raise
    t = time.perf_counter()
    visibility = evaluate_visibility(candidates, target_list, occ, table,
                                     progress=None if progress is None else
                                     (lambda done, total: progress("visibility", done, total)))
    cover = coverage_matrix(visibility, min_visible=request.min_visible, min_dori=required)
    seconds["visibility"] = time.perf_counter() - t

    t = time.perf_counter()
    weights = covering_px_per_m(visibility, covering_pairs(visibility, min_visible=request.min_visible,
                                                           min_dori=required))
    if request.zone_m > 0:
        zones = zone_index(np.array([t.centre_m for t in target_list]).reshape(-1, 3), request.zone_m)
        selection = select_by_zones(cover, k, zones, time_limit_s=request.time_limit_s, weights=weights)
    else:
        selection = select_cameras(cover, k, time_limit_s=request.time_limit_s, weights=weights)
    seconds["select"] = time.perf_counter() - t

    t = time.perf_counter()
    chosen = _named_cameras([candidates[i] for i in selection.chosen], keep_names=mounts == "setup")
    # The plan document lives in PLAN_DIR: its relative asset folders must still find the catalog.
    asset_paths = tuple(p if Path(p).is_absolute() else
                        os.path.relpath((document.resolve().parent / p).resolve(), out.resolve())
                        for p in setup.asset_paths)
    planned = dataclasses.replace(setup, cameras=tuple(chosen), asset_paths=asset_paths)
    why = why_uncovered(visibility, selection.uncoverable, min_visible=request.min_visible,
                        candidates=len(candidates))
    report = coverage_report(request.record([lens.name for lens in lenses], table, standard_name), Coverage(
        target_list, candidates, chosen, selection, visibility, cover, table, mount_count, why),
        rescored=mounts == "setup")
    report["summary"]["mounts_left_out"] = dict(sorted(left_out.items()))
    out.mkdir(parents=True, exist_ok=True)
    write_document(out / CAMERAS_FILE, write_openlabel(planned), schema=default_schema_path())
    write_json_atomic(out / COVERAGE_FILE, report)
    picked = list(selection.chosen)
    picked_cover = cover[picked].toarray() if picked else np.zeros((0, len(target_list)), bool)
    counts = picked_cover.sum(axis=0)
    best = np.where(picked_cover, visibility.dense("dori", picked), -1).max(axis=0, initial=-1)
    title = (f"{len(chosen)} cameras ({selection.method}, lower bound {selection.lower_bound}); "
             f"{int((counts >= k).sum())}/{len(target_list)} targets covered by {k} at >= {dori} "
             f"({standard_name}), "
             f"{len(selection.uncoverable)} uncoverable by any candidate")
    picture = plan_picture(triangles, target_list, chosen, counts, best, table, occ, title=title)
    write_png_atomic(out / PLAN_PICTURE, picture)
    seconds["write"] = time.perf_counter() - t
    return PlanResult(out, planned, tuple(chosen), len(candidates), tuple(target_list), selection, report,
                      seconds, occ.backend)


def covering_px_per_m(visibility: Visibility, hit: np.ndarray) -> np.ndarray:
    """(C,) per camera the summed median px/m of the targets it covers (``hit``: (P,) bool
    from :func:`usdscene.design.visibility.covering_pairs`), the selection's preference among
    equal-size sets."""
    return np.bincount(visibility.camera[hit], weights=visibility.px_per_m_pair[hit], minlength=visibility.cameras)


def _required_class(name: str, table, standard_name: str, shipped: bool) -> int:
    """Index of the required class; a class of the other shipped edition gets a hint."""
    try:
        return class_index(name, table, where="--dori")
    except DocumentError:
        if shipped:
            for edition, file in STANDARD_FILES.items():
                if any(c.name == name for c in load_dori(file)):
                    raise DocumentError(
                        f"{name!r} is a class of {table_standard(file)}, not of {standard_name}; add --standard "
                        f"{edition}, or name one of {', '.join(c.name for c in table)}", where="--dori") from None
        raise


def _pick_lenses(catalog: Mapping[str, Lens], names: Sequence[str] | None) -> list[Lens]:
    if not names:
        return list(catalog.values())
    unknown = [n for n in names if n not in catalog]
    if unknown:
        raise DocumentError(f"unknown lens {unknown[0]!r}; the catalog has {', '.join(catalog)}", where="--lens")
    return [catalog[n] for n in names]


def _named_cameras(cameras: Sequence[Camera], *, keep_names: bool) -> list[Camera]:
    if keep_names:
        return list(cameras)
    out = []
    for i, cam in enumerate(cameras):
        custom = dict(cam.custom)
        out.append(dataclasses.replace(
            cam, name=f"plan_{i + 1:02d}",
            description=f"planned by usdscene plan-cameras: {custom.get('mount')} mount, lens {custom.get('lens')}, "
                        f"candidate {cam.name}",
            custom={}))
    return out
