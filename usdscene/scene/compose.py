"""VCD2Scene: compose the layered USD stage of a :class:`~usdscene.document.model.SceneSpec`.

:func:`compose_stage` writes the layers named in :mod:`usdscene.document.stage_schema`::

    scene.usda        root: sublayers strongest first, upAxis Z, metersPerUnit 1, start/end
                      time codes = frame range, renderSettingsPrimPath, customLayerData
                      provenance (source hash, seed, toolkit version) and the document-level
                      fields without prims (places, relations, exports, ...)
    render.usda       /Render/Settings (UsdRender.Settings + usdscene:render:* knobs),
                      /Render/Products/<camera> with the camera's resolution
    cameras.usda      /World/Cameras/<camera>: UsdGeom.Camera + usdscene:lens:* attributes
    lights.usda       /World/Lights/<light>: UsdLux lights + usdscene:light:* attributes
    objects.usda      /World/Objects/<class>_<uid>: reference to the asset, time-sampled
                      transform and visibility, appearance variant, colour opinion, identity;
                      an object whose pose changes per frame (a walker) instead holds one
                      child pose_<variant> per pose it shows, each referencing the asset with
                      that variant and visible on its frames
    environment.usda  /World/Environment: reference to the environment asset (and its places)

Conventions of the authored stage:

* Frame number = time code. Transforms are one ``xformOp:transform`` (matrix4d, exact
  doubles). An attribute that never changes gets a default value only; one that changes gets
  the default (the document's base value) plus time samples at the first and last frame of
  every run of equal values, so values are exact at every integer frame whatever
  interpolation a reader uses. Visibility (a token, never interpolated) gets a sample at each
  change.
* Cameras: ``focalLength``, apertures and aperture offsets are in *tenths of a scene unit*
  as the UsdGeom.Camera spec says; with ``metersPerUnit = 1`` a 4 mm lens is authored as
  ``0.04``. Blender 5.0's importer reads them exactly so (``lens_mm = focalLength · 100 ·
  metersPerUnit``, ``shift = offset / max(aperture)``). The principal point maps to the
  aperture offsets with OpenCV pixel centres at integer coordinates::

      horizontalApertureOffset = ((w - 1) / 2 - cx) · horizontalAperture / w
      verticalApertureOffset   = (cy - (h - 1) / 2) · verticalAperture / h

  Orthographic cameras use the same unit for the view width (``horizontalAperture = 10 ·
  width_m``); Blender's importer takes ``ortho_scale = max(aperture)`` without that factor, so
  the Blender worker reads ``usdscene:lens:*`` instead. Fisheye and distorted lenses are
  authored as the pinhole with the same focal length; the exact model is in the lens
  attributes.
* Lights: ``inputs:intensity = power_w / π`` for sphere (point, spot) and rect (area) lights
  and ``inputs:intensity = irradiance / 4`` for the distant (sun) light, with
  ``inputs:exposure = 0`` and ``inputs:normalize = true``. Blender 5.0's importer
  (``usd_reader_light``) sets ``energy = π · intensity`` (``4 · intensity`` for suns), so an
  imported light gets the document's watts. π is also the physical factor: a normalised
  Lambertian emitter of radiance ``L`` emits ``Φ = π · L``. Spot cones: ``shaping:cone:angle``
  = half the full spot angle, ``shaping:cone:softness`` = blend. ``DistantLight.angle`` is the
  angular diameter (USD spec); Blender's importer doubles it, so the worker sets
  ``sun_angle`` from ``usdscene:light:sunAngleDeg``.
* Lights sit in the variant ``document`` of the variant set ``lighting`` on
  ``/World/Lights``; the variant ``off`` has no lights, and further lighting rigs are further
  variants.
* Objects: references are not instanceable (Blender realises instances badly). The colour
  opinion goes to the asset's colour shader (the catalog entry's ``color_shader``, by default
  ``Looks/Body/Surface``, ``.inputs:diffuseColor``, see :mod:`usdscene.document.stage_schema`;
  a class without one gets no colour, with a warning), to ``primvars:displayColor`` for viewers and, exact, to
  ``userProperties:usdscene_color``.

Content usdscene does not model (the ``extra`` fields, :mod:`usdscene.converters.openlabel.carry`)
is kept in the stage for :func:`usdscene.converters.stage.usd_stage.scene_from_stage`: a camera's and an
object's in the prim's customData (``usdscene:extra``, per frame ``usdscene:frameExtra``), the
scene's in the root layer's ``customLayerData`` (``extraJson``), a place's and a relation's in
``placesJson`` and ``relationsJson``; an
element's presence outside the frame range as ``usdscene:frameIntervals``. All is canonical JSON
text, authored only when there is some.

Everything random (appearance, colour, placement) is drawn from one
``numpy.random.Generator`` seeded with ``scene.seed``, in a fixed order (appearance and colour
per object in document order, then placement frame by frame), so the same scene and seed give
byte-identical layers.
"""

from __future__ import annotations

import collections
import json
import logging
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping

import numpy as np

from usdscene import __version__
from usdscene.document import stage_schema as ss
from usdscene.bulk import paused_collection
from usdscene.scene.catalog import COMBINED_SETS, Catalog
from usdscene.errors import AssetError, CompositionError, OutputError, ProblemCollector
from usdscene.files import make_folder, remove_stale_temporaries, write_text_atomic
from usdscene.document.output_layout import mask_ids
from usdscene.document.model import (Camera, FrameInterval, Intrinsics, Light, LightKind, Pose,
                            Randomization, RenderSettings, SceneSpec, canonical_json, clip_intervals,
                            cv_pose_to_usd_pose, extra_data, union_intervals)
from usdscene.lens import lens_for
from usdscene.scene.placement import ObjectPlacement, check_placement_inputs, place_objects

log = logging.getLogger(__name__)

MM_PER_TENTH_METRE = 100.0
"""USD camera lengths are tenths of a scene unit; with metersPerUnit = 1 that is 100 mm."""


@dataclass(frozen=True)
class ComposeResult:
    """What :func:`compose_stage` wrote.

    Attributes:
        stage_dir: folder of the stage.
        root_layer: ``<stage_dir>/scene.usda`` (open this one).
        layers: every layer written: the root first, then the sublayers strongest first.
        frame_start, frame_end: closed frame range (= start/end time codes).
        objects_per_class: asset class → number of objects, sorted by class.
        placements: uid → resolved placement of every object (document order).
        resolved: the scene as composed: every object with explicit poses, its appearance and
            colour fixed and no randomization left; cameras and lights with canonical
            per-frame poses and presence. Reading the stage back gives this scene.
    """

    stage_dir: Path
    root_layer: Path
    layers: tuple[Path, ...]
    frame_start: int
    frame_end: int
    objects_per_class: Mapping[str, int]
    placements: Mapping[str, ObjectPlacement]
    resolved: SceneSpec

    @property
    def frame_count(self) -> int:
        """Number of frames of the composed stage."""
        return self.frame_end - self.frame_start + 1


def _place_json(place) -> dict:
    """A place as recorded in the root layer; declared regions and carried content only when it
    has some (the layer of a document without them stays as it was)."""
    out = {"uid": place.uid, "name": place.name}
    if place.regions:
        out["regions"] = [{"relation": r.relation, "matrix": r.pose.as_array().reshape(-1).tolist(),
                           "size_m": list(r.size_m)} for r in place.regions]
    if place.extra:
        out["extra"] = place.extra
    return out


@paused_collection()  # placement and layers build up to millions of containers (see usdscene.bulk)
def compose_stage(scene: SceneSpec, catalog: Catalog, out_dir: str | os.PathLike, *,
                  rng: np.random.Generator | None = None) -> ComposeResult:
    """Write the layered USD stage of ``scene`` into ``out_dir``.

    The root layer is removed first and written last, each layer atomically, so an
    interrupted compose leaves no ``scene.usda`` that looks valid.

    Args:
        scene: the scene.
        catalog: asset catalog with every class the scene uses (and its environment).
        out_dir: stage folder (created if needed), e.g. ``<run>/stage``.
        rng: generator for every random choice; default ``numpy.random.default_rng(scene.seed)``.

    Returns:
        What was written.

    Raises:
        CompositionError: unknown class, relation to a missing place, cyclic relations,
            over-full place, clashing prim names... (every problem names the element uid).
    """
    from pxr import Sdf  # noqa: F401  (fail early with a clear ImportError if usd-core is absent)

    if rng is None:
        rng = np.random.default_rng(scene.seed)
    if scene.frame_end < scene.frame_start:
        raise CompositionError(f"frame range [{scene.frame_start}, {scene.frame_end}] is empty",
                               where="frame_end")
    check_composition_inputs(scene, catalog)
    choices = draw_looks(scene, catalog, rng)
    placements = place_objects(_with_drawn_bodies(scene, catalog, choices), catalog, rng,
                               appearances={uid: look[0] for uid, look in choices.items()})
    resolved = resolved_scene(scene, placements, choices, catalog)
    ids = mask_ids(scene)

    if Path(out_dir).is_symlink():  # writing through it would put the stage anywhere
        raise OutputError(f"the stage folder is a symbolic link to {os.readlink(out_dir)!r}; "
                          "remove it or choose another output folder", where=str(out_dir))
    stage_dir = make_folder(Path(out_dir), what="stage folder").resolve()
    remove_stale_temporaries(stage_dir, recursive=False)  # a killed compose's half-written layers
    texts = {
        "render.usda": _render_layer(resolved),
        "cameras.usda": _cameras_layer(resolved),
        "lights.usda": _lights_layer(resolved),
        "objects.usda": _objects_layer(resolved, catalog, stage_dir, ids),
        "environment.usda": _environment_layer(resolved, catalog, stage_dir),
    }
    assert tuple(texts) == ss.SUBLAYERS  # the schema's order is the strength order
    root = stage_dir / ss.ROOT_LAYER
    try:
        root.unlink()
    except FileNotFoundError:
        pass
    written = [write_text_atomic(stage_dir / name, text) for name, text in texts.items()]
    write_text_atomic(root, _root_layer(resolved))
    counts = collections.Counter(o.class_name for o in scene.objects)
    return ComposeResult(
        stage_dir=stage_dir, root_layer=root, layers=(root, *written),
        frame_start=scene.frame_start, frame_end=scene.frame_end,
        objects_per_class=dict(sorted(counts.items())), placements=placements, resolved=resolved)


def _with_drawn_bodies(scene: SceneSpec, catalog: Catalog, choices: dict) -> SceneSpec:
    """``scene`` whose objects of classes with per-appearance support places (a seated
    body's lap: ``variant_places`` ``pose+appearance``) carry their drawn appearance, so what
    rests on them lands on that body; other objects are left as they are."""
    objects = []
    changed = False
    for obj in scene.objects:
        entry = catalog[obj.class_name] if obj.class_name in catalog else None
        if (obj.appearance is None and entry is not None
                and any(COMBINED_SETS in name for name in entry.variant_places)):
            obj = replace(obj, appearance=choices[obj.uid][0])
            changed = True
        objects.append(obj)
    return replace(scene, objects=tuple(objects)) if changed else scene


# --------------------------------------------------------------------------------------------
# Decisions


def _check_prim_names(scene: SceneSpec) -> None:
    """Two elements must not map to the same prim (prim names are sanitised)."""
    problems = ProblemCollector()
    seen: dict[str, str] = {}
    items = ([(ss.camera_prim_path(c.name), f"cameras.{c.name}", c.name) for c in scene.cameras]
             + [(ss.light_prim_path(lt.name), f"lights.{lt.uid}", lt.uid) for lt in scene.lights]
             + [(ss.object_prim_path(o.class_name, o.uid), f"objects.{o.uid}", o.uid) for o in scene.objects])
    for path, where, ident in items:
        if path in seen:
            problems.add(where, f"{ident!r} maps to prim {path}, which {seen[path]!r} already uses; "
                                "rename one of them")
        else:
            seen[path] = ident
    problems.raise_if_any(CompositionError)


def draw_looks(scene: SceneSpec, catalog: Catalog,
                rng: np.random.Generator) -> dict[str, tuple[str | None, tuple[float, float, float] | None]]:
    """uid → (appearance variant, colour) as composed.

    The first draws of a composition (document order), before placement; ``usdscene.generate.sequences``
    replays them to check that a generated document composes. A class that cannot be
    recoloured (:attr:`usdscene.scene.catalog.AssetEntry.recolourable`) gets no colour.
    """
    out = {}
    uncoloured: set[str] = set()
    unvaried: set[str] = set()
    for obj in scene.objects:
        entry = catalog[obj.class_name]
        variants = entry.appearances
        appearance = obj.appearance
        if appearance is None and obj.randomization.random_appearance and variants:
            appearance = variants[int(rng.integers(len(variants)))]
        if obj.randomization.random_appearance and len(variants) < 2 and obj.class_name not in unvaried:
            log.warning("object %r asks for a random appearance, but class %r has %d appearance variant(s); "
                        "its objects all look the same", obj.uid, obj.class_name, len(variants))
            unvaried.add(obj.class_name)
        if appearance is None:
            appearance = entry.default_appearance
        color = obj.color_rgb
        if color is None and obj.randomization.random_color:
            color = tuple(float(v) for v in rng.random(3))
        if color is not None and not entry.recolourable:
            # A colour the asset cannot show must not reach the labels (drawn all the same, so
            # the draws after it stay where they were).
            if obj.class_name not in uncoloured:
                log.warning("class %r names no colour material (catalog color_shader); the colour of %r "
                            "and its class's other objects is not composed nor recorded", obj.class_name, obj.uid)
                uncoloured.add(obj.class_name)
            color = None
        out[obj.uid] = (appearance, tuple(float(c) for c in color) if color is not None else None)
    return out


def canonical_intervals(intervals, frame_start: int, frame_end: int) -> tuple[FrameInterval, ...]:
    """Presence merged; no intervals = the whole range. Frames outside the range are kept: the
    stage shows the range, and what the document says beyond it rides along
    (``stage_schema.CUSTOM_FRAME_INTERVALS``)."""
    if not intervals:
        return (FrameInterval(frame_start, frame_end),)
    return union_intervals(intervals)


def _outside_intervals(intervals, frame_start: int, frame_end: int) -> str:
    """``stage_schema.CUSTOM_FRAME_INTERVALS`` text of canonical ``intervals``: "" when the
    range's visibility says them all."""
    if intervals == clip_intervals(intervals, frame_start, frame_end):
        return ""
    return json.dumps([[iv.frame_start, iv.frame_end] for iv in intervals])


def _canonical_camera(cam: Camera, frames: range) -> Camera:
    """Per-frame poses only where they differ from ``pose``; ``pose`` is the document's base
    pose when some frame uses it, else the pose of the first frame (what a reader of the
    stage can tell)."""
    poses = [cam.pose_at(f) for f in frames]
    base = cam.pose if any(p.matrix == cam.pose.matrix for p in poses) else poses[0]
    frame_poses = tuple((f, p) for f, p in zip(frames, poses) if p.matrix != base.matrix)
    return replace(cam, pose=base, frame_poses=frame_poses, custom=dict(cam.custom))


def resolved_scene(scene: SceneSpec, placements: Mapping[str, ObjectPlacement],
                   looks: Mapping[str, tuple[str | None, tuple[float, float, float] | None]],
                   catalog: Catalog | None = None) -> SceneSpec:
    """The scene as composed (see :attr:`ComposeResult.resolved`); with ``catalog``, objects
    that ask for no pose variant get their class's default one (what a reader of the stage sees)."""
    objects = []
    for obj in scene.objects:
        pose_variant = obj.pose_variant
        if pose_variant is None and catalog is not None:
            pose_variant = catalog[obj.class_name].default_variants.get(ss.VARIANT_SET_POSE)
        spans = placements[obj.uid].spans
        appearance, color = looks[obj.uid]
        if spans:
            base = spans[0].pose
            frame_poses = tuple((f, span.pose) for span in spans if span.pose.matrix != base.matrix
                                for f in span.frames())
        else:
            # Composed invisible; its intervals outside the range ride along on the prim.
            log.warning("object %r is present in no frame of %d..%d; it is composed invisible",
                        obj.uid, scene.frame_start, scene.frame_end)
            base, frame_poses = obj.pose or Pose(), ()
        objects.append(replace(
            obj, frame_intervals=canonical_intervals(obj.frame_intervals, scene.frame_start, scene.frame_end),
            pose=base, frame_poses=frame_poses, appearance=appearance, color_rgb=color,
            pose_variant=pose_variant, randomization=Randomization()))
    lights = tuple(replace(lt, frame_intervals=canonical_intervals(lt.frame_intervals, scene.frame_start,
                                                                   scene.frame_end))
                   for lt in scene.lights)
    return replace(scene, cameras=tuple(_canonical_camera(c, scene.frames) for c in scene.cameras),
                   lights=lights, objects=tuple(objects))


# --------------------------------------------------------------------------------------------
# Layer authoring (Sdf: fast, and the text output is sorted, hence deterministic)


def _new_layer(fps: float | None = None):
    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.pseudoRoot.SetInfo("upAxis", "Z")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    if fps is not None:
        # Every layer states the rate: USD scales the time samples of a sublayer whose
        # timeCodesPerSecond differs from the root's (24 by default), frame 1 would read 24 / fps.
        layer.timeCodesPerSecond = float(fps)
        layer.framesPerSecond = float(fps)
    return layer


def _prim(parent, name: str, type_name: str = "", specifier=None):
    from pxr import Sdf

    spec = Sdf.PrimSpec(parent, name, specifier if specifier is not None else Sdf.SpecifierDef, type_name)
    return spec


def _world(layer, child: str | None = None, child_type: str = "Scope"):
    world = _prim(layer, ss.WORLD.strip("/"), "Xform")
    return _prim(world, child.rsplit("/", 1)[-1], child_type) if child else world


def _attr(prim, name: str, type_name, value=None, *, uniform: bool = False, custom: bool = False):
    from pxr import Sdf

    variability = Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying
    spec = Sdf.AttributeSpec(prim, name, type_name, variability)
    if custom:
        spec.custom = True
    if value is not None:
        spec.default = value
    return spec


def _identity(prim, uid: str, class_name: str, name: str, extra: str = "", frame_extra: str = "",
              frame_intervals: str = "") -> None:
    """The element's identity on ``prim``, with the content it carries for others
    (``stage_schema.CUSTOM_EXTRA`` / ``CUSTOM_FRAME_EXTRA``, canonical JSON text) and its
    presence outside the frame range (``CUSTOM_FRAME_INTERVALS``), each only when there is
    some: customData travels with the prim when a DCC tool renames or moves it."""
    from pxr import Sdf

    data = {ss.CUSTOM_UID.split(":")[1]: uid, ss.CUSTOM_CLASS.split(":")[1]: class_name,
            ss.CUSTOM_NAME.split(":")[1]: name}
    if extra:
        data[ss.CUSTOM_EXTRA.split(":")[1]] = extra
    if frame_extra:
        data[ss.CUSTOM_FRAME_EXTRA.split(":")[1]] = frame_extra
    if frame_intervals:
        data[ss.CUSTOM_FRAME_INTERVALS.split(":")[1]] = frame_intervals
    prim.customData = {ss.LAYER_DATA_KEY: data}
    _attr(prim, ss.ATTR_USER_UID, Sdf.ValueTypeNames.String, uid, custom=True)
    _attr(prim, ss.ATTR_USER_CLASS, Sdf.ValueTypeNames.String, class_name, custom=True)
    _attr(prim, ss.ATTR_USER_NAME, Sdf.ValueTypeNames.String, name, custom=True)


def _gf_matrix(matrix16: tuple[float, ...]):
    """Row-major column-vector 4x4 (model.Pose) → Gf.Matrix4d (row-vector convention)."""
    from pxr import Gf

    m = matrix16
    return Gf.Matrix4d(m[0], m[4], m[8], m[12], m[1], m[5], m[9], m[13],
                       m[2], m[6], m[10], m[14], m[3], m[7], m[11], m[15])


def _runs(values: list) -> list[tuple[int, int]]:
    """Index ranges ``[start, end]`` of runs of equal consecutive values."""
    runs: list[tuple[int, int]] = []
    start = 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            runs.append((start, i - 1))
            start = i
    return runs


def _author_transform(layer, prim, base: tuple[float, ...], per_frame: list[tuple[float, ...]],
                      frame_start: int) -> None:
    """Default = base; samples at both ends of every run when the value changes."""
    from pxr import Sdf, Vt

    spec = _attr(prim, "xformOp:transform", Sdf.ValueTypeNames.Matrix4d, _gf_matrix(base))
    _attr(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(["xformOp:transform"]),
          uniform=True)
    if per_frame and any(v != base for v in per_frame):
        cache: dict[tuple[float, ...], object] = {}
        for start, end in _runs(per_frame):
            value = per_frame[start]
            gf = cache.get(value)
            if gf is None:
                gf = cache[value] = _gf_matrix(value)
            layer.SetTimeSample(spec.path, float(frame_start + start), gf)
            if end != start:
                layer.SetTimeSample(spec.path, float(frame_start + end), gf)


def _author_visibility(layer, prim, present: list[bool], frame_start: int) -> None:
    """Visibility of a prim present on ``present`` (per frame of the range): none authored when
    present throughout, ``invisible`` without samples when present on no frame (a lone sample
    reads as a constant to readers that ask whether the value varies, which then take the
    default), else ``inherited`` with a sample at each change."""
    from pxr import Sdf

    if all(present):
        return
    if not any(present):
        _attr(prim, "visibility", Sdf.ValueTypeNames.Token, "invisible")
        return
    spec = _attr(prim, "visibility", Sdf.ValueTypeNames.Token, "inherited")
    previous = None
    for i, here in enumerate(present):
        if here != previous:
            layer.SetTimeSample(spec.path, float(frame_start + i), "inherited" if here else "invisible")
            previous = here


def frame_pose_data(obj) -> dict[int, str]:
    """Frame → pose variant named by the object's per-frame text object data
    ``stage_schema.FRAME_POSE_DATA`` (empty for almost every object)."""
    by_frame: dict[int, str] = {}
    for frame, text in obj.frame_extra:
        if ss.FRAME_POSE_DATA not in text:  # cheap: most frame data is about something else
            continue
        for item in extra_data(text).get("object_data", {}).get("text", ()):
            if item.get("name") == ss.FRAME_POSE_DATA and isinstance(item.get("val"), str):
                by_frame[int(frame)] = item["val"]
    return by_frame


def check_composition_inputs(scene: SceneSpec, catalog: Catalog) -> None:
    """Everything :func:`compose_stage` refuses before it draws anything, in the order it
    checks: unknown classes, places and relations, per-frame pose variants, prim names, asset
    arcs and the mask id limit. ``usdscene validate`` calls this too, so that a document the
    gate accepts composes (and one it refuses gets compose's own message).

    Raises:
        CompositionError or AssetError: the first group of problems found.
    """
    check_placement_inputs(scene, catalog)
    _check_frame_poses(scene, catalog)
    _check_prim_names(scene)
    _check_asset_arcs(scene, catalog)
    try:
        mask_ids(scene)
    except ValueError as exc:
        raise CompositionError(str(exc), where="objects") from None


def _check_frame_poses(scene: SceneSpec, catalog: Catalog) -> None:
    """Per-frame pose variants must be variants of the object's class.

    Raises:
        CompositionError: every unknown one, naming the object and the frame.
    """
    problems = ProblemCollector()
    for obj in scene.objects:
        if obj.class_name not in catalog:
            continue  # reported by check_placement_inputs
        choices = catalog[obj.class_name].variants.get(ss.VARIANT_SET_POSE, ())
        for frame, variant in sorted(frame_pose_data(obj).items()):
            if variant not in choices:
                problems.add(f"frames.{frame}.objects.{obj.uid}.object_data.text.{ss.FRAME_POSE_DATA}",
                             f"object {obj.uid!r}: pose {variant!r} is not a variant of class "
                             f"{obj.class_name!r} (variants: {', '.join(choices) or 'none'})")
    problems.raise_if_any(CompositionError)


def frame_pose_variants(obj, frames: range, present: list[bool]) -> list[str] | None:
    """The pose variant shown per frame of ``frames`` when the document gives ``obj`` one per
    frame (text object data ``stage_schema.FRAME_POSE_DATA``, a walker's walk cycle) other than
    its ``pose_variant``; None otherwise (the object's one ``pose_variant`` holds). Frames without the data
    show ``obj.pose_variant``; absent frames hold the previous variant (no extra samples)."""
    by_frame = frame_pose_data(obj)
    if not by_frame:
        return None
    shown: list[str] = []
    # Frames before the first present one show its pose: no child for a pose never seen.
    held = next((by_frame.get(f, obj.pose_variant) for i, f in enumerate(frames) if present[i]),
                obj.pose_variant)
    for i, f in enumerate(frames):
        if present[i]:
            held = by_frame.get(f, obj.pose_variant)
        shown.append(held)
    if None in shown or set(shown) == {obj.pose_variant}:
        return None
    return shown


def carried_frame_extra(obj, frames: range, present: list[bool], shown: list[str] | None) -> str:
    """``stage_schema.CUSTOM_FRAME_EXTRA`` text of ``obj``: its ``frame_extra`` as one canonical
    JSON object keyed by frame, less the per-frame pose data (``FRAME_POSE_DATA``) of the
    present frames when pose children show it (``shown``, :func:`frame_pose_variants`: the
    children are the stage's form of that data, and a DCC user may edit them); "" when nothing
    is left."""
    shown_frames = {f for f, here in zip(frames, present) if here} if shown is not None else set()
    out = {}
    for frame, text in obj.frame_extra:
        data = extra_data(text)
        if frame in shown_frames and ss.FRAME_POSE_DATA in text:
            kinds = data.get("object_data", {})
            kept = [item for item in kinds.get("text", ())
                    if not (isinstance(item, dict) and item.get("name") == ss.FRAME_POSE_DATA)]
            if kept:
                kinds["text"] = kept
            else:
                kinds.pop("text", None)
            if not kinds:
                data.pop("object_data", None)
        if data:
            out[str(int(frame))] = data
    return canonical_json(out)


def _presence(intervals, frames: range) -> list[bool]:
    return [any(iv.frame_start <= f <= iv.frame_end for iv in intervals) for f in frames]


def _root_layer(scene: SceneSpec) -> str:
    layer = _new_layer(scene.fps)
    layer.startTimeCode = float(scene.frame_start)
    layer.endTimeCode = float(scene.frame_end)
    layer.defaultPrim = ss.WORLD.strip("/")
    layer.pseudoRoot.SetInfo("renderSettingsPrimPath", ss.RENDER_SETTINGS)
    for name in ss.SUBLAYERS:
        layer.subLayerPaths.append(f"./{name}")
    prov = scene.provenance
    data = {
        "toolkitVersion": __version__,
        "seed": int(scene.seed),
        "sourceSha256": prov.source_sha256,
        "source": prov.source,
        "sourceFormat": prov.source_format,
        "sceneName": scene.name,
        "description": scene.description,
        "environment": scene.environment or "",
        "assetPathsJson": json.dumps(list(scene.asset_paths)),
        "exportsJson": json.dumps(list(scene.exports)),
        "roiRulesJson": json.dumps(dict(scene.roi_rules)),
        **({"roiIgnoreJson": json.dumps(list(scene.roi_ignore))} if scene.roi_ignore else {}),
        "placesJson": json.dumps([_place_json(p) for p in scene.places]),
        "relationsJson": json.dumps([
            {"uid": r.uid, "type": r.type, "subject": r.subject_uid, "object": r.object_uid,
             "frameIntervals": [[iv.frame_start, iv.frame_end] for iv in r.frame_intervals],
             **({"extra": r.extra} if r.extra else {})}
            for r in scene.relations]),
    }
    if scene.extra:
        data[ss.LAYER_EXTRA] = scene.extra
    layer.customLayerData = {ss.LAYER_DATA_KEY: data}
    return layer.ExportToString()


def _render_layer(scene: SceneSpec) -> str:
    from pxr import Gf, Sdf

    layer = _new_layer(scene.fps)
    render = _prim(layer, ss.RENDER_SETTINGS.split("/")[1], "Scope")
    settings = _prim(render, ss.RENDER_SETTINGS.rsplit("/", 1)[1], "RenderSettings")
    products = _prim(render, ss.RENDER_PRODUCTS.rsplit("/", 1)[1], "Scope")
    rs = scene.render
    T = Sdf.ValueTypeNames
    _attr(settings, "resolution", T.Int2, Gf.Vec2i(*rs.resolution_px), uniform=True)
    for name, type_name, value in (
            (ss.ATTR_RENDER_ENGINE, T.Token, rs.engine), (ss.ATTR_RENDER_DEVICE, T.Token, rs.device),
            (ss.ATTR_RENDER_SAMPLES, T.Int, int(rs.samples)),
            (ss.ATTR_RENDER_ADAPTIVE_THRESHOLD, T.Double, float(rs.adaptive_threshold)),
            (ss.ATTR_RENDER_DENOISE, T.Bool, bool(rs.denoise)), (ss.ATTR_RENDER_DENOISER, T.Token, rs.denoiser),
            (ss.ATTR_RENDER_DENOISING_QUALITY, T.Token, rs.denoising_quality),
            (ss.ATTR_RENDER_DENOISING_PREFILTER, T.Token, rs.denoising_prefilter),
            (ss.ATTR_RENDER_ADAPTIVE_MIN_SAMPLES, T.Int, int(rs.adaptive_min_samples)),
            (ss.ATTR_RENDER_DENOISING_INPUT_PASSES, T.Token, rs.denoising_input_passes),
            (ss.ATTR_RENDER_LIGHT_TREE, T.Bool, bool(rs.light_tree)),
            (ss.ATTR_RENDER_PATH_GUIDING, T.Bool, bool(rs.path_guiding)),
            (ss.ATTR_RENDER_CLAMP_INDIRECT, T.Double, float(rs.clamp_indirect)),
            (ss.ATTR_RENDER_SAMPLING_PATTERN, T.Token, rs.sampling_pattern),
            (ss.ATTR_RENDER_FAST_GI, T.Bool, bool(rs.fast_gi)),
            (ss.ATTR_RENDER_FAST_GI_METHOD, T.Token, rs.fast_gi_method),
            (ss.ATTR_RENDER_FAST_GI_AO_BOUNCES, T.Int, int(rs.fast_gi_ao_bounces)),
            (ss.ATTR_RENDER_FAST_GI_DISTANCE, T.Double, float(rs.fast_gi_distance_m)),
            (ss.ATTR_RENDER_SCRAMBLING_DISTANCE, T.Double, float(rs.scrambling_distance)),
            (ss.ATTR_RENDER_AUTO_SCRAMBLING_DISTANCE, T.Bool, bool(rs.auto_scrambling_distance)),
            (ss.ATTR_RENDER_MAX_BOUNCES, T.Int, int(rs.max_bounces)),
            (ss.ATTR_RENDER_CAUSTICS, T.Bool, bool(rs.caustics)),
            (ss.ATTR_RENDER_TILE_SIZE, T.Int, int(rs.tile_size_px)),
            (ss.ATTR_RENDER_RESOLUTION, T.Int2, Gf.Vec2i(*rs.resolution_px)),
            (ss.ATTR_RENDER_SEED, T.Int, int(rs.seed))):
        _attr(settings, name, type_name, value, custom=True)
    if rs.depth is not None:  # authored only when on: stages without depth keep their bytes
        _attr(settings, ss.ATTR_RENDER_DEPTH, T.Token, rs.depth, custom=True)
    if scene.world is not None:
        from usdscene.document.imaging import world_stage_json

        _attr(settings, ss.ATTR_RENDER_WORLD, T.String, world_stage_json(scene), custom=True)
    rel = Sdf.RelationshipSpec(settings, "products", custom=False)
    for cam in scene.cameras:
        product = _prim(products, ss.prim_name(cam.name), "RenderProduct")
        _attr(product, "resolution", T.Int2, Gf.Vec2i(cam.intrinsics.width_px, cam.intrinsics.height_px),
              uniform=True)
        _attr(product, "productName", T.Token, f"images/{cam.name}", uniform=True)
        cam_rel = Sdf.RelationshipSpec(product, "camera", custom=False)
        cam_rel.targetPathList.explicitItems.append(Sdf.Path(ss.camera_prim_path(cam.name)))
        rel.targetPathList.explicitItems.append(product.path)
    if scene.cameras:
        cam_rel = Sdf.RelationshipSpec(settings, "camera", custom=False)
        cam_rel.targetPathList.explicitItems.append(Sdf.Path(ss.camera_prim_path(scene.cameras[0].name)))
    return layer.ExportToString()


def render_settings_layer(render: RenderSettings) -> str:
    """``.usda`` text of a render layer holding only ``render`` (no products): the form in
    which ``layers/render_defaults.usda`` ships the defaults for stages authored by hand."""
    return _render_layer(SceneSpec(render=render))


def camera_apertures(intr: Intrinsics) -> dict[str, float]:
    """USD camera attributes (tenths of a metre) of an Intrinsics; see the module docstring.

    Returns:
        ``focalLength``, ``horizontalAperture``, ``verticalAperture``,
        ``horizontalApertureOffset``, ``verticalApertureOffset`` as floats.
    """
    w, h = intr.width_px, intr.height_px
    if lens_for(intr).orthographic:
        # fx/fy are pixels per metre; apertures are the view size in tenths of a metre.
        h_ap, v_ap = 10.0 * w / intr.fx_px, 10.0 * h / intr.fy_px
        focal = intr.sensor_width_mm / MM_PER_TENTH_METRE
    else:
        focal_mm = intr.fx_px * intr.sensor_width_mm / w
        focal = focal_mm / MM_PER_TENTH_METRE
        h_ap = intr.sensor_width_mm / MM_PER_TENTH_METRE
        v_ap = focal * h / intr.fy_px
    return {"focalLength": focal, "horizontalAperture": h_ap, "verticalAperture": v_ap,
            "horizontalApertureOffset": ((w - 1) / 2.0 - intr.cx_px) * h_ap / w,
            "verticalApertureOffset": (intr.cy_px - (h - 1) / 2.0) * v_ap / h}


def _cameras_layer(scene: SceneSpec) -> str:
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    layer = _new_layer(scene.fps)
    parent = _world(layer, ss.CAMERAS)
    for cam in scene.cameras:
        prim = _prim(parent, ss.prim_name(cam.name), "Camera")
        _identity(prim, cam.name, "camera", cam.name, extra=cam.extra)
        base = cv_pose_to_usd_pose(cam.pose).matrix
        per_frame = [cv_pose_to_usd_pose(cam.pose_at(f)).matrix for f in scene.frames] if cam.frame_poses else []
        _author_transform(layer, prim, base, per_frame, scene.frame_start)
        intr = cam.intrinsics
        _attr(prim, "projection", T.Token,
              "orthographic" if lens_for(intr).orthographic else "perspective")
        for name, value in camera_apertures(intr).items():
            _attr(prim, name, T.Float, value)
        _attr(prim, "clippingRange", T.Float2, Gf.Vec2f(cam.clip_near_m, cam.clip_far_m))
        _attr(prim, ss.ATTR_CAMERA_CLIPPING, T.Double2, Gf.Vec2d(cam.clip_near_m, cam.clip_far_m), custom=True)
        _attr(prim, ss.ATTR_LENS_MODEL, T.Token, intr.lens.value, custom=True)
        _attr(prim, ss.ATTR_LENS_WIDTH, T.Int, int(intr.width_px), custom=True)
        _attr(prim, ss.ATTR_LENS_HEIGHT, T.Int, int(intr.height_px), custom=True)
        _attr(prim, ss.ATTR_LENS_FX, T.Double, float(intr.fx_px), custom=True)
        _attr(prim, ss.ATTR_LENS_FY, T.Double, float(intr.fy_px), custom=True)
        _attr(prim, ss.ATTR_LENS_CX, T.Double, float(intr.cx_px), custom=True)
        _attr(prim, ss.ATTR_LENS_CY, T.Double, float(intr.cy_px), custom=True)
        _attr(prim, ss.ATTR_LENS_DISTORTION, T.DoubleArray,
              Vt.DoubleArray([float(v) for v in intr.distortion]), custom=True)
        if intr.fov_deg is not None:
            _attr(prim, ss.ATTR_LENS_FOV, T.Double, float(intr.fov_deg), custom=True)
        _attr(prim, ss.ATTR_LENS_SENSOR_WIDTH, T.Double, float(intr.sensor_width_mm), custom=True)
        _attr(prim, ss.ATTR_CAMERA_MODEL_NAME, T.String, cam.model_name, custom=True)
        _attr(prim, ss.ATTR_CAMERA_DESCRIPTION, T.String, cam.description, custom=True)
        _attr(prim, ss.ATTR_CAMERA_CUSTOM, T.String, json.dumps(dict(cam.custom), sort_keys=True), custom=True)
        if cam.sensor is not None:
            from usdscene.document.imaging import spec_to_json

            _attr(prim, ss.ATTR_CAMERA_SENSOR, T.String,
                  json.dumps({"sensor": spec_to_json(cam.sensor), "seed": int(scene.seed)}, sort_keys=True),
                  custom=True)
    return layer.ExportToString()


LIGHTING_DOCUMENT = "document"
"""Variant of the ``lighting`` set that holds the document's lights (selected)."""
LIGHTING_OFF = "off"
"""Variant of the ``lighting`` set without lights."""

_LIGHT_TYPES = {LightKind.POINT: "SphereLight", LightKind.SPOT: "SphereLight",
                LightKind.SUN: "DistantLight", LightKind.AREA: "RectLight"}


def light_intensity(light: Light) -> float:
    """UsdLux ``inputs:intensity`` for a document light (see the module docstring)."""
    if light.kind == LightKind.SUN:
        return light.power_w / 4.0
    return light.power_w / math.pi


def _lights_layer(scene: SceneSpec) -> str:
    from pxr import Gf, Sdf

    T = Sdf.ValueTypeNames
    layer = _new_layer(scene.fps)
    lights = _world(layer, ss.LIGHTS)
    # Lighting rigs: the document's lights live in the variant "document" (selected); "off"
    # has none. Further rigs are further variants (a DCC tool or a layer of layers/ adds them).
    rigs = Sdf.VariantSetSpec(lights, ss.VARIANT_SET_LIGHTING)
    parent = Sdf.VariantSpec(rigs, LIGHTING_DOCUMENT).primSpec
    Sdf.VariantSpec(rigs, LIGHTING_OFF)
    lights.variantSetNameList.prependedItems.append(ss.VARIANT_SET_LIGHTING)
    lights.variantSelections[ss.VARIANT_SET_LIGHTING] = LIGHTING_DOCUMENT
    for light in scene.lights:
        prim = _prim(parent, ss.prim_name(light.name), _LIGHT_TYPES[light.kind])
        _identity(prim, light.uid, "light", light.name,
                  frame_intervals=_outside_intervals(light.frame_intervals, scene.frame_start, scene.frame_end))
        _author_transform(layer, prim, light.pose.matrix, [], scene.frame_start)
        _author_visibility(layer, prim, _presence(light.frame_intervals, scene.frames), scene.frame_start)
        _attr(prim, "inputs:intensity", T.Float, light_intensity(light))
        _attr(prim, "inputs:exposure", T.Float, 0.0)
        _attr(prim, "inputs:normalize", T.Bool, True)
        _attr(prim, "inputs:color", T.Color3f, Gf.Vec3f(*light.color_rgb))
        if light.kind in (LightKind.POINT, LightKind.SPOT):
            _attr(prim, "inputs:radius", T.Float, light.radius_m)
        if light.kind == LightKind.SPOT:
            prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["ShapingAPI"]))
            _attr(prim, "inputs:shaping:cone:angle", T.Float, light.spot_angle_deg / 2.0)
            _attr(prim, "inputs:shaping:cone:softness", T.Float, light.spot_blend)
        if light.kind == LightKind.SUN:
            _attr(prim, "inputs:angle", T.Float, light.sun_angle_deg)
        if light.kind == LightKind.AREA:
            _attr(prim, "inputs:width", T.Float, light.size_m[0])
            _attr(prim, "inputs:height", T.Float, light.size_m[1])
        _attr(prim, ss.ATTR_LIGHT_KIND, T.Token, light.kind.value, custom=True)
        _attr(prim, ss.ATTR_LIGHT_POWER_W, T.Double, float(light.power_w), custom=True)
        _attr(prim, ss.ATTR_LIGHT_COLOR, T.Double3, Gf.Vec3d(*light.color_rgb), custom=True)
        _attr(prim, ss.ATTR_LIGHT_RADIUS, T.Double, float(light.radius_m), custom=True)
        _attr(prim, ss.ATTR_LIGHT_SPOT_ANGLE, T.Double, float(light.spot_angle_deg), custom=True)
        _attr(prim, ss.ATTR_LIGHT_SPOT_BLEND, T.Double, float(light.spot_blend), custom=True)
        _attr(prim, ss.ATTR_LIGHT_SIZE, T.Double2, Gf.Vec2d(*light.size_m), custom=True)
        _attr(prim, ss.ATTR_LIGHT_SUN_ANGLE, T.Double, float(light.sun_angle_deg), custom=True)
    return layer.ExportToString()


def _check_asset_arcs(scene: SceneSpec, catalog: Catalog) -> None:
    """Refuse assets whose sublayers, references or payloads leave the catalog's reading
    roots (:mod:`usdscene.document.containment`), before the stage references them.

    Raises:
        AssetError: every arc outside, naming the layer that holds it and the class.
    """
    if not catalog.roots:  # a catalog built in code, not read from folders
        return
    from usdscene.document.containment import usd_dependency_problems

    used = dict.fromkeys([*([scene.environment] if scene.environment else []),
                          *(o.class_name for o in scene.objects)])
    problems = ProblemCollector()
    for name in used:
        if name in catalog:
            for problem in usd_dependency_problems(catalog[name].usd_path, catalog.roots):
                problems.add(problem.where, f"asset class {name!r}: {problem.message}")
    problems.raise_if_any(AssetError)


def asset_reference_path(usd_path: Path, stage_dir: Path) -> str:
    """Path of an asset as the stage references it: relative to the stage folder when
    possible (the stage folder moves with its assets), forward slashes."""
    try:
        rel = os.path.relpath(Path(usd_path).resolve(), stage_dir)
    except ValueError:  # another drive
        return Path(usd_path).resolve().as_posix()
    return Path(rel).as_posix()


def _objects_layer(scene: SceneSpec, catalog: Catalog, stage_dir: Path, ids: Mapping[str, int]) -> str:
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    layer = _new_layer(scene.fps)
    parent = _world(layer, ss.OBJECTS)
    frames = scene.frames
    for obj in scene.objects:
        entry = catalog[obj.class_name]
        prim = _prim(parent, ss.object_prim_path(obj.class_name, obj.uid).rsplit("/", 1)[1], "Xform")
        present = _presence(obj.frame_intervals, frames)
        shown = frame_pose_variants(obj, frames, present)
        if shown is None:
            prim.referenceList.prependedItems.append(Sdf.Reference(asset_reference_path(entry.usd_path, stage_dir)))
        _identity(prim, obj.uid, obj.class_name, obj.name, extra=obj.extra,
                  frame_extra=carried_frame_extra(obj, frames, present, shown),
                  frame_intervals=_outside_intervals(obj.frame_intervals, scene.frame_start, scene.frame_end))
        _attr(prim, ss.ATTR_MASK_ID, T.Int, ids[obj.uid], custom=True)
        _attr(prim, ss.ATTR_USER_MASK_ID, T.Int, ids[obj.uid], custom=True)
        base = (obj.pose or Pose()).matrix
        per_frame: list[tuple[float, ...]] = []
        if obj.frame_poses:
            by_frame = {f: p.matrix for f, p in obj.frame_poses}
            # Absent frames hold the last pose so they add no samples.
            held = base
            for i, f in enumerate(frames):
                if present[i]:
                    held = by_frame.get(f, base)
                per_frame.append(held)
        _author_transform(layer, prim, base, per_frame, scene.frame_start)
        _author_visibility(layer, prim, present, scene.frame_start)
        if shown is None:
            _author_look(prim, entry, obj.appearance, obj.pose_variant, obj.color_rgb, record_color=True)
            continue
        if obj.color_rgb is not None:  # the object's recorded colour, on the object prim
            _attr(prim, ss.ATTR_USER_COLOR, T.Double3, Gf.Vec3d(*(float(c) for c in obj.color_rgb)), custom=True)
        # One child per shown pose, visible on its frames: a stage cannot switch variants per
        # frame, and geometry, keypoints and the renderer all follow visibility.
        for variant in sorted(set(shown)):
            child = _prim(prim, ss.POSE_CHILD_PREFIX + variant, "Xform")
            child.referenceList.prependedItems.append(
                Sdf.Reference(asset_reference_path(entry.usd_path, stage_dir)))
            _attr(child, ss.ATTR_USER_POSE, T.String, variant, custom=True)
            _author_visibility(layer, child, [v == variant for v in shown], scene.frame_start)
            _author_look(child, entry, obj.appearance, variant, obj.color_rgb, record_color=False)
    return layer.ExportToString()


def _author_look(prim, entry, appearance: str | None, pose_variant: str | None, color_rgb, *,
                 record_color: bool) -> None:
    """Variant selections and the colour opinion on a prim referencing the asset ``entry``;
    ``record_color`` also records the colour as a user property (once per object)."""
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    if appearance is not None:
        prim.variantSelections[ss.VARIANT_SET_APPEARANCE] = appearance
    if pose_variant is not None:
        prim.variantSelections[ss.VARIANT_SET_POSE] = pose_variant
    if color_rgb is not None:
        rgb = tuple(float(c) for c in color_rgb)
        color = _attr(prim, ss.ATTR_COLOR, T.Color3fArray, Vt.Vec3fArray([Gf.Vec3f(*rgb)]))
        color.SetInfo("interpolation", "constant")
        if record_color:
            _attr(prim, ss.ATTR_USER_COLOR, T.Double3, Gf.Vec3d(*rgb), custom=True)
        shader = prim
        for part in entry.color_shader.split("/"):
            shader = _prim(shader, part, specifier=Sdf.SpecifierOver)
        _attr(shader, ss.ATTR_ASSET_COLOR, T.Color3f, Gf.Vec3f(*rgb))


def _environment_layer(scene: SceneSpec, catalog: Catalog, stage_dir: Path) -> str:
    from pxr import Sdf

    layer = _new_layer(scene.fps)
    world = _world(layer)
    if scene.environment is not None:
        entry = catalog[scene.environment]
        env = _prim(world, ss.ENVIRONMENT.rsplit("/", 1)[1], "Xform")
        env.referenceList.prependedItems.append(Sdf.Reference(asset_reference_path(entry.usd_path, stage_dir)))
        _identity(env, scene.environment, "environment", scene.environment)
    return layer.ExportToString()
