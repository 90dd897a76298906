"""Validation against the official OpenLABEL 1.0.0 JSON schema (jsonschema, Draft 7).

The schema file is the published ASAM ``openlabel_json_schema-v1.0.0.json``
(``$id https://openlabel.asam.net/V1-0-0/schema#``). It is taken, in this order, from an explicit
path, ``$USDSCENE_OPENLABEL_SCHEMA``, or the copy that the ``uai-openlabel`` package (a runtime
dependency) ships unchanged (same sha256 as the ASAM file).

The schema has holes that :func:`usdscene.converters.openlabel.read_openlabel` covers: it never checks
``stream_properties`` (intrinsics), root ``frame_intervals`` items, ``matrix4x4`` length, or
numbers that JSON cannot hold (NaN, Infinity).
"""

from __future__ import annotations

import functools
import json
import os
from collections import deque
from pathlib import Path
from typing import Mapping

from usdscene.errors import DocumentError, Problem

SCHEMA_ENV = "USDSCENE_OPENLABEL_SCHEMA"
_MAX_MESSAGE = 240


def schema_path_from_env() -> Path | None:
    """``$USDSCENE_OPENLABEL_SCHEMA`` as a path, or None when unset/empty."""
    value = os.environ.get(SCHEMA_ENV, "").strip()
    return Path(value) if value else None


def packaged_schema_path() -> Path | None:
    """The official schema shipped inside the ``uai-openlabel`` distribution, or None.

    Found with ``importlib.util.find_spec`` so the package itself is never imported (only its
    data file is used)."""
    import importlib.util

    try:
        spec = importlib.util.find_spec("uai_openlabel")
    except (ImportError, ValueError):
        return None
    for folder in (spec.submodule_search_locations or []) if spec else []:
        candidate = Path(folder) / "official_schema" / "openlabel_json_schema.json"
        if candidate.is_file():
            return candidate
    return None


def default_schema_path() -> Path | None:
    """``$USDSCENE_OPENLABEL_SCHEMA`` if set, else the packaged official schema, else None."""
    return schema_path_from_env() or packaged_schema_path()


@functools.lru_cache(maxsize=4)
def _validator(path: str):
    """``(fast, full)``: a compiled check that raises on the first violation (fastjsonschema,
    ~50x faster on large documents; None when it cannot compile the schema) and the
    jsonschema validator that lists every violation with its path."""
    import fastjsonschema
    import jsonschema

    try:
        schema = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise DocumentError(f"cannot read the OpenLABEL schema: {exc.strerror or exc}", where=path) from None
    except json.JSONDecodeError as exc:
        raise DocumentError(f"the OpenLABEL schema is not valid JSON (line {exc.lineno}, column {exc.colno})",
                            where=path) from None
    try:
        fast = fastjsonschema.compile(schema)
    except Exception:  # noqa: BLE001 - any schema it cannot compile: jsonschema alone decides
        fast = None
    return fast, jsonschema.Draft7Validator(schema)


def _json_path(parts: deque) -> str:
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out or "document"


def schema_problems(document: Mapping, schema_path: str | os.PathLike | None = None) -> list[Problem]:
    """Every violation of the official schema, each with its JSON path.

    Args:
        document: the whole document (``{"openlabel": {...}}``); it is validated as
            serialised JSON (tuples become lists), which is what a consumer reads.
        schema_path: the schema file; default :func:`default_schema_path`.

    Returns:
        Problems sorted by path (empty when the document is valid).

    Raises:
        DocumentError: no schema path given and none found (environment, package), the schema file is
            unreadable, or the document is not JSON data (NaN, Infinity, non-JSON types).
    """
    path = Path(schema_path) if schema_path is not None else default_schema_path()
    if path is None:
        raise DocumentError(f"no OpenLABEL schema given (pass a path, set ${SCHEMA_ENV} or install "
                            "uai-openlabel)", where="schema")
    fast, validator = _validator(str(path.resolve()))
    try:
        data = json.loads(json.dumps(document, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise DocumentError(f"the document is not JSON data: {exc}", where="document") from None
    if fast is not None:
        import fastjsonschema

        try:
            fast(data)
            return []
        except fastjsonschema.JsonSchemaValueException:
            pass  # list every violation with jsonschema (it decides; the fast check only screens)
    problems = []
    for error in validator.iter_errors(data):
        message = error.message
        if len(message) > _MAX_MESSAGE:
            message = message[: _MAX_MESSAGE - 3] + "..."
        problems.append(Problem(_json_path(error.absolute_path), f"schema: {message}"))
    return sorted(problems, key=lambda p: p.where)
