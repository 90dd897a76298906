"""``usdscene annotate OUT``: instance masks of a rendered output → the annotation store
``OUT/annotations/`` and, for small runs, ``OUT/annotations.openlabel.json`` (the labelling
itself is :mod:`usdscene.dataset.annotation`)."""

from __future__ import annotations

import argparse
import sys

NAME = "annotate"
HELP = ("labels from the rendered instance masks (boxes, polygons, amodal boxes, visibility) "
        "written into the store OUT/annotations/ (and OUT/annotations.openlabel.json for small runs)")
ORDER = 40


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene annotate`` arguments and options to ``parser``."""
    parser.add_argument("output", metavar="OUT", help="output folder of a render (stage/, masks/, images/)")
    parser.add_argument("--document", metavar="DOC",
                        help="scene document to add the labels to (default: the stage's source document)")
    parser.add_argument("--epsilon", type=float, default=None, metavar="PX",
                        help="polygon simplification tolerance in pixels (default 0.49: below half a pixel the polygons fill back to exactly the mask; 0 = every corner of the pixel outline)")
    parser.add_argument("--min-visibility", type=float, default=0.0, metavar="F",
                        help="drop labels whose visible fraction is below F (0..1, default 0)")
    parser.add_argument("--no-amodal", action="store_true",
                        help="skip amodal boxes and visible fractions (no stage geometry needed)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--frames-per-shard", type=int, default=None, metavar="N",
                        help="frames per file of the annotation store OUT/annotations/frames/ (default 100)")


def run(args: argparse.Namespace) -> int:
    """``usdscene annotate``: write ``OUT/annotations.openlabel.json`` from the instance masks of a rendered
    output; returns the exit status."""
    from pathlib import Path

    from usdscene.dataset.annotation import write_annotations
    from usdscene.errors import OutputError

    out = Path(args.output)
    if not out.is_dir():
        raise OutputError(f"output folder {args.output!r} does not exist", where=args.output)
    if not 0.0 <= args.min_visibility <= 1.0:
        raise OutputError(f"--min-visibility {args.min_visibility} is outside [0, 1]", where="--min-visibility")
    if args.epsilon is not None and args.epsilon < 0:
        raise OutputError(f"--epsilon {args.epsilon} is negative", where="--epsilon")
    if args.frames_per_shard is not None and args.frames_per_shard < 1:
        raise OutputError(f"--frames-per-shard {args.frames_per_shard} is below 1", where="--frames-per-shard")
    _, summary = write_annotations(
        out, document_path=args.document, epsilon_px=args.epsilon,
        min_visible_fraction=args.min_visibility, amodal=not args.no_amodal,
        progress=not args.no_progress and sys.stderr.isatty(), frames_per_shard=args.frames_per_shard)
    print(f"{summary.store}/: {len(summary.pairs)} images, {sum(summary.visible_per_class.values())} visible "
          f"labels, {summary.hidden} fully occluded (amodal only)")
    if summary.single_document is not None:
        print(f"{summary.single_document}: the same labels in one OpenLABEL document")
    else:
        print(f"one OpenLABEL document: usdscene export-openlabel {out} -o FILE")
    return 0
