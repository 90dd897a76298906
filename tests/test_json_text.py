"""usdscene.files.dumps_json writes exactly what json.dumps(indent=2) writes, only faster."""

import enum
import json
import math

import numpy as np
import pytest

from usdscene.files import dumps_json


class _Level(enum.IntEnum):
    LOW = 3


def _reference(data) -> str:
    return json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


@pytest.mark.parametrize("data", [
    {"openlabel": {"metadata": {"schema_version": "1.0.0"}, "objects": {}, "frames": []}},
    [1, 1.5, 1e-05, 1e16, -0.0, 2 ** 80, True, False, None, "é\n\"\\\x01\u2028 seat_03A/lap"],
    {1: "int key", 2.5: "float key", True: "bool key", None: "null key", "nested": [[], {}, [[{"a": ()}]]]},
    ({"tuple": (1, (2, 3))}, [_Level.LOW, {"level": _Level.LOW}]),
    {"numpy": [np.float64(0.1), np.float64(1e-7)]},
    "a lone string", 7, None, [], {},
])
def test_same_text_as_json_dumps(data):
    assert dumps_json(data) == _reference(data)


@pytest.mark.parametrize("data, error", [
    ({"x": math.nan}, ValueError), ([math.inf], ValueError), ({-math.inf: 1}, ValueError),
    ({(1, 2): "tuple key"}, TypeError), ({"set": {1, 2}}, TypeError), ([object()], TypeError), ([np.int64(4)], TypeError),
])
def test_same_errors_as_json_dumps(data, error):
    with pytest.raises(error) as ours:
        dumps_json(data)
    with pytest.raises(error) as theirs:
        _reference(data)
    assert str(ours.value) == str(theirs.value)
