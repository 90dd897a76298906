"""``usdscene validate DOC``: check a scene document and list every problem at once."""

from __future__ import annotations

import argparse
import logging
import sys

NAME = "validate"
HELP = "check an OpenLABEL 1.0.0 / VCD 4.3 scene document and list every problem"
ORDER = 10

log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("document", help="scene document (.json, root 'openlabel' or 'vcd')")
    add_common_arguments(parser)
    parser.epilog = (
        "Exit status: 0 valid, 1 invalid (one 'usdscene: error: <JSON path>: <message>' line per "
        "problem), 2 bad usage.")


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """Options shared by ``validate`` and ``convert``."""
    parser.add_argument(
        "--schema", metavar="PATH",
        help="official OpenLABEL 1.0.0 JSON schema file to validate against as well; default: "
             "$USDSCENE_OPENLABEL_SCHEMA, else the copy shipped by the uai-openlabel package. "
             "Without any, only usdscene's own checks run (they cover intrinsics, poses, "
             "intervals, uids and the usdscene vocabulary, but not every schema rule)")
    parser.add_argument(
        "--no-catalog", action="store_true",
        help="do not check object classes, place names and relations against the asset catalog "
             "(shipped library + metadata.usdscene.asset_paths)")


def schema_path(args: argparse.Namespace):
    """The schema chosen by ``--schema``, the environment or the installed package, or None."""
    from pathlib import Path

    from usdscene.converters.openlabel import default_schema_path

    return Path(args.schema) if args.schema else default_schema_path()


def check_document(args: argparse.Namespace):
    """:func:`check_document_file` with the command line's choices."""
    return check_document_file(args.document, schema_path(args), use_catalog=not args.no_catalog)


def check_document_file(path, schema, *, use_catalog: bool = True):
    """Read a scene document with every check that applies: the official schema (when
    ``schema`` is a path), usdscene's own checks, and the asset catalog (classes, places).

    The file is parsed once. ``usdscene validate`` and ``usdscene run`` both check with this.

    Returns:
        (scene, schema_used, catalog_used); catalog_used is None when no catalog was found.

    Raises:
        DocumentError: all problems (schema + usdscene checks) at once.
    """
    from pathlib import Path

    from usdscene.converters.openlabel import load_with_provenance, read_loaded, schema_problems
    from usdscene.errors import DocumentError

    # bad JSON stops here with line and column; the file is parsed once
    document, provenance = load_with_provenance(path)
    problems = []
    if schema is not None:
        problems.extend(schema_problems(document, schema))
    catalog = _catalog_for(document, Path(path).parent) if use_catalog else None
    try:
        scene = read_loaded(document, provenance, catalog=catalog)
    except DocumentError as exc:
        problems.extend(exc.problems)
        scene = None
    if problems:
        raise DocumentError(problems)
    return scene, schema, catalog


def _catalog_for(document: dict, base_dir):
    """The asset catalog the document would be composed with, or None (with a warning) when
    there is none to check against."""
    from usdscene.catalog import CATALOG_FILE, default_asset_folder, load_catalog

    block = document["openlabel"].get("metadata", {})
    block = block.get("usdscene", {}) if isinstance(block, dict) else {}
    extra = block.get("asset_paths", []) if isinstance(block, dict) else []
    extra = [p for p in extra if isinstance(p, str)] if isinstance(extra, list) else []
    include_default = (default_asset_folder() / CATALOG_FILE).is_file()
    if not include_default and not extra:
        log.warning("no asset catalog found (%s); object classes and places are not checked",
                    default_asset_folder() / CATALOG_FILE)
        return None
    return load_catalog(extra, include_default=include_default, base_dir=base_dir)


def run(args: argparse.Namespace) -> int:
    scene, schema, catalog = check_document(args)
    checks = ["usdscene checks"]
    checks.append(f"schema {schema.name}" if schema is not None else "no official schema (use --schema)")
    checks.append("asset catalog" if catalog is not None else "no asset catalog")
    print(f"{args.document}: valid: {len(scene.cameras)} cameras, {len(scene.lights)} lights, "
          f"{len(scene.objects)} objects, {len(scene.places)} places, {len(scene.relations)} relations, "
          f"frames {scene.frame_start}..{scene.frame_end} ({', '.join(checks)})", file=sys.stdout)
    return 0
