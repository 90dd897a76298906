"""``usdscene run DOC -o OUT``: validate → compose → render → annotate → export."""

from __future__ import annotations

import argparse
import sys

from usdscene.commands._arguments import (add_executor_arguments, add_label_filter_arguments, add_split_arguments,
                                          positive_int)

from usdscene.converters.exports.registry import format_names  # pure: names no writer

NAME = "run"
HELP = ("the whole job: validate the scene document, compose the USD stage, render every camera "
        "of every frame, write labels into OUT/annotations/ (and OUT/annotations.openlabel.json for "
        "small runs) and export datasets; "
        "re-running resumes")
ORDER = 5


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene run`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("document", metavar="DOC", help="OpenLABEL (or VCD 4.3) scene document")
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT", help="output folder")
    parser.add_argument("--frames", metavar="A:B", help="closed frame range A:B, a frame N or a list N,M (default: all)")
    parser.add_argument("--cameras", nargs="+", metavar="NAME", help="cameras to render (default: all)")
    parser.add_argument("--export", nargs="*", choices=format_names(), metavar="FORMAT",
                        help=f"dataset formats to export: {', '.join(format_names())} (default: the document's "
                             "metadata.usdscene.exports; give the flag alone for none)")
    parser.add_argument("--samples", type=int, metavar="N", help="override the samples per pixel")
    parser.add_argument("--workers", type=positive_int, metavar="N",
                        help="render worker processes side by side (default 1; with --executor ray: at "
                             "most N tasks in flight, default what the cluster holds)")
    add_split_arguments(parser)
    add_label_filter_arguments(parser)
    parser.add_argument("--catalog-classes", action="store_true",
                        help="COCO/YOLO classes: every object class of the asset catalog (ids shared by all "
                             "scenes of one library); default: the document's labelled classes")
    add_executor_arguments(parser)
    parser.add_argument("--no-report", action="store_true",
                        help="do not write the browsable report OUT/report/index.html (usdscene report OUT "
                             "writes it later)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--keep-clean", action="store_true",
                        help="also keep the image before the camera's sensor effects (OUT/images_clean/)")


def run(args: argparse.Namespace) -> int:
    """``usdscene run``: validate, compose, render, annotate and export one document; returns the exit
    status."""
    from pathlib import Path

    from usdscene.commands._arguments import executor_for, parse_frames
    from usdscene.errors import DocumentError, Problem
    from usdscene.pipeline import RunOptions, run_pipeline, summary_text

    executor = executor_for(args)  # bad executor options fail before any work
    if not Path(args.document).is_file():
        raise DocumentError(f"scene document {args.document!r} does not exist", where=args.document)
    try:
        frames = parse_frames(args.frames)
    except ValueError as exc:
        raise DocumentError([Problem("--frames", str(exc))]) from None
    if args.samples is not None and args.samples < 1:
        raise DocumentError([Problem("--samples", f"{args.samples} is not a positive number of samples")])
    progress = not args.no_progress and sys.stderr.isatty()

    def show_step(name: str) -> None:
        print(f"usdscene: {name} ...", file=sys.stderr, flush=True)

    options = RunOptions(frames=frames, cameras=args.cameras, exports=args.export, samples=args.samples,
                         workers=args.workers, retries=args.retries, split=args.split,
                         split_seed=args.split_seed, report=not args.no_report,
                         document_classes=not args.catalog_classes, min_pixels=args.min_pixels,
                         min_visible_fraction=args.min_visible, rle_below_px=args.coco_rle_below,
                         keep_clean=args.keep_clean)
    summary = run_pipeline(args.document, args.output, options, executor=executor, progress=progress,
                           on_step=show_step)
    print(summary_text(summary))
    return 0
