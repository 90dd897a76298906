"""``usdscene compose DOC -o OUT``: compose the layered USD stage of a scene document."""

from __future__ import annotations

import argparse

NAME = "compose"
HELP = "compose the layered USD stage (OUT/stage/scene.usda) of an OpenLABEL scene document"
ORDER = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene compose`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import non_negative_int, output_path

    parser.add_argument("document", metavar="DOC", help="OpenLABEL/VCD scene document (.json)")
    parser.add_argument("-o", "--out", type=output_path, metavar="OUT", required=True,
                        help="output folder; the stage is written to OUT/stage/")
    parser.add_argument("--seed", type=non_negative_int, default=None,
                        help="override the document's random seed (metadata.usdscene.seed)")


def run(args: argparse.Namespace) -> int:
    """``usdscene compose``: compose the layered USD stage of a scene document; returns the exit status."""
    from pathlib import Path

    from rich.console import Console

    from usdscene.document.output_layout import STAGE_DIR
    from usdscene.pipeline import compose_document

    scene, result = compose_document(args.document, Path(args.out) / STAGE_DIR, seed=args.seed)
    console = Console(highlight=False, soft_wrap=True)
    console.print(f"composed {result.root_layer}")
    console.print("  layers:  " + ", ".join(p.name for p in result.layers))
    console.print(f"  frames:  {result.frame_count} ({result.frame_start}..{result.frame_end}), seed {scene.seed}")
    classes = ", ".join(f"{name} {count}" for name, count in result.objects_per_class.items()) or "none"
    console.print(f"  objects: {sum(result.objects_per_class.values())} ({classes})")
    console.print(f"  cameras: {len(scene.cameras)}, lights: {len(scene.lights)}")
    return 0
