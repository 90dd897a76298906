"""The parent side of rendering: plan shards, hand them to an executor, retry, track progress,
resume.

The driver never imports ``bpy``. It reads the stage with pxr (:mod:`stage_reader`), decides
which (frame, camera) pairs are missing (:mod:`manifest`), cuts them into shards of
consecutive frames as slots free up, and has an executor (:mod:`executors`: local worker
processes, or Ray tasks on a cluster) run ``python -m usdscene.render.worker JOB`` for each.
Every finished image is recorded in the manifest as it arrives; a shard whose worker died is
run again for its unfinished images.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import shutil
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from usdscene import __version__

from usdscene.document import output_layout as layout
from usdscene.errors import Problem, RenderError
from usdscene.files import write_json_atomic
from usdscene.document.model import MAX_BOUNCES, RenderSettings
from usdscene.labels.projection import undistorted_render_intrinsics
from usdscene.render.worker_process import ShardExit
from usdscene.render.job import intrinsics_to_json
from usdscene.render.manifest import Manifest, fingerprint

log = logging.getLogger(__name__)

ENGINES = ("cycles", "eevee", "workbench")
# Settings the worker knows beyond RenderSettings (benchmarked in benchmarks/render_settings.py).
# resolution_scale scales every camera's image (previews); 1 = the calibrated resolution.
EXTRA_SETTINGS = {"resolution_scale": 1.0}
# A worker process renders at most this many images, then a fresh one continues with the next
# frames. Blender's memory grows slowly with frame changes (≈ 0.08 MiB per render, see
# benchmarks/README.md); recycling bounds it for runs of any length, at the cost of one more
# start-up and import (1-2 s) per this many renders.
MAX_RENDERS_PER_WORKER = 250
# Extra attempts for a shard whose worker died (signal, lost node) before it gave up.
DEFAULT_RETRIES = 3
# Seconds per image assumed for sizing shards until the first images are measured: one
# 640x480 cabin image at the default settings on 2 CPU cores takes 13-15 s.
ASSUMED_SECONDS_PER_IMAGE = 15.0


@dataclass(frozen=True)
class RenderReport:
    """What a :func:`render` call did.

    Attributes:
        out_dir: the output folder.
        pairs_total: (frame, camera) pairs requested.
        pairs_rendered: pairs rendered by this call.
        pairs_skipped: pairs already finished by an earlier run (from the manifest).
        wall_s: wall-clock seconds of the call.
        render_s: sum over rendered pairs of Blender's render call (path tracing, denoising,
            scene update and EXR write), seconds.
        post_s: sum of EXR decoding, remapping and PNG writing in the worker, seconds.
        import_s: sum of USD import time over workers, seconds.
        startup_s: sum of worker start-up time before the first image (process start, bpy
            import, USD import, scene setup), seconds.
        render_cpu_s: CPU seconds (all threads) spent inside the render calls.
        worker_cpu_s: CPU seconds (all threads) of the worker processes, start to end.
        executor: the executor's name (``local``, ``ray``).
        retries: shards run again after their worker died.
        nodes: per node (host name, or Ray node address and id): ``images`` rendered,
            ``render_s`` seconds of render calls, ``shards`` started, in this call.
    """

    out_dir: Path
    pairs_total: int
    pairs_rendered: int
    pairs_skipped: int
    wall_s: float
    render_s: float
    post_s: float
    import_s: float
    startup_s: float
    render_cpu_s: float = 0.0
    worker_cpu_s: float = 0.0
    executor: str = "local"
    retries: int = 0
    nodes: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)


def node_summary_lines(report) -> list[str]:
    """One line per node of a :class:`~usdscene.render.driver.RenderReport`: images, shards,
    mean render seconds per image."""
    lines = []
    for node, row in sorted(report.nodes.items()):
        per_image = row["render_s"] / row["images"] if row["images"] else 0.0
        lines.append(f"  {node}: {int(row['images'])} images in {int(row['shards'])} shards, "
                     f"{per_image:.2f} s/image render")
    return lines


def resolve_settings(base: RenderSettings, override: RenderSettings | Mapping[str, Any] | None) -> dict:
    """Render settings as the worker's JSON dict: ``base`` updated by ``override`` (a whole
    RenderSettings, or a mapping of RenderSettings fields and the extra knob
    ``resolution_scale``). Denoising quality and prefilter names are case-insensitive.

    Raises:
        RenderError: an unknown key or an impossible value, every problem listed.
    """
    problems: list[Problem] = []
    settings = dict(dataclasses.asdict(base), **EXTRA_SETTINGS)
    if isinstance(override, RenderSettings):
        settings.update(dataclasses.asdict(override))
    elif override:
        for key, value in override.items():
            if key not in settings:
                problems.append(Problem(f"render.{key}", f"unknown render setting {key!r}; known: {sorted(settings)}"))
                continue
            settings[key] = value
    settings["resolution_px"] = list(settings["resolution_px"])
    if settings["engine"] not in ENGINES:
        problems.append(Problem("render.engine", f"engine {settings['engine']!r} is not one of {list(ENGINES)}"))
    elif settings["engine"] != "cycles":
        problems.append(Problem("render.engine",
                                f"engine {settings['engine']!r} cannot write the object-index pass that exact "
                                "instance masks come from; use 'cycles' (Eevee and Workbench have no such pass)"))
    if settings["device"] not in ("cpu", "gpu"):
        problems.append(Problem("render.device", f"device {settings['device']!r} is not 'cpu' or 'gpu'"))
    if int(settings["samples"]) < 1:
        problems.append(Problem("render.samples", f"samples {settings['samples']!r} must be at least 1"))
    if int(settings["max_bounces"]) < 0:
        problems.append(Problem("render.max_bounces", f"max_bounces {settings['max_bounces']!r} must be >= 0"))
    if int(settings["tile_size_px"]) < 8:
        problems.append(Problem("render.tile_size_px", f"tile_size_px {settings['tile_size_px']!r} must be >= 8"))
    if settings["denoiser"] not in ("openimagedenoise", "optix"):
        problems.append(Problem("render.denoiser", f"denoiser {settings['denoiser']!r} is not 'openimagedenoise' or 'optix'"))
    for key, allowed in (("denoising_quality", ("high", "balanced", "fast")),
                         ("denoising_prefilter", ("none", "fast", "accurate"))):
        settings[key] = str(settings[key]).lower()
        if settings[key] not in allowed:
            problems.append(Problem(f"render.{key}", f"{key} {settings[key]!r} is not one of {list(allowed)}"))
    from usdscene.converters.openlabel_metadata import DENOISING_INPUT_PASSES, FAST_GI_METHODS, SAMPLING_PATTERNS

    for key, allowed in (("denoising_input_passes", DENOISING_INPUT_PASSES), ("sampling_pattern", SAMPLING_PATTERNS),
                         ("fast_gi_method", FAST_GI_METHODS)):
        if settings[key] not in allowed:
            problems.append(Problem(f"render.{key}", f"{key} {settings[key]!r} is not one of {list(allowed)}"))
    for key in ("clamp_indirect", "adaptive_min_samples", "fast_gi_distance_m", "scrambling_distance"):
        if not isinstance(settings[key], (int, float)) or isinstance(settings[key], bool) or settings[key] < 0:
            problems.append(Problem(f"render.{key}", f"{key} {settings[key]!r} must be a number >= 0"))
        elif key == "scrambling_distance" and settings[key] > 1:
            problems.append(Problem("render.scrambling_distance",
                                    f"scrambling_distance {settings[key]!r} must be in [0, 1] "
                                    "(1 = Cycles' full per-pixel scrambling, larger values change nothing)"))
    bounces = settings["fast_gi_ao_bounces"]
    if not isinstance(bounces, int) or isinstance(bounces, bool) or not 0 <= bounces <= MAX_BOUNCES:
        problems.append(Problem("render.fast_gi_ao_bounces",
                                f"fast_gi_ao_bounces {bounces!r} must be an integer in [0, {MAX_BOUNCES}]"))
    for key in ("light_tree", "path_guiding", "fast_gi", "auto_scrambling_distance"):
        if not isinstance(settings[key], bool):
            problems.append(Problem(f"render.{key}", f"{key} {settings[key]!r} must be true or false"))
    if not 0 < float(settings["resolution_scale"]) <= 4:
        problems.append(Problem("render.resolution_scale",
                                f"resolution_scale {settings['resolution_scale']!r} must be in (0, 4]"))
    if problems:
        raise RenderError(problems)
    return settings


def scale_intrinsics(intr, scale: float):
    """The same lens at ``scale`` times the resolution (pixel centres at integers: a pixel
    position p maps to ``(p + 0.5) · s' - 0.5`` with s' the exact per-axis size ratio)."""
    if scale == 1.0:
        return intr
    return intr.resized(max(1, round(intr.width_px * scale)), max(1, round(intr.height_px * scale)))


def render(stage_path: Path, out_dir: Path, *, frames: Sequence[int] | None = None,
           cameras: Sequence[str] | None = None,
           settings_override: RenderSettings | Mapping[str, Any] | None = None,
           progress: bool = True, workers: int | None = None,
           on_event: Callable[[dict], None] | None = None,
           executor: str | Any = "local", retries: int = DEFAULT_RETRIES, keep_clean: bool = False) -> RenderReport:
    """Render every requested camera of every requested frame of a composed stage.

    Writes ``out/images/<camera>/<frame:06d>.png`` (8-bit sRGB), ``out/masks/<camera>/
    <frame:06d>.png`` (uint16 ids, 0 = background), ``out/masks/ids.json`` and
    ``out/manifest.json``; pairs a previous run finished are skipped, whichever executor ran
    it. The pixels do not depend on the executor, the number of workers or the shard order.

    Args:
        stage_path: root layer of the composed stage (``out/stage/scene.usda``).
        out_dir: output folder.
        frames: frames to render (default: the stage's whole range).
        cameras: camera names (default: every camera under ``/World/Cameras``).
        settings_override: RenderSettings or a mapping of fields that win over the stage's.
        progress: show a ``rich`` progress bar on stderr.
        workers: shards run side by side: local worker processes (default 1; CPU threads are
            split between them), or for Ray an upper bound on tasks in flight (default: what
            the cluster holds). Used only when ``executor`` is a name; an executor object
            carries its own.
        on_event: called with every progress event of the workers (dicts), in the parent, one
            at a time; a ``done`` event (its image and mask are written) before the image is
            recorded as finished in the manifest.
        executor: ``"local"``, ``"ray"`` (a local Ray runtime) or an executor object from
            :func:`usdscene.render.executors.make_executor` (e.g. Ray at an address).
        retries: how many times a shard whose worker died (a signal such as the OOM killer's
            SIGKILL, a lost node) is run again for its unfinished images, on any slot.
        keep_clean: for cameras with a sensor, also write the image before the sensor's
            effects to ``out/images_clean/<camera>/<frame:06d>.png``.

    Returns:
        A :class:`RenderReport`.

    Raises:
        RenderError: bad selection or settings, or a worker failed (finished pairs are kept
            and a re-run resumes).
    """
    from usdscene.render.executors import make_executor
    from usdscene.render.scratch import remove_stale_scratch
    from usdscene.render.stage_reader import read_stage_plan, stage_digest

    started = time.perf_counter()
    out_dir = Path(out_dir)
    plan = read_stage_plan(stage_path)
    settings = resolve_settings(plan.settings, settings_override)
    problems: list[Problem] = []
    if int(retries) < 0:
        problems.append(Problem("retries", f"retries {retries!r} must be >= 0"))
    if workers is not None and int(workers) < 1:
        problems.append(Problem("workers", f"workers {workers!r} must be at least 1"))
    frame_list = list(plan.frames) if frames is None else [int(f) for f in frames]
    for f in frame_list:
        if f not in plan.frames:
            problems.append(Problem("frames", f"frame {f} is outside the stage's range "
                                              f"{plan.frame_start}..{plan.frame_end}"))
    by_name = {c.name: c for c in plan.cameras}
    camera_list = list(by_name) if cameras is None else list(cameras)
    for name in camera_list:
        if name not in by_name:
            problems.append(Problem("cameras", f"camera {name!r} is not in the stage; cameras: {sorted(by_name)}"))
    if not by_name:
        problems.append(Problem(str(stage_path), "the stage has no camera under /World/Cameras"))
    if problems:
        raise RenderError(problems)
    if isinstance(executor, str):
        executor = make_executor(executor, workers=workers)

    cam_json = camera_jobs(plan, camera_list, frame_list, float(settings["resolution_scale"]))
    print_settings = {k: v for k, v in settings.items() if k != "device"}
    manifest = Manifest.load(out_dir, fingerprint({
        **({"keep_clean": True} if keep_clean and plan.sensors else {}),
        "stage": stage_digest(plan.stage_path), "settings": print_settings,
        "cameras": {n: {k: v for k, v in c.items()} for n, c in cam_json.items()},
        "objects": [dataclasses.asdict(o) for o in plan.objects],
    }))
    manifest.versions = {"usdscene": __version__}
    _remove_stale_temporaries(out_dir, camera_list)
    remove_stale_scratch()
    todo = [(f, c) for f in frame_list for c in camera_list if not manifest.is_done(f, c)]
    total = len(frame_list) * len(camera_list)
    skipped = total - len(todo)
    write_json_atomic(out_dir / layout.ID_MAP_FILE, {
        str(o.mask_id): {"uid": o.uid, "class": o.class_name, "prim": o.prim_path} for o in plan.objects})

    totals = {"render_s": 0.0, "post_s": 0.0, "import_s": 0.0, "startup_s": 0.0, "rendered": 0,
              "render_cpu_s": 0.0, "worker_cpu_s": 0.0, "retries": 0}
    nodes: dict[str, dict[str, float]] = {}
    if todo:
        lock = threading.Lock()
        bar = _Progress(total, skipped, enabled=progress)

        def handle(event: dict) -> None:
            with lock:
                node = nodes.setdefault(str(event.get("node", "local")),
                                        {"images": 0, "render_s": 0.0, "shards": 0})
                if event.get("event") == "done":
                    if on_event is not None:
                        # Before the image counts as finished: what the caller does with it
                        # (e.g. labels) exists for every image the manifest lists.
                        on_event(event)
                    manifest.mark_done(int(event["frame"]), event["camera"],
                                       {k: event[k] for k in ("render_s", "post_s") if k in event})
                    manifest.save()
                    totals["render_s"] += event["render_s"]
                    totals["post_s"] += event["post_s"]
                    totals["render_cpu_s"] += event.get("render_cpu_s", 0.0)
                    totals["rendered"] += 1
                    node["images"] += 1
                    node["render_s"] += event["render_s"]
                    bar.advance()
                elif event.get("event") == "started":
                    node["shards"] += 1
                elif event.get("event") == "imported":
                    totals["import_s"] += event["seconds"]
                    if event.get("missing_count"):
                        log.warning("%d objects of the stage were not found after the USD import, "
                                    "e.g. %s", event["missing_count"], event["missing_uids"])
                elif event.get("event") == "finished":
                    totals["worker_cpu_s"] += event.get("process_cpu_s", 0.0)
                elif event.get("event") == "warning":
                    log.warning("%s", event.get("message"))
                if on_event is not None and event.get("event") != "done":
                    on_event(event)

        try:
            with executor, bar:
                executor.prepare(plan.stage_path, settings)
                slots = executor.slots
                queue = _ShardQueue(todo, slots, executor.target_shard_s,
                                    _seconds_per_image(manifest), retries=int(retries))

                def job_for(pairs: list[tuple[int, str]]) -> dict:
                    frame_set = {f for f, _ in pairs}
                    objects = [{"uid": o.uid, "mask_id": o.mask_id, "prim": o.prim_path,
                                "visible_frames": [f for f in o.visible_frames if f in frame_set]}
                               for o in plan.objects if frame_set.intersection(o.visible_frames)]
                    mask = list(plan.shared_prims) + [o["prim"] for o in objects]
                    return {
                        **({"world": plan.world} if plan.world is not None else {}),
                        **({"keep_clean": True} if keep_clean else {}),
                        "stage": str(plan.stage_path),
                        # An empty mask would import everything: name a path that cannot exist.
                        "prim_path_mask": ",".join(mask) if mask else "/World/__nothing__",
                        "settings": settings,
                        "threads": executor.threads_per_worker,
                        "objects": objects,
                        "cameras": {c: cam_json[c] for c in sorted({c for _, c in pairs})},
                        "pairs": [[f, c] for f, c in pairs],
                    }

                def run_slot() -> None:
                    while (shard := queue.take()) is not None:
                        bar.set_busy(queue.in_flight)
                        done: set[tuple[int, str]] = set()
                        t0 = time.perf_counter()

                        def on_shard_event(event: dict) -> None:
                            if event.get("event") == "done":
                                if not done:
                                    totals["startup_s"] += (time.perf_counter() - t0 - event["render_s"]
                                                            - event["post_s"])
                                done.add((int(event["frame"]), event["camera"]))
                                queue.measure(event["render_s"] + event["post_s"])
                            handle(event)

                        try:
                            outcome = executor.run_shard(job_for(shard.pairs), out_dir, on_shard_event)
                        except Exception as exc:  # must end the run with a message, not hang the slots
                            log.exception("executor %s failed", executor.name)
                            outcome = ShardExit(False, False, f"{type(exc).__name__}: {exc}")
                        left = [p for p in shard.pairs if p not in done]
                        if outcome.ok and left:
                            outcome = ShardExit(False, False, f"the worker ended with {len(left)} "
                                                              "images not rendered")
                        if outcome.ok or not left:
                            if not outcome.ok:  # it died after its last image had arrived
                                log.info("%s: %s after its last image", shard.describe(), outcome.message)
                            queue.finish()
                        elif outcome.retryable and shard.attempt < queue.retries:
                            log.warning("%s: %s; rendering its %d unfinished images again "
                                        "(retry %d of %d)", shard.describe(), outcome.message, len(left),
                                        shard.attempt + 1, queue.retries)
                            with lock:
                                totals["retries"] += 1
                            queue.retry(shard, left)
                        else:
                            n = shard.attempt + 1
                            tries = f" (gave up after {n} attempt{'s' if n > 1 else ''})" if outcome.retryable else ""
                            queue.fail(f"{shard.describe()}: {outcome.message}{tries}")
                        bar.set_busy(queue.in_flight)

                threads = [threading.Thread(target=run_slot, daemon=True) for _ in range(slots)]
                for thread in threads:
                    thread.start()
                for thread in threads:
                    thread.join()
                errors = queue.errors
        finally:
            if totals["retries"]:
                # A killed worker may have died inside an atomic write; no worker runs now.
                _remove_stale_temporaries(out_dir, camera_list)
            manifest.timings = {"wall_s": round(time.perf_counter() - started, 3),
                                "render_s": round(totals["render_s"], 3)}
            manifest.save()
        if errors:
            raise RenderError([Problem(str(stage_path), e) for e in errors])
    else:
        manifest.save()
    return RenderReport(out_dir, total, totals["rendered"], skipped, time.perf_counter() - started,
                        totals["render_s"], totals["post_s"], totals["import_s"], totals["startup_s"],
                        totals["render_cpu_s"], totals["worker_cpu_s"], executor.name,
                        int(totals["retries"]), nodes)


def camera_jobs(plan, camera_names: Sequence[str], frames: Sequence[int], scale: float = 1.0) -> dict:
    """Per camera: its intrinsics, the native lens to render (a wider undistorted view for
    OpenCV models), its base pose and per-frame poses (OpenCV axes, 16 row-major numbers)."""
    by_name = {c.name: c for c in plan.cameras}
    wanted = set(frames)
    out = {}
    for name in camera_names:
        cam = by_name[name]
        intr = scale_intrinsics(cam.intrinsics, scale)
        try:
            render_intr = undistorted_render_intrinsics(intr)
        except ValueError as exc:
            raise RenderError(str(exc), where=f"{plan.stage_path}:/World/Cameras/{name}") from None
        out[name] = {
            "intrinsics": intrinsics_to_json(intr),
            "render_intrinsics": intrinsics_to_json(render_intr),
            "pose": list(cam.pose.matrix),
            "poses": {str(f): list(p.matrix) for f, p in cam.frame_poses if f in wanted},
            "clip_m": [cam.clip_near_m, cam.clip_far_m],
        }
        # Only cameras with a sensor carry the key: the manifest fingerprint of the others
        # stays what it was before sensors existed.
        if name in getattr(plan, "sensors", {}):
            out[name]["sensor"] = plan.sensors[name]
    return out


def run_job(job: dict, what: str) -> list[dict]:
    """Run one worker on ``job`` (any mode) and return its events.

    Raises:
        RenderError: the worker failed (its message, the signal that killed it, or the tail
            of its log).
    """
    from usdscene.render.worker_process import describe_exit, iter_worker_events
    from usdscene.render.scratch import make_scratch

    scratch = make_scratch("job")
    events: list[dict] = []
    try:
        job = dict(job, scratch_dir=str(scratch))
        job_path = scratch / "job-0.json"
        job_path.write_text(json.dumps(job))
        for event in iter_worker_events(job_path, scratch / "job-0.log"):
            if event["event"] == "exit":
                outcome = describe_exit(event["code"], event["error"], event["log_tail"])
            else:
                events.append(event)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    if not outcome.ok:
        raise RenderError([Problem(what, outcome.message)])
    return events


def _remove_stale_temporaries(out_dir: Path, cameras: Sequence[str]) -> None:
    """Delete the temporary files of atomic writes that a killed run left behind (a SIGKILL
    cannot be cleaned up after; the real files were never replaced by partial ones)."""
    for camera in cameras:
        for folder in (layout.image_path(out_dir, camera, 0).parent, layout.mask_path(out_dir, camera, 0).parent):
            if folder.is_dir():
                for tmp in folder.glob(".*.tmp"):
                    tmp.unlink(missing_ok=True)


def _seconds_per_image(manifest: Manifest) -> float | None:
    """Mean render + post seconds per image of the pairs the manifest lists, or None."""
    times = [float(t.get("render_s", 0.0)) + float(t.get("post_s", 0.0))
             for frames in manifest.done.values() for t in frames.values()]
    return sum(times) / len(times) if times else None


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


def _chunks(pairs: list[tuple[int, str]], limit: int) -> list[list[tuple[int, str]]]:
    """Cut pairs (in frame order) into runs of at most ``limit`` pairs, at frame boundaries
    where a frame has fewer than ``limit`` cameras."""
    chunks, start = [], 0
    while start < len(pairs):
        end = _take_prefix(pairs, start, limit)
        chunks.append(list(pairs[start:end]))
        start = end
    return chunks


@dataclass
class _Shard:
    number: int
    pairs: list[tuple[int, str]]
    attempt: int = 0

    def describe(self) -> str:
        frames = sorted({f for f, _ in self.pairs})
        span = f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}..{frames[-1]}"
        return f"shard {self.number} ({span}, {len(self.pairs)} images)"


class _ShardQueue:
    """The pairs still to render, handed out to slot threads as shards, with retries.

    ``take`` blocks while nothing is pending but a shard in flight may still come back for a
    retry; it returns None when everything is handed out and settled, or after a failure.
    """

    def __init__(self, todo: list[tuple[int, str]], slots: int, target_shard_s: float | None,
                 seconds_per_image: float | None, retries: int) -> None:
        self.todo, self.next_index = todo, 0
        self.slots, self.target_shard_s, self.retries = slots, target_shard_s, retries
        self._measured = [seconds_per_image, 1] if seconds_per_image else [0.0, 0]
        self.again: deque[_Shard] = deque()
        self.in_flight = 0
        self.errors: list[str] = []
        self._numbers = 0
        self._cond = threading.Condition()

    def measure(self, seconds: float) -> None:
        with self._cond:
            self._measured[0] += seconds
            self._measured[1] += 1

    def take(self) -> _Shard | None:
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
                    shard = _Shard(self._numbers, self.todo[self.next_index:end])
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
        with self._cond:
            self._settle()

    def retry(self, shard: _Shard, left: list[tuple[int, str]]) -> None:
        with self._cond:
            self.again.append(_Shard(shard.number, left, shard.attempt + 1))
            self._settle()

    def fail(self, message: str) -> None:
        with self._cond:
            self.errors.append(message)
            self._settle()


class _Progress:
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
        if self._progress is not None:
            self._progress.advance(self._task)

    def set_busy(self, workers: int) -> None:
        if self._progress is not None:
            self._progress.update(self._task, busy=workers)

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
