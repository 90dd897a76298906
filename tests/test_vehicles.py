"""Procedural vehicles: body types with the features a detector uses, and fleet paint."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from usdscene.assetgen import vehicles as vh
from usdscene.errors import AssetError


def test_paint_variants_are_the_fleet_in_steps_of_five_percent():
    vh.check_paint_shares(vh.PAINT_SHARES, field="paint")
    assert len(vh.PAINT_VARIANTS) == 20
    shares = collections.Counter(vh.PAINT_FAMILY.values())
    for family, share in vh.PAINT_SHARES.items():
        assert abs(shares[family] / 20 - share) <= 0.03, family
    # White, black, grey and silver dominate.
    assert sum(shares[f] for f in ("white", "black", "grey", "silver")) / 20 >= 0.8


def test_bad_paint_distribution_and_unknown_body_type_name_the_field():
    with pytest.raises(AssetError) as err:
        vh.check_paint_shares({"white": 0.6, "black": 0.3}, field="paint_shares")
    assert err.value.problems[0].where == "paint_shares" and "0.9" in str(err.value)
    with pytest.raises(AssetError, match="'limousine'"):
        vh.vehicle_parts("limousine")


@pytest.mark.parametrize("name", list(vh.BODY_TYPES))
def test_every_body_type_has_its_parts_closed_and_in_place(name):
    b = vh.BODY_TYPES[name]
    parts = vh.vehicle_parts(name)
    assert set(parts) == {"body", "glass", "tyres", "rims", "headlights", "taillights", "mirrors", "plates"}
    for part, mesh in parts.items():
        assert mesh.is_watertight and mesh.volume > 0, part  # closed, wound outwards
    body = parts["body"]
    lo, hi = body.bounds
    assert hi[2] == pytest.approx(b.height_m) and hi[0] - lo[0] == pytest.approx(b.length_m)
    # Wheels stand on the ground inside the body's length and under its arches: the body has
    # no material just above each tyre's top, inside its width.
    tyres = parts["tyres"]
    assert tyres.bounds[0][2] == pytest.approx(0.0, abs=1e-6)
    for x in (b.wheelbase_m / 2, -b.wheelbase_m / 2):
        probe = np.array([[x, 0.0, 2 * b.wheel_radius_m + 0.02]])
        assert not body.contains(probe)[0]
        assert body.contains(np.array([[x, 0.0, 2 * b.wheel_radius_m + 0.15]]))[0]
    # The windscreen rakes back: its top is behind its foot; glass lies above the belt.
    assert parts["glass"].bounds[0][2] >= b.belt_m - 0.01
    outline, greenhouse = vh.side_profile(b)
    assert greenhouse[1][0] < greenhouse[0][0] and greenhouse[1][1] > greenhouse[0][1]
    # Lights at the front (+X) and back, plates on both ends, mirrors outside the body's width.
    assert parts["headlights"].bounds[0][0] > hi[0] - 0.05 and parts["taillights"].bounds[1][0] < lo[0] + 0.05
    assert parts["mirrors"].bounds[1][1] > hi[1]


def test_body_types_differ_where_a_detector_looks():
    heights = {n: b.height_m for n, b in vh.BODY_TYPES.items()}
    assert heights["van"] > heights["suv"] > heights["sedan"]
    assert vh.BODY_TYPES["sedan"].rear == "notch" and vh.BODY_TYPES["hatchback"].rear == "hatch"
    assert vh.BODY_TYPES["pickup"].rear == "bed"
