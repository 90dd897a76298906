"""The annotation store: a run's OpenLABEL labels on disk in frame-range shards, so that no
step holds the whole run in memory. Pure (json, hashlib).

Layout of ``OUT/annotations/`` (written by :class:`StoreWriter`, read by :class:`AnnotationStore`)::

    index.json               {"format": "usdscene annotation store", "version": 1,
                              "frames_per_shard": N, "static": {"file", "sha256", "bytes"},
                              "shards": [{"file", "frame_start", "frame_end", "frames",
                                          "images", "labels", "sha256", "bytes"}, ...],
                              "frames", "images", "labels", "single_document": {...} | null}
    static.openlabel.json    the annotated document without its frames ("frames": {}): objects
                             with their data pointers and frame intervals, streams, coordinate
                             systems, ontologies, relations, metadata (indented JSON)
    frames/<a:06d>-<b:06d>.json   {"openlabel": {"metadata": {"schema_version": "1.0.0"},
                             "frames": {"<f>": ...}}}: every frame f with a <= f <= b, each
                             an OpenLABEL fragment the official schema accepts (compact JSON)

Shard ``k`` holds the frames ``k * N .. k * N + N - 1`` (only shards that hold a frame exist).
The frames of a shard are in the document's order. The index is written last: a shard file
that the index does not name (a killed writer's) is never read. Every file is written
atomically and its bytes depend only on the labels, so a rewrite gives the same bytes.

The one standard document is the static part with the shards' frames in place of its empty
``frames`` (:meth:`AnnotationStore.write_document` streams it; for a run labelled in one shard
it is byte for byte what ``write_document`` writes of the whole document).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import ItemsView, Mapping, ValuesView
from pathlib import Path
from typing import Any, Iterator

from usdscene.errors import OutputError

STORE_FORMAT = "usdscene annotation store"
STORE_VERSION = 1
INDEX_FILE = "index.json"
STATIC_FILE = "static.openlabel.json"
SHARDS_DIR = "frames"
FRAMES_PER_SHARD = 100
"""Default frames per shard: a 10-camera, 100-person frame is about 1.4 MB of labels, so a
shard is about 140 MB of JSON at that scale and a few hundred kB for small runs."""


def _compact(data: Any) -> str:
    return json.dumps(data, ensure_ascii=False, allow_nan=False, separators=(",", ":")) + "\n"


def shard_range(frame: int, frames_per_shard: int) -> tuple[int, int]:
    """``(first, last)`` frame of the shard that holds ``frame``."""
    first = (int(frame) // frames_per_shard) * frames_per_shard
    return first, first + frames_per_shard - 1


def shard_file(first: int, last: int) -> str:
    """Shard path relative to the store: ``frames/000000-000099.json``."""
    sign = lambda v: ("m" if v < 0 else "") + f"{abs(v):06d}"  # noqa: E731 (negative frames)
    return f"{SHARDS_DIR}/{sign(first)}-{sign(last)}.json"


def frame_label_count(frame: dict) -> int:
    """Visible 2D boxes in one OpenLABEL frame (``bbox`` items not named ``*_amodal_bbox``)."""
    count = 0
    for entry in ((frame or {}).get("objects") or {}).values():
        for item in ((entry or {}).get("object_data") or {}).get("bbox") or ():
            if not str(item.get("name", "")).endswith("_amodal_bbox"):
                count += 1
    return count


def _frame_image_count(frame: dict) -> int:
    streams = ((frame or {}).get("frame_properties") or {}).get("streams") or {}
    return sum(1 for stream in streams.values() if isinstance(stream, dict) and "uri" in stream)


class StoreWriter:
    """Writes a store shard by shard; :meth:`finish` writes the static part and the index.

    Args:
        folder: the store folder (``OUT/annotations``), created when missing.
        frames_per_shard: frames per shard file (at least 1).
        schema: official OpenLABEL schema file every shard and the static part must pass
            before it is written (None: no check).
    """

    def __init__(self, folder: str | os.PathLike, frames_per_shard: int = FRAMES_PER_SHARD, *,
                 schema: str | os.PathLike | None = None) -> None:
        if int(frames_per_shard) < 1:
            raise OutputError(f"frames per shard must be at least 1, not {frames_per_shard}",
                              where="frames_per_shard")
        self.folder = Path(folder)
        self.frames_per_shard = int(frames_per_shard)
        self.schema = schema
        self.entries: list[dict] = []

    def _check(self, document: dict, what: str) -> None:
        if self.schema is None:
            return
        from usdscene.converters.openlabel.checks import schema_problems
        from usdscene.errors import Problem

        problems = schema_problems(document, self.schema)
        if problems:
            raise OutputError([Problem(f"{what}: {p.where}", p.message) for p in problems])

    def write_shard(self, first: int, last: int, frames: Mapping[str, dict]) -> dict | None:
        """Write the frames ``first..last`` (every key of ``frames`` in that range, in the
        document's order) as one shard; nothing when ``frames`` is empty.

        Returns:
            The shard's index entry, or None when nothing was written.

        Raises:
            OutputError: a frame outside the range, a shard the schema rejects, or the write failed.
        """
        from usdscene.files import write_bytes_atomic

        if not frames:
            return None
        outside = [k for k in frames if not first <= int(k) <= last]
        if outside:
            raise OutputError(f"frames {outside[:3]} lie outside the shard {first}..{last}", where=str(self.folder))
        document = {"openlabel": {"metadata": {"schema_version": "1.0.0"}, "frames": dict(frames)}}
        name = shard_file(first, last)
        self._check(document, name)
        text = _compact(document).encode("utf-8")
        write_bytes_atomic(self.folder / name, text)
        entry = {"file": name, "frame_start": int(first), "frame_end": int(last), "frames": len(frames),
                 "images": sum(_frame_image_count(f) for f in frames.values()),
                 "labels": sum(frame_label_count(f) for f in frames.values()),
                 "sha256": hashlib.sha256(text).hexdigest(), "bytes": len(text)}
        self.entries.append(entry)
        return entry

    def finish(self, static_document: dict, *, single_document: dict | None = None) -> Path:
        """Write the static part (``static_document`` with its ``frames`` emptied) and then the
        index; remove shard files of an earlier write that the index does not name.

        Args:
            static_document: ``{"openlabel": {...}}``; its ``frames`` value is not read.
            single_document: what :meth:`AnnotationStore.write_document` wrote beside the
                store (``{"file", "sha256", "bytes"}``), recorded so readers know the copy.

        Returns:
            The index path.
        """
        from usdscene.files import dumps_json, write_bytes_atomic, write_json_atomic

        root = dict(static_document["openlabel"])
        root["frames"] = {}
        static = {"openlabel": root}
        self._check(static, STATIC_FILE)
        text = dumps_json(static).encode("utf-8")
        write_bytes_atomic(self.folder / STATIC_FILE, text)
        entries = sorted(self.entries, key=lambda e: e["frame_start"])
        index = {"format": STORE_FORMAT, "version": STORE_VERSION, "frames_per_shard": self.frames_per_shard,
                 "static": {"file": STATIC_FILE, "sha256": hashlib.sha256(text).hexdigest(), "bytes": len(text)},
                 "shards": entries, "frames": sum(e["frames"] for e in entries),
                 "images": sum(e["images"] for e in entries), "labels": sum(e["labels"] for e in entries),
                 "single_document": single_document}
        path = write_json_atomic(self.folder / INDEX_FILE, index)
        named = {e["file"] for e in entries}
        for stale in sorted((self.folder / SHARDS_DIR).glob("*.json")):
            if f"{SHARDS_DIR}/{stale.name}" not in named:
                stale.unlink(missing_ok=True)
        return path


def record_single_document(folder: str | os.PathLike, single_document: dict | None) -> Path:
    """Record (or clear, with None) the single document written from the store in its index."""
    from usdscene.files import write_json_atomic

    store = AnnotationStore(folder)
    index = dict(store.index, single_document=single_document)
    return write_json_atomic(store.folder / INDEX_FILE, index)


class AnnotationStore:
    """Reads a store (see the module docstring): the static part once, the frames shard by
    shard, at most one shard parsed at a time.

    Attributes:
        folder: the store folder.
        index: the parsed ``index.json``.
        shards_read: shard files parsed so far (each parse counts).
        most_frames_held: the most frames held parsed at once (one shard's at most).

    Raises (constructor):
        OutputError: no index, an unreadable one, or one of another format or version.
    """

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = Path(folder)
        path = self.folder / INDEX_FILE
        try:
            index = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise OutputError("no annotation store; run `usdscene annotate OUT` first", where=str(path)) from None
        except (OSError, ValueError) as exc:
            raise OutputError(f"unreadable annotation store index: {exc}", where=str(path)) from None
        if not isinstance(index, dict) or index.get("format") != STORE_FORMAT:
            raise OutputError(f"not a {STORE_FORMAT} index", where=str(path))
        if index.get("version") != STORE_VERSION:
            raise OutputError(f"annotation store version {index.get('version')!r}; this usdscene reads "
                              f"version {STORE_VERSION} (run `usdscene annotate OUT` again)", where=str(path))
        self.index = index
        self.shards_read = 0
        self.most_frames_held = 0
        self._static: dict | None = None
        self._held: tuple[str, dict] | None = None  # (shard file, its frames)
        self._shards: list[dict] = list(index.get("shards") or ())
        self._shard_starts = [entry["frame_start"] for entry in self._shards]  # for frame()

    @property
    def shards(self) -> list[dict]:
        """The index entries of the shards, by first frame."""
        return self._shards

    def _read(self, name: str, sha256: str | None) -> bytes:
        path = self.folder / name
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise OutputError(f"cannot read the annotation store: {exc.strerror or exc}", where=str(path)) from None
        if sha256 and hashlib.sha256(data).hexdigest() != sha256:
            raise OutputError("the file changed since the store was written (sha256 differs from "
                              f"{INDEX_FILE}); run `usdscene annotate OUT` again", where=str(path))
        return data

    def _parse(self, name: str, sha256: str | None) -> dict:
        try:
            return json.loads(self._read(name, sha256))
        except ValueError as exc:
            raise OutputError(f"unreadable annotation store file: {exc}", where=str(self.folder / name)) from None

    def static(self) -> dict:
        """The document without its frames, ``{"openlabel": {..., "frames": {}}}`` (read once;
        the same dict on every call: do not modify it)."""
        if self._static is None:
            entry = self.index.get("static") or {}
            self._static = self._parse(entry.get("file", STATIC_FILE), entry.get("sha256"))
        return self._static

    def shard_frames(self, entry: dict) -> dict:
        """The frames of one shard (key → frame), the shard held until another is read."""
        if self._held is not None and self._held[0] == entry["file"]:
            return self._held[1]
        self._held = None  # let the previous shard go before parsing the next
        frames = (self._parse(entry["file"], entry.get("sha256")).get("openlabel") or {}).get("frames") or {}
        self.shards_read += 1
        self.most_frames_held = max(self.most_frames_held, len(frames))
        self._held = (entry["file"], frames)
        return frames

    def frames(self) -> Iterator[tuple[str, dict]]:
        """Every ``(frame key, frame)`` of the run, shard by shard, in the document's order."""
        for entry in self.shards:
            yield from list(self.shard_frames(entry).items())

    def frame(self, number: int) -> dict | None:
        """One frame, or None when the store has none of that number."""
        import bisect

        number = int(number)
        at = bisect.bisect_right(self._shard_starts, number) - 1
        if at >= 0 and number <= self._shards[at]["frame_end"]:
            return self.shard_frames(self._shards[at]).get(str(number))
        return None

    def document(self) -> dict:
        """The annotated document as consumers read it: the static part with a
        :class:`StoredFrames` mapping as ``frames`` (frames are parsed as they are read, one
        shard at a time). Read-only."""
        root = dict(self.static()["openlabel"])
        root["frames"] = StoredFrames(self)
        return {"openlabel": root}

    def write_document(self, path: str | os.PathLike) -> dict:
        """Write the one standard OpenLABEL document (indented JSON, one line per frame as
        :func:`usdscene.converters.openlabel.write.document_text` writes it) to ``path`` atomically,
        frame by frame: the static part's text with every frame streamed in place of its
        empty ``frames``.

        Returns:
            ``{"file": name, "sha256", "bytes"}`` of what was written.
        """
        from usdscene.converters.openlabel.write import frame_line
        from usdscene.files import atomic_text_file, dumps_json

        static = self.static()
        root = static["openlabel"]
        digest, size = hashlib.sha256(), 0
        with atomic_text_file(path) as handle:
            def put(text: str) -> None:
                nonlocal size
                data = text.encode("utf-8")
                digest.update(data)
                size += len(data)
                handle.write(text)

            put('{\n  "openlabel": {')
            for position, (key, value) in enumerate(root.items()):
                put(("," if position else "") + "\n    " + json.dumps(key, ensure_ascii=False) + ": ")
                if key != "frames":
                    put(dumps_json(value)[:-1].replace("\n", "\n    "))
                    continue
                first = True
                for frame_key, frame in self.frames():
                    put(("{" if first else ",") + "\n" + frame_line(frame_key, frame))  # write.document_text's form
                    first = False
                put("{}" if first else "\n    }")
            put("\n  }\n}\n")
        return {"file": Path(path).name, "sha256": digest.hexdigest(), "bytes": size}


class StoredFrames(Mapping):
    """The ``frames`` of a store as a read-only mapping (frame key → frame): iterating reads
    shard after shard, one at a time; a look-up reads (and holds) the shard of that frame."""

    def __init__(self, store: AnnotationStore) -> None:
        self._store = store

    def __getitem__(self, key: str) -> dict:
        try:
            number = int(key)
        except (TypeError, ValueError):
            raise KeyError(key) from None
        frame = self._store.frame(number)
        if frame is None or str(key) != str(number):
            raise KeyError(key)
        return frame

    def __iter__(self) -> Iterator[str]:
        for key, _ in self._store.frames():
            yield key

    def __len__(self) -> int:
        return int(self._store.index.get("frames", 0))

    def __bool__(self) -> bool:
        return len(self) > 0

    def items(self) -> ItemsView:
        return _StoredItems(self)

    def values(self) -> ValuesView:
        return _StoredValues(self)


class _StoredItems(ItemsView):
    def __iter__(self):
        return self._mapping._store.frames()


class _StoredValues(ValuesView):
    def __iter__(self):
        return (frame for _, frame in self._mapping._store.frames())


def scene_document(document: dict) -> dict:
    """The document as the scene readers need it (cameras, poses, places: ``read_openlabel``,
    ``read_cameras``): unchanged when its frames are a plain dict; for a store's document, a
    plain dict whose frames keep everything but the labels (boxes, polygons, keypoints, 3D
    boxes, the cross-camera table, resolved places), read shard by shard, so that memory holds
    the input document's frames and never the run's labels."""
    frames = (document.get("openlabel") or {}).get("frames")
    if not isinstance(frames, StoredFrames):
        return document
    from usdscene.converters.openlabel.annotations import (CAMERAS_DATA, RESOLVED_PLACE, RESOLVED_RELATION)
    from usdscene.labels.cuboids import CUBOID_NAME

    label_kinds = {"bbox", "poly2d", "point2d"}
    label_names = {CUBOID_NAME, CAMERAS_DATA, RESOLVED_PLACE, RESOLVED_RELATION}
    kept = {}
    for key, frame in frames.items():
        objects = {}
        for uid, entry in ((frame or {}).get("objects") or {}).items():
            data = {kind: [i for i in items if not (isinstance(i, dict) and i.get("name") in label_names)]
                    for kind, items in ((entry or {}).get("object_data") or {}).items() if kind not in label_kinds}
            data = {kind: items for kind, items in data.items() if items}
            if data:
                objects[uid] = dict(entry, object_data=data)
            elif set(entry or {}) - {"object_data"}:
                objects[uid] = {k: v for k, v in entry.items() if k != "object_data"}
        trimmed = {k: v for k, v in frame.items() if k != "objects"}
        if objects:
            trimmed["objects"] = objects
        kept[key] = trimmed
    return {"openlabel": dict(document["openlabel"], frames=kept)}


def store_folder(out_dir: str | os.PathLike) -> Path:
    """``OUT/annotations``, the store of an output folder."""
    from usdscene.document import output_layout as layout

    return Path(out_dir) / layout.ANNOTATION_STORE_DIR


def single_document_is_copy(out_dir: str | os.PathLike, index: Mapping) -> bool:
    """Whether ``OUT/annotations.openlabel.json`` is the copy the store wrote (size and
    sha256 as recorded in its index), not a document written or edited by someone else."""
    from usdscene.document import output_layout as layout

    recorded = index.get("single_document") or {}
    path = Path(out_dir) / layout.ANNOTATIONS_FILE
    try:
        if path.stat().st_size != recorded.get("bytes"):
            return False
        digest = hashlib.sha256()
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 22), b""):
                digest.update(block)
    except OSError:
        return False
    return digest.hexdigest() == recorded.get("sha256")


def annotations_source(out_dir: str | os.PathLike) -> tuple[str | None, Path]:
    """Where an output folder's labels are read from (see :func:`open_annotations`).

    Returns:
        ``("store", OUT/annotations/static.openlabel.json)``, ``("document",
        OUT/annotations.openlabel.json)``, or ``(None, OUT/annotations.openlabel.json)`` when
        there are no annotations.

    Raises:
        OutputError: the store's index is unreadable.
    """
    from usdscene.document import output_layout as layout

    single = Path(out_dir) / layout.ANNOTATIONS_FILE
    folder = store_folder(out_dir)
    if (folder / INDEX_FILE).is_file():
        store = AnnotationStore(folder)
        if not single.is_file() or single_document_is_copy(out_dir, store.index):
            return "store", folder / STATIC_FILE
    return ("document" if single.is_file() else None), single


def open_annotations(out_dir: str | os.PathLike) -> dict:
    """The annotated document of an output folder, which every consumer reads (exports,
    report, statistics, ``export-openlabel``).

    The store (``OUT/annotations/``) when there is one and ``OUT/annotations.openlabel.json``
    is absent or the store's own copy: frames are then read shard by shard as they are used
    (:meth:`AnnotationStore.document`). Otherwise the single document, loaded whole (one
    written by hand, edited after ``annotate``, or from a usdscene before the store).

    Raises:
        OutputError: neither exists (``run `usdscene annotate OUT` first``), or the store is unreadable.
        DocumentError: the single document is unreadable.
    """
    from usdscene.converters.openlabel.load import load_document

    kind, path = annotations_source(out_dir)
    if kind == "store":
        return AnnotationStore(path.parent).document()
    if kind is None:
        raise OutputError("no annotations; run `usdscene annotate OUT` first", where=str(path))
    return load_document(path)
