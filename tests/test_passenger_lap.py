"""The passenger's lap: a support place per (pose, body), declared in the catalog and true to
the geometry of ``people/passenger.usda``; the per-pose planning lap fits inside every body's;
malformed ``variant_places`` are refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.document import stage_schema as ss
from usdscene.scene.catalog import COMBINED_SETS, load_catalog
from usdscene.errors import AssetError

POSES = ["upright", "leaning", "reading", "sleeping"]


def _bodies():
    return load_catalog()["passenger"].variants[ss.VARIANT_SET_APPEARANCE]


@pytest.mark.usd
@pytest.mark.parametrize("pose", POSES)
def test_lap_rests_on_the_thighs_within_3_mm_and_no_body_part_reaches_into_it(pose):
    from pxr import Usd, UsdGeom

    entry = load_catalog()["passenger"]
    stage = Usd.Stage.Open(str(entry.usd_path))
    root = stage.GetDefaultPrim()
    checked = 0
    for body in _bodies()[::3]:  # every third body keeps the test short; all share one code path
        root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE).SetVariantSelection(body)
        root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_POSE).SetVariantSelection(pose)
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{root.GetPath()}/Geom/Body"))
        region = entry.places_for({ss.VARIANT_SET_POSE: pose, ss.VARIANT_SET_APPEARANCE: body})["lap"].regions["is_on"]
        points = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        bottom = UsdGeom.Subset(stage.GetPrimAtPath(f"{root.GetPath()}/Geom/Body/Bottom")).GetIndicesAttr().Get()
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        legs = np.unique(np.concatenate([indices[starts[f]:starts[f] + counts[f]] for f in bottom]))
        others = np.setdiff1d(np.arange(len(points)), legs)
        local = np.linalg.inv(region.pose.as_array())
        sx, sy, sz = region.size_m

        def inside(pts, z_lo, z_hi):  # region frame: x across the thighs, y along them
            p = pts @ local[:3, :3].T + local[:3, 3]
            return p[(np.abs(p[:, 0]) < sx / 2) & (np.abs(p[:, 1]) < sy / 2) & (p[:, 2] > z_lo) & (p[:, 2] < z_hi)]

        assert min(sx, sy) >= 0.15 and sz >= 0.03, body
        # Arms, hands, belly, head: nothing inside the box (touching its top is fine); the
        # margin is the lap search's cell margin around each vertex.
        assert len(inside(points[others], 0.0, sz - 1e-3)) == 0, body
        # The support is the legs' crest under the footprint: within 3 mm of the region's floor,
        # and nothing of the legs pierces it.
        crest = inside(points[legs], -0.1, np.inf)
        assert len(crest) >= 5 and crest[:, 2].max() == pytest.approx(0.0, abs=3e-3), body
        assert inside(points[legs], 3e-3, np.inf).size == 0, body
        checked += 1
    assert checked >= 8


def test_planning_lap_of_a_pose_fits_every_body():
    entry = load_catalog()["passenger"]
    combined = f"{ss.VARIANT_SET_POSE}{COMBINED_SETS}{ss.VARIANT_SET_APPEARANCE}"
    assert set(entry.variant_places) == {ss.VARIANT_SET_POSE, combined}
    for pose in POSES:
        plan = entry.places_for({ss.VARIANT_SET_POSE: pose})["lap"].regions["is_on"]
        for body in _bodies():
            exact = entry.places_for({ss.VARIANT_SET_POSE: pose,
                                      ss.VARIANT_SET_APPEARANCE: body})["lap"].regions["is_on"]
            assert exact != plan
            assert np.all(np.asarray(plan.size_m[:2]) <= np.asarray(exact.size_m[:2]) + 1e-9), (pose, body)


def test_awake_poses_laps_span_both_thighs_and_hold_a_laptop():
    """A lap lies across both thighs (at least 0.30 m) where a box that wide fits: with the
    knees together the largest box would be a strip along them, too narrow for a laptop."""
    entry = load_catalog()["passenger"]
    laptop = np.subtract(load_catalog()["laptop"].extent_max_m, load_catalog()["laptop"].extent_min_m)
    for pose in ("upright", "leaning", "reading"):
        across, along, height = entry.places_for({ss.VARIANT_SET_POSE: pose})["lap"].regions["is_on"].size_m
        assert across >= 0.30 and across >= laptop[0] and along >= laptop[1] and height >= laptop[2], pose


def test_variant_places_name_a_variant_the_entry_has(tmp_path):
    (tmp_path / "p.usda").write_text("#usda 1.0\n")
    lap = {"lap": {"kind": "lap", "regions": {"is_on": {"matrix": list(np.eye(4).reshape(16)),
                                                          "size_m": [0.3, 0.3, 0.1]}}}}
    entry = {"kind": "passenger", "usd": "p.usda", "extent_m": [[-0.2, -0.2, -0.4], [0.2, 0.2, 0.9]],
             "relations": ["is_on"], "variants": {"pose": ["sitting"], "appearance": ["a"]},
             "variant_places": {"pose": {"dancing": lap}}}

    def write(e):
        (tmp_path / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1,
                                                           "classes": {"sitter": e}}))

    write(entry)
    with pytest.raises(AssetError, match=r"classes\.sitter.*variant_places\.pose\.dancing: 'dancing' is not a "
                                         r"variant of 'pose' \(variants: sitting\)"):
        load_catalog([tmp_path], include_default=False)
    write({**entry, "variant_places": {"pose+appearance": {"sitting+b": lap}}})
    with pytest.raises(AssetError, match=r"variant_places\.pose\+appearance\.sitting\+b: 'b' is not a variant "
                                         r"of 'appearance'"):
        load_catalog([tmp_path], include_default=False)
    write({**entry, "variant_places": {"pose+appearance": {"sitting+a": lap}}})
    sitter = load_catalog([tmp_path], include_default=False)["sitter"]
    assert sitter.places_for({"pose": "sitting", "appearance": "a"})["lap"].regions["is_on"].size_m == (0.3, 0.3, 0.1)
    assert sitter.places_for({"pose": "sitting"}) == {}  # a combination needs every set chosen
