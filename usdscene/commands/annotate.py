"""``usdscene annotate OUT``: instance masks of a rendered output → ``OUT/annotations.openlabel.json``
(the labelling itself is :mod:`usdscene.dataset.annotation`)."""

from __future__ import annotations

import argparse
import sys

NAME = "annotate"
HELP = ("labels from the rendered instance masks (boxes, polygons, amodal boxes, visibility) "
        "written into OUT/annotations.openlabel.json")
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
    target, annotations = write_annotations(
        out, document_path=args.document, epsilon_px=args.epsilon,
        min_visible_fraction=args.min_visibility, amodal=not args.no_amodal,
        progress=not args.no_progress and sys.stderr.isatty())
    labels = sum(1 for image in annotations for obj in image.objects if obj.visible)
    hidden = sum(1 for image in annotations for obj in image.objects if not obj.visible)
    print(f"{target}: {len(annotations.images)} images, {labels} visible labels, "
          f"{hidden} fully occluded (amodal only)")
    return 0
