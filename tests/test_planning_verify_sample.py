"""Verification at scale: a seeded sample of cameras and targets is rendered (Cycles, tiny
resolution) and the agreement rate carries an exact binomial interval."""

from __future__ import annotations

import numpy as np
import pytest

from usdscene.design.plan_request import PlanRequest
from usdscene.design.verify_sample import agreement_interval, sample_cameras, sample_targets


@pytest.mark.parametrize("agreeing,pairs", [(0, 10), (7, 10), (10, 10), (95, 100), (1, 1)])
def test_the_interval_is_scipys_exact_binomial_interval(agreeing, pairs):
    from scipy.stats import binomtest

    want = binomtest(agreeing, pairs).proportion_ci(confidence_level=0.95, method="exact")
    got = agreement_interval(agreeing, pairs, 0.95)
    assert got.low == pytest.approx(want.low, abs=1e-9) and got.high == pytest.approx(want.high, abs=1e-9)
    assert got.low <= agreeing / pairs <= got.high
    assert agreement_interval(0, 0).low == 0.0 and agreement_interval(0, 0).high == 1.0


def test_the_sample_is_seeded_and_drawn_from_what_is_in_view():
    in_view = np.zeros((5, 30))
    in_view[:, ::3] = 0.5
    a = sample_cameras(5, 3, np.random.default_rng(1))
    b = sample_cameras(5, 3, np.random.default_rng(1))
    assert a.tolist() == b.tolist() and len(set(a.tolist())) == 3 and sample_cameras(5, 9, np.random.default_rng(1)).tolist() == [0, 1, 2, 3, 4]
    per = sample_targets(in_view, 4, np.random.default_rng(2))
    assert all(len(p) == 4 and np.all(p % 3 == 0) and np.all(np.diff(p) > 0) for p in per)
    assert [len(p) for p in sample_targets(in_view, None, np.random.default_rng(2))] == [10] * 5


@pytest.mark.usd
@pytest.mark.blender
def test_a_sampled_verification_renders_only_the_sample_and_states_its_confidence(tmp_path, monkeypatch):
    from test_open_air_planning import write_setup

    from usdscene.design.camera_design import plan_cameras
    from usdscene.design.plan_verify import verify_plan

    document, lenses = write_setup(tmp_path)
    monkeypatch.setenv("USDSCENE_ASSET_PATH", str(tmp_path))
    request = PlanRequest.build(document, targets=["box:lot:-16,-12,0,16,12,1.6"], lenses_file=lenses,
                                occluders="setup", dori="overview", cell_m=4.0, target_spacing_m=1.0,
                                pole_heights_m=[6.0], pole_spacing_m=8.0, aims=2)
    plan = plan_cameras(request, tmp_path / "plan")
    assert len(plan.chosen) >= 2
    # 320 x 240 cameras at 0.2: 64 x 48 renders, one sample.
    result = verify_plan(tmp_path / "plan", resolution_scale=0.2, samples=1, marker_radius_m=0.25, progress=False,
                         cameras=1, targets_per_camera=5, seed=3)
    summary = result.report["summary"]
    assert summary["sample"]["cameras"] == 1 and summary["sample"]["of_cameras"] == len(plan.chosen)
    assert summary["sample"]["targets"] == 5 and summary["sample"]["of_targets"] == len(plan.targets)
    assert result.pairs == 5 and len({p["camera"] for p in result.report["pairs"]}) == 1
    lo, hi = summary["agreement_interval"]
    assert summary["confidence"] == 0.95 and 0.0 <= lo <= result.agreement <= hi <= 1.0 and hi - lo > 0.1
    # Only the drawn camera was rendered, and only the drawn targets got markers.
    from usdscene.document import output_layout as layout

    rendered = sorted(p.name for p in (tmp_path / "plan" / "verify" / layout.IMAGES_DIR).iterdir())
    assert rendered == [result.report["pairs"][0]["camera"]]
    markers = (tmp_path / "plan" / "verify" / layout.STAGE_DIR / "markers.usda").read_text()
    assert markers.count("def Mesh") == 5
