"""Camera mounts a user gives (``plan-cameras --mounts FILE``): positions and, optionally, the
aims allowed at each. Pure.

Format (metres, world frame, Z up)::

    {"mounts": [
        {"name": "gate_pole", "position_m": [12.0, -3.5, 5.0]},
        {"name": "kiosk_corner", "position_m": [2.1, 4.0, 3.2],
         "aims": [[0.0, -1.0, -0.4]], "look_at_m": [[0.0, 0.0, 0.0]]}
    ]}

``aims`` are view directions (need not be unit length), ``look_at_m`` points to look at; a
mount with neither is aimed at the nearest target clusters, like a pole.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from usdscene.design.candidates import Mount
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.labels.pixel_density import read_json_object


def _vector(value, where: str, problems: ProblemCollector) -> np.ndarray | None:
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        problems.add(where, f"expected [x, y, z] in metres, got {value!r}")
        return None
    return np.asarray(value, dtype=np.float64)


def load_mounts(path: str | Path) -> list[Mount]:
    """The mounts of a user's mount file, in file order.

    Raises:
        DocumentError: unreadable file or malformed entries (every problem at once, each
            named by its JSON path).
    """
    file = Path(path)
    problems = ProblemCollector()
    data = read_json_object(file, problems)
    mounts: list[Mount] = []
    if data is not None:
        entries = data.get("mounts")
        if not isinstance(entries, list) or not entries:
            problems.add(f"{file}:mounts", "expected a non-empty list of {name, position_m[, aims, look_at_m]}")
            entries = []
        names: set[str] = set()
        for i, entry in enumerate(entries):
            where = f"{file}:mounts[{i}]"
            if not isinstance(entry, dict):
                problems.add(where, f"expected an object, got {entry!r}")
                continue
            unknown = sorted(set(entry) - {"name", "position_m", "aims", "look_at_m"})
            if unknown:
                problems.add(where, f"unknown field(s) {', '.join(unknown)}")
            name = entry.get("name", f"mount_{i + 1}")
            if not isinstance(name, str) or not name or name in names:
                problems.add(f"{where}.name", f"expected a unique non-empty name, got {name!r}")
                continue
            names.add(name)
            position = _vector(entry.get("position_m"), f"{where}.position_m", problems)
            aims = []
            for key in ("aims", "look_at_m"):
                raw = entry.get(key, [])
                if not isinstance(raw, list):
                    problems.add(f"{where}.{key}", f"expected a list of [x, y, z], got {raw!r}")
                    continue
                for j, item in enumerate(raw):
                    v = _vector(item, f"{where}.{key}[{j}]", problems)
                    if v is None or position is None:
                        continue
                    direction = v if key == "aims" else v - position
                    norm = float(np.linalg.norm(direction))
                    if norm < 1e-9:
                        problems.add(f"{where}.{key}[{j}]", "a zero-length aim (a look-at point at the camera?)")
                        continue
                    aims.append(tuple(float(c) for c in direction / norm))
            if position is not None:
                mounts.append(Mount(tuple(float(c) for c in position), "user", (0.0, 0.0, 0.0),  # type: ignore[arg-type]
                                    tuple(aims), name))  # type: ignore[arg-type]
    problems.raise_if_any(DocumentError)
    return mounts
