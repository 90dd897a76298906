"""``usdscene report OUT [-o DIR]``: the browsable report of an output folder,
``OUT/report/index.html`` (or ``DIR/index.html``), built by :mod:`usdscene.report`.

The page opens from the file system (no server, no network). On a half-finished run it shows
what is there and says so; on a folder without annotations, labels or images it fails in one line.
"""

from __future__ import annotations

import argparse

NAME = "report"
HELP = ("a static web page to look through an output: camera × frame thumbnails, label overlays, "
        "filters, counts (OUT/report/index.html; opens from the file system)")
ORDER = 45


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene report`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("output", metavar="OUT", help="output folder of usdscene run (or render + annotate)")
    parser.add_argument("-o", "--report", type=output_path, metavar="DIR",
                        help="where to write the report (default OUT/report)")
    parser.add_argument("--document", metavar="DOC",
                        help="the run's scene document, for the balance chart of a generated document "
                             "and the coverage map of a camera plan (default: the one the stage records)")


def run(args: argparse.Namespace) -> int:
    """``usdscene report``: write the browsable report of an output folder; returns the exit status."""
    from pathlib import Path

    from usdscene.design.camera_design import plan_picture_for
    from usdscene.errors import DocumentError
    from usdscene.dataset.report import build_report, run_document

    if args.document is not None and not Path(args.document).is_file():
        raise DocumentError(f"scene document {args.document!r} does not exist", where="--document")
    document = Path(args.document) if args.document else run_document(args.output)
    summary = build_report(args.output, args.report, document=document,
                           coverage_map=plan_picture_for(document) if document is not None else None)
    print(f"usdscene report: {summary.index} ({summary.note()}; {summary.seconds:.1f} s)")
    return 0
