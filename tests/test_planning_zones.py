"""Planning in zones (``--zone``): the overlap rule keeps everything the whole-floor plan
covers, on the open lot of ``test_open_air_planning`` and on random covers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix

from usdscene.design.plan_request import PlanRequest
from usdscene.design.selection import select_cameras
from usdscene.design.zones import select_by_zones, zone_index
from usdscene.errors import DocumentError


def test_zones_are_half_open_squares_from_the_lowest_corner():
    centres = np.array([[0.0, 0.0], [9.99, 0.0], [10.0, 0.0], [0.0, 10.0], [25.0, 12.0]])
    assert zone_index(centres, 10.0).tolist() == [0, 0, 1, 2, 3]
    assert zone_index(np.zeros((0, 3)), 5.0).tolist() == []


@pytest.mark.parametrize("seed,k", [(0, 1), (1, 2)])
def test_a_zoned_selection_meets_every_demand_the_whole_one_meets(seed, k):
    rng = np.random.default_rng(seed)
    # Cameras see targets near them on a 20 x 10 grid of targets, so zones share cameras.
    xy = np.stack(np.meshgrid(np.arange(20.0), np.arange(10.0), indexing="ij"), axis=-1).reshape(-1, 2)
    cams = rng.uniform([0, 0], [20, 10], size=(120, 2))
    cover = np.linalg.norm(cams[:, None] - xy[None], axis=2) < rng.uniform(1.5, 3.5, size=(120, 1))
    whole = select_cameras(csr_matrix(cover), k, time_limit_s=10)
    zoned = select_by_zones(csr_matrix(cover), k, zone_index(xy, 5.0), time_limit_s=10)
    demand = np.minimum(cover.sum(axis=0), k)
    assert zoned.zones == 8 and zoned.method == "zones"
    got_whole = cover[list(whole.chosen)].sum(axis=0)
    got_zoned = cover[list(zoned.chosen)].sum(axis=0)
    assert np.all(got_whole >= demand) and np.all(got_zoned >= demand)
    # The bound of the zoned run bounds the whole optimum too.
    assert whole.optimal and zoned.lower_bound <= len(whole.chosen) <= len(zoned.chosen)
    # No camera of the zoned set is redundant (reverse-delete over the whole floor).
    for c in zoned.chosen:
        rest = [d for d in zoned.chosen if d != c]
        assert np.any(cover[rest].sum(axis=0) < demand)


def test_a_negative_zone_is_refused_by_name(tmp_path):
    setup = tmp_path / "setup.json"
    setup.write_text("{}")
    with pytest.raises(DocumentError) as err:
        PlanRequest.build(setup, zone_m=-1.0)
    assert "--zone" in str(err.value) and "-1.0" in str(err.value)


@pytest.mark.usd
def test_a_zoned_plan_of_the_open_lot_covers_what_the_whole_plan_covers(tmp_path):
    from test_open_air_planning import write_setup

    from usdscene.design.camera_design import plan_cameras

    document, lenses = write_setup(tmp_path)
    plans = {}
    for zone in (0.0, 12.0):
        request = PlanRequest.build(document, targets=["box:lot:-16,-12,0,16,12,1.6"], lenses_file=lenses,
                                    occluders="setup", dori="overview", cell_m=4.0, target_spacing_m=1.0,
                                    pole_heights_m=[6.0], pole_spacing_m=8.0, aims=2, zone_m=zone)
        plans[zone] = plan_cameras(request, tmp_path / f"zone_{zone:g}")
    whole, zoned = (plans[z].coverage for z in (0.0, 12.0))
    assert zoned["request"]["zone_m"] == 12.0 and "zone_m" not in whole["request"]
    assert zoned["summary"]["program"]["zones"] >= 2 and zoned["summary"]["method"] == "zones"
    covered = {z: {t["name"] for t in plans[z].coverage["targets"] if t["covering_cameras"] >= 1}
               for z in plans}
    assert len(covered[0.0]) >= 40 and covered[12.0] >= covered[0.0]
    assert zoned["summary"]["lower_bound"] <= whole["summary"]["cameras"] <= zoned["summary"]["cameras"]


def test_the_command_refuses_a_negative_zone_and_a_zero_verify_sample_readably(tmp_path, capsys):
    from usdscene.cli import main

    doc = tmp_path / "missing.json"
    assert main(["plan-cameras", "--setup", str(doc), "-o", str(tmp_path / "p"), "--zone", "-1"]) == 1
    err = capsys.readouterr().err
    assert "--zone" in err and "-1.0" in err and "Traceback" not in err
    assert not (tmp_path / "p").exists()
    assert main(["plan-cameras", "--verify", str(tmp_path / "p"), "--verify-cameras", "0"]) == 2
    assert "--verify-cameras" in capsys.readouterr().err
