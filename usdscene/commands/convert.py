"""``usdscene convert DOC -o OUT``: normalise a scene document to OpenLABEL 1.0.0."""

from __future__ import annotations

import argparse
import sys

NAME = "convert"
HELP = "normalise an OpenLABEL 1.0.0 / VCD 4.3 scene document to usdscene's OpenLABEL 1.0.0 form"
ORDER = 11


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene convert`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import add_document_check_arguments, output_path

    parser.add_argument("document", help="scene document (.json, root 'openlabel' or 'vcd')")
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT",
                        help="output file (written atomically; nothing is written when the input is invalid)")
    add_document_check_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """``usdscene convert``: normalise a scene document to OpenLABEL 1.0.0; returns the exit status."""
    from usdscene.commands._arguments import validate_from_arguments
    from usdscene.converters.openlabel import write_document, write_openlabel

    checked = validate_from_arguments(args)
    scene = checked.scene
    document = write_openlabel(scene)
    path = write_document(args.output, document, schema=checked.schema)
    print(f"{args.document} → {path}: OpenLABEL {document['openlabel']['metadata']['schema_version']}, "
          f"{len(scene.cameras)} cameras, {len(scene.objects)} objects", file=sys.stdout)
    return 0
