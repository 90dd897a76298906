"""The README's cabin example: the committed document is ``make_documents.py``'s output, and
its seated passengers face forward in the middle of their seats (luggage is the only thing
turned at random)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np

from usdscene.converters.openlabel import read_openlabel

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "aircraft_cabin"


def test_committed_cabin_document_is_the_scripts_output(tmp_path):
    spec = importlib.util.spec_from_file_location("cabin_make_documents", EXAMPLE / "make_documents.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main(["-o", str(tmp_path / "cabin.openlabel.json")]) == 0
    written = json.loads((tmp_path / "cabin.openlabel.json").read_text(encoding="utf-8"))
    committed = json.loads((EXAMPLE / "cabin.openlabel.json").read_text(encoding="utf-8"))
    assert differences(written, committed) == []


def differences(a, b, path="$"):
    """JSON paths where two documents differ; floats equal to 12 significant digits count as
    equal, since the last digit of a rotation moves with the linear algebra library's build."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{path}: keys {sorted(a.keys() ^ b.keys())}"]
        return [d for key in a for d in differences(a[key], b[key], f"{path}.{key}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items, not {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float):
        return [] if math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15) else [f"{path}: {a} != {b}"]
    return [] if (a == b and type(a) is type(b)) else [f"{path}: {a!r} != {b!r}"]


def test_cabin_passengers_sit_facing_forward_and_luggage_is_turned():
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.placement import place_objects

    scene = read_openlabel(EXAMPLE / "cabin.openlabel.json")
    passengers = [o for o in scene.objects if o.class_name == "passenger"]
    luggage = [o for o in scene.objects if o.class_name != "passenger"]
    assert len(passengers) == 18 and luggage
    assert all(o.randomization.rotation_noise_deg == 0.0 and o.randomization.position_noise_m == 0.0
               for o in passengers)
    assert all(o.randomization.rotation_noise_deg > 0.0 for o in luggage)
    catalog = load_catalog()
    seats = {r.subject_uid: r.object_uid for r in scene.relations if r.type == "is_on"}
    places = {p.uid: p.name for p in scene.places}
    cabin = catalog[scene.environment]
    placements = place_objects(scene, catalog, np.random.default_rng(scene.seed))
    for obj in passengers:
        seat = cabin.places[places[seats[obj.uid]]].regions["is_on"].pose.as_array()
        placed = placements[obj.uid].pose_at(0).as_array()
        # The seat's pose exactly: facing forward like it, on the middle of the cushion.
        assert np.allclose(placed, seat, atol=1e-9), obj.uid
