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
import functools
import logging
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from usdscene import __version__

from usdscene.document import output_layout as layout
from usdscene.errors import Problem, RenderError
from usdscene.files import remove_stale_temporaries, write_json_atomic
from usdscene.document.model import MAX_BOUNCES, RenderSettings
from usdscene.labels.projection import undistorted_render_intrinsics
from usdscene.render.job import JobCamera, to_json
from usdscene.render.manifest import Manifest, fingerprint
from usdscene.render.shards import Progress, ShardQueue, ShardRunner, Tally, shard_job
from usdscene.sensor.exposure import meter_window

log = logging.getLogger(__name__)

ENGINES = ("cycles", "eevee", "workbench")
# Settings the worker knows beyond RenderSettings (benchmarked in benchmarks/render_settings.py).
# resolution_scale scales every camera's image (previews); 1 = the calibrated resolution.
EXTRA_SETTINGS = {"resolution_scale": 1.0}
# Extra attempts for a shard whose worker died (signal, lost node) before it gave up.
DEFAULT_RETRIES = 3


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
    from usdscene.converters.openlabel.metadata import DENOISING_INPUT_PASSES, FAST_GI_METHODS, SAMPLING_PATTERNS

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
    from usdscene.converters.openlabel.metadata import DEPTH_FORMATS

    if settings["depth"] is not None and settings["depth"] not in DEPTH_FORMATS:
        problems.append(Problem("render.depth", f"unknown depth format {settings['depth']!r}; expected one of "
                                                f"{', '.join(DEPTH_FORMATS)} (or null for no depth images)"))
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


@dataclass(frozen=True)
class RenderOptions:
    """What a :func:`render` call renders, and how.

    Attributes:
        frames: frames to render (default: the stage's whole range).
        cameras: camera names (default: every camera under ``/World/Cameras``).
        settings_override: RenderSettings or a mapping of fields that win over the stage's.
        progress: show a ``rich`` progress bar on stderr.
        workers: shards run side by side: local worker processes (default 1; CPU threads are
            split between them), or for Ray an upper bound on tasks in flight (default: what
            the cluster holds). Used only when ``executor`` is a name; an executor object
            carries its own.
        executor: ``"local"``, ``"ray"`` (a local Ray runtime) or an executor object from
            :func:`usdscene.render.executors.make_executor` (e.g. Ray at an address).
        retries: how many times a shard whose worker died (a signal such as the OOM killer's
            SIGKILL, a lost node) is run again for its unfinished images, on any slot.
        keep_clean: for cameras with a sensor, also write the image before the sensor's
            effects to ``out/images_clean/<camera>/<frame:06d>.png``.
    """

    frames: Sequence[int] | None = None
    cameras: Sequence[str] | None = None
    settings_override: RenderSettings | Mapping[str, Any] | None = None
    progress: bool = True
    workers: int | None = None
    executor: str | Any = "local"
    retries: int = DEFAULT_RETRIES
    keep_clean: bool = False


def render(stage_path: Path, out_dir: Path, options: RenderOptions | None = None, *,
           on_event: Callable[[dict], None] | None = None, **fields) -> RenderReport:
    """Render every requested camera of every requested frame of a composed stage.

    Writes ``out/images/<camera>/<frame:06d>.png`` (8-bit sRGB), ``out/masks/<camera>/
    <frame:06d>.png`` (uint16 ids, 0 = background), ``out/masks/ids.json`` and
    ``out/manifest.json``; pairs a previous run finished are skipped, whichever executor ran
    it. The pixels do not depend on the executor, the number of workers or the shard order.

    Args:
        stage_path: root layer of the composed stage (``out/stage/scene.usda``).
        out_dir: output folder.
        options: what to render and how (:class:`RenderOptions`; default: everything, locally).
        on_event: called with every progress event of the workers (dicts), in the parent, one
            at a time; a ``done`` event (its image and mask are written) before the image is
            recorded as finished in the manifest.
        fields: :class:`RenderOptions` fields by keyword (``frames=[0]``), over ``options``.

    Returns:
        A :class:`RenderReport`.

    Raises:
        RenderError: bad selection or settings, or a worker failed (finished pairs are kept
            and a re-run resumes).
    """
    from usdscene.render.executors import make_executor
    from usdscene.render.scratch import remove_stale_scratch
    from usdscene.render.stage_reader import read_stage_plan

    started = time.perf_counter()
    options = dataclasses.replace(options or RenderOptions(), **fields)
    out_dir = Path(out_dir)
    plan = read_stage_plan(stage_path)
    settings = resolve_settings(plan.settings, options.settings_override)
    frame_list, camera_list = _checked_selection(plan, stage_path, options.frames, options.cameras,
                                                 workers=options.workers, retries=options.retries)
    executor = options.executor
    if isinstance(executor, str):
        executor = make_executor(executor, workers=options.workers)

    job_cameras = camera_jobs(plan, camera_list, frame_list, float(settings["resolution_scale"]))
    manifest = _open_manifest(out_dir, plan, settings, job_cameras, keep_clean=options.keep_clean)
    manifest.depth_format = settings["depth"]
    _remove_stale_temporaries(out_dir, camera_list, settings["depth"])
    remove_stale_scratch()
    todo = [(f, c) for f in frame_list for c in camera_list if not manifest.is_done(f, c)]
    _check_free_space(out_dir, plan, todo, float(settings["resolution_scale"]), options.keep_clean)
    total = len(frame_list) * len(camera_list)
    skipped = total - len(todo)
    write_json_atomic(out_dir / layout.ID_MAP_FILE, layout.id_map_json(plan.objects))

    tally = Tally(manifest, on_event)
    if todo:
        bar = Progress(total, skipped, enabled=options.progress)
        try:
            with executor, bar:
                executor.prepare(plan.stage_path, settings)
                queue = ShardQueue(todo, executor.slots, executor.target_shard_s,
                                    _seconds_per_image(manifest), retries=int(options.retries))
                runner = ShardRunner(executor, queue, tally, bar, out_dir,
                                      functools.partial(shard_job, plan, settings, job_cameras,
                                                        executor.threads_per_worker, options.keep_clean))
                errors = runner.run()
        finally:
            if tally.totals["retries"]:
                # A killed worker may have died inside an atomic write; no worker runs now.
                _remove_stale_temporaries(out_dir, camera_list, settings["depth"])
            manifest.timings = {"wall_s": round(time.perf_counter() - started, 3),
                                "render_s": round(tally.totals["render_s"], 3)}
            manifest.save()
        if errors:
            raise RenderError([Problem(str(stage_path), e) for e in errors])
    else:
        manifest.save()
    totals = tally.totals
    return RenderReport(out_dir, total, totals["rendered"], skipped, time.perf_counter() - started,
                        totals["render_s"], totals["post_s"], totals["import_s"], totals["startup_s"],
                        totals["render_cpu_s"], totals["worker_cpu_s"], executor.name,
                        int(totals["retries"]), tally.nodes)


def _check_free_space(out_dir: Path, plan, todo, scale: float, keep_clean: bool) -> None:
    """Refuse, before rendering, a run whose estimated output does not fit on the disk."""
    from usdscene.render.disk_space import check_free_space

    sizes = {c.name: scale_intrinsics(c.intrinsics, scale) for c in plan.cameras}
    check_free_space(out_dir, ((sizes[c].width_px, sizes[c].height_px) for _, c in todo), keep_clean=keep_clean)


def _checked_selection(plan, stage_path: Path, frames: Sequence[int] | None, cameras: Sequence[str] | None, *,
                       workers: int | None, retries: int) -> tuple[list[int], list[str]]:
    """The frames and cameras to render (default: all of the stage's), checked against the stage.

    Raises:
        RenderError: every bad frame, camera, worker or retry count at once.
    """
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
    return frame_list, camera_list


def _open_manifest(out_dir: Path, plan, settings: Mapping[str, Any], cameras: Mapping[str, JobCamera], *,
                   keep_clean: bool = False) -> Manifest:
    """The output's manifest of finished pairs, kept only when it was written for the same stage,
    settings (the device aside), cameras and objects."""
    from usdscene.render.stage_reader import stage_digest

    print_settings = {k: v for k, v in settings.items() if k != "device"}
    manifest = Manifest.load(out_dir, fingerprint({
        **({"keep_clean": True} if keep_clean and plan.sensors else {}),
        "stage": stage_digest(plan.stage_path), "settings": print_settings,
        "cameras": {n: c.to_json() for n, c in cameras.items()},
        "objects": [dataclasses.asdict(o) for o in plan.objects],
    }))
    manifest.versions = {"usdscene": __version__}
    return manifest


def camera_jobs(plan, camera_names: Sequence[str], frames: Sequence[int], scale: float = 1.0) -> dict[str, JobCamera]:
    """Per camera, its :class:`~usdscene.render.job.JobCamera`: its intrinsics, the native lens
    to render (a wider undistorted view for OpenCV models), its base pose and per-frame poses
    (OpenCV axes, 16 row-major numbers) and its sensor."""
    by_name = {c.name: c for c in plan.cameras}
    out = {}
    for name in camera_names:
        cam = by_name[name]
        warmup = sequence_warmup(plan, name)
        # an adapting camera's shards also pre-pass the frames before theirs (its exposure window)
        wanted = set(frames) if not warmup else {g for f in frames for g in meter_window(f, warmup, plan.frames.start)}
        intr = scale_intrinsics(cam.intrinsics, scale)
        try:
            render_intr = undistorted_render_intrinsics(intr)
        except ValueError as exc:
            raise RenderError(str(exc), where=f"{plan.stage_path}:/World/Cameras/{name}") from None
        sensor = getattr(plan, "sensors", {}).get(name)
        if warmup:  # exposure adapting over frames: the window (usdscene.sensor.exposure.meter_window)
            sensor = {**sensor, "warmup_frames": warmup, "first_frame": plan.frames.start}
        out[name] = JobCamera(intr, render_intr, tuple(cam.pose.matrix),
                              {f: tuple(p.matrix) for f, p in cam.frame_poses if f in wanted},
                              (cam.clip_near_m, cam.clip_far_m), sensor)
    return out


def sequence_warmup(plan, camera: str) -> int:
    """Frames before each frame whose pre-pass meter readings decide camera ``camera``'s
    exposure (:func:`usdscene.sensor.exposure.warmup_frames`; 0: no sensor, or an instant one)."""
    sensor = getattr(plan, "sensors", {}).get(camera)
    if sensor is None:
        return 0
    from usdscene.document.imaging import Sensor, spec_from_json
    from usdscene.sensor.exposure import warmup_frames

    spec = spec_from_json(Sensor, sensor["sensor"])
    return warmup_frames(float(spec.exposure_speed)) if spec.auto_exposure else 0


def run_job(job, what: str) -> list[dict]:
    """Run one worker on ``job`` (any kind of :mod:`usdscene.render.job`) and return its events.

    Raises:
        RenderError: the worker failed (its message, the signal that killed it, or the tail
            of its log).
    """
    from usdscene.render.worker_process import describe_exit, iter_worker_events
    from usdscene.render.scratch import make_scratch

    scratch = make_scratch("job")
    events: list[dict] = []
    try:
        job = dataclasses.replace(job, scratch_dir=str(scratch))
        job_path = scratch / "job-0.json"
        job_path.write_text(to_json(job))
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


def _remove_stale_temporaries(out_dir: Path, cameras: Sequence[str], depth_format: str | None = None) -> None:
    """Delete the temporary files of atomic writes that a killed run left behind (a SIGKILL
    cannot be cleaned up after; the real files were never replaced by partial ones)."""
    for camera in cameras:
        folders = [layout.image_path(out_dir, camera, 0).parent, layout.mask_path(out_dir, camera, 0).parent]
        if depth_format is not None:
            folders.append(layout.depth_path(out_dir, camera, 0, depth_format).parent)
        for folder in folders:
            remove_stale_temporaries(folder, recursive=False)


def _seconds_per_image(manifest: Manifest) -> float | None:
    """Mean render + post seconds per image of the pairs the manifest lists, or None."""
    times = [float(t.get("render_s", 0.0)) + float(t.get("post_s", 0.0))
             for frames in manifest.done.values() for t in frames.values()]
    return sum(times) / len(times) if times else None


