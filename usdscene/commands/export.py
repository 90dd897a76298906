"""``usdscene export coco|yolo|rois OUT``: training sets from ``OUT/annotations.openlabel.json``
(the exporters are :mod:`usdscene.export`)."""

from __future__ import annotations

import argparse

from usdscene.export import FORMATS  # a constant; the module imports nothing heavy

NAME = "export"
HELP = "export the annotated output as COCO, YOLO or ROI crops (from OUT/annotations.openlabel.json)"
ORDER = 50


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("format", choices=FORMATS, nargs="+", help="one or more formats")
    parser.add_argument("output", metavar="OUT", help="output folder with annotations.openlabel.json")
    parser.add_argument("--assets", nargs="+", default=[], metavar="DIR",
                        help="extra asset catalog folders (classes, place regions)")
    parser.add_argument("--document-classes", action="store_true",
                        help="COCO/YOLO classes from the labelled object types of the document "
                             "instead of the catalog")
    parser.add_argument("--copy-images", action="store_true",
                        help="YOLO: copy images instead of linking them")
    parser.add_argument("--min-roi-px", type=int, default=8, metavar="PX",
                        help="ROIs: smallest crop side in pixels (default 8)")


def run(args: argparse.Namespace) -> int:
    from usdscene.export import export_formats

    written = export_formats(args.output, args.format, extra_assets=args.assets,
                             document_classes=args.document_classes, copy_images=args.copy_images,
                             min_roi_px=args.min_roi_px)
    for fmt, target in written.items():
        print(f"{fmt}: {target}")
    return 0
