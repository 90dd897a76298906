"""The sample a plan is verified on when rendering every chosen camera and target would cost
too much (``plan-cameras --verify --verify-cameras N --verify-targets M``), and the confidence
the agreement rate of that sample carries. Pure (numpy, scipy).

Cameras are drawn uniformly without replacement from the plan's cameras, then, per drawn
camera, targets uniformly without replacement from those with a point in its image, from one
seeded ``numpy.random.Generator`` (same plan and seed, same sample). The agreement rate of the
sampled (camera, target) pairs gets an exact (Clopper-Pearson) binomial interval. It treats
the pairs as independent draws; pairs of one camera share its render, so with few cameras the
interval is optimistic about camera-level faults (a wrong pose would fail all its pairs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AgreementInterval:
    """An exact binomial interval on an agreement rate.

    Attributes:
        agreeing: pairs that agree.
        pairs: pairs compared.
        confidence: the interval's confidence level, in (0, 1).
        low, high: its ends, in [0, 1].
    """

    agreeing: int
    pairs: int
    confidence: float
    low: float
    high: float


def agreement_interval(agreeing: int, pairs: int, confidence: float = 0.95) -> AgreementInterval:
    """The Clopper-Pearson interval of ``agreeing`` successes in ``pairs`` trials ([0, 1] when
    nothing was compared)."""
    from scipy.stats import beta

    alpha = 1.0 - confidence
    if pairs <= 0:
        return AgreementInterval(0, 0, confidence, 0.0, 1.0)
    low = 0.0 if agreeing <= 0 else float(beta.ppf(alpha / 2, agreeing, pairs - agreeing + 1))
    high = 1.0 if agreeing >= pairs else float(beta.ppf(1 - alpha / 2, agreeing + 1, pairs - agreeing))
    return AgreementInterval(int(agreeing), int(pairs), float(confidence), low, high)


def sample_cameras(count: int, wanted: int | None, rng: np.random.Generator) -> np.ndarray:
    """Ascending indices of ``wanted`` of ``count`` cameras drawn without replacement (all of
    them when ``wanted`` is None or not smaller)."""
    if wanted is None or wanted >= count:
        return np.arange(count)
    return np.sort(rng.choice(count, size=wanted, replace=False))


def sample_targets(in_view: np.ndarray, wanted: int | None, rng: np.random.Generator) -> list[np.ndarray]:
    """Per camera, ascending indices of at most ``wanted`` targets drawn without replacement
    from those in its view.

    Args:
        in_view: (C, T) fraction of each target's points inside each camera's image.
        wanted: targets per camera (None: every target in view).
        rng: the generator.
    """
    out = []
    for row in np.asarray(in_view):
        seen = np.flatnonzero(row > 0)
        if wanted is not None and wanted < len(seen):
            seen = np.sort(rng.choice(seen, size=wanted, replace=False))
        out.append(seen)
    return out
