"""The export formats: one registry that the command line, the document's validation and
:func:`usdscene.dataset.export.export_formats` read. Pure (stdlib): naming the formats imports
none of their writers.

A format is one :class:`ExportFormat` line in :data:`FORMATS` (its name, its words for the help,
what the document must hold, which :class:`usdscene.dataset.export.ExportOptions` fields it
reads) and one module holding its writer, a function of an :class:`ExportJob` that returns the
folder or file it wrote, imported only when the format is exported. Adding a format::

    # converters/exports/myformat.py
    def write_myformat(job: ExportJob) -> Path: ...

    # here, one line (or register(...) from anywhere before the export runs)
    ExportFormat("myformat", "my rows", writer="usdscene.converters.exports.myformat:write_myformat",
                 needs=frozenset({MOVING_SEQUENCE}), options=("copy_images",)),

COCO and YOLO are *dataset* formats (``dataset=True``, no writer): several output folders
become one dataset with ids unique across them and one split, which
:func:`usdscene.dataset.export.export_dataset` writes for both at once.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

MOVING_SEQUENCE = "moving sequence"
"""A need: the document states its frame rate, its objects are tracks (``usdscene generate tracks``)."""
KEYPOINTS = "keypoints"
"""A need: some object carries ``point2d`` keypoints (people of a family with a skeleton)."""
BOXES_3D = "3D boxes"
"""A need: some object carries a ``cuboid`` (a 3D box) in some frame."""
NEEDS = (MOVING_SEQUENCE, KEYPOINTS, BOXES_3D)


@dataclass(frozen=True)
class ExportFormat:
    """One export format.

    Attributes:
        name: what the user types (``usdscene export NAME``, ``metadata.usdscene.exports``).
        summary: a few words for the help ("COCO", "MOTChallenge tracks").
        writer: ``"module:function"``, the function taking an :class:`ExportJob` and returning
            the folder or file written; empty for a dataset format.
        needs: what the document must hold, of :data:`NEEDS`; checked for every format asked
            for before any is written.
        options: the :class:`usdscene.dataset.export.ExportOptions` fields the format reads.
        dataset: written by :func:`usdscene.dataset.export.export_dataset`: several output
            folders may become one dataset (``--dataset``); others are exported per folder.
        catalog: needs the asset catalog whatever the class options (ROIs: its place regions).
        check: ``"module:function"`` taking the :class:`ExportJob`, run for every format asked
            for before any format is written (options that need the document, such as MOT's
            class mapping); raises ``OutputError``. Empty: nothing beyond ``needs``.
    """

    name: str
    summary: str
    writer: str = ""
    needs: frozenset = frozenset()
    options: tuple[str, ...] = ()
    dataset: bool = False
    catalog: bool = False
    check: str = ""

    def check_job(self, job: "ExportJob") -> None:
        """Run the format's check on ``job`` (nothing when it has none)."""
        if self.check:
            module, _, function = self.check.partition(":")
            getattr(importlib.import_module(module), function)(job)

    def write(self, job: "ExportJob") -> Any:
        """Run the format's writer on ``job``; returns what it wrote."""
        module, _, function = self.writer.partition(":")
        return getattr(importlib.import_module(module), function)(job)


class ExportJob:
    """What a writer gets: the annotated ``document`` (root ``openlabel``), the asset
    ``catalog`` (None when it could not be read and the format does not need it), the output
    folder ``out_dir`` and the ``options`` (:class:`usdscene.dataset.export.ExportOptions`).

    :meth:`object_classes` and :meth:`person_classes` are the class lists of the export
    (computed by the caller, once, when a writer asks); :meth:`label_index` is the document's
    :class:`usdscene.converters.openlabel.annotations.LabelIndex`, read once for every format.
    """

    def __init__(self, document: dict, catalog, out_dir, options, *,
                 object_classes: Callable[[], Any] = lambda: None,
                 person_classes: Callable[[], Any] = lambda: None,
                 catalog_movers: Callable[[], Any] = lambda: ((), ())) -> None:
        self.document, self.catalog, self.out_dir, self.options = document, catalog, out_dir, options
        self._object_classes, self._person_classes = object_classes, person_classes
        self._catalog_movers = catalog_movers
        self._index = None

    def catalog_movers(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """``(person classes, vehicle classes)`` of the catalog (both empty without one)."""
        return self._catalog_movers()

    def object_classes(self):
        """The export's object classes (sorted later for ids), or None: the document's labelled types."""
        return self._object_classes()

    def person_classes(self):
        """The classes exported as persons, or None: every object with ground positions."""
        return self._person_classes()

    def label_index(self):
        """The document's labels by frame and camera, read on the first call."""
        if self._index is None:
            from usdscene.converters.openlabel.annotations import LabelIndex

            self._index = LabelIndex(self.document)
        return self._index


FORMATS: dict[str, ExportFormat] = {}
"""Name → format, in the order the formats are listed and written."""


def register(fmt: ExportFormat) -> ExportFormat:
    """Add ``fmt`` to :data:`FORMATS` (a name may be registered once); returns it."""
    if fmt.name in FORMATS:
        raise ValueError(f"export format {fmt.name!r} is registered already")
    unknown = sorted(set(fmt.needs) - set(NEEDS))
    if unknown:
        raise ValueError(f"export format {fmt.name!r} needs {unknown}; known needs: {', '.join(NEEDS)}")
    if not fmt.dataset and ":" not in fmt.writer:
        raise ValueError(f"export format {fmt.name!r} needs a writer 'module:function'")
    FORMATS[fmt.name] = fmt
    return fmt


def format_names() -> tuple[str, ...]:
    """The registered format names, in order."""
    return tuple(FORMATS)


def require_needs(document: dict, names) -> None:
    """Fail before anything is written when the document lacks what a format of ``names`` needs.

    Raises:
        OutputError: naming the formats that need it (``"the mot and multiview export needs ..."``).
    """
    for need in NEEDS:
        wanting = [n for n in names if need in FORMATS[n].needs]
        if wanting:
            _CHECKS[need](document, " and ".join(wanting))


def _require_keypoints(document: dict, what: str) -> None:
    from usdscene.converters.openlabel.annotations import KEYPOINT_INFIX

    if not _has_object_data(document, "point2d", lambda item: KEYPOINT_INFIX in str(item.get("name", ""))):
        _missing(what, "keypoints: no object carries point2d keypoints (a person family with a skeleton)",
                 "objects")


def _require_boxes_3d(document: dict, what: str) -> None:
    if not _has_object_data(document, "cuboid", lambda item: True):
        _missing(what, "3D boxes: no object carries a cuboid in any frame", "objects")


def _missing(what: str, message: str, where: str) -> None:
    from usdscene.errors import OutputError

    raise OutputError(f"the {what} export needs {message}", where=where)


def _has_object_data(document: dict, kind: str, wanted: Callable[[dict], bool]) -> bool:
    """Whether some object of the document holds object data of ``kind`` (static or in a frame)
    that ``wanted`` accepts."""
    root = document.get("openlabel", {})

    def blocks():  # frame by frame, stopping at the first hit (a store's frames are read lazily)
        yield from (element.get("object_data") or {} for element in (root.get("objects") or {}).values())
        for frame in (root.get("frames") or {}).values():
            yield from (element.get("object_data") or {} for element in (frame.get("objects") or {}).values())

    return any(wanted(item) for block in blocks() for item in block.get(kind) or ())


def _require_moving(document: dict, what: str) -> None:
    from usdscene.converters.exports.tracks import require_tracks

    require_tracks(document, what)


_CHECKS = {MOVING_SEQUENCE: _require_moving, KEYPOINTS: _require_keypoints, BOXES_3D: _require_boxes_3d}

_CLASSES = ("document_classes",)
for _format in (
    ExportFormat("coco", "COCO", dataset=True,
                 options=(*_CLASSES, "split", "split_seed", "min_pixels", "min_visible_fraction", "rle_below_px")),
    ExportFormat("yolo", "YOLO", dataset=True,
                 options=(*_CLASSES, "copy_images", "split", "split_seed", "min_pixels", "min_visible_fraction")),
    ExportFormat("rois", "ROI crops", writer="usdscene.converters.exports.rois:write_rois", catalog=True,
                 options=("min_roi_px",)),
    ExportFormat("mot", "MOTChallenge tracks", writer="usdscene.converters.exports.mot:write_mot",
                 check="usdscene.converters.exports.mot:check_mot", needs=frozenset({MOVING_SEQUENCE}),
                 options=(*_CLASSES, "copy_images", "mot_class_map", "mot_static_people", "mot_ignore_occluded",
                          "mot_layout")),
    ExportFormat("multiview", "WILDTRACK / MultiviewX multi-view positions",
                 writer="usdscene.converters.exports.multiview:write_multiview",
                 check="usdscene.converters.exports.multiview:check_multiview",
                 needs=frozenset({MOVING_SEQUENCE}), options=(*_CLASSES, "grid", "multiview_flavour")),
    ExportFormat("video", "H.264 MP4 per camera", writer="usdscene.converters.exports.video:write_video",
                 needs=frozenset({MOVING_SEQUENCE})),
    # The scene's map.png is a render of the environment (validate, compose, render), so its
    # writer sits with the other steps of a run, in usdscene.dataset.
    ExportFormat("aicity", "AI City Challenge scenes", writer="usdscene.dataset.aicity_scene:write_aicity",
                 needs=frozenset({MOVING_SEQUENCE}), catalog=True,
                 options=("aicity", "aicity_map", "aicity_videos", "aicity_map_samples", "aicity_map_cut_m")),
):
    register(_format)
