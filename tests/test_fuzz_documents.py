"""validate is the gate, on over a thousand mutated documents (hypothesis, derandomized).

Each example takes the minimal example document, applies one to three mutations (replace a
value by an odd one, delete a key, rename a key, duplicate a list item) and runs it through
:func:`usdscene.validation.validate_document` exactly as ``usdscene validate`` does (official
schema and shipped catalog). A document is either refused with a :class:`UsdSceneError` or
accepted, and an accepted one must compose (:func:`usdscene.scene.compose.compose_stage`) without
any error. Anything else (another exception, a run over the per-document time limit) fails.
"""

from __future__ import annotations

import copy
import json
import signal
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from usdscene.scene.compose import compose_stage
from usdscene.errors import UsdSceneError
from usdscene.validation import validate_document

pytestmark = pytest.mark.usd

EXAMPLES = 1000
SECONDS_PER_DOCUMENT = 20  # far above the ~0.1 s a document takes: only a hang reaches it
BASE = json.loads((Path(__file__).resolve().parents[1] / "examples" / "minimal" / "scene.openlabel.json")
                  .read_text(encoding="utf-8"))

# Values that broke or could break a reader: limits of USD, Blender, numpy and memory; odd
# strings (lone surrogate, control characters, paths); wrong types; non-finite numbers.
ODD_VALUES = [
    0, -1, 1, 2, 3, 7, 2**31, -2**31, 2**40, 2**63, 10**12, -10**12, 10**30, 0.5, -0.0, 1e-300,
    1e308, -1e308, float("nan"), float("inf"), float("-inf"), "", " ", "x", "\ud800", "a\x00b",
    "é✈", "../../../etc", "/etc/passwd", "NaN", "1e999", None, True, False, [], {}, [0], [1, 2, 3],
    [0.0, 0.0, 0.0, 1.0], [[0, 0]], {"x": 1}, "is_below", "is_on", "IS_ON", "camera", "light",
    "kannala", "opencv_fisheye", "radial_poly", "backpack", "seat_01A", "cam_01", "world",
]
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=6)
VALUES = st.sampled_from(ODD_VALUES) | JSON_VALUES


def _paths(node, prefix=()) -> list[tuple]:
    """Every path to a value inside ``node`` (dict keys and list indices), root excluded."""
    out = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in items:
        out.append((*prefix, key))
        out.extend(_paths(child, (*prefix, key)))
    return out


PATHS = _paths(BASE)


def _parent(doc, path):
    node = doc
    for key in path[:-1]:
        node = node[key]
    return node


def _mutate(doc, path, operation: str, value, new_key: str) -> None:
    """Apply one mutation in place; a path that an earlier mutation removed is skipped."""
    try:
        parent = _parent(doc, path)
        key = path[-1]
        parent[key]  # noqa: B018  (still there?)
    except (KeyError, IndexError, TypeError):
        return
    if not isinstance(parent, (dict, list)):  # an earlier mutation made it a string: 'ab'[1] reads
        return
    if operation == "replace":
        parent[key] = value
    elif operation == "delete":
        del parent[key]
    elif operation == "rename" and isinstance(parent, dict):
        parent[new_key] = parent.pop(key)
    elif operation == "duplicate" and isinstance(parent, list):
        parent.insert(key, copy.deepcopy(parent[key]))
    elif operation == "insert" and isinstance(parent[key], dict):
        parent[key][new_key] = value


MUTATION = st.tuples(st.sampled_from(PATHS),
                     st.sampled_from(["replace", "replace", "replace", "delete", "rename", "duplicate", "insert"]),
                     VALUES, st.text(min_size=1, max_size=8))


class _Hang(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Hang(f"no answer within {SECONDS_PER_DOCUMENT} s")


def test_mutated_documents_are_refused_or_compose(tmp_path):
    counts = {"documents": 0, "refused": 0, "composed": 0}
    document = tmp_path / "mutated.openlabel.json"
    stage_dir = tmp_path / "stage"

    @settings(max_examples=EXAMPLES, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(st.lists(MUTATION, min_size=1, max_size=3))
    def check(mutations) -> None:
        doc = copy.deepcopy(BASE)
        for path, operation, value, new_key in mutations:
            _mutate(doc, path, operation, value, new_key)
        # ensure_ascii writes a lone surrogate as the escape a hand-written file would hold
        document.write_text(json.dumps(doc, allow_nan=True, ensure_ascii=True), encoding="utf-8")
        counts["documents"] += 1
        previous = signal.signal(signal.SIGALRM, _on_alarm)
        signal.alarm(SECONDS_PER_DOCUMENT)
        try:
            try:
                checked = validate_document(document)
            except UsdSceneError as exc:
                assert exc.problems and all(str(p) for p in exc.problems)
                counts["refused"] += 1
                return
            # Accepted: it must compose; any error here is a gap in validate.
            compose_stage(checked.scene, checked.catalog, stage_dir)
            counts["composed"] += 1
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)

    check()
    assert counts["documents"] >= EXAMPLES
    # Both sides of the gate are exercised, or the test proves nothing.
    assert counts["refused"] >= EXAMPLES // 10 and counts["composed"] >= EXAMPLES // 10, counts
