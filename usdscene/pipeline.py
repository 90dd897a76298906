"""``usdscene run``: validate → compose → render → annotate → export, resumable.

Each step is the public function of its module; this one only chains them and measures. A
re-run of the same command on the same output folder recomposes byte-identical layers, skips
the (frame, camera) pairs the render manifest lists as finished, and re-derives the labels, so
an interrupted run resumes without losing or duplicating work.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

from usdscene.document import output_layout as layout

if TYPE_CHECKING:
    from usdscene.render.driver import RenderReport

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunSummary:
    """What a pipeline run produced.

    Attributes:
        out_dir: output folder.
        document: the scene document that was run.
        images_written: images rendered by this run.
        images_skipped: images already finished by an earlier run.
        images_total: images of the whole output (frames × cameras).
        labels_per_class: class → visible labels (object × camera × frame).
        hidden_labels: labels of objects that are in view but fully occluded (amodal only).
        seconds: step name → wall seconds.
        render_seconds_per_image: wall seconds of the render step per rendered image.
        exports: format → folder written.
        render: the render step's report (executor, retries, per-node figures); None when
            nothing was rendered.
        images_labelled_while_rendering: images whose labels were computed while the next ones
            rendered (the rest are labelled in the annotate step).
        labelling_s_while_rendering: wall seconds those labels took (inside the render step).
    """

    out_dir: Path
    document: Path
    images_written: int
    images_skipped: int
    images_total: int
    labels_per_class: Mapping[str, int]
    hidden_labels: int
    seconds: Mapping[str, float] = field(default_factory=dict)
    render_seconds_per_image: float = 0.0
    exports: Mapping[str, Path] = field(default_factory=dict)
    render: RenderReport | None = None
    images_labelled_while_rendering: int = 0
    labelling_s_while_rendering: float = 0.0


def compose_document(document: str | Path, stage_dir: str | Path, *, seed: int | None = None):
    """Read a scene document, load its asset catalog (shipped library + the document's
    ``asset_paths``, relative to the document's folder) and compose its stage into ``stage_dir``.

    Args:
        document: OpenLABEL/VCD scene document.
        stage_dir: folder of the layered stage (``scene.usda`` + layers).
        seed: replace the document's seed.

    Returns:
        ``(scene, usdscene.scene.compose.ComposeResult)``.

    Raises:
        UsdSceneError: bad document, catalog or composition.
    """
    import dataclasses

    from usdscene.converters.openlabel import read_openlabel
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage

    path = Path(document)
    scene = read_openlabel(path)
    if scene.world is not None:
        from usdscene.converters.openlabel_imaging import document_hdri_problems
        from usdscene.errors import DocumentError

        hdri = document_hdri_problems(scene, path)
        if hdri:
            raise DocumentError(hdri)
    if seed is not None:
        scene = dataclasses.replace(scene, seed=seed)
    catalog = load_catalog(scene.asset_paths, base_dir=path.resolve().parent)
    return scene, compose_stage(scene, catalog, stage_dir)


def stage_for_input(path: str | Path, out_dir: str | Path) -> Path:
    """The stage to render for an input path: the stage itself (``.usd*``), or for a scene
    document (``.json``) the stage composed from it into ``out_dir/stage``."""
    path = Path(path)
    if path.suffix.lower() != ".json":
        return path
    return Path(compose_document(path, Path(out_dir) / layout.STAGE_DIR)[1].root_layer)


def run_pipeline(document: str | Path, out_dir: str | Path, *, frames: Sequence[int] | None = None,
                 cameras: Sequence[str] | None = None, exports: Sequence[str] | None = None,
                 samples: int | None = None, workers: int | None = None, executor="local",
                 retries: int | None = None, progress: bool = True,
                 on_step: Callable[[str], None] | None = None, split=None,
                 split_seed: int = 0, keep_clean: bool = False) -> RunSummary:
    """Run the whole job for one scene document.

    Args:
        document: OpenLABEL/VCD scene document.
        out_dir: output folder (created; a previous run's output is resumed).
        frames: frames to render (default: the document's range).
        cameras: camera names to render (default: all).
        exports: dataset formats (default: the document's ``metadata.usdscene.exports``).
        samples: override the document's samples per pixel.
        workers: render worker processes side by side (with an executor object: its own).
        executor: ``"local"``, ``"ray"`` or an executor object (``usdscene.render.executors``).
        retries: times a shard whose worker died is run again (None = the driver's default).
        progress: show progress bars on stderr.
        on_step: called with each step's name as it starts (for a status line).
        split: training split rule of the COCO/YOLO export (:mod:`usdscene.document.splits`); None = the
            document's own rule (``metadata.usdscene.split``), or none.
        split_seed: seed of a fraction split.
        keep_clean: also write each sensor camera's image before its sensor effects
            (``OUT/images_clean/``).

    Raises:
        UsdSceneError: bad document (official schema or usdscene's checks), assets,
            composition or render (nothing half-written).
    """
    from usdscene.render.executors import workers_started_early

    # Local workers start now: their start-up (interpreter, import bpy) overlaps validating
    # and composing, which are single-threaded.
    with workers_started_early(executor, workers):
        return _run_steps(document, out_dir, frames=frames, cameras=cameras, exports=exports, samples=samples,
                          workers=workers, executor=executor, retries=retries, progress=progress,
                          on_step=on_step, split=split, split_seed=split_seed, keep_clean=keep_clean)


def _run_steps(document, out_dir, *, frames, cameras, exports, samples, workers, executor, retries, progress,
               on_step, split, split_seed, keep_clean=False) -> RunSummary:
    """The steps of :func:`run_pipeline` (same arguments)."""
    from usdscene.dataset.annotation import LabelsWhileRendering, write_annotations
    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.compose import compose_stage
    from usdscene.dataset.export import export_formats
    from usdscene.render.driver import render
    from usdscene.validation import DEFAULT_SCHEMA, validate_document

    doc_path, out = Path(document), Path(out_dir)
    seconds: dict[str, float] = {}

    def step(name: str) -> float:
        if on_step is not None:
            on_step(name)
        log.info("%s", name)
        return time.perf_counter()

    t = step("validate")
    # Exactly the checks of `usdscene validate`: official schema, usdscene's own, the catalog.
    checked = validate_document(doc_path, schema=DEFAULT_SCHEMA)
    scene, catalog = checked.scene, checked.catalog
    if catalog is None:  # no catalog was found to check against: composing needs one, say why
        catalog = load_catalog(scene.asset_paths, base_dir=doc_path.parent)
    seconds["validate"] = time.perf_counter() - t

    t = step("compose")
    composed = compose_stage(scene, catalog, out / layout.STAGE_DIR)
    seconds["compose"] = time.perf_counter() - t

    t = step("render")
    override = {"samples": samples} if samples is not None else None
    # Each image is labelled as soon as it is written, while the workers render the next ones.
    labelling = LabelsWhileRendering(out)
    report = render(composed.root_layer, out, frames=frames, cameras=cameras, settings_override=override,
                    progress=progress, workers=workers, executor=executor, on_event=labelling,
                    keep_clean=keep_clean, **({} if retries is None else {"retries": retries}))
    seconds["render"] = time.perf_counter() - t

    t = step("annotate")
    # never writes an output document that the official schema rejects
    _, annotations = write_annotations(out, document_path=doc_path, progress=progress,
                                       schema=checked.schema, labeller=labelling.labeller)
    seconds["annotate"] = time.perf_counter() - t

    formats = tuple(exports) if exports is not None else scene.exports
    written: dict[str, Path] = {}
    if formats:
        t = step("export")
        if split is None and scene.split_rule:  # the document's own rule (metadata.usdscene.split)
            from usdscene.document.splits import DOCUMENT_FIELD, parse_split

            split, split_seed = parse_split(scene.split_rule, f"{DOCUMENT_FIELD}.rule"), scene.split_seed
        written = export_formats(out, formats, split=split, split_seed=split_seed)
        seconds["export"] = time.perf_counter() - t

    per_class = Counter(obj.class_name for image in annotations for obj in image.objects if obj.visible)
    hidden = sum(1 for image in annotations for obj in image.objects if not obj.visible)
    return RunSummary(
        out_dir=out, document=doc_path,
        images_written=report.pairs_rendered, images_skipped=report.pairs_skipped,
        images_total=report.pairs_total,
        labels_per_class=dict(sorted(per_class.items())), hidden_labels=hidden,
        seconds=seconds,
        render_seconds_per_image=seconds["render"] / report.pairs_rendered if report.pairs_rendered else 0.0,
        exports=written, render=report, images_labelled_while_rendering=labelling.images,
        labelling_s_while_rendering=labelling.seconds)


def summary_text(summary: RunSummary) -> str:
    """The short human summary printed at the end of ``usdscene run``."""
    out = summary.out_dir
    lines = [
        f"usdscene run finished in {sum(summary.seconds.values()):.0f} s "
        f"({', '.join(f'{k} {v:.1f} s' for k, v in summary.seconds.items())})",
        f"  images:  {summary.images_written} rendered, {summary.images_skipped} already done, "
        f"{summary.images_total} in all"
        + (f"; {summary.render_seconds_per_image:.2f} s per image" if summary.images_written else ""),
        f"  labels:  {sum(summary.labels_per_class.values())} visible "
        f"({', '.join(f'{k} {v}' for k, v in summary.labels_per_class.items()) or 'none'}), "
        f"{summary.hidden_labels} fully occluded (amodal only)"
        + (f"; {summary.images_labelled_while_rendering} images labelled while rendering"
           if summary.images_labelled_while_rendering else ""),
        f"  outputs: {out / layout.IMAGES_DIR}/, {out / layout.MASKS_DIR}/, {out / layout.ANNOTATIONS_FILE}, "
        f"{out / layout.STAGE_DIR}/",
    ]
    report = summary.render
    if report is not None and (report.executor != "local" or report.retries or len(report.nodes) > 1):
        from usdscene.render.driver import node_summary_lines

        lines.append(f"  render:  executor {report.executor}, {report.retries} shard retries")
        lines.extend("  " + line for line in node_summary_lines(report))
    for fmt, folder in summary.exports.items():
        lines.append(f"  {fmt}:    {folder}")
    lines.append(f"  next:    usdscene stats {out}    (counts, visibility histogram and a chart)")
    return "\n".join(lines)
