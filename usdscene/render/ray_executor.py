"""Render shards as Ray tasks on any node of a cluster (extra ``usdscene[ray]``). Never imports bpy.

Each shard becomes one Ray task that runs the usual worker process
(``python -m usdscene.render.worker JOB.json``) on its node, in a scratch folder of its own.
No shared file system is needed:

- the stage travels as a :class:`StageBundle` (the root layer, its sublayers and every asset
  layer and texture it references, and the world's HDRI, as bytes; ~2 MB for the shipped cabin) put once into the
  Ray object store and extracted by each task under its scratch folder, absolute paths
  mirrored so that the layers' relative asset paths resolve unchanged;
- the task streams one result per finished image (a Ray generator task): the PNG bytes of
  image and mask plus the worker's timings; the driver writes them atomically into the
  output folder and records them in the manifest as they arrive, so a lost task loses only
  the image in flight.

Resources per task: ``task_cpus`` CPUs (the worker's Cycles threads) and one GPU when the
render device is ``gpu``. Faults are the driver's business: a task whose worker process died
from a signal, or whose Ray worker or node was lost, ends as a retryable
:class:`~usdscene.render.worker_process.ShardExit`; Ray's own task retries are off so that a retry
re-renders only the images that did not arrive.

Every node needs the same usdscene version as the driver (``pip install usdscene[ray]`` in the
node image); a task on a node with another version fails with a message naming both.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import shutil
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Callable

from usdscene.errors import Problem, RenderError
from usdscene.render.job import RenderJob, to_json
from usdscene.render.worker_process import ShardExit, describe_exit, iter_worker_events

log = logging.getLogger(__name__)

# A Ray task should hold a few minutes of work: long enough that the worker's start-up and
# USD import (1-3 s) are noise, short enough that scheduling stays balanced at the end of a
# run and an autoscaler can drain a node.
TARGET_SHARD_S = 180.0


@dataclass(frozen=True)
class StageBundle:
    """The files a render of a stage reads, as bytes, keyed by absolute POSIX path without its
    leading ``/`` (so ``extract`` mirrors the original tree under any folder).

    Attributes:
        files: mirrored path → file content.
        stage: mirrored path of the root layer.
        hdri: mirrored path of the world's HDRI, None without one. The stage names it by an
            absolute path in its world JSON, which the task points at the extracted copy
            (:meth:`node_job`).
    """

    files: dict[str, bytes]
    stage: str
    hdri: str | None = None

    @property
    def size_bytes(self) -> int:
        """Bytes of all bundled files."""
        return sum(len(data) for data in self.files.values())

    def extract(self, folder: Path) -> Path:
        """Write every file under ``folder``; returns the root layer's path there."""
        folder = Path(folder)
        for name, data in self.files.items():
            target = folder / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        return folder / self.stage

    def node_job(self, job: RenderJob, folder: Path) -> RenderJob:
        """``job`` as a node runs it after :meth:`extract` into ``folder``: the stage and the
        world's HDRI read from the extracted copies."""
        folder = Path(folder)
        job = dataclasses.replace(job, stage=str(folder / self.stage))
        if self.hdri is not None and (job.world or {}).get("hdri_path"):
            job = dataclasses.replace(job, world=dict(job.world, hdri_path=str(folder / self.hdri)))
        return job


def _mirrored(path: Path) -> str:
    """An absolute path as a bundle key: resolved, POSIX, without its leading ``/``."""
    return PurePosixPath(Path(path).resolve().as_posix()).relative_to("/").as_posix()


def bundle_stage(stage_path: Path) -> StageBundle:
    """Collect the stage's layers and referenced assets (see
    :func:`usdscene.render.stage_reader.stage_dependencies`) into a :class:`StageBundle`.

    Raises:
        RenderError: an asset path of the stage does not resolve here.
    """
    from usdscene.render.stage_reader import stage_dependencies

    found = stage_dependencies(stage_path)
    if found.unresolved:
        raise RenderError([Problem(str(stage_path), f"asset path {u!r} does not resolve; a Ray task could not "
                                                    "load it either") for u in found.unresolved])
    return StageBundle({_mirrored(p): p.read_bytes() for p in found.files}, _mirrored(Path(stage_path)),
                       _mirrored(found.hdri) if found.hdri is not None else None)


def render_shard_task(job: RenderJob, bundle: StageBundle, driver_version: str):
    """The body of one Ray task (runs on a node): extract the stage, run the worker, stream
    its events; ``done`` events carry ``image_png`` and ``mask_png`` bytes.

    Yields:
        Event dicts, each with ``node``; the last is ``{"event": "exit", ...}`` (see
        :func:`usdscene.render.worker_process.iter_worker_events`).
    """
    import ray

    from usdscene import __version__

    from usdscene.document import output_layout as layout
    from usdscene.render.scratch import make_scratch, remove_stale_scratch

    context = ray.get_runtime_context()
    node = f"{ray.util.get_node_ip_address()} {context.get_node_id()[:8]}"
    yield {"event": "started", "node": node, "pid": os.getpid()}
    if __version__ != driver_version:
        yield {"event": "exit", "code": 1, "log_tail": [], "node": node,
               "error": f"node {node} runs usdscene {__version__}, the driver {driver_version}: "
                        "install the same version on every node"}
        return
    remove_stale_scratch()
    scratch = make_scratch("task")
    try:
        bundle.extract(scratch / "stage")
        out = scratch / "out"
        job = dataclasses.replace(bundle.node_job(job, scratch / "stage"), out_dir=str(out),
                                  scratch_dir=str(scratch), parent_pid=os.getpid())
        job_path = scratch / "job.json"
        job_path.write_text(to_json(job))
        for event in iter_worker_events(job_path, scratch / "worker.log"):
            if event["event"] == "done":
                frame, camera = int(event["frame"]), event["camera"]
                files = [("mask_png", layout.mask_path(out, camera, frame)),
                         ("image_png", layout.image_path(out, camera, frame))]
                depth = job.settings.get("depth")
                if depth:
                    files.append(("depth_bytes", layout.depth_path(out, camera, frame, depth)))
                for key, path in files:
                    event[key] = path.read_bytes()
                    path.unlink()
            event["node"] = node
            yield event
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast on a ``HOST:PORT`` (or ``ray://HOST:PORT``) nobody listens on: Ray itself
    keeps retrying for minutes.

    Raises:
        RenderError: the address does not accept a TCP connection within ``timeout_s``.
    """
    import socket

    host_port = address.split("://", 1)[-1]
    host, _, port = host_port.rpartition(":")
    if not host or not port.isdigit():
        return  # "auto" and the like: Ray resolves them
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise RenderError([Problem("ray_address", f"cannot reach Ray at {address!r}: {exc}")]) from None


class RayExecutor:
    """Shards as Ray tasks (a context manager: connects to, or starts, a Ray runtime).

    Args:
        address: Ray cluster address (``auto``, ``HOST:6379``, ``ray://HOST:10001``); None
            means ``$RAY_ADDRESS`` when set, else a local Ray runtime with this machine's
            CPUs, shut down on exit.
        max_slots: at most this many tasks in flight (default: the cluster's CPUs divided by
            ``task_cpus``, or its GPUs for GPU renders).
        task_cpus: CPUs each task reserves; its worker renders with that many threads.
    """

    name = "ray"
    target_shard_s: float | None = TARGET_SHARD_S

    def __init__(self, address: str | None = None, *, max_slots: int | None = None, task_cpus: int = 1) -> None:
        if int(task_cpus) < 1:
            raise RenderError([Problem("task_cpus", f"task_cpus {task_cpus!r} must be at least 1")])
        self.address, self.max_slots, self.task_cpus = address, max_slots, int(task_cpus)
        self.slots = 1
        self._ray = None
        self._owns_runtime = False
        self._bundle_ref = None
        self._gpus = 0
        self.bundle_bytes = 0

    @property
    def threads_per_worker(self) -> int:
        """Cycles threads of each task's worker: the CPUs the task asks for."""
        return self.task_cpus

    def __enter__(self) -> "RayExecutor":
        try:
            import ray
        except ImportError:
            raise RenderError([Problem("executor", "the 'ray' executor needs Ray: pip install 'usdscene[ray]'")]) from None
        self._ray = ray
        if not ray.is_initialized():
            if self.address:
                _check_reachable(self.address)
            try:
                if self.address is None and not os.environ.get("RAY_ADDRESS"):
                    ray.init(num_cpus=os.cpu_count() or 1, include_dashboard=False, log_to_driver=False)
                else:  # Ray's rule: no address given means the cluster in $RAY_ADDRESS
                    ray.init(address=self.address, log_to_driver=False)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = self.address or os.environ.get("RAY_ADDRESS")
                raise RenderError([Problem("ray_address", f"cannot connect to Ray at {where!r}: {exc}")]) from None
            self._owns_runtime = True
        self._remote = ray.remote(render_shard_task)
        return self

    def __exit__(self, *exc) -> None:
        self._bundle_ref = None
        if self._owns_runtime and self._ray is not None:
            self._ray.shutdown()
            self._owns_runtime = False

    def prepare(self, stage_path: Path, settings: dict) -> None:
        """Ship the stage into the object store, size the slots from the cluster's resources.

        Raises:
            RenderError: no node can hold one task (too few CPUs, or no GPU for ``gpu``).
        """
        ray = self._ray
        self._gpus = 1 if settings.get("device") == "gpu" else 0
        nodes = [n.get("Resources", {}) for n in ray.nodes() if n.get("Alive")]
        if self._gpus:
            fits = [int(r.get("GPU", 0)) for r in nodes if r.get("CPU", 0) >= self.task_cpus]
            what = f"a GPU and {self.task_cpus} CPUs"
        else:
            fits = [int(r.get("CPU", 0) // self.task_cpus) for r in nodes]
            what = f"{self.task_cpus} CPUs"
        capacity = sum(fits)
        if capacity < 1:
            raise RenderError([Problem("executor", f"no node of the Ray cluster has {what} for one render task; "
                                                   f"nodes: {[dict(r) for r in nodes]}")])
        self.slots = min(capacity, self.max_slots) if self.max_slots else capacity
        bundle = bundle_stage(stage_path)
        self.bundle_bytes = bundle.size_bytes
        self._bundle_ref = ray.put(bundle)
        from usdscene import __version__

        self._version = __version__

    def run_shard(self, job: RenderJob, out_dir: Path, on_event: Callable[[dict], None]) -> ShardExit:
        """Run one shard as a Ray task; write each image as it arrives, then report it."""
        from usdscene.document import output_layout as layout
        from usdscene.files import write_bytes_atomic

        ray = self._ray
        stream = self._remote.options(num_cpus=self.task_cpus, num_gpus=self._gpus, max_retries=0,
                                      retry_exceptions=False).remote(job, self._bundle_ref, self._version)
        try:
            for ref in stream:
                event = ray.get(ref)
                if event["event"] == "exit":
                    return describe_exit(event["code"], event["error"], event["log_tail"])
                if event["event"] == "done":
                    frame, camera = int(event["frame"]), event["camera"]
                    mask, image = event.pop("mask_png"), event.pop("image_png")
                    depth = event.pop("depth_bytes", None)
                    if depth is not None:  # before the mask, as in the worker
                        write_bytes_atomic(layout.depth_path(out_dir, camera, frame, job.settings["depth"]), depth)
                    # Mask first: a pair counts as done only when both exist (as in the worker).
                    write_bytes_atomic(layout.mask_path(out_dir, camera, frame), mask)
                    write_bytes_atomic(layout.image_path(out_dir, camera, frame), image)
                    event["transfer_bytes"] = len(mask) + len(image) + len(depth or b"")
                on_event(event)
        except ray.exceptions.RayTaskError as exc:
            return ShardExit(False, False, f"Ray task failed: {str(exc).splitlines()[-1]}")
        except ray.exceptions.RayError as exc:
            # A Ray worker or node was lost (crash, SIGKILL, OOM, preemption): the shard's
            # finished images are on disk; the rest can run anywhere.
            first = (str(exc).strip().splitlines() or [""])[0]
            return ShardExit(False, True, f"Ray lost the task ({type(exc).__name__}: {first})")
        return ShardExit(False, True, "the Ray task ended without reporting its worker's exit")
