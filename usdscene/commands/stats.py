"""``usdscene stats OUT`` / ``usdscene stats DOC``: what the labels of an output contain, or
what a scene document will hold.

Given a scene document (a file) instead of an output folder, it prints the balance report of
:func:`usdscene.generate.balance.balance_report` (instance-frames per class, class × relation,
place kinds) and draws it at ``DOC.stats.png`` (or ``--chart``).

Reads the annotations of OUT (the store ``OUT/annotations/``, read frame range by frame
range, or ``OUT/annotations.openlabel.json``; :func:`usdscene.converters.openlabel.store.open_annotations`) and prints per-class and per-camera counts and the
histogram of visible fractions as tables, the cross-camera summary (object-frames seen by 0, 1,
2, ... cameras; per class the median number of cameras, the median best px/m and the best DORI
class), and draws the same as a PNG chart at ``OUT/stats.png`` (or ``--chart``); the counting and
drawing are :mod:`usdscene.dataset.statistics`.
"""

from __future__ import annotations

import argparse

NAME = "stats"
HELP = ("per-class and per-camera label counts, the visibility histogram and the cross-camera "
        "summary (table + PNG chart)")
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene stats`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("output", metavar="OUT|DOC",
                        help="output folder with annotations.openlabel.json, or a scene document")
    parser.add_argument("--chart", type=output_path, metavar="PNG",
                        help="where to write the chart (default OUT/stats.png, or DOC.stats.png)")


def _document_stats(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rich.console import Console
    from rich.table import Table

    from usdscene.scene.catalog import load_catalog
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.generate.balance import balance_report
    from usdscene.files import write_png_atomic
    from usdscene.dataset.statistics import draw_balance_chart

    path = Path(args.output)
    scene = read_openlabel(path)
    catalog = load_catalog(scene.asset_paths, base_dir=path.resolve().parent)
    report = balance_report(scene, catalog)
    console = Console()
    relations = list(report["relations"])
    table = Table(title=f"{path.name}: {report['frames']} frames, {report['cameras']} cameras, "
                        f"{report['images']} images, {report['instance_frames']} instance-frames")
    for column in ("class", "objects", "instance-frames", *relations):
        table.add_column(column, justify="left" if column == "class" else "right")
    for name, c in report["classes"].items():
        row = report["class_relation"][name]
        table.add_row(name, str(c["objects"]), str(c["instance_frames"]), *(str(row.get(r, 0)) for r in relations))
    console.print(table)
    table = Table(title=f"place kinds ({len(report['places'])} places used)")
    table.add_column("kind")
    table.add_column("instance-frames", justify="right")
    for kind, count in report["place_kinds"].items():
        table.add_row(kind, str(count))
    console.print(table)
    chart = write_png_atomic(Path(args.chart) if args.chart else path.with_name(path.name + ".stats.png"),
                        draw_balance_chart(report))
    console.print(f"chart: {chart}")
    return 0


def run(args: argparse.Namespace) -> int:
    """``usdscene stats``: print the label statistics of an output or a document; returns the exit status."""
    from pathlib import Path

    from rich.console import Console
    from rich.table import Table

    from usdscene.document import output_layout as layout
    from usdscene.converters.openlabel.store import open_annotations
    from usdscene.files import write_png_atomic
    from usdscene.dataset.statistics import HISTOGRAM_BINS, dori_text, draw_chart, label_statistics

    out = Path(args.output)
    if out.is_file():
        return _document_stats(args)
    stats = label_statistics(open_annotations(out))
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
    cross = stats["cross_camera"]
    if cross["object_frames"]:
        table = Table(title="cross-camera", caption=f"{cross['object_frames']} object-frames")
        table.add_column("seen by")
        table.add_column("object-frames", justify="right")
        for n, count in cross["by_camera_count"].items():
            table.add_row(f"{n} camera{'s' * (n != 1)}", str(count))
        console.print(table)
        from usdscene.labels.cross_camera import ANNOTATION_DORI_FILE
        from usdscene.labels.pixel_density import table_standard

        table = Table(title="cross-camera per class",
                      caption=f"DORI classes of {table_standard(ANNOTATION_DORI_FILE)} (the annotations' table)")
        for column in ("class", "object-frames", "unseen", "median cameras", "median best px/m", "best DORI"):
            table.add_column(column, justify="left" if column in ("class", "best DORI") else "right")
        for name, c in cross["classes"].items():
            density = "-" if c["median_best_px_per_m"] is None else f"{c['median_best_px_per_m']:.1f}"
            table.add_row(name, str(c["object_frames"]), str(c["unseen"]), f"{c['median_cameras']:g}",
                          density, dori_text(c["best_dori"]))
        console.print(table)
    chart = write_png_atomic(Path(args.chart) if args.chart else out / "stats.png", draw_chart(stats))
    console.print(f"chart: {chart}")
    return 0
