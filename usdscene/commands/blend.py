"""``usdscene blend DOC -o scene.blend``: a Blender project of the composed scene for camera design."""

from __future__ import annotations

import argparse

NAME = "blend"
HELP = ("write a Blender project of the composed scene with every camera, for interactive camera "
        "design (bring cameras back with 'usdscene export-openlabel scene.blend')")
ORDER = 32


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene blend`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("input", metavar="DOC_OR_STAGE", help="scene document (.json) or composed stage (.usda)")
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="SCENE.blend", help="Blender file to write")
    parser.add_argument("--stage-dir", type=output_path, metavar="DIR",
                        help="where to compose the stage of a document (default: SCENE_stage/ beside the "
                             ".blend; the .blend reads animated transforms from it, keep it)")


def run(args: argparse.Namespace) -> int:
    """``usdscene blend``: write a Blender project of the composed scene; returns the exit status."""
    from pathlib import Path

    from usdscene.errors import RenderError
    from usdscene.render.blend_io import write_blend

    source = Path(args.input)
    if not source.exists():
        raise RenderError(f"input {args.input!r} does not exist", where=args.input)
    blend = Path(args.output)
    if blend.suffix.lower() != ".blend":
        raise RenderError(f"output {args.output!r} must end in .blend", where="--output")
    if source.suffix.lower() == ".json":
        from usdscene.pipeline import compose_document

        stage_dir = Path(args.stage_dir) if args.stage_dir else blend.with_name(blend.stem + "_stage")
        stage = Path(compose_document(source, stage_dir)[1].root_layer)
    else:
        stage = source
    write_blend(stage, blend)
    print(f"{stage} → {blend}")
    return 0
