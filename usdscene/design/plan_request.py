"""What a camera plan is asked to do: one frozen :class:`PlanRequest` (the setup document, the
targets, where cameras may go, with which lenses, the image-detail level and standard, what
blocks the views, and the solver's limits). ``usdscene plan-cameras`` builds it from its
arguments; :func:`usdscene.design.camera_design.plan_cameras` takes it; ``coverage.json``
records it. Pure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from usdscene.errors import DocumentError, ProblemCollector

DEFAULT_TARGETS = ("*:on,below,in_front,in",)
OCCLUDER_MODES = ("worst-case", "setup")


@dataclass(frozen=True)
class PlanRequest:
    """A camera-planning request.

    Attributes:
        setup_document: OpenLABEL setup (environment, optional cameras, lights, render).
        targets: ``PLACE_GLOB:REGION,...`` or ``box:NAME:x0,y0,z0,x1,y1,z1`` (metres) specs.
        mounts: ``auto`` (ceiling and wall positions every ``spacing_m``) or ``setup``
            (re-score the setup's own cameras; lenses are then the cameras' own).
        spacing_m: mount grid spacing, metres.
        lenses_file: user lens catalog extending the shipped one.
        lens_names: catalog lenses to try (None: all).
        k: cameras each target needs.
        dori: required image-detail class name.
        dori_table_file: detail table replacing the shipped one.
        occluders: ``worst-case`` (a passenger in every seat) or ``setup`` (the setup's objects).
        min_visible: fraction of a target's points a camera must see to count, in (0, 1].
        aims: target-cluster aims per mount (besides the surface normal).
        target_spacing_m: spacing of the sample points in each target region, metres.
        time_limit_s: MILP time limit, seconds.
    """

    setup_document: Path
    targets: tuple[str, ...] = DEFAULT_TARGETS
    mounts: str = "auto"
    spacing_m: float = 0.8
    lenses_file: Path | None = None
    lens_names: tuple[str, ...] | None = None
    k: int = 1
    dori: str = "observe"
    dori_table_file: Path | None = None
    occluders: str = "worst-case"
    min_visible: float = 0.25
    aims: int = 4
    target_spacing_m: float = 0.2
    time_limit_s: float = 60.0

    @classmethod
    def build(cls, setup_document: str | Path, *, targets: Sequence[str] | None = None,
              lenses_file: str | Path | None = None, lens_names: Sequence[str] | None = None,
              dori_table_file: str | Path | None = None, **values) -> "PlanRequest":
        """A request from loosely typed values (paths as strings, lists), checked.

        Raises:
            DocumentError: every out-of-range number and unknown mode at once.
        """
        request = cls(setup_document=Path(setup_document),
                      targets=tuple(targets) if targets else DEFAULT_TARGETS,
                      lenses_file=Path(lenses_file) if lenses_file is not None else None,
                      lens_names=tuple(lens_names) if lens_names else None,
                      dori_table_file=Path(dori_table_file) if dori_table_file is not None else None,
                      **values)
        request.check()
        return request

    def check(self) -> None:
        """Raise one DocumentError naming every bad option (by its command-line name)."""
        problems = ProblemCollector()
        limits = {"k": (1, None), "min_visible": (0.0, 1.0), "spacing_m": (0.05, None),
                  "target_spacing_m": (0.01, None), "aims": (0, None), "time_limit_s": (0.1, None)}
        for name, (lo, hi) in limits.items():
            value = getattr(self, name)
            if not math.isfinite(value) or value < lo or (hi is not None and value > hi):
                span = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
                problems.add(f"--{name.replace('_', '-')}", f"expected a number {span}, got {value!r}")
        if self.min_visible == 0:
            problems.add("--min-visible", "0 would let a camera that sees nothing count; use a positive fraction")
        if self.occluders not in OCCLUDER_MODES:
            problems.add("--occluders", f"unknown occluders {self.occluders!r}; expected one of "
                                        f"{', '.join(OCCLUDER_MODES)}")
        problems.raise_if_any(DocumentError)
        if self.mounts not in ("auto", "setup"):
            raise DocumentError(f"unknown mounts {self.mounts!r}; expected 'auto' or 'setup'", where="--mounts")

    def record(self, lens_names: Sequence[str], table: Sequence) -> dict:
        """The ``request`` object of ``coverage.json``.

        Args:
            lens_names: the lenses actually tried (empty when re-scoring the setup's cameras).
            table: the image-detail classes in force (``name``, ``px_per_m``).
        """
        return {"setup": self.setup_document.name, "targets": list(self.targets), "mounts": self.mounts,
                "spacing_m": self.spacing_m, "lenses": list(lens_names), "k": self.k, "dori": self.dori,
                "min_visible": self.min_visible, "occluders": self.occluders, "aims": self.aims,
                "target_spacing_m": self.target_spacing_m,
                "dori_table": [{"name": c.name, "px_per_m": c.px_per_m} for c in table]}
