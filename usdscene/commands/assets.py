"""``usdscene assets``: list the asset catalog, add your own asset, rebuild the shipped library.

    usdscene assets list [--catalog DIR ...] [--no-default] [--regions]
    usdscene assets remove NAME [--catalog DIR]
    usdscene assets add FILE --class NAME [--catalog DIR] [--kind object] [--up-axis Y|Z]
                        [--unit-scale M] [--description TEXT] [--replace] [--forward-axis AXIS]
                        [--orientations RULE] [--color-material PATH]
    usdscene assets build [--out DIR] [--rows N]
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "assets"
HELP = "list the asset catalog, add your own asset (OBJ/GLB/PLY/STL/USD/.blend), rebuild the library"
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene assets`` arguments and options to ``parser``."""
    sub = parser.add_subparsers(dest="assets_command", metavar="ACTION")
    sub.required = True
    p_list = sub.add_parser("list", help="print the catalog as a table")
    p_list.add_argument("--catalog", action="append", default=[], metavar="DIR",
                        help="extra catalog folder (repeatable; read after the shipped library)")
    p_list.add_argument("--no-default", action="store_true", help="do not read the shipped library")
    p_list.add_argument("--regions", action="store_true",
                        help="list every place region instead (class, place, kind, relation, size, up axis, origin)")

    p_remove = sub.add_parser("remove", help="unregister a class (and delete its imported/ files)")
    p_remove.add_argument("class_name", metavar="NAME", help="class to remove")
    p_remove.add_argument("--catalog", type=Path, default=None, metavar="DIR",
                          help="catalog folder (default: the shipped library, imported classes only)")

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
    p_add.add_argument("--forward-axis", choices=("-Y", "+Y", "+X", "-X"), default="-Y",
                       help="where the file's front faces once Z up; the asset is turned to face -Y (default -Y)")
    p_add.add_argument("--orientations", choices=("upright", "upright_turned", "any"), default="upright_turned",
                       help="how placement may lay the class: upright (as modelled), upright_turned (also a "
                            "quarter turn; default) or any (also on a side when it only fits lying down)")
    p_add.add_argument("--color-material", default=None, metavar="PATH",
                       help="USD files: the material (or shader) under the default prim, e.g. Looks/Paint, whose "
                            "diffuseColor a scene's colour sets (default: Looks/Body/Surface when present, else "
                            "the class is not recoloured)")

    p_build = sub.add_parser("build", help="regenerate the procedural library byte-identically")
    p_build.add_argument("--out", type=Path, default=None, help="output folder (default: the shipped library)")
    p_build.add_argument("--rows", type=int, default=20, help="seat rows of the cabin (default 20)")


def run(args: argparse.Namespace) -> int:
    """``usdscene assets``: list the catalog, add an asset or rebuild the shipped library; returns the exit
    status."""
    if args.assets_command == "list":
        return _list(args)
    if args.assets_command == "add":
        return _add(args)
    if args.assets_command == "remove":
        return _remove(args)
    return _build(args)


def _fmt_size(size: tuple[float, float, float]) -> str:
    return " x ".join(f"{v:.2f}" for v in size)


def _list(args: argparse.Namespace) -> int:
    import sys

    from usdscene.scene.catalog import load_catalog

    catalog = load_catalog(args.catalog, include_default=not args.no_default)
    columns, rows = _region_rows(catalog) if args.regions else _class_rows(catalog)
    if not sys.stdout.isatty():
        # Piped or redirected: one tab-separated line per row, never wrapped, for grep and cut.
        print("\t".join(columns))
        for row in rows:
            print("\t".join(row))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title="usdscene place regions" if args.regions else "usdscene asset catalog")
    table.add_column(columns[0], no_wrap=True)
    for column in columns[1:]:
        table.add_column(column, overflow="fold")
    for row in rows:
        table.add_row(*row)
    Console().print(table)
    return 0


def _class_rows(catalog) -> tuple[list[str], list[list[str]]]:
    from usdscene.shipped import default_asset_folder

    base = default_asset_folder().resolve()
    rows = []
    for name in catalog.classes():
        entry = catalog[name]
        variants = "; ".join(f"{k}: {', '.join(v)}" for k, v in entry.variants.items())
        try:
            usd = str(entry.usd_path.relative_to(base))
        except ValueError:
            usd = str(entry.usd_path)
        rows.append([name, entry.kind, _fmt_size(entry.size_m), variants, ", ".join(entry.relations),
                     str(len(entry.places)) if entry.places else "",
                     "" if entry.kind == "environment" else entry.orientations, usd])
    return ["class", "kind", "size x*y*z (m)", "variants", "relations", "places", "orientations", "usd"], rows


def _region_rows(catalog) -> tuple[list[str], list[list[str]]]:
    """One row per place region: where it is, how big, which way is up (its +Z in the
    environment frame: a region whose up is not +Z was read in the wrong frame)."""
    import numpy as np

    rows = []
    for name in catalog.classes():
        for place_name, place in sorted(catalog[name].places.items()):
            for relation, region in sorted(place.regions.items()):
                matrix = region.pose.as_array()
                up = " ".join(f"{v:+.2f}" for v in matrix[:3, 2])
                origin = " ".join(f"{v:.2f}" for v in matrix[:3, 3])
                yaw = float(np.degrees(np.arctan2(matrix[1, 0], matrix[0, 0])))
                rows.append([name, place_name, place.kind, relation, _fmt_size(region.size_m), up, origin,
                             f"{yaw:.1f}"])
    return ["class", "place", "kind", "relation", "size x*y*z (m)", "up axis", "origin (m)", "yaw (deg)"], rows


def _remove(args: argparse.Namespace) -> int:
    import sys

    from usdscene.assetgen.asset_import import remove_entry
    from usdscene.shipped import default_asset_folder

    catalog = args.catalog if args.catalog is not None else default_asset_folder()
    removed = remove_entry(catalog, args.class_name, imported_only=args.catalog is None)
    print(f"removed {args.class_name} from {catalog}" + (f" (deleted {', '.join(p.name for p in removed)})"
                                                          if removed else ""), file=sys.stderr)
    return 0


def _add(args: argparse.Namespace) -> int:
    import sys

    from usdscene.assetgen.asset_import import ImportOptions, import_asset
    from usdscene.shipped import default_asset_folder

    catalog = args.catalog if args.catalog is not None else default_asset_folder()
    options = ImportOptions(kind=args.kind, up_axis=args.up_axis, unit_scale_m=args.unit_scale,
                            description=args.description, replace=args.replace,
                            forward_axis=args.forward_axis, orientations=args.orientations,
                            color_material=args.color_material)
    entry = import_asset(args.file, args.class_name, catalog, options)
    size = _fmt_size(entry.size_m)
    print(f"registered {entry.class_name} ({entry.kind}, {size} m) -> {entry.usd_path}", file=sys.stderr)
    if entry.places:
        regions = sum(len(place.regions) for place in entry.places.values())
        kinds = sorted({place.kind for place in entry.places.values()})
        print(f"  {len(entry.places)} places ({', '.join(kinds)}), {regions} regions; check their sizes and up "
              f"axes with: usdscene assets list --catalog {catalog} --no-default --regions", file=sys.stderr)
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
