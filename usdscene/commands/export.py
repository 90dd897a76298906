"""``usdscene export FORMAT... OUT... [--dataset DIR] [--split RULE]``: training sets from
the labels of OUT (the store ``OUT/annotations/``, else ``OUT/annotations.openlabel.json``; the exporters are :mod:`usdscene.dataset.export`). Without
``--split``, the rule the documents carry (``metadata.usdscene.split``) applies."""

from __future__ import annotations

import argparse

from usdscene.commands._arguments import add_label_filter_arguments, add_split_arguments
from usdscene.converters.exports.registry import FORMATS  # pure: names no writer

NAME = "export"
_SUMMARIES = [f.summary for f in FORMATS.values()]
HELP = (f"export annotated outputs as {', '.join(_SUMMARIES[:-1])} or {_SUMMARIES[-1]} (from "
        "the labels of OUT/annotations/), with training splits; several outputs as one "
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
                             "folders with labels (annotations/ or annotations.openlabel.json)")
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
    mot = parser.add_argument_group("mot (MOTChallenge classes: people 1, vehicles 3, other classes left out)")
    mot.add_argument("--mot-class", action="append", default=[], metavar="CLASS=NUMBER",
                     help="give CLASS the MOT class NUMBER (1-13 or its name: bicycle=4, bench=occluder) or "
                          "leave it out (CLASS=none); repeat for more classes")
    mot.add_argument("--mot-static-people", action="store_true",
                     help="people standing still get MOT class 7 (static person), which TrackEval ignores")
    mot.add_argument("--mot-ignore-occluded", action="store_true",
                     help="conf 0 (ignore) for rows of objects without a visible pixel")
    mot.add_argument("--mot-layout", choices=("cameras", "mot17", "mot20"), default="cameras",
                     help="mot/<camera>/ (default), or a TrackEval benchmark tree mot/MOT17-train/MOT17-01/ ... "
                          "with seqmaps/")
    parser.add_argument("--multiview-flavour", choices=("free", "wildtrack", "multiviewx"), default="free",
                        help="multiview: camera-named files (free, default), or the layouts MVDet reads: "
                             "wildtrack (C1..Cn, intr_CVLab<k>.xml, centimetres) or multiviewx (C1..Cn, "
                             "intr_Camera<k>.xml, metres); at most 9 cameras")
    grid = parser.add_argument_group("multiview ground grid (default: 2.5 cm cells over the positions + 1 m)")
    grid.add_argument("--grid-origin", nargs=2, type=float, metavar=("X", "Y"),
                      help="world metres of position 0")
    grid.add_argument("--grid-cell", type=float, metavar="M", help="grid spacing in metres")
    grid.add_argument("--grid-size", nargs=2, type=int, metavar=("NX", "NY"), help="grid points along x and y")
    aic = parser.add_argument_group("aicity (AI City Challenge Track 1 scene)")
    aic.add_argument("--edition", choices=("2025", "2024"), default="2025", help="layout edition (default 2025)")
    aic.add_argument("--aic-class", action="append", default=[], metavar="CLASS=AIC_CLASS",
                     help="map a usdscene class to an AIC class (Person, Forklift, NovaCarter, Transporter, "
                          "FourierGR1T2, AgilityDigit); default: person classes are Person, others left out")
    aic.add_argument("--aic-scene", default="Scene_000", metavar="NAME", help="scene folder name (default Scene_000)")
    aic.add_argument("--aic-scene-id", type=int, default=0, metavar="N", help="scene id of track1.txt (default 0)")
    aic.add_argument("--map-m-per-px", type=float, default=0.05, metavar="M",
                     help="map.png scale in metres per pixel (default 0.05)")
    aic.add_argument("--map-bounds", nargs=4, type=float, metavar=("X0", "Y0", "X1", "Y1"),
                     help="world metres the map covers (default: cameras and positions + 2 m)")
    aic.add_argument("--map-samples", type=int, metavar="N", help="samples per pixel of the map render")
    aic.add_argument("--map-cut-m", type=float, default=2.5, metavar="Z",
                     help="the map shows what lies below Z metres (default 2.5: no roofs or ceilings)")
    aic.add_argument("--no-map", action="store_true", help="do not render map.png")
    aic.add_argument("--no-videos", action="store_true", help="do not write the videos")


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
    aicity = None
    if "aicity" in args.format:
        from usdscene.converters.exports.aicity import AicOptions

        pairs = {}
        for item in args.aic_class:
            name, sep, aic = item.partition("=")
            if not sep or not name or not aic:
                raise OutputError([Problem("--aic-class", f"{item!r} is not CLASS=AIC_CLASS")])
            pairs[name] = aic
        aicity = AicOptions(edition=args.edition, class_map=pairs, scene=args.aic_scene, scene_id=args.aic_scene_id,
                            map_m_per_px=args.map_m_per_px,
                            map_bounds_m=tuple(args.map_bounds) if args.map_bounds else None)
    if args.dataset is None:
        written = export_formats(args.outputs[0], args.format,
                                 ExportOptions(min_roi_px=args.min_roi_px, grid=grid, mot_class_map=tuple(args.mot_class),
                                               mot_static_people=args.mot_static_people,
                                               mot_ignore_occluded=args.mot_ignore_occluded, mot_layout=args.mot_layout,
                                               multiview_flavour=args.multiview_flavour, aicity=aicity,
                                               aicity_map=not args.no_map, aicity_videos=not args.no_videos,
                                               aicity_map_samples=args.map_samples, aicity_map_cut_m=args.map_cut_m,
                                               **options))
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
