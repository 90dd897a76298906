"""``usdscene validate DOC``: check a scene document and list every problem at once (the checks
are :mod:`usdscene.validation`)."""

from __future__ import annotations

import argparse
import sys

NAME = "validate"
HELP = "check an OpenLABEL 1.0.0 / VCD 4.3 scene document and list every problem"
ORDER = 10


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene validate`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import add_document_check_arguments

    parser.add_argument("document", help="scene document (.json, root 'openlabel' or 'vcd')")
    add_document_check_arguments(parser)
    parser.epilog = (
        "Exit status: 0 valid, 1 invalid (one 'usdscene: error: <JSON path>: <message>' line per "
        "problem), 2 bad usage.")


def run(args: argparse.Namespace) -> int:
    """``usdscene validate``: check a scene document and list every problem; returns the exit status."""
    from usdscene.commands._arguments import validate_from_arguments

    checked = validate_from_arguments(args)
    scene, schema = checked.scene, checked.schema
    checks = ["usdscene checks"]
    checks.append(f"schema {schema.name}" if schema is not None else "no official schema (use --schema)")
    checks.append("asset catalog" if checked.catalog is not None else "no asset catalog")
    print(f"{args.document}: valid: {len(scene.cameras)} cameras, {len(scene.lights)} lights, "
          f"{len(scene.objects)} objects, {len(scene.places)} places, {len(scene.relations)} relations, "
          f"frames {scene.frame_start}..{scene.frame_end} ({', '.join(checks)})", file=sys.stdout)
    return 0
