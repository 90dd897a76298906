"""Scratch folders of render workers (job files, EXR buffers, logs), and removal of the ones
that dead processes left behind. Pure (stdlib only).

A worker killed with SIGKILL (the OOM killer, a lost node, a user) cannot clean up after
itself; its folder on ``/dev/shm`` stays and eats shared memory. Folder names therefore carry
the owner's process id and host name, ``usdscene-<kind>-<pid>-<host>-<random>``, so that a
later run can tell a dead owner's folder (removed) from a live run's (kept). Folders of other
users, of other hosts (a ``/dev/shm`` shared between containers) and folders named without a
pid (written by older versions, whose owner cannot be known) are never touched.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import socket
import tempfile
from pathlib import Path

log = logging.getLogger(__name__)

KINDS = ("render", "job", "task")
# mkdtemp appends 8 characters from [a-z0-9_].
_NAME = re.compile(r"^usdscene-(?:%s)-(\d+)-([A-Za-z0-9.]*)-[a-z0-9_]{8}$" % "|".join(KINDS))


def scratch_root() -> Path | None:
    """``/dev/shm`` when writable (EXR buffers in memory), else None (the system temp folder)."""
    return Path("/dev/shm") if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def host_tag() -> str:
    """This machine's host name reduced to ``[A-Za-z0-9.]`` (part of scratch folder names)."""
    return re.sub(r"[^A-Za-z0-9.]", "", socket.gethostname())[:40]


def make_scratch(kind: str) -> Path:
    """A new, empty scratch folder owned by this process.

    Args:
        kind: one of :data:`KINDS` (``render`` for a render run, ``job`` for a single worker
            job, ``task`` for a Ray task on a node).
    """
    if kind not in KINDS:
        raise ValueError(f"scratch kind {kind!r} is not one of {KINDS}")
    root = scratch_root()
    return Path(tempfile.mkdtemp(prefix=f"usdscene-{kind}-{os.getpid()}-{host_tag()}-",
                                 dir=str(root) if root else None))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def remove_stale_scratch(root: Path | None = None) -> list[Path]:
    """Delete the scratch folders of dead processes of this user on this host.

    Args:
        root: folder to look in (default: :func:`scratch_root`, else the system temp folder).

    Returns:
        The folders removed.
    """
    folder = Path(root) if root is not None else (scratch_root() or Path(tempfile.gettempdir()))
    removed: list[Path] = []
    host, uid = host_tag(), os.getuid()
    try:
        entries = list(folder.iterdir())
    except OSError:
        return removed
    for entry in entries:
        match = _NAME.match(entry.name)
        if match is None or match.group(2) != host:
            continue
        try:
            if entry.is_symlink() or not entry.is_dir() or entry.stat().st_uid != uid:
                continue
        except OSError:
            continue
        if _alive(int(match.group(1))):
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    if removed:
        log.info("removed %d scratch folders of dead render workers in %s", len(removed), folder)
    return removed
