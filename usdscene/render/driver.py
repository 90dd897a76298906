"""The parent side of rendering: plan shards, run worker processes, track progress, resume.

The driver never imports ``bpy``. It reads the stage with pxr (:mod:`stage_reader`), decides
which (frame, camera) pairs are missing (:mod:`manifest`), cuts them into shards of
consecutive frames, writes one JSON job per shard and runs ``python -m usdscene.render.worker
JOB`` for each, reading the worker's progress lines from its stdout.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from usdscene import __version__, layout
from usdscene.errors import Problem, RenderError
from usdscene.files import write_json_atomic
from usdscene.model import RenderSettings
from usdscene.projection import undistorted_render_intrinsics
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
    w = max(1, round(intr.width_px * scale))
    h = max(1, round(intr.height_px * scale))
    sx, sy = w / intr.width_px, h / intr.height_px
    return dataclasses.replace(intr, width_px=w, height_px=h, fx_px=intr.fx_px * sx, fy_px=intr.fy_px * sy,
                               cx_px=(intr.cx_px + 0.5) * sx - 0.5, cy_px=(intr.cy_px + 0.5) * sy - 0.5,
                               sensor_width_mm=intr.sensor_width_mm)


def render(stage_path: Path, out_dir: Path, *, frames: Sequence[int] | None = None,
           cameras: Sequence[str] | None = None,
           settings_override: RenderSettings | Mapping[str, Any] | None = None,
           progress: bool = True, workers: int = 1,
           on_event: Callable[[dict], None] | None = None) -> RenderReport:
    """Render every requested camera of every requested frame of a composed stage.

    Writes ``out/images/<camera>/<frame:06d>.png`` (8-bit sRGB), ``out/masks/<camera>/
    <frame:06d>.png`` (uint16 ids, 0 = background), ``out/masks/ids.json`` and
    ``out/manifest.json``; pairs a previous run finished are skipped.

    Args:
        stage_path: root layer of the composed stage (``out/stage/scene.usda``).
        out_dir: output folder.
        frames: frames to render (default: the stage's whole range).
        cameras: camera names (default: every camera under ``/World/Cameras``).
        settings_override: RenderSettings or a mapping of fields that win over the stage's.
        progress: show a ``rich`` progress bar on stderr.
        workers: worker processes run side by side, each on a block of frames (each imports
            only the objects its frames show); CPU threads are split between them.
        on_event: called with every progress event of the workers (dicts), in the parent.

    Returns:
        A :class:`RenderReport`.

    Raises:
        RenderError: bad selection or settings, or a worker failed (finished pairs are kept
            and a re-run resumes).
    """
    from usdscene.render.stage_reader import read_stage_plan

    started = time.perf_counter()
    out_dir = Path(out_dir)
    plan = read_stage_plan(stage_path)
    settings = resolve_settings(plan.settings, settings_override)
    problems: list[Problem] = []
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

    cam_json = camera_jobs(plan, camera_list, frame_list, float(settings["resolution_scale"]))
    print_settings = {k: v for k, v in settings.items() if k != "device"}
    manifest = Manifest.load(out_dir, fingerprint({
        "stage": _stage_digest(plan.stage_path), "settings": print_settings,
        "cameras": {n: {k: v for k, v in c.items()} for n, c in cam_json.items()},
        "objects": [dataclasses.asdict(o) for o in plan.objects],
    }))
    manifest.versions = {"usdscene": __version__}
    _remove_stale_temporaries(out_dir, camera_list)
    todo = [(f, c) for f in frame_list for c in camera_list if not manifest.is_done(f, c)]
    total = len(frame_list) * len(camera_list)
    skipped = total - len(todo)
    write_json_atomic(out_dir / layout.ID_MAP_FILE, {
        str(o.mask_id): {"uid": o.uid, "class": o.class_name, "prim": o.prim_path} for o in plan.objects})

    totals = {"render_s": 0.0, "post_s": 0.0, "import_s": 0.0, "startup_s": 0.0, "rendered": 0,
              "render_cpu_s": 0.0, "worker_cpu_s": 0.0}
    if todo:
        shards = _shards(todo, max(1, int(workers)))
        threads = max(1, (os.cpu_count() or 1) // len(shards)) if len(shards) > 1 else None
        # Each shard runs as a sequence of worker processes of bounded length (one per chunk).
        chunked = [_chunks(pairs, MAX_RENDERS_PER_WORKER) for pairs in shards]
        scratch = Path(tempfile.mkdtemp(prefix="usdscene-render-", dir=_scratch_root()))
        lock = threading.Lock()
        bar = _Progress(total, skipped, enabled=progress)
        try:
            jobs: list[list[Path]] = [[] for _ in chunked]
            for index, (lane, pairs) in enumerate((lane, pairs) for lane, chunks in enumerate(chunked)
                                                  for pairs in chunks):
                shard_frames = sorted({f for f, _ in pairs})
                frame_set = set(shard_frames)
                objects = [{"uid": o.uid, "mask_id": o.mask_id, "prim": o.prim_path,
                            "visible_frames": [f for f in o.visible_frames if f in frame_set]}
                           for o in plan.objects if frame_set.intersection(o.visible_frames)]
                mask = list(plan.shared_prims) + [o["prim"] for o in objects]
                job = {
                    "stage": str(plan.stage_path),
                    "out_dir": str(out_dir.resolve()),
                    "scratch_dir": str(scratch),
                    # An empty mask would import everything: name a path that cannot exist.
                    "prim_path_mask": ",".join(mask) if mask else "/World/__nothing__",
                    "settings": settings,
                    "threads": threads,
                    "objects": objects,
                    "cameras": {c: cam_json[c] for c in sorted({c for _, c in pairs})},
                    "pairs": [[f, c] for f, c in pairs],
                }
                job_path = scratch / f"job-{index}.json"
                job_path.write_text(json.dumps(job))
                jobs[lane].append(job_path)

            def handle(event: dict) -> None:
                with lock:
                    if event.get("event") == "done":
                        manifest.mark_done(int(event["frame"]), event["camera"],
                                           {k: event[k] for k in ("render_s", "post_s") if k in event})
                        manifest.save()
                        totals["render_s"] += event["render_s"]
                        totals["post_s"] += event["post_s"]
                        totals["render_cpu_s"] += event.get("render_cpu_s", 0.0)
                        totals["rendered"] += 1
                        bar.advance()
                    elif event.get("event") == "imported":
                        totals["import_s"] += event["seconds"]
                        if event.get("missing_count"):
                            log.warning("%d objects of the stage were not found after the USD import, "
                                        "e.g. %s", event["missing_count"], event["missing_uids"])
                    elif event.get("event") == "finished":
                        totals["worker_cpu_s"] += event.get("process_cpu_s", 0.0)
                    elif event.get("event") == "warning":
                        log.warning("%s", event.get("message"))
                    if on_event is not None:
                        on_event(event)

            with bar:
                errors = _run_workers(jobs, scratch, handle, totals)
        finally:
            manifest.timings = {"wall_s": round(time.perf_counter() - started, 3),
                                "render_s": round(totals["render_s"], 3)}
            manifest.save()
            shutil.rmtree(scratch, ignore_errors=True)
        if errors:
            raise RenderError([Problem(str(stage_path), e) for e in errors])
    else:
        manifest.save()
    return RenderReport(out_dir, total, totals["rendered"], skipped, time.perf_counter() - started,
                        totals["render_s"], totals["post_s"], totals["import_s"], totals["startup_s"],
                        totals["render_cpu_s"], totals["worker_cpu_s"])


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
    return out


def run_job(job: dict, what: str) -> list[dict]:
    """Run one worker on ``job`` (any mode) and return its events.

    Raises:
        RenderError: the worker failed (its message, or the tail of its log).
    """
    scratch = Path(tempfile.mkdtemp(prefix="usdscene-job-", dir=_scratch_root()))
    events: list[dict] = []
    try:
        job = dict(job, scratch_dir=str(scratch))
        job_path = scratch / "job-0.json"
        job_path.write_text(json.dumps(job))
        errors = _run_workers([[job_path]], scratch, events.append,
                              {"startup_s": 0.0})
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    if errors:
        raise RenderError([Problem(what, e) for e in errors])
    return events


def _remove_stale_temporaries(out_dir: Path, cameras: Sequence[str]) -> None:
    """Delete the temporary files of atomic writes that a killed run left behind (a SIGKILL
    cannot be cleaned up after; the real files were never replaced by partial ones)."""
    for camera in cameras:
        for folder in (layout.image_path(out_dir, camera, 0).parent, layout.mask_path(out_dir, camera, 0).parent):
            if folder.is_dir():
                for tmp in folder.glob(".*.tmp"):
                    tmp.unlink(missing_ok=True)


def _scratch_root() -> str | None:
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def _stage_digest(stage_path: Path) -> str:
    """Digest of every USD layer file beside the root layer (the composed stage's layers)."""
    import hashlib

    digest = hashlib.sha256()
    folder = Path(stage_path).parent
    for path in sorted(folder.glob("*.usd*")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _shards(pairs: list[tuple[int, str]], count: int) -> list[list[tuple[int, str]]]:
    """Split pairs (in frame order) into at most ``count`` blocks of consecutive frames."""
    frames = sorted({f for f, _ in pairs})
    count = min(count, len(frames))
    blocks = [frames[i * len(frames) // count:(i + 1) * len(frames) // count] for i in range(count)]
    return [[p for p in pairs if p[0] in set(block)] for block in blocks if block]


def _chunks(pairs: list[tuple[int, str]], limit: int) -> list[list[tuple[int, str]]]:
    """Cut pairs (in frame order) into runs of at most ``limit`` pairs, at frame boundaries
    where a frame has fewer than ``limit`` cameras (so a chunk imports only its frames)."""
    chunks: list[list[tuple[int, str]]] = []
    current: list[tuple[int, str]] = []
    by_frame: dict[int, list[tuple[int, str]]] = {}
    for pair in pairs:
        by_frame.setdefault(pair[0], []).append(pair)
    for frame_pairs in by_frame.values():
        if current and len(current) + len(frame_pairs) > limit:
            chunks.append(current)
            current = []
        for pair in frame_pairs:
            if len(current) == limit:
                chunks.append(current)
                current = []
            current.append(pair)
    if current:
        chunks.append(current)
    return chunks


def _run_workers(lanes: list[list[Path]], scratch: Path, handle, totals) -> list[str]:
    """Run the lanes side by side, the jobs of a lane one after the other (one worker process
    per job); return error messages. A lane stops at its first failed job."""
    errors: list[str] = []
    threads = []

    def run_lane(lane: list[Path]) -> None:
        for job_path in lane:
            if not run(job_path):
                return

    def run(job_path: Path) -> bool:
        log_path = scratch / (job_path.stem + ".log")
        t0 = time.perf_counter()
        first = True
        with open(log_path, "w") as log_file:
            proc = subprocess.Popen([sys.executable, "-m", "usdscene.render.worker", str(job_path)],
                                    stdout=subprocess.PIPE, stderr=log_file, text=True, bufsize=1)
            tail: deque[str] = deque(maxlen=20)
            failed = None
            try:
                for line in proc.stdout:
                    if not line.startswith("@usdscene "):
                        tail.append(line.rstrip())
                        log_file.write(line)
                        continue
                    event = json.loads(line[len("@usdscene "):])
                    if event.get("event") == "done" and first:
                        first = False
                        totals["startup_s"] += time.perf_counter() - t0 - event["render_s"] - event["post_s"]
                    if event.get("event") == "error":
                        failed = event.get("message")
                    handle(event)
            finally:
                code = proc.wait()
        if code != 0:
            log_file_tail = log_path.read_text(errors="replace").splitlines()[-10:]
            detail = failed or "; ".join(log_file_tail[-5:]) or f"exit code {code}"
            errors.append(f"render worker ({job_path.name}) failed: {detail}")
            return False
        return True

    for lane in lanes:
        thread = threading.Thread(target=run_lane, args=(lane,), daemon=True)
        thread.start()
        threads.append(thread)
    for thread in threads:
        thread.join()
    return errors


class _Progress:
    """A rich progress bar over frames × cameras (images/s and ETA), or nothing."""

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
                                      TimeRemainingColumn(), transient=False)
            self._progress.__enter__()
            self._task = self._progress.add_task("render", total=self.total, completed=self.done)
        return self

    def advance(self) -> None:
        if self._progress is not None:
            self._progress.advance(self._task)

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
