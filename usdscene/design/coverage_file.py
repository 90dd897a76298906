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
        cover: (candidates, targets) bool sparse matrix, the pair meets the requirement.
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


def floor_area(targets: Sequence[Target], covered: Sequence[bool]) -> dict:
    """The floor area of the targets and the share of it seen at the level, in total and per
    place (boxes under their own names).

    Returns:
        ``{"total_m2", "covered_m2", "share", "places": {place: {"total_m2", "covered_m2", "share"}}}``.
    """
    places: dict[str, list[float]] = {}
    for target, ok in zip(targets, covered):
        key = target.place or target.name.split("#")[0]
        entry = places.setdefault(key, [0.0, 0.0])
        entry[0] += target.area_m2
        entry[1] += target.area_m2 if ok else 0.0

    def row(total: float, seen: float) -> dict:
        return {"total_m2": round_figure(total, 2), "covered_m2": round_figure(seen, 2), "share": round_figure(seen / total if total else 0.0)}

    total, seen = sum(v[0] for v in places.values()), sum(v[1] for v in places.values())
    return {**row(total, seen), "places": {k: row(*v) for k, v in sorted(places.items())}}


def coverage_report(request: Mapping, coverage: Coverage, *, rescored: bool = False) -> dict:
    """The ``coverage.json`` content: request, summary, per target, per chosen camera.

    With ``rescored`` (the candidates are the setup's own cameras), every target also lists
    every candidate that sees any of it (``scored``), chosen or not, and ``scored_cameras``
    lists every candidate with the targets it covers: a camera that reaches the level nowhere
    still appears, with what it does see.

    Per (camera, target) pair the visible fraction, the median px/m over the visible points
    and its DORI class; ``covers`` says whether the pair meets the requirement. ``why``
    (``coverage.why``, one per uncoverable target) becomes
    ``summary.why_uncoverable``: per target the reason and the best class any candidate reaches.
    """
    targets, candidates, chosen = coverage.targets, coverage.candidates, coverage.chosen
    selection, visibility, cover, table = coverage.selection, coverage.visibility, coverage.cover, coverage.table
    mount_count, why = coverage.mount_count, coverage.why
    picked = list(selection.chosen)
    names = [chosen[i].name for i in range(len(picked))]
    # Dense rows of the chosen cameras only: (P, T) each.
    vis, in_img = visibility.dense("visible", picked), visibility.dense("in_image", picked)
    px, dori = visibility.dense("px_per_m", picked), visibility.dense("dori", picked)
    covers = cover[picked].toarray() if picked else np.zeros((0, len(targets)), bool)
    coverable = np.asarray(cover.sum(axis=0)).ravel()

    def pair(i: int, t: int) -> dict:
        d = int(dori[i, t])
        return {"camera": names[i], "visible_fraction": round_figure(vis[i, t]),
                "in_image_fraction": round_figure(in_img[i, t]),
                "px_per_m": round_figure(px[i, t], 1),
                "dori": table[d].name if d >= 0 else None, "covers": bool(covers[i, t])}

    picked_set = set(picked)
    if rescored:
        every = list(range(len(candidates)))
        s_vis, s_in = visibility.dense("visible", every), visibility.dense("in_image", every)
        s_px, s_dori = visibility.dense("px_per_m", every), visibility.dense("dori", every)
        s_cover = cover.toarray()

    def scored(t: int) -> list[dict]:
        return [{"camera": candidates[c].name, "chosen": c in picked_set, "visible_fraction": round_figure(s_vis[c, t]),
                 "in_image_fraction": round_figure(s_in[c, t]), "px_per_m": round_figure(s_px[c, t], 1),
                 "dori": table[int(s_dori[c, t])].name if s_dori[c, t] >= 0 else None, "covers": bool(s_cover[c, t])}
                for c in range(len(candidates)) if s_in[c, t] > 0]

    target_rows = []
    holes = []
    vis_t, covers_t = np.ascontiguousarray(vis.T), np.ascontiguousarray(covers.T)
    for t, target in enumerate(targets):
        # The chosen cameras that see the target, from the column (not a loop over all of them:
        # 203 cameras x 19,560 targets at the terminal's 1 m cells).
        seen = [pair(int(i), t) for i in np.flatnonzero(vis_t[t] > 0)]
        count = sum(1 for p in seen if p["covers"])
        best = max((int(dori[i, t]) for i in np.flatnonzero(covers_t[t])), default=-1)
        if count < int(request["k"]):
            holes.append(target.name)
        target_rows.append({"name": target.name, "place": target.place, "region": target.region,
                            "covering_cameras": count, "best_dori": table[best].name if best >= 0 else None,
                            "coverable_by_candidates": int(coverable[t]),
                            "cameras": seen, **({"scored": scored(t)} if rescored else {}),
                            "points_m": [[round_figure(v) for v in p] for p in target.points_m.tolist()]})
    camera_rows = []
    for i, c in enumerate(picked):
        cam = chosen[i]
        camera_rows.append({"name": cam.name, "candidate": candidates[c].name,
                            "lens": candidates[c].custom.get("lens", cam.model_name) if candidates[c].custom else
                            cam.model_name,
                            "position_m": [round_figure(v) for v in cam.pose.translation_m],
                            "forward": [round_figure(v) for v in cam.pose.rotation[:, 2]],
                            "targets": [targets[t].name for t in np.flatnonzero(covers[i])]})
    summary = {
        "cameras": len(picked), "method": selection.method, "optimal": selection.optimal,
        "lower_bound": selection.lower_bound, "gap": round_figure(selection.gap), "greedy_cameras": selection.greedy_size,
        "candidates": len(candidates), "mounts": mount_count, "targets": len(targets),
        "targets_covered": len(targets) - len(holes), "holes": holes,
        "uncoverable": [targets[t].name for t in selection.uncoverable],
        "short_of_k": [targets[t].name for t in selection.short],
        "why_uncoverable": {targets[u.target].name: {"reason": u.reason, "best_dori": table[u.best_dori].name
                                                     if u.best_dori >= 0 else None} for u in why},
        "pairs": len(visibility.camera), "program": {"rows": selection.rows, "columns": selection.columns,
                                                **({"zones": selection.zones} if selection.zones > 1 else {})},
        "floor_area": floor_area(targets, [r["covering_cameras"] >= int(request["k"]) for r in target_rows]),
    }
    extra = {}
    if rescored:
        extra["scored_cameras"] = [{"name": cam.name, "chosen": c in picked_set,
                                    "targets_in_view": int((s_in[c] > 0).sum()), "targets_seen": int((s_vis[c] > 0).sum()),
                                    "targets_covered": [targets[t].name for t in np.flatnonzero(s_cover[c])]}
                                   for c, cam in enumerate(candidates)]
    return {"format": "usdscene-coverage", "version": 1, "request": dict(request), "summary": summary,
            "cameras": camera_rows, "targets": target_rows, **extra}
