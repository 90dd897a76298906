"""``usdscene preview DOC_OR_STAGE -o sheet.png``: a fast contact sheet of every camera view."""

from __future__ import annotations

import argparse

NAME = "preview"
HELP = "render a fast low-sample contact sheet of all camera views (one PNG, camera names on the tiles)"
ORDER = 31


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene preview`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("input", metavar="DOC_OR_STAGE", help="scene document (.json) or composed stage (.usda)")
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="SHEET.png", help="contact sheet PNG")
    parser.add_argument("--frame", type=int, help="frame to show (default: the first)")
    parser.add_argument("--samples", type=int, default=2, help="samples per pixel (default 2)")
    parser.add_argument("--tile-width", type=int, default=320, metavar="PX",
                        help="width of each tile in pixels (default 320)")
    parser.add_argument("--columns", type=int, default=0, help="tiles per row (default: about square)")


def run(args: argparse.Namespace) -> int:
    """``usdscene preview``: write the contact sheet of every camera view; returns the exit status."""
    import sys
    import tempfile
    from pathlib import Path

    import cv2

    from usdscene.document import output_layout as layout
    from usdscene.dataset.contact_sheet import contact_sheet
    from usdscene.pipeline import stage_for_input
    from usdscene.errors import RenderError
    from usdscene.files import prepare_output_file, write_png_atomic
    from usdscene.render.driver import RenderOptions, render
    from usdscene.render.stage_reader import read_stage_plan

    if not Path(args.input).exists():
        raise RenderError(f"input {args.input!r} does not exist", where=args.input)
    prepare_output_file(args.output, what="contact sheet")
    with tempfile.TemporaryDirectory(prefix="usdscene-preview-") as tmp:
        stage = stage_for_input(args.input, tmp)
        plan = read_stage_plan(stage)
        frame = plan.frame_start if args.frame is None else args.frame
        widest = max((c.intrinsics.width_px for c in plan.cameras), default=args.tile_width)
        scale = min(1.0, args.tile_width / widest)
        render(stage, Path(tmp) / "out", RenderOptions(
            frames=[frame], settings_override={"samples": args.samples, "denoise": False, "resolution_scale": scale},
            progress=sys.stderr.isatty()))
        tiles = [(c.name, cv2.imread(str(layout.image_path(Path(tmp) / "out", c.name, frame))))
                 for c in plan.cameras]
    sheet = contact_sheet(tiles, args.tile_width, args.columns)
    write_png_atomic(args.output, sheet)
    print(f"{len(tiles)} camera views of frame {frame} → {args.output}")
    return 0
