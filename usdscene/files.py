"""Atomic writes and path containment: the only way usdscene writes an output file.

Every output is written to a temporary file in the same folder and renamed over the target,
so a killed run never leaves a half-written file that looks valid.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

from usdscene.errors import OutputError


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file + fsync + rename); creates parents."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return target


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


def dumps_json(data: Any) -> str:
    """Canonical JSON text of usdscene outputs: insertion order kept (documents read like
    their input), 2-space indent, no NaN/Infinity, trailing newline."""
    return json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def write_json_atomic(path: str | os.PathLike, data: Any) -> Path:
    """Serialise ``data`` (fails on NaN/Infinity before touching the file) and write it atomically."""
    return write_text_atomic(path, dumps_json(data))


def resolve_inside(root: str | os.PathLike, relative: str | os.PathLike, *, what: str = "path") -> Path:
    """``root / relative`` resolved, refusing anything that escapes ``root``.

    Raises:
        OutputError: the path is absolute outside ``root`` or climbs out with ``..``/symlinks.
    """
    base = Path(root).resolve()
    candidate = (base / relative).resolve()
    if candidate != base and base not in candidate.parents:
        raise OutputError(f"{what} {str(relative)!r} escapes the folder {str(base)!r}", where=what)
    return candidate
