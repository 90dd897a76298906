"""What a camera plan is asked to do: one frozen :class:`PlanRequest` (the setup document, the
targets, where cameras may go, with which lenses, the image-detail level and standard, what
blocks the views, and the solver's limits). ``usdscene plan-cameras`` builds it from its
arguments; :func:`usdscene.design.camera_design.plan_cameras` takes it; ``coverage.json``
records it. Pure.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from usdscene.design.targets import DEFAULT_CELL_M
from usdscene.errors import DocumentError, ProblemCollector

DEFAULT_TARGETS = ("*:on,below,in_front,in",)
OCCLUDER_MODES = ("worst-case", "setup")
# The planner's default edition of IEC 62676-4, and the level asked for when --dori is not
# given: discern (80 px/m) is the 2025 level next above the 2015 "observe" (62.5 px/m).
DEFAULT_STANDARD = "2025"
DEFAULT_LEVEL = {"2015": "observe", "2025": "discern"}


@dataclass(frozen=True)
class PlanRequest:
    """A camera-planning request.

    Attributes:
        setup_document: OpenLABEL setup (environment, optional cameras, lights, render).
        targets: ``PLACE_GLOB:REGION,...`` or ``box:NAME:x0,y0,z0,x1,y1,z1`` (metres) specs.
        mounts: ``auto`` (ceiling and wall positions every ``spacing_m``; poles and façades
            in the open air; the environment's ``mount_*`` nodes), ``setup`` (re-score the
            setup's own cameras; lenses are then the cameras' own) or the path of a mount file
            (:mod:`usdscene.design.user_mounts`).
        spacing_m: mount grid spacing of rooms, metres.
        lenses_file: user lens catalog extending the shipped one.
        lens_names: catalog lenses to try (None: all).
        k: cameras each target needs.
        dori: required image-detail class name (None: :data:`DEFAULT_LEVEL` of the standard).
        dori_table_file: detail table replacing the shipped one of ``standard``.
        standard: edition of IEC 62676-4 whose shipped table is used (``2015`` or ``2025``).
        occluders: ``worst-case`` (a passenger in every seat) or ``setup`` (the setup's objects).
        min_visible: fraction of a target's points a camera must see to count, in (0, 1].
        aims: target-cluster aims per mount (besides the surface normal).
        target_spacing_m: spacing of the sample points in each target region, metres.
        cell_m: regions longer than this are split into cells no longer than this, metres.
        max_memory_gb: the most the kept (camera, target) pairs may take; a larger request is
            refused before any ray is cast, GB.
        time_limit_s: MILP time limit, seconds.
        zone_m: plan the floor in square zones of this side, one program each
            (:mod:`usdscene.design.zones`), metres; 0: the whole floor in one program.
        pole_heights_m: camera heights of open-air poles above the ground, metres (empty: no
            poles and no façade mounts).
        pole_spacing_m: grid spacing of open-air poles, metres.
    """

    setup_document: Path
    targets: tuple[str, ...] = DEFAULT_TARGETS
    mounts: str = "auto"
    spacing_m: float = 0.8
    lenses_file: Path | None = None
    lens_names: tuple[str, ...] | None = None
    k: int = 1
    dori: str | None = None
    dori_table_file: Path | None = None
    standard: str = DEFAULT_STANDARD
    occluders: str = "worst-case"
    min_visible: float = 0.25
    aims: int = 4
    target_spacing_m: float = 0.2
    cell_m: float = DEFAULT_CELL_M
    max_memory_gb: float = 6.0
    time_limit_s: float = 60.0
    pole_heights_m: tuple[float, ...] = (4.0, 6.0)
    pole_spacing_m: float = 4.0
    zone_m: float = 0.0

    @classmethod
    def build(cls, setup_document: str | Path, *, targets: Sequence[str] | None = None,
              lenses_file: str | Path | None = None, lens_names: Sequence[str] | None = None,
              dori_table_file: str | Path | None = None, pole_heights_m: Sequence[float] | None = None,
              **values) -> "PlanRequest":
        """A request from loosely typed values (paths as strings, lists), checked.

        Raises:
            DocumentError: every out-of-range number and unknown mode at once.
        """
        request = cls(setup_document=Path(setup_document),
                      targets=tuple(targets) if targets else DEFAULT_TARGETS,
                      lenses_file=Path(lenses_file) if lenses_file is not None else None,
                      lens_names=tuple(lens_names) if lens_names else None,
                      dori_table_file=Path(dori_table_file) if dori_table_file is not None else None,
                      **({} if pole_heights_m is None else {"pole_heights_m": tuple(float(h) for h in pole_heights_m)}),
                      **values)
        request.check()
        return request

    def check(self) -> None:
        """Raise one DocumentError naming every bad option (by its command-line name)."""
        problems = ProblemCollector()
        limits = {"k": (1, None), "min_visible": (0.0, 1.0), "spacing_m": (0.05, None),
                  "target_spacing_m": (0.01, None), "aims": (0, None), "time_limit_s": (0.1, None),
                  "pole_spacing_m": (0.5, None), "cell_m": (0.1, None), "max_memory_gb": (1e-9, None),
                  "zone_m": (0.0, None)}
        values = [(name, getattr(self, name)) for name in limits] + \
            [("pole_heights_m", h) for h in self.pole_heights_m]
        limits["pole_heights_m"] = (0.5, 100.0)
        for name, value in values:
            lo, hi = limits[name]
            if not math.isfinite(value) or value < lo or (hi is not None and value > hi):
                span = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
                problems.add("--" + re.sub(r"_(m|s|gb)$", "", name).replace("_", "-"),
                             f"expected a number {span}, got {value!r}")
        if self.min_visible == 0:
            problems.add("--min-visible", "0 would let a camera that sees nothing count; use a positive fraction")
        if self.occluders not in OCCLUDER_MODES:
            problems.add("--occluders", f"unknown occluders {self.occluders!r}; expected one of "
                                        f"{', '.join(OCCLUDER_MODES)}")
        if self.standard not in DEFAULT_LEVEL:
            problems.add("--standard", f"unknown standard {self.standard!r}; expected one of "
                                       f"{', '.join(DEFAULT_LEVEL)}")
        if self.dori is None and self.dori_table_file is not None:
            problems.add("--dori", "a --dori-table needs --dori naming one of its classes")
        if self.mounts not in ("auto", "setup") and not Path(self.mounts).is_file():
            problems.add("--mounts", f"expected 'auto', 'setup' or a mount file, got {self.mounts!r} "
                                     "(no such file)")
        problems.raise_if_any(DocumentError)

    @property
    def level(self) -> str:
        """The required image-detail class: ``dori``, or the standard's default level."""
        return self.dori if self.dori is not None else DEFAULT_LEVEL[self.standard]

    def record(self, lens_names: Sequence[str], table: Sequence, standard_name: str) -> dict:
        """The ``request`` object of ``coverage.json``.

        Args:
            lens_names: the lenses actually tried (empty when re-scoring the setup's cameras).
            table: the image-detail classes in force (``name``, ``px_per_m``, ``group``).
            standard_name: the standard that table follows (``IEC 62676-4:2025``).
        """
        mounts = self.mounts if self.mounts in ("auto", "setup") else Path(self.mounts).name
        return {"setup": Path(self.setup_document).name, "targets": list(self.targets), "mounts": mounts,
                "spacing_m": self.spacing_m, "lenses": list(lens_names), "k": self.k, "dori": self.level,
                "min_visible": self.min_visible, "occluders": self.occluders, "aims": self.aims,
                "target_spacing_m": self.target_spacing_m, "cell_m": self.cell_m,
                "dori_table": [{"name": c.name, "px_per_m": c.px_per_m, **({"group": c.group} if c.group else {})}
                               for c in table],
                "standard": standard_name, "pole_heights_m": list(self.pole_heights_m),
                "pole_spacing_m": self.pole_spacing_m, **({"zone_m": self.zone_m} if self.zone_m else {})}
