"""Loading OpenLABEL 1.0.0 / VCD 4.3 documents: JSON, dialects, provenance. Pure module.

A document is read from a file or a mapping into ``{"openlabel": {...}}``; a VCD 4.3 document
(root ``vcd``) is converted to the OpenLABEL 1.0.0 form on the way. Problems found while
loading (bad JSON, repeated keys, NaN/Infinity) are raised at once as one
:class:`~usdscene.errors.DocumentError`: nothing after loading can work around them.

:class:`DocumentBody` is the loaded ``openlabel`` object as the section readers
(``openlabel_metadata``, ``openlabel_cameras``, ``openlabel_objects``) see it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from pathlib import Path
from typing import Any, Iterator, Mapping

from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import MAX_FRAME, Provenance

from usdscene.converters.openlabel.values import describe

SCHEMA_VERSION = "1.0.0"

_NON_FINITE_TEXT = re.compile(r"NaN|Infinity|[eE]\+?[0-9]{3,}")
# JSON can escape half of a UTF-16 surrogate pair alone (\ud800); no encoding can write that
# string (UTF-8 files, USD names, Blender names), so it is refused where it is found.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")
_SURROGATE = re.compile("[\ud800-\udfff]")


MAX_DOCUMENT_BYTES = 512 * 1024 * 1024
"""The largest scene document read (512 MiB): parsed, a JSON document takes about ten times its
size in memory, and this keeps the whole gate under about 6 GB."""


def load_document(source: str | os.PathLike | Mapping) -> dict:
    """Read an OpenLABEL 1.0.0 or VCD 4.3 document into ``{"openlabel": {...}}``.

    Args:
        source: a path to a JSON file, or an already parsed mapping.

    Returns:
        The document with root ``openlabel``; a VCD document (root ``vcd``) is converted to
        the OpenLABEL 1.0.0 form on the fly (flat 16-number poses → ``matrix4x4``,
        ``transform_src_to_dst_4x4`` → ``transform_src_to_dst``, ``schema_version`` 1.0.0).

    Raises:
        DocumentError: unreadable file, bad JSON (with line and column), a root that is not an
            object or is neither ``openlabel`` nor ``vcd``, non-finite numbers (NaN, Infinity).
    """
    document, _ = load_with_provenance(source)
    return document


def load_with_provenance(source: str | os.PathLike | Mapping) -> tuple[dict, Provenance]:
    """:func:`load_document` plus the provenance :func:`read_openlabel` would record, so that
    a caller that also needs the raw document (schema validation) parses the file once.

    Returns:
        (document, provenance): provenance names the path (empty for a mapping), the sha256 of
        the file's bytes (of the canonical JSON for a mapping), the root key and the toolkit
        version.

    Raises:
        DocumentError: as :func:`load_document`.
    """
    from usdscene import __version__

    problems = ProblemCollector()
    if isinstance(source, Mapping):
        data: Any = source
        label = ""
        try:
            canonical = json.dumps(source, sort_keys=True, separators=(",", ":"), allow_nan=True)
        except (TypeError, ValueError) as exc:
            raise DocumentError(f"the document is not JSON data: {exc}", where="document") from None
        digest = hashlib.sha256(canonical.encode("utf-8")).hexdigest()
        scan_non_finite = scan_surrogates = True
    else:
        path = Path(source)
        label = str(path)
        try:
            size = path.stat().st_size
            if size > MAX_DOCUMENT_BYTES:
                raise DocumentError(f"the document is {size:,} bytes, over the {MAX_DOCUMENT_BYTES:,} bytes "
                                    "(MAX_DOCUMENT_BYTES) usdscene reads in one piece; a longer sequence is "
                                    "split into documents of frame ranges", where=label)
            raw = path.read_bytes()
        except OSError as exc:
            raise DocumentError(f"cannot read the document: {exc.strerror or exc}", where=label) from None
        digest = hashlib.sha256(raw).hexdigest()
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise DocumentError(f"the document is not UTF-8 text ({exc.reason} at byte {exc.start})",
                                where=label) from None
        duplicated: list[tuple[dict, list[str]]] = []

        def keep_duplicates(pairs: list) -> dict:
            # json keeps the last of repeated keys silently; a repeated uid in a hand-edited
            # document would drop an element without a word, so remember where it happened.
            obj = dict(pairs)
            if len(obj) != len(pairs):
                seen: set = set()
                duplicated.append((obj, sorted({k for k, _ in pairs if k in seen or seen.add(k)})))
            return obj

        try:
            data = json.loads(text, object_pairs_hook=keep_duplicates)
        except json.JSONDecodeError as exc:
            raise DocumentError(f"invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}",
                                where=f"{label}:{exc.lineno}:{exc.colno}") from None
        except RecursionError:
            raise DocumentError("invalid JSON: nested too deeply", where=label) from None
        except ValueError:  # an integer literal beyond Python's 4300-digit limit
            raise DocumentError("an integer of more than 4300 digits (no value usdscene reads can be that "
                                "large)", where=_huge_integer_where(text, label)) from None
        # Python's json accepts NaN/Infinity (and 1e999 → inf); look for them only when the
        # text could hold one, so that a clean large document is not walked twice.
        scan_non_finite = bool(_NON_FINITE_TEXT.search(text))
        scan_surrogates = bool(_SURROGATE_ESCAPE.search(text))
        if duplicated:
            targets = {id(obj): keys for obj, keys in duplicated}
            for where, keys in _find_objects(data, "", targets):
                for key in keys:
                    problems.add(f"{where}.{key}" if where else key,
                                 f"key {key!r} appears more than once in one JSON object (only the last would count)")
    if not isinstance(data, Mapping):
        raise DocumentError(f"the document root must be a JSON object, got {type(data).__name__}",
                            where=label or "document")
    if "openlabel" in data:
        root_key = "openlabel"
    elif "vcd" in data:
        root_key = "vcd"
    else:
        keys = sorted(str(k) for k in data)[:5]
        raise DocumentError(f"the root object must have the key 'openlabel' (OpenLABEL 1.0.0) or "
                            f"'vcd' (VCD 4.3); found {keys}", where=label or "document")
    extra = sorted(str(k) for k in data if k != root_key)
    if extra:
        problems.add(extra[0], f"unexpected key {extra[0]!r} beside {root_key!r} at the root")
    if scan_non_finite:
        _find_non_finite(data, "", problems)
    if scan_surrogates:
        _find_lone_surrogates(data, "", problems)
    problems.raise_if_any(DocumentError)
    body = data[root_key]
    if isinstance(body, Mapping) and not isinstance(body, dict):
        body = dict(body)
    if not isinstance(body, dict):
        raise DocumentError(f"expected a JSON object, got {describe(body)}", where=root_key)
    if root_key == "vcd":
        body = vcd_to_openlabel(body)
    provenance = Provenance(source=label, source_sha256=digest, source_format=root_key,
                            toolkit_version=__version__)
    return {"openlabel": dict(body)}, provenance


def _find_non_finite(value: Any, where: str, problems: ProblemCollector) -> None:
    if isinstance(value, float):
        if not math.isfinite(value):
            problems.add(where or "document", f"non-finite number {value!r} (JSON has no NaN or Infinity)")
    elif isinstance(value, dict):
        for key, item in value.items():
            _find_non_finite(item, f"{where}.{key}" if where else str(key), problems)
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            _find_non_finite(item, f"{where}[{index}]", problems)


def _find_lone_surrogates(value: Any, where: str, problems: ProblemCollector) -> None:
    if isinstance(value, str):
        if _SURROGATE.search(value):
            problems.add(where or "document", f"the text {value!r} holds a lone UTF-16 surrogate, which no "
                                              "encoding can write")
    elif isinstance(value, dict):
        for key, item in value.items():
            here = f"{where}.{key}" if where else str(key)
            if isinstance(key, str) and _SURROGATE.search(key):
                problems.add(here, f"the key {key!r} holds a lone UTF-16 surrogate, which no encoding can write")
            _find_lone_surrogates(item, here, problems)
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            _find_lone_surrogates(item, f"{where}[{index}]", problems)


def _huge_integer_where(text: str, label: str) -> str:
    """``file:line:column`` of the first integer literal of more than 4300 digits."""
    match = re.search(r"[0-9]{4301,}", text)
    if match is None:
        return label
    line = text.count("\n", 0, match.start()) + 1
    column = match.start() - (text.rfind("\n", 0, match.start()) + 1) + 1
    return f"{label}:{line}:{column}"


def _find_objects(value: Any, where: str, targets: dict):
    """(JSON path, keys) of the objects whose ``id`` is in ``targets``."""
    if isinstance(value, dict):
        if id(value) in targets:
            yield where, targets[id(value)]
        for key, item in value.items():
            yield from _find_objects(item, f"{where}.{key}" if where else str(key), targets)
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from _find_objects(item, f"{where}[{index}]", targets)


def vcd_to_openlabel(vcd: Mapping) -> dict:
    """VCD 4.3 → OpenLABEL 1.0.0 (copies what it changes; the input is not modified): schema
    version, poses as ``matrix4x4`` objects, ``transform_src_to_dst``, and ``poly2d`` values
    given as ``[x, y]`` pairs flattened."""
    out = dict(vcd)
    metadata = dict(out.get("metadata") or {}) if isinstance(out.get("metadata"), dict) else out.get("metadata")
    if isinstance(metadata, dict):
        metadata["schema_version"] = SCHEMA_VERSION
        out["metadata"] = metadata
    elif "metadata" not in out:
        out["metadata"] = {"schema_version": SCHEMA_VERSION}
    systems = out.get("coordinate_systems")
    if isinstance(systems, dict):
        converted = {}
        for name, cs in systems.items():
            if isinstance(cs, dict) and isinstance(cs.get("pose_wrt_parent"), list):
                cs = dict(cs)
                cs["pose_wrt_parent"] = {"matrix4x4": cs["pose_wrt_parent"]}
            converted[name] = cs
        out["coordinate_systems"] = converted
    if isinstance(out.get("objects"), dict):
        out["objects"] = _objects_with_flat_poly2d(out["objects"])
    frames = out.get("frames")
    if isinstance(frames, dict):
        new_frames = {}
        for key, frame in frames.items():
            if isinstance(frame, dict) and isinstance(frame.get("objects"), dict):
                frame = dict(frame, objects=_objects_with_flat_poly2d(frame["objects"]))
            props = frame.get("frame_properties") if isinstance(frame, dict) else None
            transforms = props.get("transforms") if isinstance(props, dict) else None
            if isinstance(transforms, dict):
                new_transforms = {}
                for tname, t in transforms.items():
                    if isinstance(t, dict) and "transform_src_to_dst_4x4" in t:
                        t = dict(t)
                        t["transform_src_to_dst"] = {"matrix4x4": t.pop("transform_src_to_dst_4x4")}
                    new_transforms[tname] = t
                frame = dict(frame)
                frame["frame_properties"] = dict(props, transforms=new_transforms)
            new_frames[key] = frame
        out["frames"] = new_frames
    return out


def _objects_with_flat_poly2d(objects: Mapping) -> dict:
    """Objects whose ``poly2d`` values given as ``[x, y]`` pairs (as VCD 4.3 writers do) are
    flattened to ``[x0, y0, x1, y1, ...]``, OpenLABEL's form (copies what it changes)."""
    def is_pairs(val) -> bool:
        return (isinstance(val, list) and len(val) > 0 and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                        for v in p) for p in val))

    out = {}
    for uid, obj in objects.items():
        data = obj.get("object_data") if isinstance(obj, dict) else None
        polys = data.get("poly2d") if isinstance(data, dict) else None
        if isinstance(polys, list) and any(isinstance(p, dict) and is_pairs(p.get("val")) for p in polys):
            flat = [dict(p, val=[v for pair in p["val"] for v in pair]) if isinstance(p, dict) and is_pairs(p.get("val"))
                    else p for p in polys]
            obj = dict(obj, object_data=dict(data, poly2d=flat))
        out[uid] = obj
    return out


class DocumentBody:
    """The ``openlabel`` object of one loaded document, as the section readers see it.

    It hands out the top-level sections (each checked to be a JSON object once) and the
    frames, and collects the problems every reader finds, so that they are raised together.

    Args:
        body: the ``openlabel`` object (``load_document(...)["openlabel"]``).
        root: the root key the document was written with (``"openlabel"`` or ``"vcd"``); it
            starts every JSON path in messages.
    """

    def __init__(self, body: Mapping, root: str = "openlabel") -> None:
        self.body = body
        self.root = root
        self.problems = ProblemCollector()
        self._sections: dict[str, Mapping] = {}
        self._frames: dict[int, Mapping] | None = None

    def add(self, where: str, message: str) -> None:
        """Record one problem at the JSON path ``where``."""
        self.problems.add(where, message)

    def section(self, key: str) -> Mapping:
        """A top-level section as a dict ({} and one problem if it is not an object)."""
        if key not in self._sections:
            value = self.body.get(key, {})
            if not isinstance(value, dict):
                self.add(f"{self.root}.{key}", f"expected a JSON object, got {describe(value)}")
                value = {}
            self._sections[key] = value
        return self._sections[key]

    def frames(self) -> dict[int, Mapping]:
        """``frames`` as ``{frame number: frame object}``; bad keys and frames are reported once."""
        if self._frames is None:
            self._frames = {}
            for key, frame in self.section("frames").items():
                where = f"{self.root}.frames.{key}"
                if not isinstance(key, str) or not key.isascii() or not key.isdigit():
                    self.add(where, f"frame keys are frame numbers (digits), got {describe(key)}")
                    continue
                if len(key) > len(str(MAX_FRAME)) or int(key) > MAX_FRAME:
                    self.add(where, f"frame {describe(key)} is above {MAX_FRAME}, Blender's last frame")
                    continue
                if not isinstance(frame, dict):
                    self.add(where, f"expected a JSON object, got {describe(frame)}")
                    continue
                self._frames[int(key)] = frame
        return self._frames

    def frame_sections(self, key: str) -> Iterator[tuple[int, str, Mapping]]:
        """``(frame, JSON path, frames[f][key])`` for every frame, in frame order, that has a
        ``key`` object; a ``key`` that is not a JSON object is reported and skipped."""
        frames = self.frames()
        for number in sorted(frames):
            section = frames[number].get(key)
            if section is None:
                continue
            where = f"{self.root}.frames.{number}.{key}"
            if not isinstance(section, dict):
                self.add(where, f"expected a JSON object, got {describe(section)}")
                continue
            yield number, where, section
