"""The ``coverage.json`` of a camera plan (:func:`usdscene.design.camera_design.plan_cameras`):
the request, the summary, per target the cameras that cover it, per chosen camera its pose and
targets."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from usdscene.design.selection import Selection
from usdscene.design.targets import Target
from usdscene.design.visibility import Uncovered, Visibility
from usdscene.document.model import Camera
from usdscene.labels.pixel_density import DoriClass


def round_figure(value: float, digits: int = 4) -> float:
    """``value`` as a float rounded to ``digits`` decimals, as the plan files write figures."""
    return float(round(float(value), digits))


@dataclass(frozen=True)
class Coverage:
    """What a camera plan found, for :func:`coverage_report`.

    Attributes:
        targets: the targets; candidates: every candidate camera; chosen: the cameras chosen
            (``selection.chosen`` indexes ``candidates``, in the order of ``chosen``).
        selection: the chosen candidates and the uncoverable targets.
        visibility: per (candidate, target) visible fraction, in-image fraction, px/m, DORI class.
        cover: (candidates, targets) bool, the pair meets the requirement.
        table: the DORI classes (``visibility.dori`` indexes it).
        mount_count: mounts the candidates were placed on.
        why: :func:`usdscene.design.visibility.why_uncovered`, one per uncoverable target.
    """

    targets: Sequence[Target]
    candidates: Sequence[Camera]
    chosen: Sequence[Camera]
    selection: Selection
    visibility: Visibility
    cover: np.ndarray
    table: Sequence[DoriClass]
    mount_count: int
    why: Sequence[Uncovered] = ()


def coverage_report(request: Mapping, coverage: Coverage) -> dict:
    """The ``coverage.json`` content: request, summary, per target, per chosen camera.

    Per (camera, target) pair the visible fraction, the median px/m over the visible points
    and its DORI class; ``covers`` says whether the pair meets the requirement. ``coverage.why``
    becomes ``summary.why_uncoverable``: per target the reason and the best class any candidate
    reaches.
    """
    targets, candidates, chosen = coverage.targets, coverage.candidates, coverage.chosen
    selection, visibility, cover, table = coverage.selection, coverage.visibility, coverage.cover, coverage.table
    mount_count, why = coverage.mount_count, coverage.why
    picked = list(selection.chosen)
    names = {c: chosen[i].name for i, c in enumerate(picked)}

    def pair(c: int, t: int) -> dict:
        d = int(visibility.dori[c, t])
        return {"camera": names[c], "visible_fraction": round_figure(visibility.visible[c, t]),
                "in_image_fraction": round_figure(visibility.in_image[c, t]),
                "px_per_m": round_figure(visibility.px_per_m[c, t], 1),
                "dori": table[d].name if d >= 0 else None, "covers": bool(cover[c, t])}

    target_rows = []
    holes = []
    for t, target in enumerate(targets):
        seen = [pair(c, t) for c in picked if visibility.visible[c, t] > 0]
        count = sum(1 for p in seen if p["covers"])
        best = max((int(visibility.dori[c, t]) for c in picked if cover[c, t]), default=-1)
        if count < int(request["k"]):
            holes.append(target.name)
        target_rows.append({"name": target.name, "place": target.place, "region": target.region,
                            "covering_cameras": count, "best_dori": table[best].name if best >= 0 else None,
                            "coverable_by_candidates": int(cover[:, t].sum()),
                            "cameras": seen,
                            "points_m": [[round_figure(v) for v in p] for p in target.points_m.tolist()]})
    camera_rows = []
    for i, c in enumerate(picked):
        cam = chosen[i]
        camera_rows.append({"name": cam.name, "candidate": candidates[c].name,
                            "lens": candidates[c].custom.get("lens", cam.model_name) if candidates[c].custom else
                            cam.model_name,
                            "position_m": [round_figure(v) for v in cam.pose.translation_m],
                            "forward": [round_figure(v) for v in cam.pose.rotation[:, 2]],
                            "targets": [targets[t].name for t in np.flatnonzero(cover[c])]})
    summary = {
        "cameras": len(picked), "method": selection.method, "optimal": selection.optimal,
        "lower_bound": selection.lower_bound, "gap": round_figure(selection.gap), "greedy_cameras": selection.greedy_size,
        "candidates": len(candidates), "mounts": mount_count, "targets": len(targets),
        "targets_covered": len(targets) - len(holes), "holes": holes,
        "uncoverable": [targets[t].name for t in selection.uncoverable],
        "short_of_k": [targets[t].name for t in selection.short],
        "why_uncoverable": {targets[u.target].name: {"reason": u.reason, "best_dori": table[u.best_dori].name
                                                     if u.best_dori >= 0 else None} for u in why},
    }
    return {"format": "usdscene-coverage", "version": 1, "request": dict(request), "summary": summary,
            "cameras": camera_rows, "targets": target_rows}
