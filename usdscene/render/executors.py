"""Where render shards run: the executor boundary of the driver. Never imports bpy.

A *shard* is a :class:`~usdscene.render.job.RenderJob` for a run of (frame, camera) pairs
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
import dataclasses
import itertools
import logging
import os
import socket
from pathlib import Path
from typing import Callable

from usdscene.render.job import RenderJob, to_json
from usdscene.render.worker_process import (
    ShardExit,
    describe_exit,
    discard_prestarted_workers,
    iter_worker_events,
    prestart_workers,
)

log = logging.getLogger(__name__)

EXECUTORS = ("local", "ray")


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

    def run_shard(self, job: RenderJob, out_dir: Path, on_event: Callable[[dict], None]) -> ShardExit:
        """Run one shard in one worker process; every event goes to ``on_event`` (from this
        thread), each tagged with ``node``."""
        assert self._scratch is not None, "use LocalExecutor as a context manager"
        job_path = self._scratch / f"job-{next(self._numbers)}.json"
        job = dataclasses.replace(job, out_dir=str(Path(out_dir).resolve()), scratch_dir=str(self._scratch),
                                  parent_pid=os.getpid())
        job_path.write_text(to_json(job))
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
