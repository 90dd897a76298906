"""``usdscene preview DOC_OR_STAGE -o sheet.png``: a fast contact sheet of every camera view."""

from __future__ import annotations

import argparse

NAME = "preview"
HELP = "render a fast low-sample contact sheet of all camera views (one PNG, camera names on the tiles)"
ORDER = 31


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="DOC_OR_STAGE", help="scene document (.json) or composed stage (.usda)")
    parser.add_argument("-o", "--output", required=True, metavar="SHEET.png", help="contact sheet PNG")
    parser.add_argument("--frame", type=int, help="frame to show (default: the first)")
    parser.add_argument("--samples", type=int, default=2, help="samples per pixel (default 2)")
    parser.add_argument("--tile-width", type=int, default=320, metavar="PX",
                        help="width of each tile in pixels (default 320)")
    parser.add_argument("--columns", type=int, default=0, help="tiles per row (default: about square)")


def contact_sheet(tiles: list[tuple[str, "object"]], tile_width: int, columns: int = 0):
    """Tile labelled images into one sheet.

    Args:
        tiles: (name, (H, W, 3) uint8 BGR image) in display order.
        tile_width: tile width in pixels (images are resized keeping their aspect).
        columns: tiles per row; 0 = ceil(sqrt(n)).

    Returns:
        (H, W, 3) uint8 BGR sheet.
    """
    import math

    import cv2
    import numpy as np

    n = len(tiles)
    columns = columns or max(1, math.ceil(math.sqrt(n)))
    rows = math.ceil(n / columns)
    resized = []
    for name, image in tiles:
        h, w = image.shape[:2]
        th = max(1, round(h * tile_width / w))
        resized.append((name, cv2.resize(image, (tile_width, th), interpolation=cv2.INTER_AREA)))
    tile_h = max(img.shape[0] for _, img in resized) + 22
    pad = 4
    sheet = np.full((rows * (tile_h + pad) + pad, columns * (tile_width + pad) + pad, 3), 32, np.uint8)
    for i, (name, img) in enumerate(resized):
        r, c = divmod(i, columns)
        y, x = pad + r * (tile_h + pad), pad + c * (tile_width + pad)
        sheet[y:y + img.shape[0], x:x + tile_width] = img
        cv2.putText(sheet, name, (x + 4, y + tile_h - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return sheet


def run(args: argparse.Namespace) -> int:
    import sys
    import tempfile
    from pathlib import Path

    import cv2

    from usdscene import layout
    from usdscene.commands.render import stage_for_input
    from usdscene.errors import RenderError
    from usdscene.files import write_bytes_atomic
    from usdscene.render.driver import render
    from usdscene.render.stage_reader import read_stage_plan

    if not Path(args.input).exists():
        raise RenderError(f"input {args.input!r} does not exist", where=args.input)
    with tempfile.TemporaryDirectory(prefix="usdscene-preview-") as tmp:
        stage = stage_for_input(args.input, tmp)
        plan = read_stage_plan(stage)
        frame = plan.frame_start if args.frame is None else args.frame
        widest = max((c.intrinsics.width_px for c in plan.cameras), default=args.tile_width)
        scale = min(1.0, args.tile_width / widest)
        render(stage, Path(tmp) / "out", frames=[frame],
               settings_override={"samples": args.samples, "denoise": False, "resolution_scale": scale},
               progress=sys.stderr.isatty())
        tiles = [(c.name, cv2.imread(str(layout.image_path(Path(tmp) / "out", c.name, frame))))
                 for c in plan.cameras]
    sheet = contact_sheet(tiles, args.tile_width, args.columns)
    ok, png = cv2.imencode(".png", sheet)
    write_bytes_atomic(args.output, png.tobytes())
    print(f"{len(tiles)} camera views of frame {frame} → {args.output}")
    return 0
