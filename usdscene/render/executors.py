"""Where render shards run: the executor boundary of the driver. Never imports bpy.

A *shard* is a job dict (see :mod:`usdscene.render.job`) for a run of (frame, camera) pairs
of consecutive frames, without the machine-specific paths (``out_dir``, ``scratch_dir``). An
executor runs one shard at a time per *slot* and reports every worker event to the driver:

- :class:`LocalExecutor` (default): one ``python -m usdscene.render.worker JOB.json`` process
  per shard on this machine, writing straight into the output folder.
- :class:`usdscene.render.ray_executor.RayExecutor` (extra ``usdscene[ray]``): the same worker
  process inside a Ray task on any node; the images come back as bytes and the driver writes
  them.

Both end a shard with a :class:`ShardExit` saying whether a failure is worth a retry (the
worker process died from a signal, a node or a Ray worker was lost) or not (the worker
reported an error: the stage or the settings are wrong, and a retry would fail the same way).
The driver owns planning, retries, the manifest and progress.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

log = logging.getLogger(__name__)

EXECUTORS = ("local", "ray")
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


@contextlib.contextmanager
def workers_started_early(executor, workers: int | None):
    """Within the block, the worker processes of a local executor (``"local"`` with
    ``workers`` slots, or a :class:`LocalExecutor`) are started ahead of their jobs
    (:func:`prestart_workers`); those no shard took end with the block. Other executors:
    nothing."""
    slots = (workers or 1 if executor == "local"
             else executor.slots if isinstance(executor, LocalExecutor) else 0)
    prestart_workers(slots)
    try:
        yield
    finally:
        discard_prestarted_workers()


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


class LocalExecutor:
    """Worker processes on this machine, ``slots`` of them side by side.

    A context manager (it owns a scratch folder for job files and logs).

    Args:
        slots: worker processes run side by side; CPU threads are split between them.
    """

    name = "local"
    # A local worker writes each image itself as it finishes: a long shard loses nothing when
    # it dies, so shards are cut by the per-process budget only, not by time.
    target_shard_s: float | None = None

    def __init__(self, slots: int = 1) -> None:
        self.slots = max(1, int(slots))
        self.node = socket.gethostname()
        self._scratch: Path | None = None
        self._numbers = itertools.count(1)  # next() is atomic: slots run in threads

    @property
    def threads_per_worker(self) -> int | None:
        """Cycles threads per worker (None: all cores, for a single slot)."""
        return max(1, (os.cpu_count() or 1) // self.slots) if self.slots > 1 else None

    def __enter__(self) -> "LocalExecutor":
        from usdscene.render.scratch import make_scratch

        self._scratch = make_scratch("render")
        return self

    def __exit__(self, *exc) -> None:
        import shutil

        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)
            self._scratch = None

    def prepare(self, stage_path: Path, settings: dict) -> None:
        """Nothing to ship: the worker reads the stage where it lies."""

    def run_shard(self, job: dict, out_dir: Path, on_event: Callable[[dict], None]) -> ShardExit:
        """Run one shard in one worker process; every event goes to ``on_event`` (from this
        thread), each tagged with ``node``."""
        assert self._scratch is not None, "use LocalExecutor as a context manager"
        job_path = self._scratch / f"job-{next(self._numbers)}.json"
        job = dict(job, out_dir=str(Path(out_dir).resolve()), scratch_dir=str(self._scratch),
                   parent_pid=os.getpid())
        job_path.write_text(json.dumps(job))
        on_event({"event": "started", "node": self.node, "pid": os.getpid()})
        for event in iter_worker_events(job_path, job_path.with_suffix(".log")):
            if event["event"] == "exit":
                job_path.unlink(missing_ok=True)
                return describe_exit(event["code"], event["error"], event["log_tail"])
            event["node"] = self.node
            on_event(event)
        raise AssertionError("iter_worker_events ends with an exit event")  # pragma: no cover


def make_executor(name: str, *, workers: int | None = None, ray_address: str | None = None,
                  task_cpus: int = 1):
    """The executor called ``name`` (``local`` or ``ray``), not yet entered.

    Args:
        name: ``local`` or ``ray``.
        workers: local worker processes side by side (default 1); for Ray an upper bound on
            the tasks in flight (default: the cluster's CPUs / ``task_cpus``).
        ray_address: Ray cluster address (``ray://host:10001``, ``host:6379`` or ``auto``);
            None starts a local Ray runtime.
        task_cpus: CPUs each Ray task asks for (Cycles threads of its worker).

    Raises:
        RenderError: an unknown executor name, or Ray is not installed.
    """
    from usdscene.errors import Problem, RenderError

    if name == "local":
        if ray_address is not None:
            raise RenderError([Problem("--ray-address", f"{ray_address!r} needs --executor ray")])
        return LocalExecutor(workers or 1)
    if name == "ray":
        from usdscene.render.ray_executor import RayExecutor

        return RayExecutor(ray_address, max_slots=workers, task_cpus=task_cpus)
    raise RenderError([Problem("--executor", f"executor {name!r} is not one of {list(EXECUTORS)}")])
