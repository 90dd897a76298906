"""``usdscene render STAGE_OR_DOC -o OUT``: render every camera of every frame with Cycles."""

from __future__ import annotations

import argparse
import sys

NAME = "render"
HELP = ("render every camera of every frame with Blender Cycles: RGB images and exact uint16 "
        "instance masks from one render; re-running resumes")
ORDER = 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="STAGE_OR_DOC",
                        help="composed stage (scene.usda) or scene document (.json, composed into OUT/stage first)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder")
    parser.add_argument("--frames", metavar="A:B",
                        help="closed frame range A:B, a single frame N, or a list N,M,... (default: all)")
    parser.add_argument("--cameras", nargs="+", metavar="NAME", help="cameras to render (default: all)")
    parser.add_argument("--samples", type=int, metavar="N", help="path-tracing samples per pixel")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="worker processes side by side, each on a block of frames (default 1; with "
                             "--executor ray: at most N tasks in flight, default what the cluster holds)")
    add_executor_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--executor``, ``--ray-address``, ``--task-cpus``, ``--retries`` (shared with ``usdscene run``)."""
    parser.add_argument("--executor", choices=("local", "ray"), default="local",
                        help="where shards run: local worker processes (default) or Ray tasks "
                             "(pip install 'usdscene[ray]')")
    parser.add_argument("--ray-address", metavar="ADDRESS",
                        help="Ray cluster to use (auto, HOST:6379 or ray://HOST:10001); default: start a "
                             "local Ray runtime")
    parser.add_argument("--task-cpus", type=int, default=1, metavar="N",
                        help="CPUs per Ray task = Cycles threads of its worker (default 1)")
    parser.add_argument("--retries", type=int, default=3, metavar="N",
                        help="times a shard whose worker died (signal, OOM killer, lost node) is run "
                             "again for its unfinished images (default 3)")


def executor_for(args: argparse.Namespace):
    """The executor the arguments ask for (not yet entered).

    Raises:
        RenderError: a bad combination or value, naming the option.
    """
    from usdscene.errors import Problem, RenderError
    from usdscene.render.executors import make_executor

    problems = []
    if args.workers is not None and args.workers < 1:
        problems.append(Problem("--workers", f"{args.workers} is not a positive number of workers"))
    if args.retries < 0:
        problems.append(Problem("--retries", f"{args.retries} must be 0 or more"))
    if args.task_cpus < 1:
        problems.append(Problem("--task-cpus", f"{args.task_cpus} is not a positive number of CPUs"))
    if args.executor != "ray" and args.ray_address is not None:
        problems.append(Problem("--ray-address", f"{args.ray_address!r} needs --executor ray"))
    if problems:
        raise RenderError(problems)
    return make_executor(args.executor, workers=args.workers, ray_address=args.ray_address,
                         task_cpus=args.task_cpus)


def node_summary_lines(report) -> list[str]:
    """One line per node of a :class:`~usdscene.render.driver.RenderReport`: images, shards,
    mean render seconds per image."""
    lines = []
    for node, row in sorted(report.nodes.items()):
        per_image = row["render_s"] / row["images"] if row["images"] else 0.0
        lines.append(f"  {node}: {int(row['images'])} images in {int(row['shards'])} shards, "
                     f"{per_image:.2f} s/image render")
    return lines


def parse_frames(text: str | None) -> list[int] | None:
    """``"A:B"`` → [A..B] (closed), ``"N"`` → [N], ``"N,M"`` → [N, M]; None → None.

    Raises:
        UsageError-like ValueError with the bad text.
    """
    if text is None:
        return None
    text = text.strip()
    if ":" in text:
        a, _, b = text.partition(":")
        start, end = int(a), int(b)
        if end < start:
            raise ValueError(f"--frames {text!r}: end {end} is before start {start}")
        return list(range(start, end + 1))
    return [int(v) for v in text.split(",") if v.strip()]


def stage_for_input(path, out_dir):
    """The stage to render: ``path`` itself, or the stage composed from a scene document."""
    from pathlib import Path

    from usdscene import layout

    path = Path(path)
    if path.suffix.lower() != ".json":
        return path
    from usdscene.pipeline import compose_document

    return Path(compose_document(path, Path(out_dir) / layout.STAGE_DIR)[1].root_layer)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from usdscene.errors import Problem, RenderError
    from usdscene.render.driver import render

    try:
        frames = parse_frames(args.frames)
    except ValueError as exc:
        raise RenderError([Problem("--frames", str(exc))]) from None
    if not Path(args.input).exists():
        raise RenderError(f"input {args.input!r} does not exist", where=args.input)
    stage = stage_for_input(args.input, args.output)
    override = {"samples": args.samples} if args.samples is not None else None
    executor = executor_for(args)
    report = render(stage, Path(args.output), frames=frames, cameras=args.cameras,
                    settings_override=override, progress=not args.no_progress and sys.stderr.isatty(),
                    workers=args.workers, executor=executor, retries=args.retries)
    rate = report.pairs_rendered / report.wall_s if report.wall_s > 0 else 0.0
    retried = f", {report.retries} shards retried" if report.retries else ""
    print(f"{report.pairs_rendered} images rendered, {report.pairs_skipped} already done, "
          f"{report.wall_s:.1f} s ({rate:.2f} images/s){retried} → {args.output}")
    if report.nodes:
        print(f"per node ({report.executor} executor):")
        print("\n".join(node_summary_lines(report)))
    return 0
