"""``usdscene render STAGE_OR_DOC -o OUT``: render every camera of every frame with Cycles."""

from __future__ import annotations

import argparse
import sys

from usdscene.commands._arguments import add_executor_arguments, positive_int

NAME = "render"
HELP = ("render every camera of every frame with Blender Cycles: RGB images and exact uint16 "
        "instance masks from one render; re-running resumes")
ORDER = 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene render`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("input", metavar="STAGE_OR_DOC",
                        help="composed stage (scene.usda) or scene document (.json, composed into OUT/stage first)")
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT", help="output folder")
    parser.add_argument("--frames", metavar="A:B",
                        help="closed frame range A:B, a single frame N, or a list N,M,... (default: all)")
    parser.add_argument("--cameras", nargs="+", metavar="NAME", help="cameras to render (default: all)")
    parser.add_argument("--samples", type=int, metavar="N", help="path-tracing samples per pixel")
    parser.add_argument("--workers", type=positive_int, metavar="N",
                        help="worker processes side by side, each on a block of frames (default 1; with "
                             "--executor ray: at most N tasks in flight, default what the cluster holds)")
    add_executor_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--keep-clean", action="store_true",
                        help="also keep the image before the camera's sensor effects (OUT/images_clean/)")


def run(args: argparse.Namespace) -> int:
    """``usdscene render``: render every camera of every frame; returns the exit status."""
    from pathlib import Path

    from usdscene.commands._arguments import executor_for, parse_frames
    from usdscene.errors import Problem, RenderError
    from usdscene.pipeline import stage_for_input
    from usdscene.render.driver import RenderOptions, node_summary_lines, render

    executor = executor_for(args)  # bad executor options fail before composing a document
    try:
        frames = parse_frames(args.frames)
    except ValueError as exc:
        raise RenderError([Problem("--frames", str(exc))]) from None
    if not Path(args.input).exists():
        raise RenderError(f"input {args.input!r} does not exist", where=args.input)
    stage = stage_for_input(args.input, args.output)
    override = {"samples": args.samples} if args.samples is not None else None
    report = render(stage, Path(args.output), RenderOptions(
        frames=frames, cameras=args.cameras, settings_override=override,
        progress=not args.no_progress and sys.stderr.isatty(), executor=executor, retries=args.retries,
        keep_clean=args.keep_clean))
    rate = report.pairs_rendered / report.wall_s if report.wall_s > 0 else 0.0
    retried = f", {report.retries} shards retried" if report.retries else ""
    print(f"{report.pairs_rendered} images rendered, {report.pairs_skipped} already done, "
          f"{report.wall_s:.1f} s ({rate:.2f} images/s){retried} → {args.output}")
    if report.nodes:
        print(f"per node ({report.executor} executor):")
        print("\n".join(node_summary_lines(report)))
    return 0
