"""Render worker processes: starting ``python -m usdscene.render.worker``, reading its events,
and telling how it ended. Shared by every executor (:mod:`usdscene.render.executors` runs them
on this machine, :mod:`usdscene.render.ray_executor` inside Ray tasks). Never imports bpy.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import threading
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

log = logging.getLogger(__name__)

EVENT_PREFIX = "@usdscene "
# The worker's argument that makes it import bpy first and then read its job path from stdin.
WAIT_FOR_JOB = "--wait-for-job"


@dataclass(frozen=True)
class ShardExit:
    """How a shard ended.

    Attributes:
        ok: every pair of the shard was rendered.
        retryable: the failure came from a lost process or node, not from the shard itself.
        message: what went wrong, for people ("" when ok).
    """

    ok: bool
    retryable: bool = False
    message: str = ""


def signal_name(number: int) -> str:
    """``9`` → ``"SIGKILL"`` (``"signal 77"`` for numbers without a name)."""
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def describe_exit(code: int, error_message: str | None, log_tail: list[str]) -> ShardExit:
    """The :class:`ShardExit` of a worker process from its exit code, its ``error`` event (if
    any) and the last lines of its log.

    A negative code is a death by signal (subprocess convention): retryable, and the message
    names the signal (SIGKILL is what the Linux OOM killer sends).
    """
    if code == 0:
        return ShardExit(True)
    if code < 0:
        name = signal_name(-code)
        hint = " (the Linux OOM killer sends SIGKILL when memory runs out)" if -code == signal.SIGKILL else ""
        return ShardExit(False, True, f"render worker was killed by {name}{hint}")
    detail = error_message or "; ".join(log_tail[-5:]) or f"exit code {code}"
    return ShardExit(False, False, f"render worker failed: {detail}")


# Worker processes started ahead of their job (prestart_workers): each has imported bpy and
# waits for a job path on its stdin. Taken by iter_worker_events, first started first.
_WARM: deque[tuple[subprocess.Popen, Path]] = deque()
_WARM_LOCK = threading.Lock()


def prestart_workers(count: int) -> None:
    """Start ``count`` render worker processes now, so that their start-up (the interpreter,
    ``import bpy``: about a second each) overlaps what the caller does before rendering
    (validating and composing the document). The next shards run by :func:`iter_worker_events`
    in this process use them; :func:`discard_prestarted_workers` ends those left unused.
    """
    from usdscene.render.scratch import make_scratch

    for _ in range(max(0, int(count))):
        log_path = make_scratch("job") / "worker.log"
        with open(log_path, "w") as log_file:
            proc = subprocess.Popen([sys.executable, "-m", "usdscene.render.worker", WAIT_FOR_JOB],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log_file,
                                    text=True, bufsize=1)
        with _WARM_LOCK:
            _WARM.append((proc, log_path))


def discard_prestarted_workers() -> None:
    """End the pre-started workers no shard took (their stdin closes: they exit at once)."""
    import shutil

    with _WARM_LOCK:
        left = list(_WARM)
        _WARM.clear()
    for proc, log_path in left:
        try:
            proc.stdin.close()
            proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()
        proc.stdout.close()
        shutil.rmtree(log_path.parent, ignore_errors=True)


def _take_prestarted(job_path: Path) -> tuple[subprocess.Popen, Path] | None:
    """A pre-started worker, given ``job_path``; None when there is none (or it died)."""
    while True:
        with _WARM_LOCK:
            if not _WARM:
                return None
            proc, log_path = _WARM.popleft()
        try:
            proc.stdin.write(f"{job_path}\n")
            proc.stdin.close()
            return proc, log_path
        except OSError:  # it died while waiting: use the next one, or a new process
            proc.kill()
            proc.wait()
            proc.stdout.close()


def iter_worker_events(job_path: Path, log_path: Path) -> Iterator[dict]:
    """Run ``python -m usdscene.render.worker JOB`` and yield its events as they come.

    The worker's ``@usdscene {json}`` lines become dicts; Blender's own output goes to
    ``log_path``. The last item is ``{"event": "exit", "code": int, "error": str | None,
    "log_tail": [str]}`` (code < 0: killed by that signal). Closing the generator early kills
    the worker. A worker pre-started by :func:`prestart_workers` is used when there is one.
    """
    import shutil

    tail: deque[str] = deque(maxlen=20)
    error = None
    prestarted = _take_prestarted(job_path)
    if prestarted is not None:
        proc, warm_log = prestarted
        log_file = open(warm_log, "a")
    else:
        log_file = open(log_path, "w")
        proc = subprocess.Popen([sys.executable, "-m", "usdscene.render.worker", str(job_path)],
                                stdout=subprocess.PIPE, stderr=log_file, text=True, bufsize=1)
    with log_file:
        try:
            for line in proc.stdout:
                if not line.startswith(EVENT_PREFIX):
                    tail.append(line.rstrip())
                    log_file.write(line)
                    continue
                event = json.loads(line[len(EVENT_PREFIX):])
                if event.get("event") == "error":
                    error = event.get("message")
                yield event
        finally:
            if proc.poll() is None and sys.exc_info()[0] is not None:
                proc.kill()
            code = proc.wait()
            proc.stdout.close()
    if prestarted is not None:  # its log joins the others
        os.replace(prestarted[1], log_path)
        shutil.rmtree(prestarted[1].parent, ignore_errors=True)
    log_tail = log_path.read_text(errors="replace").splitlines()[-10:] or list(tail)
    yield {"event": "exit", "code": code, "error": error, "log_tail": log_tail}
