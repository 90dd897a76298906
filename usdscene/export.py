"""Training sets from an annotated output: ``OUT/annotations.openlabel.json`` → COCO, YOLO, ROI crops.

Exporters read only the annotated document (and the asset catalog for class lists and place
regions), never internal state:

* ``coco``: ``OUT/exports/coco/annotations.json`` (see :mod:`usdscene.converters.coco`);
* ``yolo``: ``OUT/exports/yolo/{detect,segment}/`` with ``data.yaml`` (see :mod:`usdscene.converters.yolo`);
* ``rois``: ``OUT/exports/rois/<label>/*.png`` + ``index.csv`` (see :mod:`usdscene.converters.rois`).

Class lists come from the asset catalog (object and passenger classes, sorted), so ids are
the same for every scene built from one library; the catalog is the shipped library plus the
document's asset folders (relative to the source document recorded in the stage) plus
``extra_assets``.
"""

from __future__ import annotations

FORMATS = ("coco", "yolo", "rois")
"""Dataset formats :func:`export_formats` writes."""


def _source_folder(out_dir):
    """Folder of the stage's source document (asset paths are relative to it), else None."""
    import json
    import re
    from pathlib import Path

    from usdscene import layout

    root = layout.stage_root(out_dir)
    if not root.is_file():
        return None
    try:
        from pxr import Sdf
    except ImportError:  # a text search of the root layer is enough for one string
        match = re.search(r'string source = "((?:[^"\\]|\\.)*)"', root.read_text(encoding="utf-8"))
        source = json.loads(f'"{match.group(1)}"') if match else ""
    else:
        layer = Sdf.Layer.FindOrOpen(str(root))
        source = ((layer.customLayerData or {}).get("usdscene", {}) if layer else {}).get("source", "")
    return Path(source).parent if source else None


def load_export_catalog(document: dict, out_dir, extra_folders=()):
    """The catalog for an annotated document (see the module docstring)."""
    from pathlib import Path

    from usdscene.converters.openlabel import read_openlabel
    from usdscene.catalog import load_catalog

    scene = read_openlabel(document)
    base = _source_folder(out_dir) or Path(out_dir)
    extra = [Path(p).resolve() for p in extra_folders]  # given on the command line: consented
    return load_catalog([*scene.asset_paths, *extra], base_dir=base, consented=extra)


def export_formats(out_dir, formats, *, extra_assets=(), document_classes: bool = False,
                   copy_images: bool = False, min_roi_px: int = 8) -> dict:
    """Export ``OUT/annotations.openlabel.json`` to each of ``formats``.

    Args:
        out_dir: annotated output folder.
        formats: names from :data:`FORMATS`, in order (duplicates ignored).
        extra_assets: extra asset catalog folders (classes, place regions).
        document_classes: COCO/YOLO classes from the document's labelled types, not the catalog.
        copy_images: YOLO copies images instead of linking them.
        min_roi_px: ROIs: smallest crop side in pixels.

    Returns:
        format → folder written.

    Raises:
        OutputError: no annotations yet. AssetError: the catalog cannot be read.
    """
    import logging
    from pathlib import Path

    from usdscene.converters.openlabel import load_document
    from usdscene import layout
    from usdscene.errors import AssetError, OutputError

    out = Path(out_dir)
    path = out / layout.ANNOTATIONS_FILE
    if not path.is_file():
        raise OutputError("no annotations; run `usdscene annotate OUT` first", where=str(path))
    document = load_document(path)
    catalog = None
    try:
        catalog = load_export_catalog(document, out, extra_assets)
    except AssetError:
        if "rois" in formats or not document_classes:
            raise
    classes = None
    if catalog is not None and not document_classes:
        classes = [*catalog.classes("object"), *catalog.classes("passenger")]
        labelled = {e.get("type", "") for e in document["openlabel"].get("objects", {}).values()
                    if any(p.get("type") == "bbox" for p in e.get("object_data_pointers", {}).values())}
        unknown = sorted(labelled - set(classes))
        if unknown:
            logging.getLogger(__name__).warning("labelled types %s are not object classes of the catalog; "
                                                "they are left out (use --document-classes)", unknown)
    written = {}
    for fmt in dict.fromkeys(formats):
        if fmt == "coco":
            from usdscene.converters.coco import export_coco

            written[fmt] = export_coco(document, out, classes)
        elif fmt == "yolo":
            from usdscene.converters.yolo import export_yolo

            written[fmt] = export_yolo(document, out, classes, link_images=True, copy_images=copy_images)
        elif fmt == "rois":
            from usdscene.converters.rois import export_rois

            written[fmt] = export_rois(document, out, catalog, min_size_px=min_roi_px)
        else:
            raise OutputError(f"unknown export format {fmt!r}; expected one of {FORMATS}", where="exports")
    return written
