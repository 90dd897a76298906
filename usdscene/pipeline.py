"""``usdscene run``: validate → compose → render → annotate → export → report, resumable.

Each step is the public function of its module; this one only chains them and measures. A
re-run of the same command on the same output folder recomposes byte-identical layers, skips
the (frame, camera) pairs the render manifest lists as finished, and re-derives the labels, so
an interrupted run resumes without losing or duplicating work.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

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
        report_page: the browsable report's page (``OUT/report/index.html``); None when not written.
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
    report_page: Path | None = None


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
        from usdscene.converters.openlabel.imaging import document_hdri_problems
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


@dataclass(frozen=True)
class RunOptions:
    """What one ``usdscene run`` renders and writes, besides the document and the output folder.

    Attributes:
        frames: frames to render (default: the document's range).
        cameras: camera names to render (default: all).
        exports: dataset formats (default: the document's ``metadata.usdscene.exports``).
        samples: samples per pixel replacing the document's (None: the document's).
        workers: render worker processes side by side (with an executor object: its own).
        retries: times a shard whose worker died is run again (None = the driver's default).
        split: training split rule of the COCO/YOLO export (:mod:`usdscene.document.splits`);
            None = the document's own rule (``metadata.usdscene.split``), or none.
        split_seed: seed of a fraction split.
        report: write the browsable report (``OUT/report/``, :mod:`usdscene.dataset.report`);
            its thumbnails and mask tints are drawn while rendering.
        document_classes: COCO/YOLO classes are the document's labelled classes (the default:
            a run's export names only what its scene holds); False lists every object class
            of the asset catalog, so that class ids agree between scenes of one library.
        min_pixels, min_visible_fraction: the COCO/YOLO export leaves out labels of fewer
            visible pixels or a smaller visible fraction (0: keep all).
        rle_below_px: COCO segmentation as RLE for objects of fewer visible pixels (0: polygons
            only). See :func:`usdscene.dataset.export.export_formats`.
        keep_clean: also write each sensor camera's image before its sensor effects
            (``OUT/images_clean/``).
    """

    frames: Sequence[int] | None = None
    cameras: Sequence[str] | None = None
    exports: Sequence[str] | None = None
    samples: int | None = None
    workers: int | None = None
    retries: int | None = None
    split: Any = None
    split_seed: int = 0
    report: bool = True
    document_classes: bool = True
    min_pixels: int = 0
    min_visible_fraction: float = 0.0
    rle_below_px: int = 0
    keep_clean: bool = False


def run_pipeline(document: str | Path, out_dir: str | Path, options: RunOptions = RunOptions(), *,
                 executor="local", progress: bool = True,
                 on_step: Callable[[str], None] | None = None) -> RunSummary:
    """Run the whole job for one scene document: validate → compose → render (each image
    labelled as it arrives) → annotate → export → report.

    Args:
        document: OpenLABEL/VCD scene document.
        out_dir: output folder (created; a previous run's output is resumed).
        options: what to render and write (:class:`RunOptions`).
        executor: ``"local"``, ``"ray"`` or an executor object (``usdscene.render.executors``).
        progress: show progress bars on stderr.
        on_step: called with each step's name as it starts (for a status line).

    Raises:
        UsdSceneError: bad document (official schema or usdscene's checks), assets,
            composition or render (nothing half-written).
    """
    from usdscene.render.executors import workers_started_early

    run = _Run(Path(document), Path(out_dir), options, executor, progress, on_step)
    # Local workers start now: their start-up (interpreter, import bpy) overlaps validating
    # and composing, which are single-threaded.
    with workers_started_early(executor, options.workers):
        checked = run.validate()
        composed = run.compose(checked)
        labelling, report = run.render(composed.root_layer)
        annotations = run.annotate(checked, labelling)
        exports = run.export(checked.scene)
        page = run.report()
    return run.summary(report, annotations, labelling, exports, page)


class _Run:
    """The steps of one :func:`run_pipeline` call, each timed under its name."""

    def __init__(self, document: Path, out: Path, options: RunOptions, executor, progress: bool,
                 on_step: Callable[[str], None] | None):
        self.document, self.out, self.options = document, out, options
        self.executor, self.progress, self.on_step = executor, progress, on_step
        self.seconds: dict[str, float] = {}
        self.catalog = None

    @contextlib.contextmanager
    def _step(self, name: str):
        if self.on_step is not None:
            self.on_step(name)
        log.info("%s", name)
        started = time.perf_counter()
        yield
        self.seconds[name] = time.perf_counter() - started

    def validate(self):
        """Exactly the checks of ``usdscene validate``: official schema, usdscene's own, the catalog."""
        from usdscene.scene.catalog import load_catalog
        from usdscene.validation import DEFAULT_SCHEMA, validate_document

        with self._step("validate"):
            checked = validate_document(self.document, schema=DEFAULT_SCHEMA)
            self.catalog = checked.catalog
            if self.catalog is None:  # no catalog was found to check against: composing needs one, say why
                self.catalog = load_catalog(checked.scene.asset_paths, base_dir=self.document.parent)
        return checked

    def compose(self, checked):
        from usdscene.scene.compose import compose_stage

        with self._step("compose"):
            return compose_stage(checked.scene, self.catalog, self.out / layout.STAGE_DIR)

    def render(self, stage_path):
        """Render every image; each is labelled as soon as it is written, while the workers
        render the next ones."""
        from usdscene.dataset.annotation import LabelsWhileRendering
        from usdscene.render.driver import DEFAULT_RETRIES, RenderOptions, render

        options = self.options
        with self._step("render"):
            override = {"samples": options.samples} if options.samples is not None else None
            labelling = LabelsWhileRendering(self.out)
            listeners = [labelling]
            if options.report:
                from usdscene.dataset.report_pictures import PicturesWhileRendering

                # the report's thumbnails and mask tints too: its step at the end only writes data
                listeners.append(PicturesWhileRendering(self.out))

            def on_event(event: dict) -> None:
                for listener in listeners:
                    listener(event)

            report = render(stage_path, self.out, RenderOptions(
                frames=options.frames, cameras=options.cameras, settings_override=override, progress=self.progress,
                workers=options.workers, executor=self.executor, keep_clean=options.keep_clean,
                retries=DEFAULT_RETRIES if options.retries is None else options.retries), on_event=on_event)
        return labelling, report

    def annotate(self, checked, labelling):
        from usdscene.dataset.annotation import write_annotations

        with self._step("annotate"):
            # never writes an output document that the official schema rejects
            _, annotations = write_annotations(self.out, document_path=self.document, progress=self.progress,
                                               schema=checked.schema, labeller=labelling.labeller)
        return annotations

    def export(self, scene) -> dict[str, Path]:
        """The dataset formats asked for (else the document's), with the split rule asked for
        (else the document's own)."""
        from usdscene.dataset.export import ExportOptions, export_formats

        options = self.options
        formats = tuple(options.exports) if options.exports is not None else scene.exports
        if not formats:
            return {}
        split, split_seed = options.split, options.split_seed
        with self._step("export"):
            if split is None and scene.split_rule:  # the document's own rule (metadata.usdscene.split)
                from usdscene.document.splits import DOCUMENT_FIELD, parse_split

                split, split_seed = parse_split(scene.split_rule, f"{DOCUMENT_FIELD}.rule"), scene.split_seed
            return export_formats(self.out, formats, ExportOptions(
                split=split, split_seed=split_seed, document_classes=options.document_classes,
                min_pixels=options.min_pixels, min_visible_fraction=options.min_visible_fraction,
                rle_below_px=options.rle_below_px))

    def report(self) -> Path | None:
        """The browsable report, with the balance chart of a generated document and the
        coverage map of a camera plan when the document has them."""
        if not self.options.report:
            return None
        from usdscene.dataset.report import build_report
        from usdscene.design.camera_design import plan_picture_for

        with self._step("report"):
            return build_report(self.out, document=self.document,
                                coverage_map=plan_picture_for(self.document)).index

    def summary(self, report, annotations, labelling, exports, page) -> RunSummary:
        per_class, hidden = annotations.visible_per_class, annotations.hidden
        seconds = self.seconds
        return RunSummary(
            out_dir=self.out, document=self.document,
            images_written=report.pairs_rendered, images_skipped=report.pairs_skipped,
            images_total=report.pairs_total,
            labels_per_class=dict(sorted(per_class.items())), hidden_labels=hidden,
            seconds=dict(seconds),
            render_seconds_per_image=seconds["render"] / report.pairs_rendered if report.pairs_rendered else 0.0,
            exports=exports, render=report, images_labelled_while_rendering=labelling.images,
            labelling_s_while_rendering=labelling.seconds, report_page=page)


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
        f"  outputs: {out / layout.IMAGES_DIR}/, {out / layout.MASKS_DIR}/, "
        + (f"{out / layout.DEPTH_DIR}/, " if (out / layout.DEPTH_DIR).is_dir() else "")
        + f"{out / layout.ANNOTATION_STORE_DIR}/"
        + (f", {out / layout.ANNOTATIONS_FILE}" if (out / layout.ANNOTATIONS_FILE).is_file() else "")
        + f", {out / layout.STAGE_DIR}/",
    ]
    report = summary.render
    if report is not None and (report.executor != "local" or report.retries or len(report.nodes) > 1):
        from usdscene.render.driver import node_summary_lines

        lines.append(f"  render:  executor {report.executor}, {report.retries} shard retries")
        lines.extend("  " + line for line in node_summary_lines(report))
    for fmt, folder in summary.exports.items():
        lines.append(f"  {fmt}:    {folder}")
    if summary.report_page is not None:
        lines.append(f"  report:  {summary.report_page}    (open it in a web browser)")
    lines.append(f"  next:    usdscene stats {out}    (counts, visibility histogram and a chart)")
    return "\n".join(lines)
