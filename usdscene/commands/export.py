"""``usdscene export FORMAT... OUT... [--dataset DIR] [--split RULE]``: training sets from
``OUT/annotations.openlabel.json`` (the exporters are :mod:`usdscene.dataset.export`). Without
``--split``, the rule the documents carry (``metadata.usdscene.split``) applies."""

from __future__ import annotations

import argparse

from usdscene.commands._arguments import add_label_filter_arguments, add_split_arguments
from usdscene.converters.exports.registry import FORMATS  # pure: names no writer

NAME = "export"
_SUMMARIES = [f.summary for f in FORMATS.values()]
HELP = (f"export annotated outputs as {', '.join(_SUMMARIES[:-1])} or {_SUMMARIES[-1]} (from "
        "OUT/annotations.openlabel.json), with training splits; several outputs as one "
        f"{'/'.join(f.summary for f in FORMATS.values() if f.dataset)} dataset")


class _FormatsThenOutputs(argparse.Action):
    """``coco yolo OUT1 OUT2``: the leading format names, then at least one output folder."""

    def __call__(self, parser, namespace, values, option_string=None):
        count = 0
        while count < len(values) and values[count] in FORMATS:
            count += 1
        if count == 0:
            parser.error(f"argument FORMAT: invalid choice: {values[0]!r} (choose from {', '.join(FORMATS)})")
        if count == len(values):
            parser.error("the following arguments are required: OUT")
        namespace.format, namespace.outputs = values[:count], values[count:]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene export`` arguments and options to ``parser``."""
    parser.add_argument("items", nargs="+", action=_FormatsThenOutputs, metavar="FORMAT|OUT",
                        help=f"one or more formats ({', '.join(FORMATS)}), then one or more output "
                             "folders with annotations.openlabel.json")
    parser.add_argument("--dataset", metavar="DIR",
                        help="write one COCO/YOLO dataset of every OUT into DIR (needed for several OUT); "
                             "default: OUT/exports")
    add_split_arguments(parser)
    parser.add_argument("--assets", nargs="+", default=[], metavar="DIR",
                        help="extra asset catalog folders (classes, place regions)")
    parser.add_argument("--document-classes", action="store_true",
                        help="COCO/YOLO classes from the labelled object types of the document "
                             "instead of the catalog")
    parser.add_argument("--copy-images", action="store_true",
                        help="YOLO: copy images instead of linking them")
    add_label_filter_arguments(parser)
    parser.add_argument("--min-roi-px", type=int, default=8, metavar="PX",
                        help="ROIs: smallest crop side in pixels (default 8)")
    grid = parser.add_argument_group("multiview ground grid (default: 2.5 cm cells over the positions + 1 m)")
    grid.add_argument("--grid-origin", nargs=2, type=float, metavar=("X", "Y"),
                      help="world metres of position 0")
    grid.add_argument("--grid-cell", type=float, metavar="M", help="grid spacing in metres")
    grid.add_argument("--grid-size", nargs=2, type=int, metavar=("NX", "NY"), help="grid points along x and y")


def run(args: argparse.Namespace) -> int:
    """``usdscene export``: write training sets in the requested formats; returns the exit status."""
    from usdscene.commands._arguments import label_filter_options
    from usdscene.errors import OutputError, Problem
    from usdscene.dataset.export import ExportOptions, carried_split, export_dataset, export_formats

    # The command line's rule wins over the one the documents carry.
    split, split_seed = args.split, args.split_seed
    if split is None:
        split, split_seed = carried_split(args.outputs) or (None, 0)
    options = dict(extra_assets=tuple(args.assets or ()), document_classes=args.document_classes,
                   copy_images=args.copy_images, split=split, split_seed=split_seed,
                   **label_filter_options(args))
    if args.dataset is None and len(args.outputs) > 1:
        raise OutputError([Problem("--dataset", f"{len(args.outputs)} output folders make one dataset: "
                                                "name its folder with --dataset DIR")])
    given = [args.grid_origin is not None, args.grid_cell is not None, args.grid_size is not None]
    grid = None
    if any(given):
        if not all(given):
            raise OutputError([Problem("--grid-origin/--grid-cell/--grid-size",
                                       "a ground grid needs all three: --grid-origin X Y --grid-cell M "
                                       "--grid-size NX NY")])
        from usdscene.converters.exports.multiview import GroundGrid

        grid = GroundGrid(tuple(args.grid_origin), args.grid_cell, tuple(args.grid_size))
    if args.dataset is None:
        written = export_formats(args.outputs[0], args.format,
                                 ExportOptions(min_roi_px=args.min_roi_px, grid=grid, **options))
    else:
        for per_output in (name for name, fmt in FORMATS.items() if not fmt.dataset):
            if per_output in args.format:
                raise OutputError([Problem("--dataset", f"{per_output} is exported per output folder; "
                                                        f"export {per_output} without --dataset")])
        written = export_dataset(args.outputs, args.format, args.dataset, ExportOptions(**options))
    for fmt, target in written.items():
        print(f"{fmt}: {target}")
    if split is not None:
        import json
        from pathlib import Path

        folder = Path(args.dataset) if args.dataset else Path(args.outputs[0]) / "exports"
        counts = json.loads((folder / "splits.json").read_text(encoding="utf-8"))["counts"]
        print("splits: " + ", ".join(f"{name} {c['images']} images ({c['frames']} frames)"
                                     for name, c in counts.items()))
    return 0
