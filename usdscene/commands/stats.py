"""``usdscene stats OUT``: what the labels of an output contain.

Reads ``OUT/annotations.openlabel.json`` and prints per-class and per-camera counts and the
histogram of visible fractions as tables, and draws the same as a PNG chart at
``OUT/stats.png`` (or ``--chart``); the counting and drawing are :mod:`usdscene.statistics`.
"""

from __future__ import annotations

import argparse

NAME = "stats"
HELP = "per-class and per-camera label counts and the visibility histogram (table + PNG chart)"
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("output", metavar="OUT", help="output folder with annotations.openlabel.json")
    parser.add_argument("--chart", metavar="PNG", help="where to write the chart (default OUT/stats.png)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import cv2
    from rich.console import Console
    from rich.table import Table

    from usdscene import layout
    from usdscene.converters.openlabel import load_document
    from usdscene.errors import OutputError
    from usdscene.files import write_bytes_atomic
    from usdscene.statistics import HISTOGRAM_BINS, draw_chart, label_statistics

    out = Path(args.output)
    path = out / layout.ANNOTATIONS_FILE
    if not path.is_file():
        raise OutputError("no annotations; run `usdscene annotate OUT` first", where=str(path))
    stats = label_statistics(load_document(path))
    console = Console()
    table = Table(title=f"classes ({stats['images']} images)")
    for column in ("class", "objects", "labels", "hidden"):
        table.add_column(column, justify="left" if column == "class" else "right")
    for name, c in stats["classes"].items():
        table.add_row(name, str(c["objects"]), str(c["labels"]), str(c["hidden"]))
    console.print(table)
    table = Table(title="cameras")
    for column in ("camera", "images", "labels", "hidden"):
        table.add_column(column, justify="left" if column == "camera" else "right")
    for name, c in stats["cameras"].items():
        table.add_row(name, str(c["images"]), str(c["labels"]), str(c["hidden"]))
    console.print(table)
    table = Table(title="visible fraction")
    table.add_column("range")
    table.add_column("labels", justify="right")
    for k, count in enumerate(stats["visibility"]):
        table.add_row(f"{k / HISTOGRAM_BINS:.1f} – {(k + 1) / HISTOGRAM_BINS:.1f}", str(count))
    if stats["visibility_unknown"]:
        table.add_row("unknown", str(stats["visibility_unknown"]))
    console.print(table)
    chart = Path(args.chart) if args.chart else out / "stats.png"
    ok, encoded = cv2.imencode(".png", draw_chart(stats))
    if not ok:
        raise OutputError("cannot encode the chart", where=str(chart))
    write_bytes_atomic(chart, encoded.tobytes())
    console.print(f"chart: {chart}")
    return 0
