"""OpenLABEL 1.0.0 / VCD 4.3 documents → :class:`usdscene.model.SceneSpec`. Pure module.

The vocabulary is documented in ``docs/scene-format.md``; this module is its implementation.
Every problem of a document is collected with its JSON path (``openlabel.streams.cam_01.
stream_properties.usdscene.fov_deg``) and raised once as a :class:`DocumentError`.

Content that the scene model does not represent is read past without error: non-camera
streams, bounding boxes / cuboids / polygons and other geometric object data, per-frame
stream properties (per-frame intrinsics, sync), actions, events, contexts, tags, ontologies,
and relations that involve actions, events or contexts (their uids are still checked).
"""

from __future__ import annotations

import difflib
import hashlib
import json
import logging
import math
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from usdscene.errors import DocumentError, ProblemCollector
from usdscene.model import (
    Camera,
    FrameInterval,
    Intrinsics,
    LensModel,
    Light,
    LightKind,
    PlaceRef,
    Pose,
    Provenance,
    Randomization,
    Relation,
    RelationType,
    RenderSettings,
    SceneObject,
    SceneSpec,
    union_intervals,
)

from usdscene.converters.openlabel_values import (
    describe,
    pose_from_rotation,
    read_bool,
    read_int,
    read_interval,
    read_intervals,
    read_matrix4x4,
    read_number,
    read_numbers,
    read_object,
    read_text,
    read_transform,
    suggest,
)

if TYPE_CHECKING:
    from usdscene.catalog import Catalog

log = logging.getLogger(__name__)

SCHEMA_VERSION = "1.0.0"
LIGHT_TYPE = "light"
PLACE_TYPE = "place"
PLACEMENT_RELATIONS = frozenset(r.value for r in RelationType)
UID_PATTERN = re.compile(r"^(-?[0-9]+|[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12})$")
ROOT_KEYS = frozenset({"metadata", "streams", "coordinate_systems", "objects", "relations", "frames",
                       "frame_intervals", "actions", "events", "contexts", "ontologies", "resources",
                       "tags"})

# Kannala-Brandt (OpenCV fisheye) coefficients of the equisolid projection r = 2 f sin(θ/2):
# the Taylor series 2 sin(θ/2) = θ (1 - θ²/24 + θ⁴/1920 - θ⁶/322560 + θ⁸/92897280 - ...),
# exact to 1e-10 rad for θ <= 1.1 rad.
EQUISOLID_KB_COEFFS = (-1.0 / 24.0, 1.0 / 1920.0, -1.0 / 322560.0, 1.0 / 92897280.0)

# The friendly camera block ``stream_properties.usdscene``.
FRIENDLY_KEYS = ("model", "model_name", "resolution_px", "sensor_size_mm", "focal_length_mm", "fov_deg",
                 "distortion", "principal_point_px", "ortho_width_m", "position_m", "orientation_deg",
                 "target_m", "clip_range_m", "custom")
# Friendly keys that define optics; they may not be combined with calibrated intrinsics.
FRIENDLY_OPTICS = ("resolution_px", "focal_length_mm", "distortion", "principal_point_px", "ortho_width_m")
DEFAULT_SENSOR_WIDTH_MM = 36.0  # Blender's default sensor width
FOV_TOLERANCE_DEG = 0.5

METADATA_KEYS = ("seed", "environment", "asset_paths", "render", "exports", "roi_rules", "frame_range")
RENDER_KEYS = ("engine", "device", "samples", "adaptive_threshold", "denoise", "denoiser",
               "denoising_quality", "denoising_prefilter", "max_bounces", "caustics", "tile_size_px",
               "resolution_px", "seed")
ENGINES = ("cycles", "eevee", "workbench")
DEVICES = ("cpu", "gpu")
DENOISERS = ("openimagedenoise", "optix")
DENOISING_QUALITIES = ("high", "balanced", "fast")
DENOISING_PREFILTERS = ("accurate", "fast", "none")
EXPORT_FORMATS = ("coco", "yolo", "rois")

# Object data names (``object_data.<kind>[i].name``).
POSE_DATA = {"position_m": "vec", "rotation_xyz_deg": "vec", "rotation_quaternion_xyzw": "vec",
             "pose_matrix4x4": "vec"}
LIGHT_DATA = {"kind": "text", "power_w": "num", "color_rgb": "vec", "radius_m": "num",
              "spot_angle_deg": "num", "spot_blend": "num", "size_m": "vec", "sun_angle_deg": "num",
              **POSE_DATA}
OBJECT_DATA = {"appearance": "text", "color_rgb": "vec", "position_noise_m": "num",
               "rotation_noise_deg": "num", "random_color": "boolean", "random_appearance": "boolean",
               **POSE_DATA}
DATA_KINDS = ("text", "num", "vec", "boolean")

_NON_FINITE_TEXT = re.compile(r"NaN|Infinity|[eE]\+?[0-9]{3,}")
_BAD = object()  # marker: a value was present but invalid (problem already recorded)


# --------------------------------------------------------------------------------------------
# Loading


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
    document, _ = _load(source)
    return document


def _load(source: str | os.PathLike | Mapping) -> tuple[dict, Provenance]:
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
        scan_non_finite = True
    else:
        path = Path(source)
        label = str(path)
        try:
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
        # Python's json accepts NaN/Infinity (and 1e999 → inf); look for them only when the
        # text could hold one, so that a clean large document is not walked twice.
        scan_non_finite = bool(_NON_FINITE_TEXT.search(text))
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
    problems.raise_if_any(DocumentError)
    body = data[root_key]
    if isinstance(body, Mapping) and not isinstance(body, dict):
        body = dict(body)
    if not isinstance(body, dict):
        raise DocumentError(f"expected a JSON object, got {describe(body)}", where=root_key)
    if root_key == "vcd":
        body = _vcd_to_openlabel(body)
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


def _vcd_to_openlabel(vcd: Mapping) -> dict:
    """VCD 4.3 → OpenLABEL 1.0.0 (copies what it changes; the input is not modified)."""
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
    frames = out.get("frames")
    if isinstance(frames, dict):
        new_frames = {}
        for key, frame in frames.items():
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


# --------------------------------------------------------------------------------------------
# The reader


def read_openlabel(source: str | os.PathLike | Mapping, *, catalog: Catalog | None = None) -> SceneSpec:
    """Read a scene document into a :class:`SceneSpec`.

    Args:
        source: path of an OpenLABEL 1.0.0 / VCD 4.3 JSON file, or the parsed document.
        catalog: a :class:`usdscene.catalog.Catalog`; when given, object classes, place names
            and placement relations are checked against it. Without one those checks are
            skipped.

    Returns:
        The scene, with ``provenance`` describing the document that was read (path, sha256 of
        its bytes — of its canonical JSON for a mapping —, ``openlabel`` or ``vcd``, toolkit
        version).

    Raises:
        DocumentError: every problem of the document at once, each with its JSON path.
    """
    document, provenance = _load(source)
    return read_loaded(document, provenance, catalog=catalog)


def load_with_provenance(source: str | os.PathLike | Mapping) -> tuple[dict, Provenance]:
    """:func:`load_document` plus the provenance :func:`read_openlabel` would record, so that
    a caller that also needs the raw document (schema validation) parses the file once."""
    return _load(source)


def read_loaded(document: dict, provenance: Provenance, *, catalog: Catalog | None = None) -> SceneSpec:
    """:func:`read_openlabel` of a document returned by :func:`load_with_provenance`."""
    reader = _Reader(document["openlabel"], provenance.source_format)
    scene = reader.read(catalog)
    return SceneSpec(**{**scene, "provenance": provenance})


class _Reader:
    """One pass over one document; collects problems, raises once."""

    def __init__(self, body: Mapping, root_key: str) -> None:
        self.body = body
        self.root = root_key
        self.problems = ProblemCollector()
        self._sections: dict[str, Mapping] = {}

    # -- helpers -------------------------------------------------------------------------

    def add(self, where: str, message: str) -> None:
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

    # -- top level -----------------------------------------------------------------------

    def read(self, catalog) -> dict:
        R = self.root
        for key in self.body:
            if key not in ROOT_KEYS:
                self.add(f"{R}.{key}", f"unknown key {key!r} in the {R} object{suggest(key, ROOT_KEYS)}")
        settings = self.read_metadata()
        frames = self.read_frames_index()
        cameras = self.read_cameras(settings["render"], frames)
        lights, places, objects, uids = self.read_objects(frames)
        relations = self.read_relations(uids, lights, places, objects)
        self.check_frame_relations(frames)
        frame_start, frame_end = self.frame_range(settings, frames, lights, objects, relations)
        scene = dict(
            name=settings["name"], frame_start=frame_start, frame_end=frame_end,
            cameras=tuple(cameras), lights=tuple(lights), objects=tuple(objects), places=tuple(places),
            relations=tuple(relations), render=settings["render"], seed=settings["seed"],
            environment=settings["environment"], asset_paths=settings["asset_paths"],
            exports=settings["exports"], roi_rules=settings["roi_rules"],
            description=settings["description"])
        if catalog is not None:
            self.check_catalog(catalog, scene, uids)
        self.problems.raise_if_any(DocumentError)
        return scene

    # -- metadata ------------------------------------------------------------------------

    def read_metadata(self) -> dict:
        R = self.root
        where = f"{R}.metadata"
        meta = self.body.get("metadata")
        out: dict = dict(name="scene", description="", render=RenderSettings(), seed=0, environment=None,
                         asset_paths=(), exports=(), roi_rules={}, frame_range=None)
        if meta is None:
            self.add(where, f"missing 'metadata' with 'schema_version': '{SCHEMA_VERSION}'")
            return out
        if not isinstance(meta, dict):
            self.add(where, f"expected a JSON object, got {describe(meta)}")
            return out
        version = meta.get("schema_version")
        if version != SCHEMA_VERSION:
            self.add(f"{where}.schema_version", f"expected '{SCHEMA_VERSION}', got {describe(version)}")
        if "name" in meta:
            name = read_text(meta["name"], f"{where}.name", self.problems)
            if name:
                out["name"] = name
        if "comment" in meta:
            comment = read_text(meta["comment"], f"{where}.comment", self.problems)
            out["description"] = comment or ""
        block = meta.get("usdscene")
        if block is None:
            return out
        where = f"{where}.usdscene"
        if not isinstance(block, dict):
            self.add(where, f"expected a JSON object, got {describe(block)}")
            return out
        for key in block:
            if key not in METADATA_KEYS:
                self.add(f"{where}.{key}", f"unknown key {key!r}{suggest(key, METADATA_KEYS)}; "
                                           f"known keys: {', '.join(METADATA_KEYS)}")
        if "seed" in block:
            seed = read_int(block["seed"], f"{where}.seed", self.problems, non_negative=True)
            out["seed"] = seed if seed is not None else 0
        if "environment" in block:
            out["environment"] = read_text(block["environment"], f"{where}.environment", self.problems,
                                           non_empty=True)
        if "asset_paths" in block:
            out["asset_paths"] = self.read_strings(block["asset_paths"], f"{where}.asset_paths")
        if "exports" in block:
            exports = self.read_strings(block["exports"], f"{where}.exports")
            for index, fmt in enumerate(exports):
                if fmt not in EXPORT_FORMATS:
                    self.add(f"{where}.exports[{index}]",
                             f"unknown export format {fmt!r}; expected one of {', '.join(EXPORT_FORMATS)}")
            out["exports"] = exports
        if "roi_rules" in block:
            rules = read_object(block["roi_rules"], f"{where}.roi_rules", self.problems) or {}
            out["roi_rules"] = {k: v for k, v in rules.items()
                                if read_text(v, f"{where}.roi_rules.{k}", self.problems, non_empty=True)}
        if "frame_range" in block:
            out["frame_range"] = self.read_frame_range(block["frame_range"], f"{where}.frame_range")
        if "render" in block:
            out["render"] = self.read_render(block["render"], f"{where}.render")
        return out

    def read_strings(self, value: Any, where: str) -> tuple[str, ...]:
        if not isinstance(value, list):
            self.add(where, f"expected a list of strings, got {describe(value)}")
            return ()
        out = []
        for index, item in enumerate(value):
            text = read_text(item, f"{where}[{index}]", self.problems, non_empty=True)
            if text:
                out.append(text)
        return tuple(out)

    def read_frame_range(self, value: Any, where: str) -> FrameInterval | None:
        return read_interval(value, where, self.problems)

    def read_render(self, value: Any, where: str) -> RenderSettings:
        block = read_object(value, where, self.problems)
        if block is None:
            return RenderSettings()
        P = self.problems
        kwargs: dict = {}
        for key, item in block.items():
            here = f"{where}.{key}"
            if key not in RENDER_KEYS:
                self.add(here, f"unknown render setting {key!r}{suggest(key, RENDER_KEYS)}; "
                               f"known: {', '.join(RENDER_KEYS)}")
                continue
            parsed: Any
            if key in ("engine", "device", "denoiser", "denoising_quality", "denoising_prefilter"):
                choices = {"engine": ENGINES, "device": DEVICES, "denoiser": DENOISERS,
                           "denoising_quality": DENOISING_QUALITIES,
                           "denoising_prefilter": DENOISING_PREFILTERS}[key]
                parsed = read_text(item, here, P)
                if parsed is not None and parsed not in choices:
                    self.add(here, f"unknown {key} {parsed!r}; expected one of {', '.join(choices)}")
                    parsed = None
            elif key in ("samples", "tile_size_px"):
                parsed = read_int(item, here, P, positive=True)
            elif key in ("max_bounces", "seed"):
                parsed = read_int(item, here, P, non_negative=True)
            elif key == "adaptive_threshold":
                parsed = read_number(item, here, P, non_negative=True)
            elif key in ("denoise", "caustics"):
                parsed = read_bool(item, here, P)
            else:  # resolution_px
                parsed = self.read_resolution(item, here)
            if parsed is not None:
                kwargs[key] = parsed
        return RenderSettings(**kwargs)

    def read_resolution(self, value: Any, where: str) -> tuple[int, int] | None:
        if not isinstance(value, list) or len(value) != 2:
            self.add(where, f"expected [width, height] in pixels, got {describe(value)}")
            return None
        w = read_int(value[0], f"{where}[0]", self.problems, positive=True)
        h = read_int(value[1], f"{where}[1]", self.problems, positive=True)
        return (w, h) if w is not None and h is not None else None

    # -- frames --------------------------------------------------------------------------

    def read_frames_index(self) -> dict[int, Mapping]:
        """``frames`` as ``{frame number: frame object}`` (keys checked)."""
        R = self.root
        out: dict[int, Mapping] = {}
        for key, frame in self.section("frames").items():
            where = f"{R}.frames.{key}"
            if not isinstance(key, str) or not key.isdigit():
                self.add(where, f"frame keys are frame numbers (digits), got {key!r}")
                continue
            if not isinstance(frame, dict):
                self.add(where, f"expected a JSON object, got {describe(frame)}")
                continue
            out[int(key)] = frame
        return out

    def frame_range(self, settings: dict, frames: Mapping[int, Mapping], lights, objects,
                    relations) -> tuple[int, int]:
        explicit = settings["frame_range"]
        root_intervals = None
        if "frame_intervals" in self.body:
            root_intervals = read_intervals(self.body["frame_intervals"], f"{self.root}.frame_intervals",
                                            self.problems)
        if explicit is not None:
            return explicit.frame_start, explicit.frame_end
        if root_intervals:
            return min(iv.frame_start for iv in root_intervals), max(iv.frame_end for iv in root_intervals)
        intervals = [iv for element in (*lights, *objects, *relations) for iv in element.frame_intervals]
        intervals += [FrameInterval(f, f) for f in frames]
        merged = union_intervals(intervals)
        if not merged:
            return 0, 0
        return merged[0].frame_start, merged[-1].frame_end

    # -- cameras -------------------------------------------------------------------------

    def read_coordinate_systems(self, frames: Mapping[int, Mapping]):
        """Parents, static poses and per-frame poses of every coordinate system.

        Returns:
            (parents, static, per_frame): name → parent name ("" for a root); name → Pose of
            the system in its parent (identity if none given); frame → {name: Pose in parent}.
        """
        R = self.root
        parents: dict[str, str] = {}
        static: dict[str, Pose] = {}
        systems = self.section("coordinate_systems")
        for name, cs in systems.items():
            where = f"{R}.coordinate_systems.{name}"
            if not isinstance(cs, dict):
                self.add(where, f"expected a JSON object, got {describe(cs)}")
                continue
            parent = cs.get("parent")
            if not isinstance(parent, str):
                self.add(f"{where}.parent", f"expected the parent's name ('' for a root), got {describe(parent)}")
                parent = ""
            if parent and parent not in systems:
                self.add(f"{where}.parent", f"parent coordinate system {parent!r} does not exist")
                parent = ""
            if not isinstance(cs.get("type"), str):
                self.add(f"{where}.type", f"expected a string such as 'scene_cs', 'local_cs', 'sensor_cs', "
                                          f"got {describe(cs.get('type'))}")
            parents[name] = parent
            pose = Pose()
            if "pose_wrt_parent" in cs:
                read = read_transform(cs["pose_wrt_parent"], f"{where}.pose_wrt_parent", self.problems)
                pose = read if read is not None else pose
            static[name] = pose
        # cycles
        for name in parents:
            seen = {name}
            current = parents[name]
            while current:
                if current in seen:
                    self.add(f"{R}.coordinate_systems.{name}.parent",
                             f"the parent chain of {name!r} loops through {current!r}")
                    parents[name] = ""
                    break
                seen.add(current)
                current = parents.get(current, "")
        per_frame: dict[int, dict[str, Pose]] = {}
        for number, frame in frames.items():
            props = frame.get("frame_properties")
            if props is None:
                continue
            where = f"{R}.frames.{number}.frame_properties"
            if not isinstance(props, dict):
                self.add(where, f"expected a JSON object, got {describe(props)}")
                continue
            transforms = props.get("transforms")
            if transforms is None:
                continue
            if not isinstance(transforms, dict):
                self.add(f"{where}.transforms", f"expected a JSON object, got {describe(transforms)}")
                continue
            for tname, t in transforms.items():
                here = f"{where}.transforms.{tname}"
                if not isinstance(t, dict):
                    self.add(here, f"expected a JSON object, got {describe(t)}")
                    continue
                src, dst = t.get("src"), t.get("dst")
                bad = False
                for key, value in (("src", src), ("dst", dst)):
                    if not isinstance(value, str) or value not in parents:
                        self.add(f"{here}.{key}", f"coordinate system {describe(value)} does not exist")
                        bad = True
                if "transform_src_to_dst" not in t:
                    self.add(f"{here}.transform_src_to_dst", "missing 'transform_src_to_dst'")
                    continue
                pose = read_transform(t["transform_src_to_dst"], f"{here}.transform_src_to_dst", self.problems)
                if bad or pose is None:
                    continue
                # transform_src_to_dst maps points from src to dst coordinates
                # (X_dst = M · X_src, as the schema states), so a child → parent transform is
                # the child's pose in its parent, and parent → child its inverse.
                if parents.get(src) == dst:
                    per_frame.setdefault(number, {})[src] = pose
                elif parents.get(dst) == src:
                    per_frame.setdefault(number, {})[dst] = pose.inverse()
                else:
                    self.add(here, f"transforms must connect a coordinate system and its parent; "
                                   f"{src!r} and {dst!r} are not parent and child")
        return parents, static, per_frame

    def world_pose(self, name: str, parents, static, overrides: Mapping[str, Pose]) -> Pose:
        """Pose of coordinate system ``name`` in the root of its tree."""
        chain = []
        current = name
        while parents.get(current):
            chain.append(overrides.get(current, static[current]))
            current = parents[current]
        if not chain:
            return Pose()
        pose = chain[-1]
        for child in reversed(chain[:-1]):
            pose = pose.compose(child)
        return pose

    def read_cameras(self, render: RenderSettings, frames: Mapping[int, Mapping]) -> list[Camera]:
        R = self.root
        parents, static, per_frame = self.read_coordinate_systems(frames)
        streams = self.section("streams")
        for name in parents:
            cs = self.section("coordinate_systems").get(name)
            cs_type = cs.get("type") if isinstance(cs, dict) else None
            if cs_type in ("sensor_cs", "sensor") and name not in streams:
                self.add(f"{R}.coordinate_systems.{name}",
                         f"sensor coordinate system {name!r} has no stream of the same name")
        cameras = []
        for name, stream in streams.items():
            where = f"{R}.streams.{name}"
            if not isinstance(stream, dict):
                self.add(where, f"expected a JSON object, got {describe(stream)}")
                continue
            if stream.get("type") != "camera":
                if not isinstance(stream.get("type"), str):
                    self.add(f"{where}.type", f"expected 'camera', 'lidar', 'radar', 'gps_imu' or 'other', "
                                              f"got {describe(stream.get('type'))}")
                continue
            camera = self.read_camera(name, stream, where, render, parents, static, per_frame)
            if camera is not None:
                cameras.append(camera)
        return cameras

    def read_camera(self, name, stream, where, render, parents, static, per_frame) -> Camera | None:
        props = stream.get("stream_properties", {})
        if not isinstance(props, dict):
            self.add(f"{where}.stream_properties", f"expected a JSON object, got {describe(props)}")
            return None
        where_props = f"{where}.stream_properties"
        friendly = props.get("usdscene")
        if friendly is not None and not isinstance(friendly, dict):
            self.add(f"{where_props}.usdscene", f"expected a JSON object, got {describe(friendly)}")
            return None
        friendly = friendly or {}
        where_f = f"{where_props}.usdscene"
        for key in friendly:
            if key not in FRIENDLY_KEYS:
                self.add(f"{where_f}.{key}", f"unknown camera key {key!r}{suggest(key, FRIENDLY_KEYS)}; "
                                             f"known: {', '.join(FRIENDLY_KEYS)}")
        intrinsics = self.read_intrinsics(name, props, friendly, where_props, render)
        # pose: the coordinate system of the same name, else the friendly pose (read even when
        # the intrinsics are bad, so that all problems are reported in one pass)
        friendly_pose = self.read_friendly_pose(friendly, where_f)
        if intrinsics is _BAD:
            return None
        if intrinsics is None:
            log.warning("%s: camera stream %r has no intrinsics usdscene can use (intrinsics_pinhole, "
                        "intrinsics_fisheye, orthographic intrinsics_custom or stream_properties.usdscene); "
                        "it is not read as a camera", where, name)
            return None
        frame_poses: list[tuple[int, Pose]] = []
        if name in parents and (parents[name] or friendly_pose is None):
            pose = self.world_pose(name, parents, static, {})
            chain = set()
            current = name
            while parents.get(current):
                chain.add(current)
                current = parents[current]
            for number in sorted(per_frame):
                overrides = per_frame[number]
                if chain & overrides.keys():
                    frame_poses.append((number, self.world_pose(name, parents, static, overrides)))
            if parents[name] and friendly_pose not in (None, _BAD):
                self.add(f"{where_f}", f"camera {name!r} has a pose in coordinate system {name!r}; "
                                       f"remove position_m/orientation_deg/target_m from the friendly form")
        elif friendly_pose is _BAD:
            return None
        elif friendly_pose is not None:
            pose = friendly_pose
        else:
            if parents:
                self.add(where, f"camera stream {name!r} has no coordinate system of the same name "
                                f"(and no position_m in stream_properties.usdscene)")
                return None
            pose = Pose()
        clip = (0.01, 1000.0)
        if "clip_range_m" in friendly:
            values = read_numbers(friendly["clip_range_m"], f"{where_f}.clip_range_m", self.problems, lengths=(2,))
            if values is not None:
                if not 0 < values[0] < values[1]:
                    self.add(f"{where_f}.clip_range_m", f"expected [near, far] with 0 < near < far, got {list(values)}")
                else:
                    clip = values
        model_name = ""
        if "model_name" in friendly:
            model_name = read_text(friendly["model_name"], f"{where_f}.model_name", self.problems) or ""
        custom = {}
        if "custom" in friendly:
            custom = read_object(friendly["custom"], f"{where_f}.custom", self.problems) or {}
        description = stream.get("description", "")
        if not isinstance(description, str):
            self.add(f"{where}.description", f"expected a string, got {describe(description)}")
            description = ""
        return Camera(name=name, intrinsics=intrinsics, pose=pose, frame_poses=tuple(frame_poses),
                      clip_near_m=clip[0], clip_far_m=clip[1], model_name=model_name,
                      description=description, custom=dict(custom))

    def read_friendly_pose(self, friendly: Mapping, where: str):
        """Pose from ``position_m`` + ``orientation_deg`` or ``target_m``; None if absent."""
        if not any(k in friendly for k in ("position_m", "orientation_deg", "target_m")):
            return None
        if "position_m" not in friendly:
            self.add(f"{where}.position_m", "orientation_deg/target_m need a position_m [x, y, z] (metres)")
            return _BAD
        position = read_numbers(friendly["position_m"], f"{where}.position_m", self.problems, lengths=(3,))
        if "orientation_deg" in friendly and "target_m" in friendly:
            self.add(f"{where}.target_m", "give orientation_deg or target_m, not both")
            return _BAD
        yaw = pitch = roll = 0.0
        if "orientation_deg" in friendly:
            angles = read_numbers(friendly["orientation_deg"], f"{where}.orientation_deg", self.problems,
                                  lengths=(3,), what="angles [yaw, pitch, roll] in degrees")
            if angles is None:
                return _BAD
            yaw, pitch, roll = (math.radians(a) for a in angles)
        elif "target_m" in friendly:
            target = read_numbers(friendly["target_m"], f"{where}.target_m", self.problems, lengths=(3,))
            if target is None or position is None:
                return _BAD
            d = [t - p for t, p in zip(target, position)]
            if math.sqrt(sum(v * v for v in d)) < 1e-9:
                self.add(f"{where}.target_m", f"target_m {list(target)} equals position_m")
                return _BAD
            yaw = math.atan2(d[1], d[0])
            pitch = math.atan2(d[2], math.hypot(d[0], d[1]))
        else:
            self.add(f"{where}.orientation_deg", "position_m needs orientation_deg [yaw, pitch, roll] or target_m")
            return _BAD
        if position is None:
            return _BAD
        return pose_from_rotation(friendly_camera_rotation(yaw, pitch, roll), position)

    # -- intrinsics ----------------------------------------------------------------------

    def read_intrinsics(self, name: str, props: Mapping, friendly: Mapping, where: str,
                        render: RenderSettings):
        """Intrinsics, None (no usable intrinsics) or _BAD (problem recorded)."""
        where_f = f"{where}.usdscene"
        custom = props.get("intrinsics_custom")
        ortho_custom = isinstance(custom, dict) and custom.get("model") == "orthographic"
        present = [k for k in ("intrinsics_pinhole", "intrinsics_fisheye") if k in props]
        if ortho_custom:
            present.append("intrinsics_custom")
        if len(present) > 1:
            self.add(f"{where}.{present[1]}", f"give one calibration, not {' and '.join(present)}")
            return _BAD
        model = None
        if "model" in friendly:
            text = read_text(friendly["model"], f"{where_f}.model", self.problems)
            if text is None:
                return _BAD
            try:
                model = LensModel(text)
            except ValueError:
                self.add(f"{where_f}.model", f"unknown lens model {text!r}{suggest(text, [m.value for m in LensModel])}; "
                                             f"expected one of {', '.join(m.value for m in LensModel)}")
                return _BAD
        sensor_w = None
        if "sensor_size_mm" in friendly:
            size = read_numbers(friendly["sensor_size_mm"], f"{where_f}.sensor_size_mm", self.problems,
                                lengths=(2,), what="sensor [width, height] in mm")
            if size is None:
                return _BAD
            if size[0] <= 0 or size[1] <= 0:
                self.add(f"{where_f}.sensor_size_mm", f"sensor size must be positive, got {list(size)}")
                return _BAD
            sensor_w = size[0]
        if not present:
            if not friendly:
                return None
            return self.friendly_intrinsics(friendly, where_f, model, sensor_w, render)
        mixed = [k for k in FRIENDLY_OPTICS if k in friendly]
        if mixed:
            self.add(f"{where_f}.{mixed[0]}", f"{mixed[0]!r} cannot be combined with {present[0]}: give the "
                                              f"calibration or the friendly optics, not both")
            return _BAD
        kind = present[0]
        block = props[kind]
        here = f"{where}.{kind}"
        if not isinstance(block, dict):
            self.add(here, f"expected a JSON object, got {describe(block)}")
            return _BAD
        fov = None
        if "fov_deg" in friendly:
            fov = read_number(friendly["fov_deg"], f"{where_f}.fov_deg", self.problems, positive=True)
            if fov is None:
                return _BAD
        if kind == "intrinsics_pinhole":
            result = self.pinhole(block, here)
            allowed = (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE)
        elif kind == "intrinsics_fisheye":
            result = self.fisheye(block, here)
            allowed = (LensModel.OPENCV_FISHEYE, LensModel.FISHEYE_EQUIDISTANT, LensModel.FISHEYE_EQUISOLID)
        else:
            result = self.orthographic(block, here)
            allowed = (LensModel.ORTHOGRAPHIC,)
        if result is None:
            return _BAD
        lens, w, h, fx, fy, cx, cy, dist = result
        if model is not None:
            if model not in allowed:
                self.add(f"{where_f}.model", f"lens model {model.value!r} does not match {kind} "
                                             f"(expected {' or '.join(m.value for m in allowed)})")
                return _BAD
            if model is LensModel.PERSPECTIVE and dist:
                self.add(f"{here}", "lens model 'perspective' has no distortion; use 'opencv_pinhole' or "
                                    f"zero coefficients (got {list(dist)})")
                return _BAD
            if model is LensModel.FISHEYE_EQUIDISTANT:
                if any(dist):
                    self.add(here, f"lens model 'fisheye_equidistant' needs zero lens coefficients, got {list(dist)}")
                    return _BAD
                dist = ()
            elif model is LensModel.FISHEYE_EQUISOLID:
                if len(dist) != 4 or any(abs(a - b) > 1e-12 + 1e-9 * abs(b) for a, b in zip(dist, EQUISOLID_KB_COEFFS)):
                    self.add(here, "lens model 'fisheye_equisolid' is written as opencv_fisheye with the "
                                   f"coefficients {list(EQUISOLID_KB_COEFFS)}, got {list(dist)}")
                    return _BAD
                dist = ()
            lens = model
        if fov is not None and lens not in (LensModel.OPENCV_FISHEYE, LensModel.FISHEYE_EQUIDISTANT,
                                            LensModel.FISHEYE_EQUISOLID):
            self.add(f"{where_f}.fov_deg", f"with {kind}, fov_deg is the image circle of a fisheye lens; "
                                           f"lens model {lens.value!r} has none")
            return _BAD
        return Intrinsics(lens=lens, width_px=w, height_px=h, fx_px=fx, fy_px=fy, cx_px=cx, cy_px=cy,
                          distortion=dist, fov_deg=fov,
                          sensor_width_mm=sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM)

    def size(self, block: Mapping, where: str) -> tuple[int, int] | None:
        for key in ("width_px", "height_px"):
            if key not in block:
                self.add(f"{where}.{key}", f"missing {key!r}")
                return None
        w = read_int(block["width_px"], f"{where}.width_px", self.problems, positive=True)
        h = read_int(block["height_px"], f"{where}.height_px", self.problems, positive=True)
        return (w, h) if w is not None and h is not None else None

    def dialect(self, block: Mapping, where: str, keys: tuple[str, str], required: bool = True):
        """The value of one of two dialect keys (VCD ``..._3x4`` vs schema name); _BAD if both."""
        found = [k for k in keys if k in block]
        if len(found) == 2:
            self.add(f"{where}.{found[1]}", f"give {keys[0]!r} or {keys[1]!r}, not both")
            return _BAD, found[1]
        if not found:
            if required:
                self.add(f"{where}.{keys[1]}", f"missing {keys[1]!r} (or {keys[0]!r})")
                return _BAD, keys[1]
            return None, keys[1]
        return block[found[0]], found[0]

    def pinhole(self, block: Mapping, where: str):
        size = self.size(block, where)
        raw, key = self.dialect(block, where, ("camera_matrix_3x4", "camera_matrix"))
        if raw is _BAD:
            return None
        here = f"{where}.{key}"
        if isinstance(raw, list) and len(raw) == 9:
            self.add(here, "a 3x3 matrix (9 numbers) was given where the 3x4 camera matrix (12 numbers, "
                           "row-major) is expected")
            return None
        k = read_numbers(raw, here, self.problems, lengths=(12,))
        raw_d, dkey = self.dialect(block, where, ("distortion_coeffs_1xN", "distortion_coeffs"), required=False)
        if raw_d is _BAD:
            return None
        dist = self.opencv_distortion(raw_d, f"{where}.{dkey}") if raw_d is not None else ()
        if k is None or size is None or dist is None:
            return None
        fx, skew, cx, fy, cy = k[0], k[1], k[2], k[5], k[6]
        ok = True
        for index, value in ((0, fx), (5, fy)):
            if value <= 0:
                self.add(f"{here}[{index}]", f"focal length must be positive, got {value}")
                ok = False
        if skew != 0:
            self.add(f"{here}[1]", f"skew {skew} is not supported (the camera matrix must have 0 there)")
            ok = False
        if k[4] != 0 or k[8] != 0 or k[9] != 0 or k[10] != 1:
            self.add(here, f"not a camera matrix: expected [fx 0 cx t; 0 fy cy t; 0 0 1 t], got {list(k)}")
            ok = False
        if not ok:
            return None
        if k[3] or k[7] or k[11]:
            # Rectified stereo files (KITTI) fold the baseline into the 4th column; the camera's
            # position comes from its coordinate system, so the column is not used.
            log.warning("%s: the 4th column %s of the camera matrix is ignored (the pose comes from "
                        "the coordinate system)", here, [k[3], k[7], k[11]])
        lens = LensModel.OPENCV_PINHOLE if any(dist) else LensModel.PERSPECTIVE
        return lens, size[0], size[1], fx, fy, cx, cy, (dist if any(dist) else ())

    def opencv_distortion(self, raw: Any, where: str) -> tuple[float, ...] | None:
        """OpenCV (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [τx τy]]]]) → canonical: the shortest of
        4, 5, 8 coefficients that keeps every non-zero one."""
        values = read_numbers(raw, where, self.problems, lengths=(0, 4, 5, 8, 12, 14))
        if values is None:
            return None
        if len(values) > 8 and any(values[8:]):
            self.add(f"{where}[8]", f"thin-prism and tilt coefficients (index 8 and up) are not supported; "
                                    f"got {list(values[8:])}")
            return None
        values = values[:8]
        if len(values) == 8 and not any(values[5:]):
            values = values[:5]
        if len(values) == 5 and values[4] == 0:
            values = values[:4]
        return values

    def fisheye(self, block: Mapping, where: str):
        size = self.size(block, where)
        out = {}
        for names in (("focal_length_x", "focal_length_x_px"), ("focal_length_y", "focal_length_y_px"),
                      ("center_x", "center_x_px"), ("center_y", "center_y_px")):
            raw, key = self.dialect(block, where, names)
            if raw is _BAD:
                return None
            out[names[0]] = read_number(raw, f"{where}.{key}", self.problems,
                                        positive=names[0].startswith("focal"))
        raw_c, ckey = self.dialect(block, where, ("lens_coeffs_1xN", "lens_coeffs"))
        if raw_c is _BAD:
            return None
        coeffs = read_numbers(raw_c, f"{where}.{ckey}", self.problems, lengths=(4, 5))
        model = block.get("model", "opencv_fisheye")
        if model not in ("opencv_fisheye", "kannala", "radial_poly"):
            self.add(f"{where}.model", f"unknown fisheye model {describe(model)}; expected 'opencv_fisheye', "
                                       f"'kannala' or 'radial_poly'")
            return None
        if size is None or coeffs is None or None in out.values():
            return None
        fx, fy = out["focal_length_x"], out["focal_length_y"]
        if model == "radial_poly":
            # r_px = c1 θ + c2 θ² + c3 θ³ + c4 θ⁴ [+ c5 θ⁵]: a Kannala-Brandt lens only when the
            # even powers vanish: then f = c1, k1 = c3 / c1, k2 = c5 / c1.
            if coeffs[0] <= 0 or coeffs[1] != 0 or coeffs[3] != 0:
                self.add(f"{where}.{ckey}", f"radial_poly r = c1·θ + c2·θ² + c3·θ³ + c4·θ⁴ can only be read when "
                                            f"c1 > 0 and the even terms c2, c4 are 0 (then it is an opencv_fisheye "
                                            f"lens); got {list(coeffs)}")
                return None
            c1 = coeffs[0]
            k2 = coeffs[4] / c1 if len(coeffs) == 5 else 0.0
            aspect = fy / fx
            return LensModel.OPENCV_FISHEYE, size[0], size[1], c1, c1 * aspect, out["center_x"], out["center_y"], \
                (coeffs[2] / c1, k2, 0.0, 0.0)
        if len(coeffs) == 5:
            if coeffs[4] != 0:
                self.add(f"{where}.{ckey}[4]", f"a fifth lens coefficient ({coeffs[4]}) is not supported by "
                                               f"the opencv_fisheye model (k1..k4)")
                return None
            coeffs = coeffs[:4]
        return LensModel.OPENCV_FISHEYE, size[0], size[1], fx, fy, out["center_x"], out["center_y"], coeffs

    def orthographic(self, block: Mapping, where: str):
        size = self.size(block, where)
        values = {}
        for key in ("scale_x_px_per_m", "scale_y_px_per_m", "center_x_px", "center_y_px"):
            if key not in block:
                self.add(f"{where}.{key}", f"orthographic intrinsics_custom needs {key!r}")
                return None
            values[key] = read_number(block[key], f"{where}.{key}", self.problems, positive=key.startswith("scale"))
        if size is None or None in values.values():
            return None
        return (LensModel.ORTHOGRAPHIC, size[0], size[1], values["scale_x_px_per_m"], values["scale_y_px_per_m"],
                values["center_x_px"], values["center_y_px"], ())

    def friendly_intrinsics(self, friendly: Mapping, where: str, model: LensModel | None,
                            sensor_w: float | None, render: RenderSettings):
        P = self.problems
        if model is None:
            self.add(f"{where}.model", f"missing 'model' (one of {', '.join(m.value for m in LensModel)})")
            return _BAD
        if "resolution_px" in friendly:
            resolution = self.read_resolution(friendly["resolution_px"], f"{where}.resolution_px")
            if resolution is None:
                return _BAD
        else:
            resolution = render.resolution_px
        w, h = resolution
        focal = fov = None
        if "focal_length_mm" in friendly:
            focal = read_number(friendly["focal_length_mm"], f"{where}.focal_length_mm", P, positive=True)
            if focal is None:
                return _BAD
        if "fov_deg" in friendly:
            fov = read_number(friendly["fov_deg"], f"{where}.fov_deg", P, positive=True)
            if fov is None:
                return _BAD
            limit = 180.0 if model in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE) else 360.0
            if fov >= limit:
                self.add(f"{where}.fov_deg", f"a {model.value} lens needs fov_deg < {limit:g}, got {fov:g}")
                return _BAD
        dist: tuple[float, ...] = ()
        if "distortion" in friendly:
            if model is LensModel.OPENCV_PINHOLE:
                dist = self.opencv_distortion(friendly["distortion"], f"{where}.distortion")
            elif model is LensModel.OPENCV_FISHEYE:
                dist = read_numbers(friendly["distortion"], f"{where}.distortion", P, lengths=(4,),
                                    what="Kannala-Brandt coefficients k1..k4")
            else:
                self.add(f"{where}.distortion", f"lens model {model.value!r} has no distortion coefficients; "
                                                f"use 'opencv_pinhole' or 'opencv_fisheye'")
                return _BAD
            if dist is None:
                return _BAD
        elif model is LensModel.OPENCV_FISHEYE:
            dist = (0.0, 0.0, 0.0, 0.0)
        if "ortho_width_m" in friendly and model is not LensModel.ORTHOGRAPHIC:
            self.add(f"{where}.ortho_width_m", f"ortho_width_m is for the orthographic model, not {model.value!r}")
            return _BAD
        sensor = sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM
        circle = None
        if model is LensModel.ORTHOGRAPHIC:
            if "ortho_width_m" not in friendly:
                self.add(f"{where}.ortho_width_m", "the orthographic model needs ortho_width_m (view width in metres)")
                return _BAD
            width_m = read_number(friendly["ortho_width_m"], f"{where}.ortho_width_m", P, positive=True)
            if width_m is None:
                return _BAD
            for key in ("focal_length_mm", "fov_deg"):
                if key in friendly:
                    self.add(f"{where}.{key}", f"{key} has no meaning for an orthographic camera")
                    return _BAD
            fx = w / width_m
        elif model in (LensModel.PERSPECTIVE, LensModel.OPENCV_PINHOLE):
            fx_or_none = self.pinhole_focal(friendly, where, focal, fov, sensor_w, w)
            if fx_or_none is None:
                return _BAD
            fx, sensor = fx_or_none
        elif model is LensModel.FISHEYE_EQUIDISTANT:
            # Blender maps fisheye_fov across the full sensor width: r_px = θ · w / fov_rad.
            if fov is None and focal is None:
                self.add(f"{where}.fov_deg", "a fisheye_equidistant lens needs fov_deg (or focal_length_mm)")
                return _BAD
            if fov is not None and focal is not None and sensor_w is not None:
                implied = math.degrees(sensor_w / focal)
                if abs(implied - fov) > FOV_TOLERANCE_DEG:
                    self.add(f"{where}.fov_deg", f"focal_length_mm {focal:g} on a {sensor_w:g} mm wide sensor "
                                                 f"implies a horizontal FOV of {implied:.1f}° for a fisheye_equidistant "
                                                 f"lens, not {fov:g}°")
                    return _BAD
            if fov is not None:
                fx = w / math.radians(fov)
                if focal is not None and sensor_w is None:
                    sensor = focal * math.radians(fov)
            else:
                fx = focal * w / sensor
                fov = math.degrees(w / fx)
            circle = fov
        else:  # FISHEYE_EQUISOLID, OPENCV_FISHEYE: r = f·g(θ) on the sensor; fov crops the circle
            if focal is None:
                self.add(f"{where}.focal_length_mm", f"a {model.value} lens needs focal_length_mm "
                                                     f"(and sensor_size_mm, default {DEFAULT_SENSOR_WIDTH_MM:g} mm wide)")
                return _BAD
            fx = focal * w / sensor
            circle = fov
        cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        if "principal_point_px" in friendly:
            pp = read_numbers(friendly["principal_point_px"], f"{where}.principal_point_px", P, lengths=(2,))
            if pp is None:
                return _BAD
            cx, cy = pp
        return Intrinsics(lens=model, width_px=w, height_px=h, fx_px=fx, fy_px=fx, cx_px=cx, cy_px=cy,
                          distortion=tuple(dist), fov_deg=circle, sensor_width_mm=sensor)

    def pinhole_focal(self, friendly, where, focal, fov, sensor_w, w) -> tuple[float, float] | None:
        """(fx_px, sensor_width_mm) of a pinhole from any two of focal, FOV, sensor width."""
        if focal is None and fov is None:
            self.add(f"{where}.fov_deg", "a pinhole camera needs fov_deg or focal_length_mm "
                                         "(with sensor_size_mm)")
            return None
        if focal is not None and fov is not None and sensor_w is not None:
            implied = math.degrees(2 * math.atan(sensor_w / (2 * focal)))
            if abs(implied - fov) > FOV_TOLERANCE_DEG:
                self.add(f"{where}.fov_deg", fov_mismatch_message(focal, sensor_w, fov, implied))
                return None
        if focal is not None and fov is not None and sensor_w is None:
            sensor = 2 * focal * math.tan(math.radians(fov) / 2)
            return w / (2 * math.tan(math.radians(fov) / 2)), sensor
        sensor = sensor_w if sensor_w is not None else DEFAULT_SENSOR_WIDTH_MM
        if fov is not None:
            return w / (2 * math.tan(math.radians(fov) / 2)), sensor
        return focal * w / sensor, sensor

    # -- objects -------------------------------------------------------------------------

    def data_items(self, data: Any, where: str, known: Mapping[str, str], strict: bool) -> dict | None:
        """``object_data`` → {name: (kind, val, where)} for the names in ``known``.

        Unknown names are errors when ``strict`` (lights: our own type); otherwise they are
        somebody else's annotations and pass, unless they look like a misspelt known name.
        """
        if data is None:
            return {}
        if not isinstance(data, dict):
            self.add(where, f"expected a JSON object, got {describe(data)}")
            return None
        out: dict = {}
        seen: set = set()
        for kind, items in data.items():
            if not isinstance(items, list):
                self.add(f"{where}.{kind}", f"expected a list, got {describe(items)}")
                continue
            for index, item in enumerate(items):
                here = f"{where}.{kind}[{index}]"
                if not isinstance(item, dict):
                    self.add(here, f"expected a JSON object, got {describe(item)}")
                    continue
                name = item.get("name")
                if not isinstance(name, str):
                    if kind in DATA_KINDS and (strict or name is not None):
                        self.add(f"{here}.name", f"expected a name, got {describe(name)}")
                    continue
                if name in seen:
                    self.add(f"{here}.name", f"duplicate object data name {name!r} in one element")
                    continue
                seen.add(name)
                if name not in known:
                    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.75)
                    # a near miss of a known name of the same kind is a typo, not foreign data
                    if kind in DATA_KINDS and (strict or (close and known[close[0]] == kind)):
                        self.add(f"{here}.name", f"unknown {kind} {name!r}{suggest(name, known)}; known: "
                                                 f"{', '.join(known)}")
                    continue
                if known[name] != kind:
                    self.add(here, f"{name!r} must be a {known[name]!r} entry, not {kind!r}")
                    continue
                if "val" not in item:
                    self.add(f"{here}.val", f"{name!r} has no 'val'")
                    continue
                out[name] = (kind, item["val"], f"{here}.val")
        return out

    def data_pose(self, items: Mapping, where: str):
        """Pose from ``pose_matrix4x4`` or ``position_m`` [+ ``rotation_xyz_deg`` |
        ``rotation_quaternion_xyzw``]; None if absent, _BAD if invalid."""
        P = self.problems
        if "pose_matrix4x4" in items:
            clash = [k for k in ("position_m", "rotation_xyz_deg", "rotation_quaternion_xyzw") if k in items]
            if clash:
                self.add(items[clash[0]][2], f"give pose_matrix4x4 or {clash[0]}, not both")
                return _BAD
            pose = read_matrix4x4(items["pose_matrix4x4"][1], items["pose_matrix4x4"][2], P)
            return _BAD if pose is None else pose
        rotations = [k for k in ("rotation_xyz_deg", "rotation_quaternion_xyzw") if k in items]
        if "position_m" not in items:
            if rotations:
                self.add(items[rotations[0]][2], f"{rotations[0]} needs a position_m vec [x, y, z] (metres)")
                return _BAD
            return None
        position = read_numbers(items["position_m"][1], items["position_m"][2], P, lengths=(3,))
        if len(rotations) > 1:
            self.add(items[rotations[1]][2], "give rotation_xyz_deg or rotation_quaternion_xyzw, not both")
            return _BAD
        rotation: Any = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
        if rotations == ["rotation_xyz_deg"]:
            angles = read_numbers(items["rotation_xyz_deg"][1], items["rotation_xyz_deg"][2], P, lengths=(3,),
                                  what="angles [rx, ry, rz] in degrees")
            if angles is None:
                return _BAD
            from usdscene.model import euler_zyx_to_rotation

            rotation = euler_zyx_to_rotation(math.radians(angles[2]), math.radians(angles[1]),
                                             math.radians(angles[0]))
        elif rotations:
            quaternion = read_numbers(items["rotation_quaternion_xyzw"][1], items["rotation_quaternion_xyzw"][2],
                                      P, lengths=(4,))
            if quaternion is None:
                return _BAD
            if math.sqrt(sum(q * q for q in quaternion)) < 1e-9:
                self.add(items["rotation_quaternion_xyzw"][2], f"quaternion {list(quaternion)} has zero length")
                return _BAD
            from usdscene.model import quaternion_to_rotation

            rotation = quaternion_to_rotation(quaternion)
        if position is None:
            return _BAD
        return pose_from_rotation(rotation, position)

    def read_objects(self, frames: Mapping[int, Mapping]):
        R = self.root
        lights: list[Light] = []
        places: list[PlaceRef] = []
        objects: list[SceneObject] = []
        uids: dict[str, str] = {}  # uid → "light" | "place" | "object" (| "other" for bad ones)
        place_names: dict[str, str] = {}
        light_names: dict[str, str] = {}
        frame_poses = self.read_frame_object_poses(frames)
        for uid, obj in self.section("objects").items():
            where = f"{R}.objects.{uid}"
            uids[uid] = "other"
            if not UID_PATTERN.match(uid):
                self.add(where, f"object uid {uid!r} must be an integer string or a UUID")
            if not isinstance(obj, dict):
                self.add(where, f"expected a JSON object, got {describe(obj)}")
                continue
            name = obj.get("name")
            if not isinstance(name, str):
                self.add(f"{where}.name", f"expected the object's name (a string), got {describe(name)}")
                name = ""
            otype = obj.get("type")
            if not isinstance(otype, str) or not otype:
                self.add(f"{where}.type", f"expected the object's type (class name), got {describe(otype)}")
                continue
            intervals: tuple[FrameInterval, ...] = ()
            if "frame_intervals" in obj:
                intervals = read_intervals(obj["frame_intervals"], f"{where}.frame_intervals", self.problems) or ()
            if otype == PLACE_TYPE:
                uids[uid] = "place"
                if not name:
                    self.add(f"{where}.name", "a place needs its name in the environment (e.g. 'seat_03A')")
                    continue
                if name in place_names:
                    self.add(f"{where}.name", f"place {name!r} is already object {place_names[name]}")
                    continue
                place_names[name] = uid
                places.append(PlaceRef(uid=uid, name=name))
                if uid in frame_poses:
                    self.add(frame_poses[uid][0][2], "places have no per-frame poses (their geometry is "
                                                     "in the environment asset)")
            elif otype == LIGHT_TYPE:
                uids[uid] = "light"
                if name in light_names:
                    self.add(f"{where}.name", f"light name {name!r} is already used by object {light_names[name]}")
                light_names[name] = uid
                light = self.read_light(uid, name, obj, where, intervals)
                if light is not None:
                    lights.append(light)
                if uid in frame_poses:
                    self.add(frame_poses[uid][0][2], "lights have no per-frame poses")
            else:
                uids[uid] = "object"
                scene_object = self.read_scene_object(uid, name, otype, obj, where, intervals,
                                                      tuple((f, p) for f, p, _ in frame_poses.get(uid, ())))
                if scene_object is not None:
                    objects.append(scene_object)
        return lights, places, objects, uids

    def read_frame_object_poses(self, frames: Mapping[int, Mapping]) -> dict[str, list]:
        """uid → [(frame, Pose, where)] from ``frames[f].objects[uid].object_data``; frame
        entries of uids that are not objects are reported as dangling."""
        out: dict[str, list] = {}
        R = self.root
        known = self.body.get("objects", {})
        known = known if isinstance(known, dict) else {}
        dangling: set = set()
        for number, where, objs in self.frame_sections(frames, "objects"):
            for uid, entry in objs.items():
                if uid not in known:
                    if uid not in dangling:
                        dangling.add(uid)
                        self.add(f"{where}.{uid}", f"object {uid!r} does not exist in {R}.objects")
                    continue
                if not entry:
                    continue
                if not isinstance(entry, dict):
                    self.add(f"{where}.{uid}", f"expected a JSON object, got {describe(entry)}")
                    continue
                items = self.data_items(entry.get("object_data"), f"{where}.{uid}.object_data", POSE_DATA,
                                        strict=False)
                if not items:
                    continue
                pose = self.data_pose(items, f"{where}.{uid}.object_data")
                if pose is not None and pose is not _BAD:
                    out.setdefault(uid, []).append((number, pose, f"{where}.{uid}"))
        return out

    def read_light(self, uid, name, obj, where, intervals) -> Light | None:
        P = self.problems
        items = self.data_items(obj.get("object_data"), f"{where}.object_data", LIGHT_DATA, strict=True)
        if items is None:
            return None
        kwargs: dict = {}
        if "kind" not in items:
            self.add(f"{where}.object_data", "a light needs a text 'kind': point, spot, sun or area")
            return None
        kind_text = read_text(items["kind"][1], items["kind"][2], P)
        if kind_text is None:
            return None
        try:
            kind = LightKind(kind_text)
        except ValueError:
            self.add(items["kind"][2], f"unknown light kind {describe(kind_text)}; expected point, spot, sun or area")
            return None
        for key, opts in (("power_w", dict(non_negative=True)), ("radius_m", dict(non_negative=True)),
                          ("spot_angle_deg", dict(positive=True)), ("spot_blend", dict(non_negative=True)),
                          ("sun_angle_deg", dict(non_negative=True))):
            if key in items:
                value = read_number(items[key][1], items[key][2], P, **opts)
                if value is not None:
                    if key == "spot_angle_deg" and value > 180:
                        self.add(items[key][2], f"spot_angle_deg is the full cone angle, at most 180, got {value:g}")
                    elif key == "spot_blend" and value > 1:
                        self.add(items[key][2], f"spot_blend is in [0, 1], got {value:g}")
                    else:
                        kwargs[key] = value
        if "color_rgb" in items:
            color = self.read_color(items["color_rgb"])
            if color is not None:
                kwargs["color_rgb"] = color
        if "size_m" in items:
            size = read_numbers(items["size_m"][1], items["size_m"][2], P, lengths=(2,), what="[width, height] in metres")
            if size is not None:
                if min(size) <= 0:
                    self.add(items["size_m"][2], f"area light size must be positive, got {list(size)}")
                else:
                    kwargs["size_m"] = size
        pose = self.data_pose(items, f"{where}.object_data")
        if pose is _BAD:
            return None
        if pose is None:
            self.add(f"{where}.object_data", "a light needs a pose: vec 'position_m' (+ 'rotation_xyz_deg' or "
                                             "'rotation_quaternion_xyzw') or vec 'pose_matrix4x4'")
            return None
        return Light(uid=uid, name=name, kind=kind, pose=pose, frame_intervals=intervals, **kwargs)

    def read_color(self, item) -> tuple[float, float, float] | None:
        color = read_numbers(item[1], item[2], self.problems, lengths=(3,), what="linear RGB values")
        if color is None:
            return None
        if min(color) < 0 or max(color) > 1:
            self.add(item[2], f"colour components are linear RGB in [0, 1], got {list(color)}")
            return None
        return color  # type: ignore[return-value]

    def read_scene_object(self, uid, name, otype, obj, where, intervals, frame_poses) -> SceneObject | None:
        P = self.problems
        items = self.data_items(obj.get("object_data"), f"{where}.object_data", OBJECT_DATA, strict=False)
        if items is None:
            return None
        kwargs: dict = {}
        if "appearance" in items:
            kwargs["appearance"] = read_text(items["appearance"][1], items["appearance"][2], P, non_empty=True)
        if "color_rgb" in items:
            kwargs["color_rgb"] = self.read_color(items["color_rgb"])
        knobs: dict = {}
        for key in ("position_noise_m", "rotation_noise_deg"):
            if key in items:
                value = read_number(items[key][1], items[key][2], P, non_negative=True)
                if value is not None:
                    knobs[key] = value
        for key in ("random_color", "random_appearance"):
            if key in items:
                value = read_bool(items[key][1], items[key][2], P)
                if value is not None:
                    knobs[key] = value
        pose = self.data_pose(items, f"{where}.object_data")
        if pose is _BAD:
            return None
        return SceneObject(uid=uid, name=name, class_name=otype, frame_intervals=intervals, pose=pose,
                           frame_poses=frame_poses, randomization=Randomization(**knobs), **kwargs)

    # -- relations -----------------------------------------------------------------------

    def read_relations(self, uids, lights, places, objects) -> list[Relation]:
        R = self.root
        others = {kind: self.section(kind) for kind in ("actions", "events", "contexts")}
        relations = []
        for ruid, rel in self.section("relations").items():
            where = f"{R}.relations.{ruid}"
            if not UID_PATTERN.match(ruid):
                self.add(where, f"relation uid {ruid!r} must be an integer string or a UUID")
            if not isinstance(rel, dict):
                self.add(where, f"expected a JSON object, got {describe(rel)}")
                continue
            rtype = rel.get("type")
            if not isinstance(rtype, str) or not rtype:
                self.add(f"{where}.type", f"expected the relation type (e.g. 'is_below'), got {describe(rtype)}")
                continue
            agents = {}
            ok = True
            for side in ("rdf_subjects", "rdf_objects"):
                entries = rel.get(side)
                if not isinstance(entries, list) or not entries:
                    self.add(f"{where}.{side}", f"expected a non-empty list of {{'uid', 'type'}}, got {describe(entries)}")
                    ok = False
                    continue
                agents[side] = []
                for index, agent in enumerate(entries):
                    here = f"{where}.{side}[{index}]"
                    if not isinstance(agent, dict) or not isinstance(agent.get("uid"), str):
                        self.add(here, f"expected {{'uid': str, 'type': 'object'}}, got {describe(agent)}")
                        ok = False
                        continue
                    kind = agent.get("type", "object")
                    if kind not in ("object", "action", "event", "context"):
                        self.add(f"{here}.type", f"expected object, action, event or context, got {describe(kind)}")
                        ok = False
                        continue
                    target = agent["uid"]
                    exists = target in uids if kind == "object" else target in others[kind + "s"]
                    if not exists:
                        self.add(f"{here}.uid", f"relation {ruid} refers to {kind} {target!r}, which does not exist")
                        ok = False
                        continue
                    agents[side].append((kind, target))
            intervals: tuple[FrameInterval, ...] = ()
            if "frame_intervals" in rel:
                intervals = read_intervals(rel["frame_intervals"], f"{where}.frame_intervals", self.problems) or ()
            if not ok:
                continue
            if any(kind != "object" for side in agents.values() for kind, _ in side):
                log.debug("%s: relation with actions/events/contexts is not modelled", where)
                continue
            if len(agents["rdf_subjects"]) != 1 or len(agents["rdf_objects"]) != 1:
                self.add(where, f"relation {ruid} has {len(agents['rdf_subjects'])} subjects and "
                                f"{len(agents['rdf_objects'])} objects; usdscene relations have exactly one of each")
                continue
            subject, target = agents["rdf_subjects"][0][1], agents["rdf_objects"][0][1]
            if rtype in PLACEMENT_RELATIONS:
                if uids.get(subject) != "object":
                    self.add(f"{where}.rdf_subjects[0].uid",
                             f"{rtype} places a dynamic object, but {subject!r} is a {uids.get(subject)}")
                    continue
                if uids.get(target) not in ("object", "place"):
                    self.add(f"{where}.rdf_objects[0].uid",
                             f"{rtype} needs a place or a dynamic object, but {target!r} is a {uids.get(target)}")
                    continue
                if subject == target:
                    self.add(f"{where}.rdf_objects[0].uid", f"object {subject!r} cannot be {rtype} itself")
                    continue
            relations.append(Relation(uid=ruid, type=rtype, subject_uid=subject, object_uid=target,
                                      frame_intervals=intervals))
        return relations

    def frame_sections(self, frames: Mapping[int, Mapping], key: str):
        """``(frame, JSON path, frames[f][key])`` for every frame, in frame order, that has a
        ``key`` object; a ``key`` that is not a JSON object is reported and skipped."""
        for number in sorted(frames):
            section = frames[number].get(key)
            if section is None:
                continue
            where = f"{self.root}.frames.{number}.{key}"
            if not isinstance(section, dict):
                self.add(where, f"expected a JSON object, got {describe(section)}")
                continue
            yield number, where, section

    def check_frame_relations(self, frames: dict) -> None:
        """``frames[f].relations[uid]`` markers must name existing relations."""
        known = self.section("relations")
        for _, where, marks in self.frame_sections(frames, "relations"):
            for uid in marks:
                if uid not in known:
                    self.add(f"{where}.{uid}", f"relation {uid!r} does not exist in {self.root}.relations")

    # -- catalog -------------------------------------------------------------------------

    def check_catalog(self, catalog, scene: dict, uids) -> None:
        R = self.root
        environment = scene["environment"]
        where_env = f"{R}.metadata.usdscene.environment"
        env_places = None
        if environment is not None:
            if environment not in catalog:
                self.add(where_env, f"environment {environment!r} is not in the asset catalog"
                                    f"{suggest(environment, catalog.classes('environment'))}")
            elif catalog[environment].kind != "environment":
                self.add(where_env, f"{environment!r} is a {catalog[environment].kind}, not an environment")
            else:
                env_places = catalog.places(environment)
        for obj in scene["objects"]:
            if obj.class_name not in catalog:
                self.add(f"{R}.objects.{obj.uid}.type",
                         f"unknown object class {obj.class_name!r}{suggest(obj.class_name, catalog.classes())}; "
                         f"the catalog has: {', '.join(c for c in catalog.classes() if catalog[c].kind != 'environment')}")
        for place in scene["places"]:
            where = f"{R}.objects.{place.uid}.name"
            if environment is None:
                self.add(where, f"place {place.name!r} needs metadata.usdscene.environment")
            elif env_places is not None and place.name not in env_places:
                self.add(where, f"place {place.name!r} is not in environment {environment!r}"
                                f"{suggest(place.name, env_places)}")
        classes = {o.uid: o.class_name for o in scene["objects"]}
        for rel in scene["relations"]:
            if rel.type not in PLACEMENT_RELATIONS:
                continue
            cls = classes.get(rel.subject_uid)
            if cls in catalog and catalog[cls].relations and rel.type not in catalog[cls].relations:
                self.add(f"{R}.relations.{rel.uid}.type",
                         f"class {cls!r} does not support {rel.type!r}; it supports "
                         f"{', '.join(catalog[cls].relations)}")


# --------------------------------------------------------------------------------------------
# Conventions of the friendly form


def friendly_camera_rotation(yaw_rad: float, pitch_rad: float, roll_rad: float):
    """Camera → world rotation (OpenCV camera axes) of the friendly ``orientation_deg``.

    At yaw = pitch = roll = 0 the camera looks along world +X with the image up along world +Z
    (image right = world -Y). Yaw turns the view about world +Z (counter-clockwise seen from
    above, +90° looks along +Y), pitch raises it (+ looks up), roll turns the camera about
    its optical axis (+ turns the image content counter-clockwise, i.e. the camera clockwise
    as seen from behind it).

    Returns:
        (3, 3) float64 array whose columns are the camera x (right), y (down), z (forward)
        axes in world coordinates.
    """
    import numpy as np

    from usdscene.converters.openlabel_values import axis_rotation

    base = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return (np.asarray(axis_rotation("Z", yaw_rad)) @ np.asarray(axis_rotation("Y", -pitch_rad))
            @ base @ np.asarray(axis_rotation("Z", roll_rad)))


def fov_mismatch_message(focal_mm: float, sensor_w_mm: float, fov_deg: float, implied_deg: float) -> str:
    """The message for an over-determined pinhole whose FOV disagrees with focal and sensor.

    It gives the FOV the numbers imply for a perspective lens and for the two fisheye
    projections, and names the lens model that makes the three consistent: the equidistant
    fisheye when its FOV matches, else the equisolid fisheye, whose ``fov_deg`` is the image
    circle (it only crops), so any FOV is consistent with its focal length and sensor.
    """
    ratio = sensor_w_mm / focal_mm
    equidistant = math.degrees(ratio)
    text = (f"focal_length_mm {focal_mm:g} on sensor_size_mm {sensor_w_mm:g} implies a horizontal FOV of "
            f"{implied_deg:.1f}° for a perspective lens, not {fov_deg:g}°; across the sensor width a "
            f"fisheye_equidistant lens gives {equidistant:.1f}°")
    if ratio / 4 <= 1:
        text += f" and a fisheye_equisolid lens gives {math.degrees(4 * math.asin(ratio / 4)):.1f}°"
    if abs(equidistant - fov_deg) <= FOV_TOLERANCE_DEG:
        hint = "model 'fisheye_equidistant' makes the three consistent"
    else:
        hint = ("model 'fisheye_equisolid' makes the three consistent (its fov_deg is the image circle, "
                "which only crops)")
    return f"{text}. If this is a fisheye lens, {hint}; otherwise give only two of focal_length_mm, " \
           f"sensor_size_mm, fov_deg"
