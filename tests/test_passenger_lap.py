"""The passenger's lap: a support place per pose, declared in the catalog and true to the
geometry of ``passengers/passenger.usda``; malformed ``variant_places`` are refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from usdscene.document import stage_schema as ss
from usdscene.scene.catalog import load_catalog
from usdscene.errors import AssetError


@pytest.mark.parametrize("pose", ["upright", "leaning", "reading", "sleeping"])
def test_lap_rests_on_the_thighs_and_no_body_part_reaches_into_it(pose):
    from pxr import Usd, UsdGeom

    entry = load_catalog()["passenger"]
    region = entry.places_for({ss.VARIANT_SET_POSE: pose})["lap"].regions["is_on"]
    stage = Usd.Stage.Open(str(entry.usd_path))
    root = stage.GetDefaultPrim()
    root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_POSE).SetVariantSelection(pose)

    def points(name):  # asset frame (the meshes carry no transform of their own)
        mesh = UsdGeom.Mesh(root.GetPrimAtPath(f"Geom/{name}"))
        return np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)

    local = np.linalg.inv(region.pose.as_array())
    sx, sy, sz = region.size_m

    def inside(pts, z_lo, z_hi, across=sx):  # region frame: x across the thighs, y along them
        p = pts @ local[:3, :3].T + local[:3, 3]
        return p[(np.abs(p[:, 0]) < across / 2) & (np.abs(p[:, 1]) < sy / 2) & (p[:, 2] > z_lo) & (p[:, 2] < z_hi)]

    assert min(sx, sy) >= 0.15 and sz >= 0.03
    for part in ("Body", "Skin", "Hair"):  # arms, hands, belly, head: none inside the box
        assert len(inside(points(part), 0.0, sz - 1e-3)) == 0, part  # touching the top is fine
    # The support is the thighs' crest line along the lap (objects lie across it), and no part
    # of the legs pierces it under the footprint.
    crest = inside(points("Trousers"), -0.1, np.inf, across=np.inf)
    assert len(crest) > 20 and crest[:, 2].max() == pytest.approx(0.0, abs=1e-3)
    assert inside(points("Trousers"), 1e-3, np.inf).size == 0


def test_variant_places_name_a_variant_the_entry_has(tmp_path):
    (tmp_path / "p.usda").write_text("#usda 1.0\n")
    lap = {"lap": {"kind": "lap", "regions": {"is_on": {"matrix": list(np.eye(4).reshape(16)),
                                                          "size_m": [0.3, 0.3, 0.1]}}}}
    entry = {"kind": "passenger", "usd": "p.usda", "extent_m": [[-0.2, -0.2, -0.4], [0.2, 0.2, 0.9]],
             "relations": ["is_on"], "variants": {"pose": ["sitting"]},
             "variant_places": {"pose": {"dancing": lap}}}
    (tmp_path / "catalog.json").write_text(json.dumps({"format": "usdscene-catalog", "version": 1,
                                                       "classes": {"sitter": entry}}))
    with pytest.raises(AssetError, match=r"classes\.sitter.*variant_places\.pose\.dancing: 'dancing' is not a "
                                         r"variant of 'pose' \(variants: sitting\)"):
        load_catalog([tmp_path], include_default=False)
