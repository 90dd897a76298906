"""``usdscene export aicity``: an annotated moving sequence as an AI City Challenge Track 1 scene
(the layout is :mod:`usdscene.converters.exports.aicity`). This module supplies what the pure
exporter cannot know: the class mapping's defaults, the catalog extents of the 3D boxes, the
top-down map rendered through the ordinary pipeline, and the videos (the video export's encoder).

**Classes.** By default the catalog's person classes (:func:`usdscene.generate.motion.person_classes`)
are ``Person``; every other class is left out (AIC has no name for cars, luggage or vans)
unless mapped with ``--aic-class CLASS=AIC_CLASS``.

**The map** (``map.png``) is a render of the environment alone (its lights and sky, no movers)
cut at ``map_cut_m`` (2.5 m: roofs and ceilings are left out, as on a floor plan) through one
orthographic camera looking straight down, image right = world +x and image up =
world +y, at ``map_m_per_px``: the scene's source document with its movers and cameras
replaced by that camera, validated, composed and rendered by the ordinary steps
(:func:`usdscene.validation.validate_document`, :func:`usdscene.scene.compose.compose_stage`,
:func:`usdscene.render.driver.render`) into a scratch folder of the output.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

MAP_CAMERA = "aic_map"
MAP_HEIGHT_ABOVE_M = 50.0
MAP_CUT_M = 2.5
"""Default height of the map's cut: a floor plan shows what lies below it (a roof deck, a
ceiling, a pole's top are left out: the near clip plane of the map camera lies at this height)."""


def default_class_map(catalog, given: Mapping[str, str]) -> dict[str, str]:
    """The catalog's person classes → ``Person``, then the ``given`` mapping over them."""
    from usdscene.generate.motion import person_classes

    mapping = {name: "Person" for name in (person_classes(catalog) if catalog is not None else ())}
    mapping.update(given)
    return mapping


def class_extents(catalog) -> dict:
    """class → (min, max) object-frame bounds in metres of every catalog class."""
    if catalog is None:
        return {}
    return {name: (catalog[name].extent_min_m, catalog[name].extent_max_m) for name in catalog.classes()}


def map_document(source: dict, frame_map, *, samples: int | None = None, cut_m: float = MAP_CUT_M) -> dict:
    """The environment-only document of the map: ``source`` without its movers, frames and cameras,
    with one orthographic camera over ``frame_map`` (a :class:`MapFrame`) that sees what lies
    below ``cut_m`` metres."""
    doc = json.loads(json.dumps(source))
    root = doc["openlabel"]
    meta = root.setdefault("metadata", {}).setdefault("usdscene", {})
    for key in ("exports", "frame_range", "fps", "split"):
        meta.pop(key, None)
    if samples is not None:
        meta.setdefault("render", {})["samples"] = int(samples)
    root["objects"] = {uid: o for uid, o in (root.get("objects") or {}).items() if o.get("type") in ("light", "place")}
    for key in ("frames", "relations", "coordinate_systems", "frame_intervals", "ontologies", "actions", "events",
                "contexts"):
        root.pop(key, None)
    # Keep object pointers from naming data of the dropped frames.
    for element in root["objects"].values():
        for pointer in (element.get("object_data_pointers") or {}).values():
            pointer["frame_intervals"] = []
        element.pop("frame_intervals", None)
    x0, y0, x1, y1 = frame_map.bounds_m
    root["streams"] = {MAP_CAMERA: {"type": "camera", "description": "AI City Challenge map: top-down orthographic",
                                    "stream_properties": {"usdscene": {
                                        "model": "orthographic",
                                        "resolution_px": [frame_map.width_px, frame_map.height_px],
                                        "ortho_width_m": frame_map.width_px / frame_map.scale_px_per_m,
                                        "position_m": [(x0 + x1) / 2.0, (y0 + y1) / 2.0, MAP_HEIGHT_ABOVE_M],
                                        # yaw 90, pitch -90: looking down, image right +x, image up +y
                                        "orientation_deg": [90.0, -90.0, 0.0],
                                        "clip_range_m": [MAP_HEIGHT_ABOVE_M - cut_m, MAP_HEIGHT_ABOVE_M + 50.0]}}}}
    return doc


def render_map(source_path: Path, scratch: Path, target: Path, frame_map, *, samples: int | None = None,
               cut_m: float = MAP_CUT_M) -> None:
    """Render the map of ``source_path``'s environment into ``target`` (``map.png``).

    The map document is written beside the source document (its asset paths are relative to
    that folder) under a hidden name and removed afterwards; the run goes to ``scratch``.
    """
    from usdscene.document import output_layout as layout
    from usdscene.render.driver import render
    from usdscene.scene.compose import compose_stage
    from usdscene.validation import validate_document

    doc = map_document(json.loads(source_path.read_text(encoding="utf-8")), frame_map, samples=samples, cut_m=cut_m)
    temporary = source_path.with_name(f".{source_path.stem}.aicity_map.{os.getpid()}.json")
    temporary.write_text(json.dumps(doc), encoding="utf-8")
    try:
        checked = validate_document(temporary)
        composed = compose_stage(checked.scene, checked.catalog, layout.stage_root(scratch).parent)
        render(composed.root_layer, scratch, frames=[composed.frame_start], cameras=[MAP_CAMERA], progress=False)
        image = layout.image_path(scratch, MAP_CAMERA, composed.frame_start)
        shutil.copyfile(image, target)
    finally:
        temporary.unlink(missing_ok=True)
        shutil.rmtree(scratch, ignore_errors=True)


def write_videos(folder: Path, images: Mapping[str, list[Path]], fps: float) -> None:
    """``<folder>/<name>.mp4`` of each camera's images (in frame order): the video export's own
    encoder (:mod:`usdscene.converters.exports.video`: H.264 yuv420p, crf 18, one thread)."""
    from usdscene.converters.exports.video import DEFAULT_CRF, encode_video, frame_rate
    from usdscene.errors import OutputError

    try:
        import av
    except ImportError:
        raise OutputError("the AI City Challenge videos need PyAV: pip install 'usdscene[aicity]' "
                          "(or export with --no-videos)", where="aicity videos") from None
    for name, paths in images.items():
        path = folder / f"{name}.mp4"
        path.parent.mkdir(parents=True, exist_ok=True)
        encode_video(av, path, list(paths), frame_rate(fps), DEFAULT_CRF)


@dataclass(frozen=True)
class SceneParts:
    """What :func:`export_aicity_scene` writes beside the pure exporter's files.

    Attributes:
        render_the_map: render ``map.png`` (2025); needs the scene's source document.
        map_samples: samples per pixel of the map render (None: the document's).
        map_cut_m: the map shows what lies below this height (metres).
        videos: write the videos (needs PyAV).
    """

    render_the_map: bool = True
    map_samples: int | None = None
    map_cut_m: float = MAP_CUT_M
    videos: bool = True


def export_aicity_scene(out_dir, document: dict, catalog, options, parts: SceneParts = SceneParts()) -> Path:
    """Write ``OUT/exports/aicity/<scene>/`` (:func:`usdscene.converters.exports.aicity.export_aicity`)
    with the defaults of this module; returns the scene folder.

    Args:
        out_dir: annotated output folder.
        document, catalog: its annotated document and catalog (None: no person classes, no extents).
        options: :class:`usdscene.converters.exports.aicity.AicOptions` (``class_map`` = the
            user's mapping, merged over the defaults here).
        parts: the map and the videos (:class:`SceneParts`).

    Raises:
        UsdSceneError: as the exporter; OutputError when the map needs a source document that is gone.
    """
    from dataclasses import replace

    from usdscene.converters.exports.aicity import export_aicity
    from usdscene.converters.exports.tracks import document_fps
    from usdscene.document import output_layout as layout
    from usdscene.errors import OutputError

    render_the_map, videos = parts.render_the_map, parts.videos
    map_samples, map_cut_m = parts.map_samples, parts.map_cut_m
    out = Path(out_dir)
    options = replace(options, class_map=default_class_map(catalog, options.class_map))
    write_map = None
    if render_the_map and options.edition == "2025":
        from usdscene.render.stage_reader import recorded_source

        source, _ = recorded_source(layout.stage_root(out))
        if source is None or not source.is_file():
            raise OutputError("the map renders the scene's source document, which the stage no longer finds; "
                              "export with --no-map", where=str(source or layout.stage_root(out)))
        scratch = out / ".aicity_map"

        def write_map(target, frame_map):
            render_map(source, scratch, target, frame_map, samples=map_samples, cut_m=map_cut_m)

    fps = document_fps(document) or 30.0
    environment = ((document["openlabel"].get("metadata") or {}).get("usdscene") or {}).get("environment") or ""
    bounds = None
    if catalog is not None and environment in catalog.classes():
        entry = catalog[environment]
        bounds = (entry.extent_min_m[0], entry.extent_min_m[1], entry.extent_max_m[0], entry.extent_max_m[1])
    return export_aicity(document, out, options, extents=class_extents(catalog), place=environment,
                         environment_bounds_m=bounds,
                         write_map=write_map,
                         write_videos=(lambda folder, images: write_videos(folder, images, fps)) if videos else None)


def write_aicity(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`):
    :func:`export_aicity_scene` of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    from usdscene.converters.exports.aicity import AicOptions

    options = job.options
    parts = SceneParts(render_the_map=options.aicity_map, map_samples=options.aicity_map_samples,
                       map_cut_m=options.aicity_map_cut_m, videos=options.aicity_videos)
    return export_aicity_scene(job.out_dir, job.document, job.catalog, options.aicity or AicOptions(), parts)
