"""Atomic writes and path containment: the only way usdscene writes an output file.

Every output is written to a temporary file in the same folder and renamed over the target,
so a killed run never leaves a half-written file that looks valid. Every failure of the
operating system (no space left, file size limit, a parent that is a file, no permission)
becomes one :class:`~usdscene.errors.OutputError` naming the path and the cause.
"""

from __future__ import annotations

import errno
import json
import os
import tempfile
from pathlib import Path
from typing import Any

from usdscene.errors import OutputError, Problem

# Causes worded for people; the rest use the operating system's own text (``strerror``).
_REASONS = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large (the file size limit, ulimit -f, was reached)",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.ENAMETOOLONG: "the file name is too long",
}


def _creation_mode() -> int:
    """Permission bits of a new file under the process umask (mkstemp alone gives 0600, which
    would hide outputs from the other users of a shared dataset folder)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


_FILE_MODE = _creation_mode()


def _file_in_the_way(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` (or ``path`` itself) that is not a folder."""
    for candidate in (path, *path.parents):
        if candidate.is_dir():
            return None
        if candidate.exists() or candidate.is_symlink():
            return candidate
    return None


def os_problem(exc: OSError, *, what: str = "") -> Problem:
    """One readable problem for an operating-system error: where = the path, message = the cause.

    Args:
        exc: the error (``filename`` names the path when the OS gave one).
        what: what the path is for (``"output folder"``, ``"scene document"``), if known.

    Returns:
        ``Problem(path, "cannot <what>: <cause>")``; a parent that is a regular file is named.
    """
    path = Path(os.fsdecode(exc.filename)) if exc.filename not in (None, "") else None
    reason = _REASONS.get(exc.errno) or (exc.strerror or str(exc)).rstrip(".").lower() or type(exc).__name__
    if path is not None and exc.errno in (errno.ENOTDIR, errno.EEXIST):
        blocker = _file_in_the_way(path)
        if blocker is not None:
            reason = f"{str(blocker)!r} is a file, not a folder"
    prefix = f"cannot write the {what}: " if what else ""
    return Problem(str(path) if path is not None else "", prefix + reason)


def make_folder(path: str | os.PathLike, *, what: str = "output folder") -> Path:
    """Create ``path`` and its parents (nothing happens when it exists as a folder).

    Raises:
        OutputError: naming the path and the cause (a parent is a file, no permission...).
    """
    folder = Path(path)
    if str(path) == "":
        raise OutputError(f"the {what} is an empty path", where=what)
    blocker = _file_in_the_way(folder)
    if blocker is not None:
        raise OutputError(f"cannot create the {what}: {str(blocker)!r} is a file, not a folder",
                          where=str(folder))
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError([os_problem(exc, what=what)]) from None
    return folder


def prepare_output_file(path: str | os.PathLike, *, what: str = "output file") -> Path:
    """Check that ``path`` can become a file and create its folder: called before long work
    (a render) so that a bad output path fails in a second, not after the work.

    Raises:
        OutputError: the path is empty, an existing folder, or its folder cannot be created.
    """
    if str(path) == "":
        raise OutputError(f"the {what} is an empty path", where=what)
    target = Path(path)
    if target.is_dir():
        raise OutputError(f"cannot write the {what}: it is an existing folder", where=str(target))
    make_folder(target.parent, what=f"folder of the {what}")
    return target


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file + fsync + rename); creates parents.

    Raises:
        OutputError: the path is empty or a folder, a parent cannot be created, or the
            operating system refused the write (no space, file size limit, permission); the
            target is then untouched and no temporary file is left behind.
    """
    target = prepare_output_file(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        os.fchmod(fd, _FILE_MODE)
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        if isinstance(exc, OSError):
            problem = os_problem(exc, what="file")
            raise OutputError([Problem(str(target), problem.message)]) from None
        raise
    return target


def write_png_atomic(path: str | os.PathLike, image) -> Path:
    """Encode an (H, W[, C]) uint8/uint16 image (BGR channel order) as PNG and write it atomically.

    Raises:
        OutputError: the image cannot be encoded, or the file cannot be written.
    """
    import cv2

    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise OutputError(f"cannot encode a {getattr(image, 'shape', '?')} image as PNG", where=str(path))
    return write_bytes_atomic(path, encoded.tobytes())


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


def dumps_json(data: Any) -> str:
    """Canonical JSON text of usdscene outputs: insertion order kept (documents read like
    their input), 2-space indent, no NaN/Infinity, trailing newline."""
    return json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def write_json_atomic(path: str | os.PathLike, data: Any, *, compact: bool = False) -> Path:
    """Serialise ``data`` (fails on NaN/Infinity before touching the file) and write it atomically.

    ``compact``: one line without indent, for files people do not read (caches); Python's
    compiled encoder writes it several times faster than the indented text.
    """
    text = (json.dumps(data, ensure_ascii=False, allow_nan=False, separators=(",", ":")) + "\n"
            if compact else dumps_json(data))
    return write_text_atomic(path, text)


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
