"""``metadata`` of an OpenLABEL document: name, comment and the ``usdscene`` block. Pure module.

The ``metadata.usdscene`` block holds what a scene needs beyond OpenLABEL: the random seed, the
environment asset, extra asset folders, export formats, ROI rules, an explicit frame range and
the render settings (``docs/scene-format.md`` lists every key).
"""

from __future__ import annotations

from typing import Any, Mapping

from usdscene.document.model import MAX_BOUNCES, MAX_FPS, MAX_RENDER_SEED, MAX_SAMPLES, MAX_TILE_SIZE_PX, RenderSettings

from usdscene.converters.exports.registry import FORMATS, format_names
from usdscene.converters.openlabel.load import SCHEMA_VERSION, DocumentBody
from usdscene.converters.openlabel.values import (
    describe,
    read_bool,
    read_int,
    read_interval,
    read_number,
    read_object,
    read_resolution,
    read_text,
    suggest,
)
from usdscene.errors import ProblemCollector

METADATA_KEYS = ("seed", "environment", "asset_paths", "render", "exports", "roi_rules", "roi_ignore", "frame_range",
                 "split", "fps", "world")
RENDER_KEYS = ("engine", "device", "samples", "adaptive_threshold", "adaptive_min_samples", "denoise",
               "denoiser", "denoising_quality", "denoising_prefilter", "denoising_input_passes", "light_tree",
               "path_guiding", "clamp_indirect", "sampling_pattern", "fast_gi", "fast_gi_method",
               "fast_gi_ao_bounces", "fast_gi_distance_m", "scrambling_distance", "auto_scrambling_distance",
               "max_bounces", "caustics", "tile_size_px", "resolution_px", "seed", "depth")
# Depth image encodings (usdscene.render.depth.DEPTH_FORMATS; a constant here keeps the reader pure).
DEPTH_FORMATS = ("png16", "exr")
ENGINES = ("cycles", "eevee", "workbench")
DEVICES = ("cpu", "gpu")
DENOISERS = ("openimagedenoise", "optix")
DENOISING_QUALITIES = ("high", "balanced", "fast")
DENOISING_PREFILTERS = ("accurate", "fast", "none")
DENOISING_INPUT_PASSES = ("rgb_albedo_normal", "rgb_albedo", "rgb")
SAMPLING_PATTERNS = ("tabulated_sobol", "blue_noise")
FAST_GI_METHODS = ("replace", "add")
RENDER_LIMITS = {"samples": (MAX_SAMPLES, "Cycles' most samples"),
                 "tile_size_px": (MAX_TILE_SIZE_PX, "Cycles' largest tile"),
                 "max_bounces": (MAX_BOUNCES, "Cycles' most bounces"),
                 "fast_gi_ao_bounces": (MAX_BOUNCES, "Cycles' most bounces"),
                 "seed": (MAX_RENDER_SEED, "Cycles' largest seed")}


def read_metadata(doc: DocumentBody) -> dict:
    """The scene-wide settings of ``metadata``.

    Returns:
        ``name``, ``description``, ``render`` (:class:`RenderSettings`), ``seed``,
        ``environment`` (or None), ``asset_paths``, ``exports``, ``roi_rules``, ``roi_ignore``
        (names only: that they are catalog classes or kinds is checked against the catalog),
        ``frame_range`` (a :class:`FrameInterval` or None), ``fps`` (or None), ``world`` (a
        :class:`usdscene.document.imaging.World` or None), ``split_rule`` and ``split_seed``
        (``split``: ``{"rule", "seed"}``, checked by :mod:`usdscene.document.splits`), with defaults for what is absent
        or bad (the problem is recorded in ``doc``).
    """
    problems = doc.problems
    R = doc.root
    where = f"{R}.metadata"
    meta = doc.body.get("metadata")
    out: dict = dict(name="scene", description="", render=RenderSettings(), seed=0, environment=None,
                     asset_paths=(), exports=(), roi_rules={}, roi_ignore=(), frame_range=None, split_rule="",
                     split_seed=0, fps=None, world=None)
    if meta is None:
        problems.add(where, f"missing 'metadata' with 'schema_version': '{SCHEMA_VERSION}'")
        return out
    if not isinstance(meta, dict):
        problems.add(where, f"expected a JSON object, got {describe(meta)}")
        return out
    version = meta.get("schema_version")
    if version != SCHEMA_VERSION:
        problems.add(f"{where}.schema_version", f"expected '{SCHEMA_VERSION}', got {describe(version)}")
    if "name" in meta:
        name = read_text(meta["name"], f"{where}.name", problems)
        if name:
            out["name"] = name
    if "comment" in meta:
        comment = read_text(meta["comment"], f"{where}.comment", problems)
        out["description"] = comment or ""
    block = meta.get("usdscene")
    if block is None:
        return out
    where = f"{where}.usdscene"
    if not isinstance(block, dict):
        problems.add(where, f"expected a JSON object, got {describe(block)}")
        return out
    _read_usdscene_block(block, where, problems, out)
    return out


def _read_usdscene_block(block: Mapping, where: str, problems, out: dict) -> None:
    """Read ``metadata.usdscene`` (at ``where``) into ``out``, the result of :func:`read_metadata`."""
    for key in block:
        if key not in METADATA_KEYS:
            problems.add(f"{where}.{key}", f"unknown key {key!r}{suggest(key, METADATA_KEYS)}; "
                                           f"known keys: {', '.join(METADATA_KEYS)}")
    if "seed" in block:
        seed = read_int(block["seed"], f"{where}.seed", problems, non_negative=True)
        out["seed"] = seed if seed is not None else 0
    if "environment" in block:
        out["environment"] = read_text(block["environment"], f"{where}.environment", problems,
                                       non_empty=True)
    if "asset_paths" in block:
        out["asset_paths"] = _read_strings(block["asset_paths"], f"{where}.asset_paths", problems)
    if "exports" in block:
        exports = _read_strings(block["exports"], f"{where}.exports", problems)
        for index, fmt in enumerate(exports):
            if fmt not in FORMATS:
                problems.add(f"{where}.exports[{index}]",
                             f"unknown export format {fmt!r}; expected one of {', '.join(format_names())}")
        out["exports"] = exports
    if "roi_rules" in block:
        rules = read_object(block["roi_rules"], f"{where}.roi_rules", problems) or {}
        out["roi_rules"] = {k: v for k, v in rules.items()
                            if read_text(v, f"{where}.roi_rules.{k}", problems, non_empty=True)}
    if "roi_ignore" in block:
        out["roi_ignore"] = _read_strings(block["roi_ignore"], f"{where}.roi_ignore", problems)
    if "split" in block:
        from usdscene.document.splits import read_document_split

        rule, seed = read_document_split(block["split"], f"{where}.split", problems)
        if rule is not None:
            out["split_rule"], out["split_seed"] = rule.text, seed
    if "fps" in block:
        out["fps"] = read_fps(block["fps"], f"{where}.fps", problems)
    if "frame_range" in block:
        out["frame_range"] = read_interval(block["frame_range"], f"{where}.frame_range", problems)
    if "render" in block:
        out["render"] = read_render(block["render"], f"{where}.render", problems)
    if "world" in block:
        from usdscene.converters.openlabel.imaging import read_world

        out["world"] = read_world(block["world"], f"{where}.world", problems)


def read_fps(value: Any, where: str, problems: ProblemCollector) -> float | None:
    """``metadata.usdscene.fps``: a frame rate in (0, MAX_FPS] frames per second (None when bad)."""
    fps = read_number(value, where, problems)
    if fps is None:
        return None
    if not 0.0 < fps <= MAX_FPS:
        problems.add(where, f"frame rate {fps:g} fps is not in (0, {MAX_FPS:g}]; give frames per second, "
                            "e.g. 10 or 29.97")
        return None
    return float(fps)


def _read_strings(value: Any, where: str, problems: ProblemCollector) -> tuple[str, ...]:
    """A list of non-empty strings (bad items are reported and left out)."""
    if not isinstance(value, list):
        problems.add(where, f"expected a list of strings, got {describe(value)}")
        return ()
    out = []
    for index, item in enumerate(value):
        text = read_text(item, f"{where}[{index}]", problems, non_empty=True)
        if text:
            out.append(text)
    return tuple(out)


def read_render(value: Any, where: str, problems: ProblemCollector) -> RenderSettings:
    """``metadata.usdscene.render`` → :class:`RenderSettings` (defaults for bad or absent keys)."""
    block = read_object(value, where, problems)
    if block is None:
        return RenderSettings()
    P = problems
    kwargs: dict = {}
    for key, item in block.items():
        here = f"{where}.{key}"
        if key not in RENDER_KEYS:
            problems.add(here, f"unknown render setting {key!r}{suggest(key, RENDER_KEYS)}; "
                               f"known: {', '.join(RENDER_KEYS)}")
            continue
        parsed: Any
        if key in ("engine", "device", "denoiser", "denoising_quality", "denoising_prefilter",
                   "denoising_input_passes", "sampling_pattern", "fast_gi_method"):
            choices = {"engine": ENGINES, "device": DEVICES, "denoiser": DENOISERS,
                       "denoising_quality": DENOISING_QUALITIES,
                       "denoising_prefilter": DENOISING_PREFILTERS,
                       "denoising_input_passes": DENOISING_INPUT_PASSES,
                       "sampling_pattern": SAMPLING_PATTERNS, "fast_gi_method": FAST_GI_METHODS}[key]
            parsed = read_text(item, here, P)
            if parsed is not None and parsed not in choices:
                problems.add(here, f"unknown {key} {parsed!r}; expected one of {', '.join(choices)}")
                parsed = None
        elif key in ("samples", "tile_size_px"):
            parsed = read_int(item, here, P, positive=True, maximum=RENDER_LIMITS[key])
        elif key in ("max_bounces", "seed", "fast_gi_ao_bounces"):
            parsed = read_int(item, here, P, non_negative=True, maximum=RENDER_LIMITS[key])
        elif key == "adaptive_min_samples":
            parsed = read_int(item, here, P, non_negative=True, maximum=RENDER_LIMITS["samples"])
        elif key in ("adaptive_threshold", "clamp_indirect", "fast_gi_distance_m"):
            parsed = read_number(item, here, P, non_negative=True)
        elif key == "scrambling_distance":
            parsed = read_number(item, here, P, non_negative=True)
            if parsed is not None and parsed > 1:
                problems.add(here, f"scrambling distance {parsed:g} is above 1; expected a number in [0, 1] "
                                   "(1 = Cycles' full per-pixel scrambling, larger values change nothing)")
                parsed = None
        elif key in ("denoise", "caustics", "light_tree", "path_guiding", "fast_gi", "auto_scrambling_distance"):
            parsed = read_bool(item, here, P)
        elif key == "depth":
            if item is None:
                continue
            parsed = read_text(item, here, P)
            if parsed is not None and parsed not in DEPTH_FORMATS:
                problems.add(here, f"unknown depth format {parsed!r}; expected one of {', '.join(DEPTH_FORMATS)} "
                                   "(or null for no depth images)")
                parsed = None
        else:  # resolution_px
            parsed = read_resolution(item, here, P)
        if parsed is not None:
            kwargs[key] = parsed
    return RenderSettings(**kwargs)
