"""The worker's side of the process boundary: progress events on stdout, importing ``bpy``,
resident memory, dying with the process that started it."""

from __future__ import annotations

import json
import os
import sys

PROGRESS_PREFIX = "@usdscene "


def emit(event: dict) -> None:
    """Report ``event`` to the driver: one ``@usdscene {json}`` line on stdout, flushed."""
    sys.stdout.write(PROGRESS_PREFIX + json.dumps(event) + "\n")
    sys.stdout.flush()


def import_bpy():
    """The ``bpy`` module; ImportError with the install command when this Python lacks it."""
    try:
        import bpy  # noqa: F401  (the one place usdscene imports bpy)
    except ImportError as exc:  # pragma: no cover - environment problem
        raise ImportError("usdscene's renderer needs the 'bpy' package (pip install bpy==5.0.1) "
                          f"in this Python ({sys.executable}): {exc}") from exc
    return bpy


def rss_mb() -> float:
    """Resident memory of this process in MiB (Linux; 0 elsewhere)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def die_with_parent(parent_pid: int | None) -> None:
    """Linux: have the kernel SIGKILL this worker when the process that started it dies, so a
    killed driver or Ray task leaves no renderer running. Elsewhere nothing happens."""
    if not parent_pid or not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        import signal

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != int(parent_pid):  # the parent died before prctl took effect
        os._exit(1)
