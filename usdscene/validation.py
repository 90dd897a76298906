"""Check a scene document with every check that applies, and read it.

The checks, all reported at once: the official OpenLABEL 1.0.0 schema, usdscene's own checks of
what the schema misses (intrinsics, poses, intervals, uids, the usdscene vocabulary) and the
asset catalog (object classes, place names, relations). ``usdscene validate``, ``usdscene
convert`` and ``usdscene run`` all check with :func:`validate_document`.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from usdscene.bulk import paused_collection

if TYPE_CHECKING:
    from usdscene.scene.catalog import Catalog
    from usdscene.document.model import SceneSpec

log = logging.getLogger(__name__)

DEFAULT_SCHEMA = "default"
"""``schema=DEFAULT_SCHEMA``: ``$USDSCENE_OPENLABEL_SCHEMA``, else the official schema file
shipped by the ``uai-openlabel`` package."""


@dataclass(frozen=True)
class ValidatedDocument:
    """A scene document that passed every check.

    Attributes:
        scene: the document read into the scene model.
        schema: the official schema file it was checked against (None: none was found).
        catalog: the asset catalog it was checked against (None: none was found or asked for).
    """

    scene: SceneSpec
    schema: Path | None
    catalog: Catalog | None


def resolve_schema(schema: str | os.PathLike | None) -> Path | None:
    """The schema file meant by ``schema``: :data:`DEFAULT_SCHEMA`, a path, or None for none."""
    if schema is None:
        return None
    if isinstance(schema, str) and schema == DEFAULT_SCHEMA:
        from usdscene.converters.openlabel import default_schema_path

        return default_schema_path()
    return Path(schema)


@paused_collection()  # a document holds up to millions of containers (see usdscene.bulk)
def validate_document(path: str | os.PathLike, *,
                      schema: str | os.PathLike | None | Literal["default"] = DEFAULT_SCHEMA,
                      use_catalog: bool = True) -> ValidatedDocument:
    """Read a scene document with every check that applies (see the module docstring).

    The file is parsed once.

    Args:
        path: scene document (``.json``, root ``openlabel`` or ``vcd``).
        schema: official schema to check against: :data:`DEFAULT_SCHEMA`, a file, or None.
        use_catalog: check object classes, places and relations against the asset catalog
            (shipped library + the document's ``metadata.usdscene.asset_paths``).

    Returns:
        The scene with the schema and catalog used.

    Raises:
        DocumentError: every problem (schema + usdscene's checks + catalog) at once.
    """
    from usdscene.converters.openlabel import load_with_provenance, read_loaded, schema_problems
    from usdscene.errors import DocumentError

    schema_path = resolve_schema(schema)
    # bad JSON stops here with line and column
    document, provenance = load_with_provenance(path)
    problems = []
    if schema_path is not None:
        problems.extend(schema_problems(document, schema_path))
    catalog = catalog_for_document(document, Path(path).parent) if use_catalog else None
    try:
        scene = read_loaded(document, provenance, catalog=catalog)
    except DocumentError as exc:
        problems.extend(exc.problems)
        scene = None
    if scene is not None and catalog is not None:
        problems.extend(_composition_input_problems(scene, catalog))
    if scene is not None and scene.world is not None:
        from usdscene.converters.openlabel.imaging import document_hdri_problems

        problems.extend(document_hdri_problems(scene, path))
    if problems:
        raise DocumentError(problems)
    return ValidatedDocument(scene=scene, schema=schema_path, catalog=catalog)


def _composition_input_problems(scene, catalog) -> list:
    """What composition would refuse before drawing anything (appearances that are not
    variants, relations to unknown places, cyclic relations...): validate is the gate, so a
    document it accepts composes."""
    from usdscene.errors import AssetError, CompositionError
    from usdscene.scene.compose import check_composition_inputs

    try:
        check_composition_inputs(scene, catalog)
    except (CompositionError, AssetError) as exc:
        return list(exc.problems)
    return []


def catalog_for_document(document: dict, base_dir: str | os.PathLike) -> Catalog | None:
    """The asset catalog a loaded document would be composed with, or None (with a warning)
    when there is none to check against.

    Args:
        document: the loaded ``{"openlabel": ...}`` document.
        base_dir: folder that the document's relative ``asset_paths`` are relative to.
    """
    from usdscene.scene.catalog import CATALOG_FILE, load_catalog
    from usdscene.shipped import default_asset_folder

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
