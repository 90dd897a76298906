"""Atomic writes and path containment: the only way usdscene writes an output file.

Every output is written to a temporary file in the same folder and renamed over the target,
so a killed run never leaves a half-written file that looks valid. Every failure of the
operating system (no space left, file size limit, a parent that is a file, no permission)
becomes one :class:`~usdscene.errors.OutputError` naming the path and the cause.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterator

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


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike, *, what: str = "output folder") -> Iterator[Path]:
    """A fresh hidden folder beside ``path`` to write a whole folder of outputs into.

    When the block ends normally the staged folder replaces ``path`` (an old one is removed);
    when it raises, the staged folder is removed and ``path`` is untouched. A reader therefore
    sees the old folder or the complete new one, never a half-written one, and the files inside
    need no atomic writes of their own.

    Raises:
        OutputError: the folder cannot be created or renamed (naming the path and the cause).
    """
    target = Path(path)
    make_folder(target.parent, what=f"folder of the {what}")
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent))
        os.chmod(staging, _FILE_MODE | 0o111)
    except OSError as exc:
        raise OutputError([os_problem(exc, what=what)]) from None
    try:
        yield staging
        old = None
        if target.exists() or target.is_symlink():
            old = target.with_name(f".{target.name}.old-{os.getpid()}")
            os.replace(target, old)
        os.replace(staging, target)
        if old is not None:
            shutil.rmtree(old) if old.is_dir() and not old.is_symlink() else old.unlink()
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise OutputError([os_problem(exc, what=what)]) from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


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
    with _atomic_handle(path, "wb") as (target, handle):
        handle.write(data)
    return target


@contextlib.contextmanager
def _atomic_handle(path: str | os.PathLike, mode: str, **open_args) -> Iterator[tuple[Path, object]]:
    """``(target, handle)`` of a temporary file beside ``path`` that replaces it when the block
    ends without an exception (fsync + rename); on an exception the temporary file is removed
    and an operating-system refusal becomes one :class:`OutputError` naming the path."""
    target = prepare_output_file(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        os.fchmod(fd, _FILE_MODE)
        with os.fdopen(fd, mode, **open_args) as handle:
            yield target, handle
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


@contextlib.contextmanager
def atomic_text_file(path: str | os.PathLike) -> Iterator:
    """A UTF-8 text handle whose content replaces ``path`` atomically when the block ends
    without an exception (temp file + fsync + rename, as :func:`write_bytes_atomic`), for a
    file written piece by piece (a streamed document); on an exception nothing is left.

    Raises:
        OutputError: as :func:`write_bytes_atomic`.
    """
    with _atomic_handle(path, "w", encoding="utf-8", newline="\n") as (_, handle):
        yield handle


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
    """Write ``text`` as UTF-8 to ``path`` atomically (see :func:`write_bytes_atomic`); returns the path."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def dumps_json(data: Any) -> str:
    """Canonical JSON text of usdscene outputs: insertion order kept (documents read like
    their input), 2-space indent, no NaN/Infinity, trailing newline.

    The text is exactly ``json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False)``
    plus the newline (the same separators, escapes, number forms and errors); it is built by
    :func:`_indented_chunks` because the standard library's indented encoder is pure Python
    generators, which took seconds for a generated 15 MB document.

    Raises:
        ValueError: a NaN or infinite float.
        TypeError: a value or key JSON cannot hold.
    """
    out: list[str] = []
    _indented_chunks(data, "\n", out)
    out.append("\n")
    return "".join(out)


_INDENT = "  "
_encode_string = json.encoder.encode_basestring  # the C escaper where available, as json.dumps uses
_int_text = int.__repr__  # int and float subclasses (IntEnum, numpy.float64) as plain numbers
_float_repr = float.__repr__


def _float_text(value: float) -> str:
    if value != value or value in (math.inf, -math.inf):
        raise ValueError("Out of range float values are not JSON compliant: " + repr(value))
    return _float_repr(value)


def _scalar_text(value: Any) -> str | None:
    """JSON text of a scalar as :func:`json.dumps` writes it; None for containers and others."""
    exact = _EXACT_SCALARS.get(type(value))  # the common case, one look-up
    if exact is not None:
        return exact(value)
    if isinstance(value, str):
        return _encode_string(value)
    if isinstance(value, int):  # bool is an exact type above; IntEnum and numpy integers land here
        return _int_text(value)
    if isinstance(value, float):
        return _float_text(value)
    return None


_EXACT_SCALARS = {str: _encode_string, int: _int_text, float: _float_text,
                  bool: lambda value: "true" if value else "false", type(None): lambda value: "null"}


def _key_text(key: Any) -> str:
    """A mapping key as :func:`json.dumps` converts it (numbers, booleans and None as text)."""
    if isinstance(key, str):
        return _encode_string(key)
    if isinstance(key, float):
        return _encode_string(_float_text(key))
    if key is True:
        return '"true"'
    if key is False:
        return '"false"'
    if key is None:
        return '"null"'
    if isinstance(key, int):
        return _encode_string(_int_text(key))
    raise TypeError(f"keys must be str, int, float, bool or None, not {key.__class__.__name__}")


def _indented_chunks(value: Any, newline: str, out: list[str]) -> None:
    """Append the indented JSON text of ``value`` to ``out``; ``newline`` is the line break
    plus the indentation of the line ``value`` starts on."""
    text = _scalar_text(value)
    if text is not None:
        out.append(text)
        return
    if isinstance(value, (list, tuple)):
        if not value:
            out.append("[]")
            return
        inner = newline + _INDENT
        out.append("[")
        for item in value:
            out.append(inner)
            text = _scalar_text(item)
            if text is None:
                _indented_chunks(item, inner, out)
            else:
                out.append(text)
            out.append(",")
        out[-1] = newline + "]"
        return
    if isinstance(value, dict):
        if not value:
            out.append("{}")
            return
        inner = newline + _INDENT
        out.append("{")
        for key, item in value.items():
            out.append(inner)
            out.append(_key_text(key))
            out.append(": ")
            text = _scalar_text(item)
            if text is None:
                _indented_chunks(item, inner, out)
            else:
                out.append(text)
            out.append(",")
        out[-1] = newline + "}"
        return
    raise TypeError(f"Object of type {value.__class__.__name__} is not JSON serializable")


def remove_stale_temporaries(folder: str | os.PathLike, *, recursive: bool = True, name: str | None = None) -> int:
    """Delete what the atomic writes of a killed process left in ``folder``: temporary files
    (``.<name>.<random>.tmp``, :func:`write_text_atomic` and kin) and the hidden folders of
    :func:`staged_folder` (``.<name>.<random>.partial`` and ``.<name>.old-<pid>``). A SIGKILL
    cannot be cleaned up after; the real files were never replaced by partial ones. Call it
    before a step writes there again, never while another process writes into the folder.
    ``name``: only those of files whose name starts so (a user's folder holds other things).

    Returns:
        How many were removed (0 when the folder does not exist).
    """
    root = Path(folder)
    if not root.is_dir():
        return 0
    stem = f".{glob.escape(name)}*" if name else ".*"
    removed = 0
    for suffix in (".tmp", ".partial", ".old-*"):
        found = root.rglob(stem + suffix) if recursive else root.glob(stem + suffix)
        for path in sorted(found, key=lambda p: len(p.parts)):
            if path.is_symlink() or path.is_file():
                path.unlink(missing_ok=True)
            elif path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                continue
            removed += 1
    return removed


def write_json_atomic(path: str | os.PathLike, data: Any, *, compact: bool = False) -> Path:
    """Serialise ``data`` (fails on NaN/Infinity before touching the file) and write it atomically.

    ``compact``: one line without indent, for files people do not read (caches); Python's
    compiled encoder writes it several times faster than the indented text.
    """
    text = (json.dumps(data, ensure_ascii=False, allow_nan=False, separators=(",", ":")) + "\n"
            if compact else dumps_json(data))
    return write_text_atomic(path, text)


def user_cache_folder() -> Path:
    """Where usdscene keeps caches that only save time (compiled schema checks):
    ``$USDSCENE_CACHE_DIR``, else ``$XDG_CACHE_HOME/usdscene``, else ``~/.cache/usdscene``.
    Not created here; writers must treat any failure as "no cache"."""
    explicit = os.environ.get("USDSCENE_CACHE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "usdscene"


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
