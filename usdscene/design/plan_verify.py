"""``usdscene plan-cameras --verify``: prove a plan of :mod:`usdscene.design.camera_design` by a render.

:func:`verify_plan` renders the chosen cameras with Cycles at low cost, with every target point
as a small marker sphere, and compares predicted with rendered visibility::

    PLAN_DIR/verify/images, masks     the renders
    PLAN_DIR/verify/verification.json per (camera, target): predicted and rendered fractions
    PLAN_DIR/verify/sheet.png         contact sheet of the chosen views (markers in magenta)
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from usdscene.design.camera_design import CAMERAS_FILE, COVERAGE_FILE, occluder_scene, read_setup, stage_triangles
from usdscene.design.coverage_file import round_figure
from usdscene.design.occluders import Occluders, RAY_MARGIN_M
from usdscene.design.targets import Target
from usdscene.design.verify_sample import AgreementInterval, agreement_interval, sample_cameras, sample_targets
from usdscene.design.visibility import evaluate_visibility
from usdscene.document.model import Camera
from usdscene.errors import DocumentError, OutputError
from usdscene.labels.pixel_density import DoriClass, pixel_density

VERIFY_DIR = "verify"
VERIFY_FILE = "verification.json"


@dataclass(frozen=True)
class VerifyResult:
    """Predicted against rendered visibility of a plan.

    Attributes:
        pairs: (camera, target) pairs compared (target at least partly inside the image).
        agreeing: pairs whose predicted and rendered visible fractions differ by at most
            ``tolerance``.
        tolerance: that tolerance (fraction of the target's points).
        points: (camera, point) comparisons; ``points_agreeing`` of them agree.
        points_agreeing: see ``points``.
        report: the ``verification.json`` content.
        seconds: wall seconds (compose, render, compare).
        interval: exact binomial interval on the agreement rate (the report's confidence).
    """

    pairs: int
    agreeing: int
    tolerance: float
    points: int
    points_agreeing: int
    report: Mapping
    seconds: Mapping[str, float] = field(default_factory=dict)
    interval: AgreementInterval | None = None

    @property
    def agreement(self) -> float:
        """Fraction of the checked pairs that agree, in [0, 1]; 1.0 when no pair was checked."""
        return self.agreeing / self.pairs if self.pairs else 1.0


MARKER_UID_PREFIX = "marker_"


def write_marker_layer(targets: Sequence[Target], path: Path, *, radius_m: float, first_mask_id: int) -> dict[int, int]:
    """A USD layer with one object per target under ``/World/Objects``: a small sphere at
    each of its points (one mesh, one mask id), flat magenta.

    Returns:
        mask id → target index.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

    from usdscene.document import stage_schema as names
    from usdscene.render.synthetic import uv_sphere

    stage = Usd.Stage.CreateInMemory()
    pts, counts, idx = uv_sphere(radius_m, 8, 4)
    material = UsdShade.Material.Define(stage, "/World/Looks/Marker")
    shader = UsdShade.Shader.Define(stage, "/World/Looks/Marker/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.0, 0.0, 0.0))
    shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(1.0, 0.0, 1.0))
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    ids = {}
    for t, target in enumerate(targets):
        uid = f"{MARKER_UID_PREFIX}{t:05d}"
        mesh = UsdGeom.Mesh.Define(stage, names.object_prim_path("marker", uid))
        centres = target.points_m
        all_pts = (pts[None, :, :] + centres[:, None, :]).reshape(-1, 3)
        offsets = (np.arange(len(centres)) * len(pts))[:, None]
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in all_pts.tolist()]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray(np.tile(counts, len(centres)).tolist()))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray((idx[None, :] + offsets).ravel().tolist()))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        prim = mesh.GetPrim()
        prim.SetCustomDataByKey(names.CUSTOM_UID, uid)
        prim.SetCustomDataByKey(names.CUSTOM_CLASS, "marker")
        prim.CreateAttribute(names.ATTR_USER_UID, Sdf.ValueTypeNames.String).Set(uid)
        prim.CreateAttribute(names.ATTR_USER_CLASS, Sdf.ValueTypeNames.String).Set("marker")
        mask_id = first_mask_id + t
        prim.CreateAttribute(names.ATTR_MASK_ID, Sdf.ValueTypeNames.Int).Set(mask_id)
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)
        ids[mask_id] = t
    from usdscene.files import write_text_atomic

    write_text_atomic(path, stage.GetRootLayer().ExportToString())
    return ids


def verify_plan(plan_dir: str | Path, *, resolution_scale: float = 0.5, samples: int = 1,
                marker_radius_m: float = RAY_MARGIN_M, tolerance: float = 0.15,
                progress: bool = True, cameras: int | None = None, targets_per_camera: int | None = None,
                seed: int = 0, confidence: float = 0.95) -> VerifyResult:
    """Render the plan's cameras with its targets as markers and compare with the prediction.

    At scale a random sample is rendered instead (:mod:`usdscene.design.verify_sample`):
    ``cameras`` of the chosen cameras and, per sampled camera, ``targets_per_camera`` of the
    targets in its view (markers only for those), drawn with ``seed``; the report gives the
    sample and an exact binomial interval at ``confidence`` on the agreement rate.

    The occluder scene of the plan is composed again with the chosen cameras, a layer of
    marker spheres (radius ``marker_radius_m``, one object per target) is added, and every
    camera is rendered at ``resolution_scale`` of its resolution with ``samples`` samples and
    no denoising. A target point counts as seen in the render when its marker's mask id is
    found within a marker radius (at least one pixel) of its projected centre. Predicted
    visibility is recomputed by ray casting on the same stage.

    Args:
        plan_dir: folder written by :func:`plan_cameras`.
        resolution_scale: render size relative to the cameras' resolution.
        samples: Cycles samples per pixel (masks need one).
        marker_radius_m: marker sphere radius, metres.
        tolerance: pairs agree when the fractions differ by at most this.
        progress: render progress bar on stderr.
        cameras: cameras to draw from the plan's (None: all).
        targets_per_camera: targets to draw per drawn camera from those in its view (None: all).
        seed: seed of the draws.
        confidence: confidence level of the agreement interval, in (0, 1).

    Returns:
        A :class:`VerifyResult`; ``PLAN_DIR/verify/verification.json`` and ``sheet.png`` written.

    Raises:
        DocumentError: the folder is not a plan.
    """
    import cv2

    from pxr import Sdf

    from usdscene.document import output_layout as layout
    from usdscene.scene.compose import compose_stage
    from usdscene.files import write_json_atomic, write_png_atomic
    from usdscene.render.driver import render, scale_intrinsics

    plan = Path(plan_dir)
    seconds: dict[str, float] = {}
    try:
        report = json.loads((plan / COVERAGE_FILE).read_text(encoding="utf-8"))
        request = report["request"]
        occluders = str(request["occluders"])
        table = [DoriClass(c["name"], float(c["px_per_m"])) for c in request["dori_table"]]
        targets = [Target(t["name"], t["place"], t["region"], np.asarray(t["points_m"], dtype=np.float64))
                   for t in report["targets"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DocumentError(f"not a plan folder (cannot read {COVERAGE_FILE}: {exc})", where=str(plan)) from None
    if not 0 < resolution_scale <= 4:
        raise DocumentError(f"expected a scale in (0, 4], got {resolution_scale!r}", where="--verify-scale")
    for name, value in (("--verify-cameras", cameras), ("--verify-targets", targets_per_camera)):
        if value is not None and value < 1:
            raise DocumentError(f"expected a positive count, got {value!r}", where=name)
    if not 0 < confidence < 1:
        raise DocumentError(f"expected a confidence in (0, 1), got {confidence!r}", where="--verify-confidence")
    t0 = time.perf_counter()
    planned, catalog = read_setup(plan / CAMERAS_FILE)
    if not planned.cameras:
        raise DocumentError("the plan has no cameras to verify", where=str(plan / CAMERAS_FILE))
    rng = np.random.default_rng(seed)
    all_cameras = len(planned.cameras)
    drawn = sample_cameras(all_cameras, cameras, rng)
    planned = dataclasses.replace(planned, cameras=tuple(planned.cameras[i] for i in drawn))
    scene = occluder_scene(planned, catalog, occluders)
    verify = plan / VERIFY_DIR
    composed = compose_stage(scene, catalog, verify / layout.STAGE_DIR)
    triangles = stage_triangles(composed.root_layer, scene.frame_start)
    occ = Occluders(triangles)
    all_targets = len(targets)
    sampled = targets_per_camera is not None or cameras is not None
    if sampled:
        # Only the drawn targets get markers: a marker for every cell of a terminal is
        # millions of spheres.
        in_view = evaluate_visibility(planned.cameras, targets, occ, table).in_image
        per_camera = sample_targets(in_view, targets_per_camera, rng)
        keep = np.unique(np.concatenate(per_camera)) if per_camera else np.zeros(0, np.int64)
        targets = [targets[t] for t in keep]
        wanted = {(c, int(np.searchsorted(keep, t))) for c, ts in enumerate(per_camera) for t in ts}
    else:
        wanted = None
    marker_file = composed.stage_dir / "markers.usda"
    first_id = max(layout.mask_ids(scene).values(), default=0) + 1
    target_mask_ids = {t: mask_id for mask_id, t in
                       write_marker_layer(targets, marker_file, radius_m=marker_radius_m, first_mask_id=first_id).items()}
    root = Sdf.Layer.FindOrOpen(str(composed.root_layer))
    root.subLayerPaths.append(marker_file.name)
    root.Save()
    seconds["compose"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    frame = scene.frame_start
    render(composed.root_layer, verify, frames=[frame], settings_override={
        "samples": samples, "denoise": False, "resolution_scale": resolution_scale}, progress=progress)
    seconds["render"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    scaled = [dataclasses.replace(c, intrinsics=scale_intrinsics(c.intrinsics, resolution_scale))
               for c in planned.cameras]
    predicted = evaluate_visibility(scaled, targets, occ, table, keep_points=True)
    predicted_in_image, predicted_visible = predicted.in_image, predicted.visible
    rows, pairs, agreeing, points, points_ok = [], 0, 0, 0, 0
    thumbs = []
    for c, camera in enumerate(scaled):
        mask_file = layout.mask_path(verify, camera.name, frame)
        mask = cv2.imread(str(mask_file), cv2.IMREAD_UNCHANGED)
        if mask is None:
            raise OutputError("the verification render wrote no readable mask", where=str(mask_file))
        image = cv2.imread(str(layout.image_path(verify, camera.name, frame)), cv2.IMREAD_COLOR)
        thumbs.append((camera.name, image))
        for t, target in enumerate(targets):
            if predicted_in_image[c, t] == 0 or (wanted is not None and (c, t) not in wanted):
                continue
            seen = _rendered_points(camera, target.points_m, mask, target_mask_ids[t], marker_radius_m)
            pred = predicted.point_visible[predicted.pair_index(c, t)]
            rendered_fraction = float(seen.mean())
            predicted_fraction = float(predicted_visible[c, t])
            ok = abs(rendered_fraction - predicted_fraction) <= tolerance + 1e-12
            pairs += 1
            agreeing += ok
            points += len(seen)
            points_ok += int((seen == pred).sum())
            rows.append({"camera": camera.name, "target": target.name,
                         "predicted_visible_fraction": round_figure(predicted_fraction),
                         "rendered_visible_fraction": round_figure(rendered_fraction), "agree": bool(ok)})
    interval = agreement_interval(agreeing, pairs, confidence)
    summary = {"pairs": pairs, "agreeing_pairs": agreeing, "agreement": round_figure(agreeing / pairs if pairs else 1.0),
               "agreement_interval": [round_figure(interval.low), round_figure(interval.high)],
               "confidence": confidence, "tolerance": tolerance, "points": points, "agreeing_points": points_ok,
               "sample": {"cameras": len(scaled), "of_cameras": all_cameras, "targets": len(targets),
                          "of_targets": all_targets, "targets_per_camera": targets_per_camera, "seed": seed,
                          "sampled": sampled},
               "resolution_scale": resolution_scale, "samples": samples, "marker_radius_m": marker_radius_m}
    out = {"format": "usdscene-verification", "version": 1, "summary": summary, "pairs": rows}
    write_json_atomic(verify / VERIFY_FILE, out)
    from usdscene.dataset.contact_sheet import contact_sheet

    tiles = [(name, image if image is not None else np.zeros((180, 240, 3), np.uint8)) for name, image in thumbs]
    write_png_atomic(verify / "sheet.png", contact_sheet(tiles, tile_width=240, columns=6))
    seconds["compare"] = time.perf_counter() - t0
    return VerifyResult(pairs, agreeing, tolerance, points, points_ok, out, seconds, interval)


def _rendered_points(camera: Camera, points_m: np.ndarray, mask: np.ndarray, mask_id: int,
                     radius_m: float) -> np.ndarray:
    """(N,) bool: the marker of each point shows in ``mask`` within its projected radius."""
    from usdscene.labels.projection import project_points

    uv, ok = project_points(camera, points_m)
    h, w = mask.shape[:2]
    density = pixel_density(camera, points_m)
    out = np.zeros(len(points_m), dtype=bool)
    for i in np.flatnonzero(ok):
        r = max(1, int(math.ceil(density[i] * radius_m)))
        u, v = int(round(uv[i, 0])), int(round(uv[i, 1]))
        v0, v1, u0, u1 = max(0, v - r), min(h, v + r + 1), max(0, u - r), min(w, u + r + 1)
        # A point beyond the image border projects to an empty window (a negative end would
        # wrap around in numpy and look at the far side of the image).
        if v1 <= v0 or u1 <= u0:
            continue
        out[i] = bool((mask[v0:v1, u0:u1] == mask_id).any())
    return out
