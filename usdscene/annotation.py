"""Labels of a rendered output folder: instance masks → ``OUT/annotations.openlabel.json``.

For every mask ``OUT/masks/<camera>/<frame:06d>.png`` (ids explained by ``OUT/masks/ids.json``):
tight boxes, polygons and pixel counts from the mask; amodal boxes, truncation and visible
fractions from the objects' triangles in the composed stage (``OUT/stage/scene.usda``)
projected through the exact camera the renderer used. The labels are added to the scene
document, which is, in this order: the ``document_path`` given; the source document recorded in
the stage when it still exists unchanged (same sha256); or the scene read back from the stage.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from usdscene.validation import DEFAULT_SCHEMA


def write_annotations(out_dir: str | os.PathLike, *, document_path: str | os.PathLike | None = None,
                      epsilon_px: float | None = None, min_visible_fraction: float = 0.0,
                      amodal: bool = True, progress: bool = False,
                      schema: str | os.PathLike | None | Literal["default"] = DEFAULT_SCHEMA):
    """Label every mask of a rendered output folder and write ``OUT/annotations.openlabel.json``
    atomically, never a document that the official schema rejects.

    Args:
        out_dir: output folder of a render.
        document_path, epsilon_px, min_visible_fraction, amodal, progress: as in
            :func:`annotate_output`.
        schema: official schema the written document must pass (see
            :func:`usdscene.validation.validate_document`); None: no schema check.

    Returns:
        ``(path written, usdscene.labels.Annotations)``.

    Raises:
        OutputError: no masks, unreadable masks, or a document the schema rejects (nothing
            is written then). DocumentError: the document does not match the render.
    """
    from usdscene import layout
    from usdscene.converters.openlabel import schema_problems
    from usdscene.errors import OutputError
    from usdscene.files import write_json_atomic
    from usdscene.validation import resolve_schema

    document, annotations = annotate_output(out_dir, document_path=document_path, epsilon_px=epsilon_px,
                                            min_visible_fraction=min_visible_fraction, amodal=amodal,
                                            progress=progress)
    schema_path = resolve_schema(schema)
    if schema_path is not None:
        problems = schema_problems(document, schema_path)
        if problems:
            raise OutputError(problems)
    return write_json_atomic(Path(out_dir) / layout.ANNOTATIONS_FILE, document), annotations


def _source_document(stage_path):
    """The stage's recorded source document when it still exists unchanged, else None."""
    import hashlib
    import logging

    from pxr import Sdf

    from usdscene import stage_schema

    layer = Sdf.Layer.FindOrOpen(str(stage_path))
    data = (layer.customLayerData or {}).get(stage_schema.LAYER_DATA_KEY, {}) if layer else {}
    source, digest = data.get("source", ""), data.get("sourceSha256", "")
    if not source or not Path(source).is_file():
        return None
    if digest and hashlib.sha256(Path(source).read_bytes()).hexdigest() != digest:
        logging.getLogger(__name__).warning("%s changed since the stage was composed; the labels go "
                                            "into the scene read back from the stage", source)
        return None
    return Path(source)


def annotate_output(out_dir, *, document_path=None, epsilon_px: float | None = None,
                    min_visible_fraction: float = 0.0, amodal: bool = True, progress: bool = False):
    """Label every mask of a rendered output folder.

    Args:
        out_dir: output folder (``stage/``, ``masks/``, ``masks/ids.json``).
        document_path: scene document to extend; None = see the module docstring.
        epsilon_px: polygon tolerance (None = :data:`usdscene.labels.DEFAULT_EPSILON_PX`).
        min_visible_fraction: minimum-visibility filter.
        amodal: compute amodal boxes and visible fractions from the stage geometry.
        progress: show a ``rich`` progress bar on stderr.

    Returns:
        ``(document, annotations)``: the annotated ``{"openlabel": ...}`` dict (not yet
        written) and the :class:`usdscene.labels.Annotations`.

    Raises:
        OutputError: no masks, unreadable mask or id map.
        DocumentError: the document does not match the render (unknown camera or object).
    """
    import dataclasses
    import json

    import cv2

    from usdscene.converters.openlabel import load_document, read_openlabel, write_openlabel
    from usdscene.converters.openlabel_annotations import add_annotations
    from usdscene import layout
    from usdscene.errors import OutputError
    from usdscene.amodal import amodal_projections
    from usdscene.labels import DEFAULT_EPSILON_PX, label_image, label_images

    out = Path(out_dir)
    epsilon = DEFAULT_EPSILON_PX if epsilon_px is None else float(epsilon_px)
    stage_path = layout.stage_root(out)
    id_file = out / layout.ID_MAP_FILE
    try:
        id_map = json.loads(id_file.read_text(encoding="utf-8"))
        ids = {int(k): str(v["uid"]) for k, v in id_map.items()}
        classes = {str(v["uid"]): str(v.get("class", "")) for v in id_map.values()}
    except FileNotFoundError:
        raise OutputError("no mask id map; render the output first", where=str(id_file)) from None
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise OutputError(f"unreadable mask id map: {exc}", where=str(id_file)) from None
    masks_dir = out / layout.MASKS_DIR
    pairs = sorted((int(p.stem), p.parent.name) for p in masks_dir.glob("*/*.png") if p.stem.isdigit())
    if not pairs:
        raise OutputError("no masks found; render the output first", where=str(masks_dir))

    if document_path is None and stage_path.is_file():
        document_path = _source_document(stage_path)
    if document_path is not None:
        document = load_document(document_path)
        scene = read_openlabel(document)
    else:
        from usdscene.converters.usd_stage import scene_from_stage

        # Keep the stage's scene (its uids are the mask map's) even where the writer has to
        # renumber uids for OpenLABEL; add_annotations matches those by name and class.
        scene = scene_from_stage(stage_path)
        document = write_openlabel(scene)

    cameras = {}
    geometry = None
    if amodal:
        from usdscene.render.stage_reader import read_stage_plan
        from usdscene.stage_geometry import StageGeometry

        # The cameras exactly as rendered (per-frame poses from the stage).
        cameras = {c.name: c for c in read_stage_plan(stage_path).cameras}
        geometry = StageGeometry(stage_path)

    bar = None
    if progress:
        from rich.progress import Progress

        bar = Progress(transient=True)
        bar.start()
        task = bar.add_task("annotating", total=len(pairs))
    images = []
    triangles_frame, triangles = None, {}
    try:
        for frame, camera_name in pairs:
            path = layout.mask_path(out, camera_name, frame)
            mask = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if mask is None or mask.ndim != 2 or mask.dtype.kind != "u":
                raise OutputError("not a single-channel 16-bit instance mask", where=str(path))
            amodal_masks = None
            camera = cameras.get(camera_name)
            if geometry is not None and camera is not None:
                if triangles_frame != frame:
                    triangles_frame, triangles = frame, geometry.triangles(frame, set(ids.values()))
                height, width = mask.shape
                intr = camera.intrinsics
                if (intr.width_px, intr.height_px) != (width, height):  # rendered at a resolution scale
                    sx, sy = width / intr.width_px, height / intr.height_px
                    camera = dataclasses.replace(camera, intrinsics=dataclasses.replace(
                        intr, width_px=width, height_px=height, fx_px=intr.fx_px * sx, fy_px=intr.fy_px * sy,
                        cx_px=(intr.cx_px + 0.5) * sx - 0.5, cy_px=(intr.cy_px + 0.5) * sy - 0.5))
                amodal_masks = amodal_projections(camera, triangles, frame)
                # Objects the camera does not see at all carry no label there.
                amodal_masks = {uid: a for uid, a in amodal_masks.items() if a.pixel_count}
            images.append(label_image(mask, ids, amodal_masks, classes=classes, camera=camera_name,
                                      frame=frame, epsilon_px=epsilon,
                                      min_visible_fraction=min_visible_fraction))
            if bar is not None:
                bar.advance(task)
    finally:
        if bar is not None:
            bar.stop()
    annotations = label_images(images, epsilon_px=epsilon, min_visible_fraction=min_visible_fraction)
    return add_annotations(document, scene, annotations, out), annotations
