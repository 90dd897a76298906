"""``usdscene assets``: list the asset catalog, add your own asset, rebuild the shipped library.

    usdscene assets list [--catalog DIR ...] [--no-default]
    usdscene assets add FILE --class NAME [--catalog DIR] [--kind object] [--up-axis Y|Z]
                        [--unit-scale M] [--description TEXT] [--replace]
    usdscene assets build [--out DIR] [--rows N]
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "assets"
HELP = "list the asset catalog, add your own asset (OBJ/GLB/PLY/STL/USD/.blend), rebuild the library"
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="assets_command", metavar="ACTION")
    sub.required = True
    p_list = sub.add_parser("list", help="print the catalog as a table")
    p_list.add_argument("--catalog", action="append", default=[], metavar="DIR",
                        help="extra catalog folder (repeatable; read after the shipped library)")
    p_list.add_argument("--no-default", action="store_true", help="do not read the shipped library")

    p_add = sub.add_parser("add", help="convert or reference a file and register it as an asset class")
    p_add.add_argument("file", type=Path, help="OBJ, GLB/glTF, PLY, STL, USD file or Blender project (.blend)")
    p_add.add_argument("--class", dest="class_name", required=True, help="class name (lower_snake_case)")
    p_add.add_argument("--catalog", type=Path, default=None, metavar="DIR",
                       help="catalog folder to register into (default: the shipped library)")
    p_add.add_argument("--kind", default="object", choices=("object", "passenger", "environment", "person"),
                       help="person: a rigged person (USD UsdSkel or glTF skin); checked and refused with the "
                            "reason (posing one's own rig is not supported yet)")
    p_add.add_argument("--up-axis", choices=("Y", "Z"), default=None,
                       help="up axis of the file (default: Y for OBJ/glTF, Z for STL/PLY, USD: its upAxis)")
    p_add.add_argument("--unit-scale", type=float, default=None, metavar="M",
                       help="metres per file unit, e.g. 0.001 for millimetres (default 1; USD: metersPerUnit)")
    p_add.add_argument("--description", default="", help="catalog description")
    p_add.add_argument("--replace", action="store_true", help="replace an existing class of that name")

    p_build = sub.add_parser("build", help="regenerate the procedural library byte-identically")
    p_build.add_argument("--out", type=Path, default=None, help="output folder (default: the shipped library)")
    p_build.add_argument("--rows", type=int, default=20, help="seat rows of the cabin (default 20)")


def run(args: argparse.Namespace) -> int:
    if args.assets_command == "list":
        return _list(args)
    if args.assets_command == "add":
        return _add(args)
    return _build(args)


def _fmt_size(size: tuple[float, float, float]) -> str:
    return " x ".join(f"{v:.2f}" for v in size)


def _list(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from usdscene.scene.catalog import load_catalog
    from usdscene.shipped import default_asset_folder

    catalog = load_catalog(args.catalog, include_default=not args.no_default)
    table = Table(title="usdscene asset catalog")
    table.add_column("class", no_wrap=True)
    for column in ("kind", "size x*y*z (m)", "variants", "relations", "places", "usd"):
        table.add_column(column, overflow="fold")
    base = default_asset_folder().resolve()
    for name in catalog.classes():
        entry = catalog[name]
        variants = "; ".join(f"{k}: {', '.join(v)}" for k, v in entry.variants.items())
        try:
            usd = str(entry.usd_path.relative_to(base))
        except ValueError:
            usd = str(entry.usd_path)
        table.add_row(name, entry.kind, _fmt_size(entry.size_m), variants, ", ".join(entry.relations),
                      str(len(entry.places)) if entry.places else "", usd)
    Console().print(table)
    return 0


def _add(args: argparse.Namespace) -> int:
    import sys

    from usdscene.assetgen.asset_import import ImportOptions, import_asset
    from usdscene.shipped import default_asset_folder

    catalog = args.catalog if args.catalog is not None else default_asset_folder()
    options = ImportOptions(kind=args.kind, up_axis=args.up_axis, unit_scale_m=args.unit_scale,
                            description=args.description, replace=args.replace)
    entry = import_asset(args.file, args.class_name, catalog, options)
    size = _fmt_size(entry.size_m)
    print(f"registered {entry.class_name} ({entry.kind}, {size} m) -> {entry.usd_path}", file=sys.stderr)
    return 0


def _build(args: argparse.Namespace) -> int:
    import sys

    from usdscene.assetgen.cabin import CabinConfig
    from usdscene.assetgen.library import build_library
    from usdscene.shipped import default_asset_folder

    from usdscene.errors import AssetError

    if not 1 <= args.rows <= 60:
        raise AssetError(f"rows {args.rows} must be between 1 and 60", where="--rows")
    out = args.out if args.out is not None else default_asset_folder()
    paths = build_library(out, CabinConfig(rows=args.rows))
    print(f"wrote {len(paths)} files to {out}", file=sys.stderr)
    return 0
