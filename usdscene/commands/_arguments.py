"""Command-line arguments and output lines shared by several sub-commands (not a sub-command
itself: the leading underscore keeps it out of the command discovery)."""

from __future__ import annotations

import argparse


def add_document_check_arguments(parser: argparse.ArgumentParser) -> None:
    """``--schema`` and ``--no-catalog``, shared by ``validate`` and ``convert``."""
    parser.add_argument(
        "--schema", metavar="PATH",
        help="official OpenLABEL 1.0.0 JSON schema file to validate against as well; default: "
             "$USDSCENE_OPENLABEL_SCHEMA, else the copy shipped by the uai-openlabel package. "
             "Without any, only usdscene's own checks run (they cover intrinsics, poses, "
             "intervals, uids and the usdscene vocabulary, but not every schema rule)")
    parser.add_argument(
        "--no-catalog", action="store_true",
        help="do not check object classes, place names and relations against the asset catalog "
             "(shipped library + metadata.usdscene.asset_paths)")


def validate_from_arguments(args: argparse.Namespace):
    """:func:`usdscene.validation.validate_document` with the choices of
    :func:`add_document_check_arguments` (and ``args.document``)."""
    from usdscene.validation import DEFAULT_SCHEMA, validate_document

    return validate_document(args.document, schema=args.schema or DEFAULT_SCHEMA,
                             use_catalog=not args.no_catalog)


def parse_frames(text: str | None) -> list[int] | None:
    """``--frames``: ``"A:B"`` → [A..B] (closed), ``"N"`` → [N], ``"N,M"`` → [N, M]; None → None.

    Raises:
        ValueError: naming the bad text.
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


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--executor``, ``--ray-address``, ``--task-cpus``, ``--retries`` (shared with ``usdscene run``)."""
    parser.add_argument("--executor", choices=("local", "ray"), default="local",
                        help="where shards run: local worker processes (default) or Ray tasks "
                             "(pip install 'usdscene[ray]')")
    parser.add_argument("--ray-address", metavar="ADDRESS",
                        help="Ray cluster to use (auto, HOST:6379 or ray://HOST:10001); default: start a "
                             "local Ray runtime")
    parser.add_argument("--task-cpus", type=positive_int, default=1, metavar="N",
                        help="CPUs per Ray task = Cycles threads of its worker (default 1)")
    parser.add_argument("--retries", type=non_negative_int, default=3, metavar="N",
                        help="times a shard whose worker died (signal, OOM killer, lost node) is run "
                             "again for its unfinished images (default 3)")


def executor_for(args: argparse.Namespace):
    """The executor the arguments ask for (not yet entered); the numbers are checked by their
    argparse types, the combination by :func:`usdscene.render.executors.make_executor`.

    Raises:
        RenderError: a bad combination (``--ray-address`` without ``--executor ray``), or Ray
            is not installed.
    """
    from usdscene.render.executors import make_executor

    return make_executor(args.executor, workers=args.workers, ray_address=args.ray_address,
                         task_cpus=args.task_cpus)


def _whole_number(text: str, minimum: int, meaning: str) -> int:
    """``text`` as a whole number >= ``minimum``.

    Raises:
        argparse.ArgumentTypeError: naming the bad text (argparse exits 2 with it).
    """
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{text!r} is too small; {meaning}")
    return value


def non_negative_int(text: str) -> int:
    """argparse type of seeds (numpy seeds are unsigned) and counts that may be 0."""
    return _whole_number(text, 0, "expected a whole number >= 0")


def positive_int(text: str) -> int:
    """argparse type of counts (``--frames N``): a whole number >= 1."""
    return _whole_number(text, 1, "expected a positive whole number")


def output_path(text: str) -> str:
    """argparse type of output options (``-o``): any path but the empty one, which would
    silently mean the current folder, and the file-system root, which would scatter outputs
    (``stage/``, ``images/``) over the top of the disk.

    Raises:
        argparse.ArgumentTypeError: for an empty or blank path or the root (argparse exits 2).
    """
    import os

    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r} is an empty path; name a file or folder")
    resolved = os.path.realpath(text)
    if os.path.dirname(resolved) == resolved:
        raise argparse.ArgumentTypeError(f"{text!r} is the root of the file system; name a folder below it")
    return text


def split_rule(text: str):
    """argparse type of ``--split``: a :class:`usdscene.document.splits.SplitRule`.

    Raises:
        argparse.ArgumentTypeError: every problem of the rule (argparse exits 2 with it).
    """
    from usdscene.errors import DocumentError
    from usdscene.document.splits import parse_split

    try:
        return parse_split(text)
    except DocumentError as exc:
        raise argparse.ArgumentTypeError("; ".join(p.message for p in exc.problems)) from None


def add_split_arguments(parser: argparse.ArgumentParser) -> None:
    """``--split`` and ``--split-seed``, shared by ``export``, ``run`` and ``generate``."""
    parser.add_argument(
        "--split", type=split_rule, metavar="RULE",
        help="training splits for COCO and YOLO: seeded fractions grouped by frame "
             "(train=0.8,val=0.1,test=0.1), closed frame ranges (frames:train=0:399,val=400:449), "
             "cameras (cameras:val=cam_01,cam_02) or output folders (documents:val=out_b); "
             "images a listing rule leaves unnamed go to train unless train is listed")
    parser.add_argument("--split-seed", type=non_negative_int, default=0, metavar="N",
                        help="seed of a fraction split (default 0)")


def add_label_filter_arguments(parser: argparse.ArgumentParser) -> None:
    """``--min-pixels``, ``--min-visible``, ``--coco-rle-below`` (shared by ``export`` and ``run``)."""
    parser.add_argument("--min-pixels", type=non_negative_int, default=0, metavar="N",
                        help="COCO/YOLO: leave out labels of fewer than N visible pixels (default 0: keep all)")
    parser.add_argument("--min-visible", type=fraction, default=0.0, metavar="F",
                        help="COCO/YOLO: leave out labels whose visible fraction is below F, 0..1 "
                             "(default 0: keep all)")
    parser.add_argument("--coco-rle-below", type=non_negative_int, default=0, metavar="N",
                        help="COCO: objects of fewer than N visible pixels get an RLE segmentation "
                             "instead of polygons (default 0: polygons only)")


def label_filter_options(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`usdscene.dataset.export.export_formats` for the choices of
    :func:`add_label_filter_arguments`."""
    return {"min_pixels": args.min_pixels, "min_visible_fraction": args.min_visible,
            "rle_below_px": args.coco_rle_below}


def fraction(text: str) -> float:
    """argparse type of fractions (``--min-visible``, ``--occupancy``): a number in [0, 1].

    Raises:
        argparse.ArgumentTypeError: naming the bad text (argparse exits 2 with it).
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r} is not between 0 and 1")
    return value
