"""Value readers and pose encodings shared by the OpenLABEL reader and writer. Pure module.

Every reader takes the raw JSON value, the JSON path it was found at (``where``) and a
:class:`~usdscene.errors.ProblemCollector`; it returns the parsed value, or ``None`` after
adding a problem that quotes the bad value. Nothing here raises on bad input.

Pose encodings (``pose_wrt_parent``, ``transform_src_to_dst``) are the three of the OpenLABEL
schema: ``matrix4x4`` (16 numbers, row-major, last row ``0 0 0 1``), ``quaternion`` ``(x, y, z,
w)`` + ``translation``, and ``euler_angles`` + ``translation`` with a ``sequence`` of three
axes (default ``"ZYX"``): ``sequence = "ABC"`` with angles ``[a, b, c]`` (radians) is the
rotation ``R_A(a) · R_B(b) · R_C(c)``, so ``"ZYX"`` takes ``[rz, ry, rx]``.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Iterable, Sequence

from usdscene.errors import ProblemCollector
from usdscene.document.model import (
    MAX_FRAME,
    MAX_IMAGE_SIDE_PX,
    FrameInterval,
    Pose,
    euler_zyx_to_rotation,
    quaternion_to_rotation,
)

# Returned by readers of optional parts (a pose, a calibration) whose value was present but
# invalid, as opposed to None for absent: the problem is already recorded, and the caller must
# not fall back to a default as it would for an absent part.
INVALID = object()

# ``read_int(maximum=...)`` limits shared by several readers.
FRAME_LIMIT = (MAX_FRAME, "Blender's last frame")
IMAGE_SIDE_LIMIT = (MAX_IMAGE_SIDE_PX, "Blender's largest image side in pixels")

# Orthonormality tolerance of rotation blocks read from documents (absolute, per entry of
# R·Rᵀ - I). Loose enough for matrices printed with 7 significant digits.
ROTATION_TOLERANCE = 1e-5


def describe(value: Any, limit: int = 60) -> str:
    """Short ``repr`` of a JSON value for messages."""
    if isinstance(value, int) and not isinstance(value, bool):
        return _short_int(value)
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def suggest(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for a close known name, else ``""``."""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.75)
    return f" (did you mean {close[0]!r}?)" if close else ""


def is_number(value: Any) -> bool:
    """Whether ``value`` is a JSON number (a bool is not)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def read_number(value: Any, where: str, problems: ProblemCollector, *, positive: bool = False,
                non_negative: bool = False, what: str = "a number") -> float | None:
    """A finite JSON number as float; optionally > 0 or >= 0."""
    if not is_number(value):
        problems.add(where, f"expected {what}, got {describe(value)}")
        return None
    number = _as_float(value)
    if not math.isfinite(number):
        problems.add(where, f"expected a finite number, got {describe(value)}")
        return None
    if positive and number <= 0:
        problems.add(where, f"expected a positive number, got {describe(value)}")
        return None
    if non_negative and number < 0:
        problems.add(where, f"expected a number >= 0, got {describe(value)}")
        return None
    return number


def _as_float(value: int | float) -> float:
    """``float(value)``; inf for an integer beyond the float range (10³⁰⁸), which JSON allows."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def read_int(value: Any, where: str, problems: ProblemCollector, *, positive: bool = False,
             non_negative: bool = False, maximum: tuple[int, str] | None = None) -> int | None:
    """A JSON integer (``3``; ``3.0`` is refused: sizes and frames are counts).

    Args:
        maximum: ``(largest value, why)``, e.g. ``(65536, "Blender's largest image side")``.
    """
    if not isinstance(value, int) or isinstance(value, bool):
        problems.add(where, f"expected an integer, got {describe(value)}")
        return None
    if maximum is not None and value > maximum[0]:
        problems.add(where, f"{_short_int(value)} is above {maximum[0]}, {maximum[1]}")
        return None
    if positive and value <= 0:
        problems.add(where, f"expected a positive integer, got {describe(value)}")
        return None
    if non_negative and value < 0:
        problems.add(where, f"expected an integer >= 0, got {describe(value)}")
        return None
    return int(value)


def _short_int(value: int) -> str:
    """An integer for messages; a huge one is described, not printed (Python refuses to turn
    integers of more than 4300 digits into text)."""
    if abs(value) < 10 ** 60:
        return str(value)
    return f"an integer of about {int(value.bit_length() * math.log10(2))} digits"


def read_bool(value: Any, where: str, problems: ProblemCollector) -> bool | None:
    """``value`` if it is a JSON boolean; else None and a problem at ``where``."""
    if not isinstance(value, bool):
        problems.add(where, f"expected true or false, got {describe(value)}")
        return None
    return value


def read_text(value: Any, where: str, problems: ProblemCollector, *, non_empty: bool = False) -> str | None:
    """``value`` if it is a string (non-empty when asked); else None and a problem at ``where``."""
    if not isinstance(value, str):
        problems.add(where, f"expected a string, got {describe(value)}")
        return None
    if non_empty and not value:
        problems.add(where, "expected a non-empty string")
        return None
    return value


def read_numbers(value: Any, where: str, problems: ProblemCollector, *,
                 lengths: Sequence[int] | None = None, what: str = "numbers") -> tuple[float, ...] | None:
    """A list of finite numbers, optionally of one of ``lengths``."""
    if not isinstance(value, list):
        problems.add(where, f"expected a list of {what}, got {describe(value)}")
        return None
    if lengths is not None and len(value) not in lengths:
        expected = " or ".join(str(n) for n in lengths)
        problems.add(where, f"expected {expected} {what}, got {len(value)}: {describe(value)}")
        return None
    # fast path (documents hold 10⁵ of these): plain finite ints/floats, no bools
    if all(type(item) is float or type(item) is int for item in value):
        numbers = tuple(map(_as_float, value))
        if all(map(math.isfinite, numbers)):
            return numbers
    out = []
    ok = True
    for index, item in enumerate(value):
        if not is_number(item) or not math.isfinite(_as_float(item)):
            problems.add(f"{where}[{index}]", f"expected a finite number, got {describe(item)}")
            ok = False
        else:
            out.append(float(item))
    return tuple(out) if ok else None


def read_resolution(value: Any, where: str, problems: ProblemCollector) -> tuple[int, int] | None:
    """``[width, height]`` in pixels (positive integers)."""
    if not isinstance(value, list) or len(value) != 2:
        problems.add(where, f"expected [width, height] in pixels, got {describe(value)}")
        return None
    w = read_int(value[0], f"{where}[0]", problems, positive=True, maximum=IMAGE_SIDE_LIMIT)
    h = read_int(value[1], f"{where}[1]", problems, positive=True, maximum=IMAGE_SIDE_LIMIT)
    return (w, h) if w is not None and h is not None else None


def read_object(value: Any, where: str, problems: ProblemCollector) -> dict | None:
    """``value`` if it is a JSON object; else None and a problem at ``where``."""
    if not isinstance(value, dict):
        problems.add(where, f"expected a JSON object, got {describe(value)}")
        return None
    return value


def read_interval(item: Any, where: str, problems: ProblemCollector) -> FrameInterval | None:
    """``{"frame_start": a, "frame_end": b}`` → a closed interval (integers, a <= b)."""
    if not isinstance(item, dict):
        problems.add(where, f"expected {{'frame_start': int, 'frame_end': int}}, got {describe(item)}")
        return None
    extra = sorted(set(item) - {"frame_start", "frame_end"})
    if extra:
        problems.add(f"{where}.{extra[0]}", f"unknown key {extra[0]!r} in a frame interval")
        return None
    for key in ("frame_start", "frame_end"):
        if key not in item:
            problems.add(f"{where}.{key}", f"frame interval lacks {key!r}")
            return None
    start = read_int(item["frame_start"], f"{where}.frame_start", problems, non_negative=True, maximum=FRAME_LIMIT)
    end = read_int(item["frame_end"], f"{where}.frame_end", problems, non_negative=True, maximum=FRAME_LIMIT)
    if start is None or end is None:
        return None
    if start > end:
        problems.add(where, f"frame_start {start} is after frame_end {end}")
        return None
    return FrameInterval(start, end)


def read_intervals(value: Any, where: str, problems: ProblemCollector) -> tuple[FrameInterval, ...] | None:
    """``[{"frame_start": a, "frame_end": b}, ...]`` → closed intervals (order kept)."""
    if not isinstance(value, list):
        problems.add(where, f"expected a list of frame intervals, got {describe(value)}")
        return None
    out = [read_interval(item, f"{where}[{index}]", problems) for index, item in enumerate(value)]
    return None if None in out else tuple(out)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# Rotations and poses (pure Python for the per-pose checks: a document can hold 10⁵ poses)


def rotation_problem(m: Sequence[float]) -> str | None:
    """Why the row-major 4x4 ``m`` is not a rigid transform, or None."""
    if abs(m[12]) > 1e-9 or abs(m[13]) > 1e-9 or abs(m[14]) > 1e-9 or abs(m[15] - 1.0) > 1e-9:
        return f"last row must be 0 0 0 1, got {[m[12], m[13], m[14], m[15]]}"
    rows = ((m[0], m[1], m[2]), (m[4], m[5], m[6]), (m[8], m[9], m[10]))
    for i in range(3):
        for j in range(i, 3):
            dot = rows[i][0] * rows[j][0] + rows[i][1] * rows[j][1] + rows[i][2] * rows[j][2]
            if abs(dot - (1.0 if i == j else 0.0)) > ROTATION_TOLERANCE:
                return ("the 3x3 block is not a rotation (rows are not orthonormal; scale and "
                        "shear are not allowed in poses)")
    det = (rows[0][0] * (rows[1][1] * rows[2][2] - rows[1][2] * rows[2][1])
           - rows[0][1] * (rows[1][0] * rows[2][2] - rows[1][2] * rows[2][0])
           + rows[0][2] * (rows[1][0] * rows[2][1] - rows[1][1] * rows[2][0]))
    if det < 0:
        return "the 3x3 block is a reflection (determinant -1), not a rotation"
    return None


def read_matrix4x4(value: Any, where: str, problems: ProblemCollector) -> Pose | None:
    """16 numbers, row-major, rigid → Pose (values kept bit for bit)."""
    if isinstance(value, list) and len(value) == 9:
        problems.add(where, "a 3x3 matrix (9 numbers) was given where a 4x4 matrix (16 numbers, "
                            "row-major, last row 0 0 0 1) is expected")
        return None
    if isinstance(value, list) and len(value) == 4 and all(isinstance(r, list) for r in value):
        problems.add(where, "expected a flat list of 16 numbers (row-major), got a nested 4x4 list")
        return None
    numbers = read_numbers(value, where, problems, lengths=(16,))
    if numbers is None:
        return None
    problem = rotation_problem(numbers)
    if problem:
        problems.add(where, problem)
        return None
    return Pose(numbers)


def axis_rotation(axis: str, angle_rad: float) -> list[list[float]]:
    """(3, 3) rotation matrix (nested lists) by ``angle_rad`` radians about ``"X"``, ``"Y"`` or ``"Z"``."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    if axis == "X":
        return [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
    if axis == "Y":
        return [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    return [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]


def euler_to_rotation(sequence: str, angles_rad: Sequence[float]):
    """(3, 3) rotation ``R_A(a) · R_B(b) · R_C(c)`` for ``sequence = "ABC"`` (numpy array)."""
    import numpy as np

    if sequence == "ZYX":
        return euler_zyx_to_rotation(*angles_rad)
    r = np.eye(3)
    for axis, angle in zip(sequence, angles_rad):
        r = r @ np.asarray(axis_rotation(axis, angle))
    return r


def pose_from_rotation(rotation, translation: Sequence[float]) -> Pose:
    """The :class:`Pose` of a (3, 3) rotation and a translation (metres)."""
    return Pose((float(rotation[0][0]), float(rotation[0][1]), float(rotation[0][2]), float(translation[0]),
                 float(rotation[1][0]), float(rotation[1][1]), float(rotation[1][2]), float(translation[1]),
                 float(rotation[2][0]), float(rotation[2][1]), float(rotation[2][2]), float(translation[2]),
                 0.0, 0.0, 0.0, 1.0))


def read_transform(value: Any, where: str, problems: ProblemCollector) -> Pose | None:
    """A ``transform_data`` object (``pose_wrt_parent`` / ``transform_src_to_dst``) → Pose."""
    if not isinstance(value, dict):
        problems.add(where, "expected an object with 'matrix4x4', 'quaternion'+'translation' or "
                            f"'euler_angles'+'translation', got {describe(value)}")
        return None
    forms = [k for k in ("matrix4x4", "quaternion", "euler_angles") if k in value]
    if len(forms) != 1:
        if not forms:
            problems.add(where, "a pose needs 'matrix4x4', 'quaternion'+'translation' or "
                                f"'euler_angles'+'translation'; got keys {sorted(value)}")
        else:
            problems.add(where, f"give one pose form, not {' and '.join(forms)}")
        return None
    form = forms[0]
    allowed = {"matrix4x4": {"matrix4x4"}, "quaternion": {"quaternion", "translation"},
               "euler_angles": {"euler_angles", "translation", "sequence"}}[form]
    extra = sorted(set(value) - allowed)
    if extra:
        problems.add(f"{where}.{extra[0]}", f"unexpected key {extra[0]!r} beside {form!r}")
        return None
    if form == "matrix4x4":
        return read_matrix4x4(value["matrix4x4"], f"{where}.matrix4x4", problems)
    if "translation" not in value:
        problems.add(f"{where}.translation", f"{form!r} needs a 'translation' [x, y, z] (metres)")
        return None
    translation = read_numbers(value["translation"], f"{where}.translation", problems, lengths=(3,))
    if form == "quaternion":
        quaternion = read_numbers(value["quaternion"], f"{where}.quaternion", problems, lengths=(4,))
        if quaternion is None or translation is None:
            return None
        if math.sqrt(sum(q * q for q in quaternion)) < 1e-9:
            problems.add(f"{where}.quaternion", f"quaternion {list(quaternion)} has zero length")
            return None
        return pose_from_rotation(quaternion_to_rotation(quaternion), translation)
    angles = read_numbers(value["euler_angles"], f"{where}.euler_angles", problems, lengths=(3,))
    sequence = value.get("sequence", "ZYX")
    if (not isinstance(sequence, str) or len(sequence) != 3 or set(sequence) - set("XYZ")
            or sequence[0] == sequence[1] or sequence[1] == sequence[2]):
        problems.add(f"{where}.sequence", f"expected three axes like 'ZYX' (no axis twice in a "
                                          f"row), got {describe(sequence)}")
        return None
    if angles is None or translation is None:
        return None
    return pose_from_rotation(euler_to_rotation(sequence, angles), translation)

