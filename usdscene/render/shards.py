"""Shards of a render call: which (frame, camera) pairs go together, the queue the slots take
them from, the runner that decides after each shard (finished, run again, failed), the tally of
worker events and the progress bar. The driver (:mod:`usdscene.render.driver`) plans and owns
the manifest; this module schedules. Never imports bpy.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from usdscene.render.job import JobCamera, JobObject, RenderJob
from usdscene.document.stage_schema import POSE_CHILD_PREFIX
from usdscene.render.manifest import Manifest
from usdscene.sensor.exposure import meter_window
from usdscene.render.worker_process import ShardExit

log = logging.getLogger(__name__)

# A worker process renders at most this many images, then a fresh one continues with the next
# frames. Blender's memory grows slowly with frame changes (≈ 0.08 MiB per render, see
# benchmarks/README.md); recycling bounds it for runs of any length, at the cost of one more
# start-up and import (1-2 s) per this many renders.
MAX_RENDERS_PER_WORKER = 250
# Seconds per image assumed for sizing shards until the first images are measured: one
# 640x480 cabin image at the default settings on 2 CPU cores takes 13-15 s.
ASSUMED_SECONDS_PER_IMAGE = 15.0


def _imported_prims(job_object: JobObject) -> list[str]:
    """The prims a shard imports for one job object: the object, or of an object whose pose
    changes per frame only the pose children shown in the shard's frames (their ancestors come
    with them): a walker of a one-frame shard brings one body, not one per pose it ever shows."""
    shown = sorted(v for v, frames in (job_object.pose_frames or {}).items() if frames)
    return [f"{job_object.prim}/{POSE_CHILD_PREFIX}{v}" for v in shown] or [job_object.prim]


def shard_job(plan, settings: Mapping[str, Any], cameras: Mapping[str, JobCamera], threads: int | None,
              keep_clean: bool, pairs: Sequence[tuple[int, str]]) -> RenderJob:
    """The :class:`~usdscene.render.job.RenderJob` of one shard: its (frame, camera) pairs, the
    objects present in its frames and the prims to import, without machine-specific paths;
    ``keep_clean`` asks sensor cameras' workers for the image before the sensor too."""
    frame_set = {f for f, _ in pairs}
    # an adapting camera's pre-passes: the frames of its exposure window (driver.sequence_warmup)
    frame_set |= {g for f, c in pairs if "warmup_frames" in (cameras[c].sensor or {})
                  for g in meter_window(f, cameras[c].sensor["warmup_frames"], cameras[c].sensor["first_frame"])}
    frame_set = frozenset(frame_set)
    objects = tuple(JobObject.of(o, frame_set) for o in plan.objects if frame_set.intersection(o.visible_frames))
    mask = list(plan.shared_prims) + [prim for o in objects for prim in _imported_prims(o)]
    return RenderJob(
        world=plan.world,
        keep_clean=keep_clean,
        stage=str(plan.stage_path),
        # An empty mask would import everything: name a path that cannot exist.
        prim_path_mask=",".join(mask) if mask else "/World/__nothing__",
        settings=settings,
        threads=threads,
        objects=objects,
        cameras={c: cameras[c] for c in sorted({c for _, c in pairs})},
        pairs=tuple((f, c) for f, c in pairs),
    )


class Tally:
    """Worker events of a render call → the manifest, the totals and the per-node figures; one
    event at a time (events of all slots come through :meth:`handle`)."""

    def __init__(self, manifest: Manifest, on_event: Callable[[dict], None] | None):
        self.manifest = manifest
        self.on_event = on_event
        self.lock = threading.Lock()
        self.totals = {"render_s": 0.0, "post_s": 0.0, "import_s": 0.0, "startup_s": 0.0, "rendered": 0,
                       "render_cpu_s": 0.0, "worker_cpu_s": 0.0, "retries": 0}
        self.nodes: dict[str, dict[str, float]] = {}
        self.bar: Progress | None = None

    def handle(self, event: dict) -> None:
        """Account for one worker event (any slot): a ``done`` image is passed to the caller's
        ``on_event`` first, then marked finished in the manifest, which is saved."""
        with self.lock:
            node = self.nodes.setdefault(str(event.get("node", "local")),
                                         {"images": 0, "render_s": 0.0, "shards": 0})
            kind = event.get("event")
            if kind == "done":
                if self.on_event is not None:
                    # Before the image counts as finished: what the caller does with it
                    # (e.g. labels) exists for every image the manifest lists.
                    self.on_event(event)
                self.manifest.mark_done(int(event["frame"]), event["camera"],
                                        {k: event[k] for k in ("render_s", "render_cpu_s", "post_s") if k in event})
                self.manifest.save()
                self.totals["render_s"] += event["render_s"]
                self.totals["post_s"] += event["post_s"]
                self.totals["render_cpu_s"] += event.get("render_cpu_s", 0.0)
                self.totals["rendered"] += 1
                node["images"] += 1
                node["render_s"] += event["render_s"]
                if self.bar is not None:
                    self.bar.advance()
            elif kind == "started":
                node["shards"] += 1
            elif kind == "imported":
                self.totals["import_s"] += event["seconds"]
                if event.get("missing_count"):
                    log.warning("%d objects of the stage were not found after the USD import, "
                                "e.g. %s", event["missing_count"], event["missing_uids"])
            elif kind == "finished":
                self.totals["worker_cpu_s"] += event.get("process_cpu_s", 0.0)
            elif kind == "warning":
                log.warning("%s", event.get("message"))
            if self.on_event is not None and kind != "done":
                self.on_event(event)

    def add(self, name: str, value: float) -> None:
        """Add ``value`` to the total ``name`` (seconds, or a count), under the lock."""
        with self.lock:
            self.totals[name] += value


class ShardRunner:
    """Runs the shards of a queue on every slot of an executor (one thread per slot), and
    decides after each shard: finished, run again (its worker died), or failed."""

    def __init__(self, executor, queue: ShardQueue, tally: Tally, bar: Progress, out_dir: Path,
                 job_for: Callable[[Sequence[tuple[int, str]]], RenderJob]):
        self.executor, self.queue, self.tally, self.bar = executor, queue, tally, bar
        self.out_dir, self.job_for = out_dir, job_for
        tally.bar = bar

    def run(self) -> list[str]:
        """Run every shard; returns the queue's error messages (empty when all finished)."""
        threads = [threading.Thread(target=self._run_slot, daemon=True) for _ in range(self.executor.slots)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        return self.queue.errors

    def _run_slot(self) -> None:
        queue = self.queue
        while (shard := queue.take()) is not None:
            self.bar.set_busy(queue.in_flight)
            done: set[tuple[int, str]] = set()
            t0 = time.perf_counter()

            def on_shard_event(event: dict) -> None:
                if event.get("event") == "done":
                    if not done:
                        self.tally.add("startup_s", time.perf_counter() - t0 - event["render_s"] - event["post_s"])
                    done.add((int(event["frame"]), event["camera"]))
                    queue.measure(event["render_s"] + event["post_s"])
                self.tally.handle(event)

            try:
                outcome = self.executor.run_shard(self.job_for(shard.pairs), self.out_dir, on_shard_event)
            except Exception as exc:  # must end the run with a message, not hang the slots
                log.exception("executor %s failed", self.executor.name)
                outcome = ShardExit(False, False, f"{type(exc).__name__}: {exc}")
            self._settle(shard, outcome, [p for p in shard.pairs if p not in done])
            self.bar.set_busy(queue.in_flight)

    def _settle(self, shard: Shard, outcome: ShardExit, left: list[tuple[int, str]]) -> None:
        """After a shard: finished, retried for its ``left`` pairs, or failed."""
        queue = self.queue
        if outcome.ok and left:
            outcome = ShardExit(False, False, f"the worker ended with {len(left)} images not rendered")
        if outcome.ok or not left:
            if not outcome.ok:  # it died after its last image had arrived
                log.info("%s: %s after its last image", shard.describe(), outcome.message)
            queue.finish()
        elif outcome.retryable and shard.attempt < queue.retries:
            log.warning("%s: %s; rendering its %d unfinished images again (retry %d of %d)",
                        shard.describe(), outcome.message, len(left), shard.attempt + 1, queue.retries)
            self.tally.add("retries", 1)
            queue.retry(shard, left)
        else:
            n = shard.attempt + 1
            tries = f" (gave up after {n} attempt{'s' if n > 1 else ''})" if outcome.retryable else ""
            queue.fail(f"{shard.describe()}: {outcome.message}{tries}")


def shard_size(remaining: int, slots: int, *, seconds_per_image: float | None = None,
               target_shard_s: float | None = None, max_pairs: int | None = None) -> int:
    """How many (frame, camera) pairs the next shard gets.

    Guided self-scheduling: at most an equal share of what remains per slot (large shards
    first, smaller towards the end so that slots finish together), at most ``max_pairs``
    (default :data:`MAX_RENDERS_PER_WORKER`, the per-process budget) and, for executors with a
    time target, about ``target_shard_s`` of work at the measured (or assumed) seconds per
    image.
    """
    size = min(MAX_RENDERS_PER_WORKER if max_pairs is None else max_pairs, -(-remaining // max(1, slots)))
    if target_shard_s:
        per_image = seconds_per_image or ASSUMED_SECONDS_PER_IMAGE
        size = min(size, int(target_shard_s / per_image))
    return max(1, size)


def _take_prefix(pairs: Sequence[tuple[int, str]], start: int, limit: int) -> int:
    """End index of the next shard of ``pairs[start:]`` (in frame order): whole frames while
    they fit in ``limit`` pairs (so a shard imports only its frames), else part of one frame."""
    end = start
    while end < len(pairs):
        frame_end = end
        while frame_end < len(pairs) and pairs[frame_end][0] == pairs[end][0]:
            frame_end += 1
        if frame_end - start > limit:
            return end if end > start else start + limit
        end = frame_end
    return end


def chunks(pairs: list[tuple[int, str]], limit: int) -> list[list[tuple[int, str]]]:
    """Cut pairs (in frame order) into runs of at most ``limit`` pairs, at frame boundaries
    where a frame has fewer than ``limit`` cameras."""
    chunks, start = [], 0
    while start < len(pairs):
        end = _take_prefix(pairs, start, limit)
        chunks.append(list(pairs[start:end]))
        start = end
    return chunks


@dataclass
class Shard:
    """A run of (frame, camera) pairs handed to one worker: its number in the call, its pairs
    and how many times it has been run before (0 = first attempt)."""
    number: int
    pairs: list[tuple[int, str]]
    attempt: int = 0

    def describe(self) -> str:
        """Shard number, frames and image count, for messages."""
        frames = sorted({f for f, _ in self.pairs})
        span = f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}..{frames[-1]}"
        return f"shard {self.number} ({span}, {len(self.pairs)} images)"


class ShardQueue:
    """The pairs still to render, handed out to slot threads as shards, with retries.

    ``take`` blocks while nothing is pending but a shard in flight may still come back for a
    retry; it returns None when everything is handed out and settled, or after a failure.
    """

    def __init__(self, todo: list[tuple[int, str]], slots: int, target_shard_s: float | None,
                 seconds_per_image: float | None, retries: int) -> None:
        self.todo, self.next_index = todo, 0
        self.slots, self.target_shard_s, self.retries = slots, target_shard_s, retries
        self._measured = [seconds_per_image, 1] if seconds_per_image else [0.0, 0]
        self.again: deque[Shard] = deque()
        self.in_flight = 0
        self.errors: list[str] = []
        self._numbers = 0
        self._cond = threading.Condition()

    def measure(self, seconds: float) -> None:
        """Record the seconds one image took (render + post), which sizes the shards not yet cut."""
        with self._cond:
            self._measured[0] += seconds
            self._measured[1] += 1

    def take(self) -> Shard | None:
        """The next shard for a free slot (a retry first), cut to the measured time per image;
        blocks while others are in flight and may still be retried; None when nothing is left
        or the run failed."""
        with self._cond:
            while True:
                if self.errors:
                    return None
                if self.again:
                    shard = self.again.popleft()
                    break
                if self.next_index < len(self.todo):
                    per_image = self._measured[0] / self._measured[1] if self._measured[1] else None
                    size = shard_size(len(self.todo) - self.next_index, self.slots, seconds_per_image=per_image,
                                      target_shard_s=self.target_shard_s)
                    end = _take_prefix(self.todo, self.next_index, size)
                    self._numbers += 1
                    shard = Shard(self._numbers, self.todo[self.next_index:end])
                    self.next_index = end
                    break
                if self.in_flight == 0:
                    return None
                self._cond.wait()
            self.in_flight += 1
            return shard

    def _settle(self) -> None:
        self.in_flight -= 1
        self._cond.notify_all()

    def finish(self) -> None:
        """A shard taken by :meth:`take` ended with all its images."""
        with self._cond:
            self._settle()

    def retry(self, shard: Shard, left: list[tuple[int, str]]) -> None:
        """A shard's worker died: queue its ``left`` pairs again as the next attempt."""
        with self._cond:
            self.again.append(Shard(shard.number, left, shard.attempt + 1))
            self._settle()

    def fail(self, message: str) -> None:
        """A shard failed for good: record ``message``; no further shards are handed out."""
        with self._cond:
            self.errors.append(message)
            self._settle()


class Progress:
    """A rich progress bar over frames × cameras (images/s, ETA, busy workers), or nothing."""

    def __init__(self, total: int, done: int, enabled: bool) -> None:
        self.enabled = enabled
        self.total, self.done = total, done
        self._progress = None

    def __enter__(self):
        if self.enabled:
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                       TimeElapsedColumn, TimeRemainingColumn)

            class _Rate(TextColumn):
                def render(self, task):
                    speed = task.finished_speed or task.speed
                    return f"{speed:.2f} images/s" if speed else "… images/s"

            self._progress = Progress(TextColumn("rendering"), BarColumn(), MofNCompleteColumn(),
                                      _Rate(""), TimeElapsedColumn(), TextColumn("ETA"),
                                      TimeRemainingColumn(), TextColumn("{task.fields[busy]} busy"),
                                      transient=False)
            self._progress.__enter__()
            self._task = self._progress.add_task("render", total=self.total, completed=self.done, busy=0)
        return self

    def advance(self) -> None:
        """One more image finished."""
        if self._progress is not None:
            self._progress.advance(self._task)

    def set_busy(self, workers: int) -> None:
        """Show ``workers`` shards in flight."""
        if self._progress is not None:
            self._progress.update(self._task, busy=workers)

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
