"""Scene2VCD: read any USD stage back into a :class:`~usdscene.document.model.SceneSpec`.

``scene_from_stage(stage_or_path)`` reads

* a stage written by :func:`usdscene.scene.compose.compose_stage`: the result equals
  ``ComposeResult.resolved`` (explicit per-frame poses, appearance and colour fixed);
* the same stage after cameras, lights or objects were moved in a DCC tool: transforms are
  always evaluated (``UsdGeom.XformCache`` at every time code of the frame range), and an exact
  ``usdscene:*`` value is used only while it still agrees with the plain USD attribute it
  shadows (a focal length edited in usdview wins over the stale lens attribute);
* a stage exported by Blender's USD exporter: identity comes from ``userProperties:usdscene_*``
  (Blender keeps custom properties there and drops customData), cameras are perspective, the
  stage may be Y-up or in centimetres: ``upAxis`` and ``metersPerUnit`` are honoured.

What a stage cannot say comes back as defaults: a stage without the composer's
``customLayerData`` has no places and relations; a flattened stage has no variant selections
left, so appearances come back empty.

Other people's content (the ``extra`` fields, :mod:`usdscene.converters.openlabel.carry`) comes
back from where compose put it: a camera's and an object's from the prim's customData
(``usdscene:extra``; per frame ``usdscene:frameExtra``, joined with the pose the pose children
show), the scene's from the root layer's ``customLayerData`` (``extraJson``), a place's and a
relation's from ``placesJson`` and ``relationsJson``. It follows the prim's uid, so a renamed or moved prim keeps it and a deleted one
takes it along. An element's presence is its visibility over the frame range joined with the
frames outside the range of the intervals the document gave it (``usdscene:frameIntervals``).

Element discovery: cameras are every ``UsdGeom.Camera``; lights every sphere, distant, rect
or disk light (dome lights such as Blender's exported world are skipped); objects the
outermost prims carrying an identity (customData ``usdscene:uid`` or
``userProperties:usdscene_uid``) whose class is not ``camera``, ``light`` or ``environment``.

Conventions: scale in transforms is dropped (poses are rigid). A Y-up stage converts the world
axes only; object frames stay asset frames (Z up), as in Blender's Y-up exports. Object poses:
``pose`` is the authored default transform when it occurs in the frame range, else the pose of
the first frame the object is visible; ``frame_poses`` lists the visible frames that differ.
A camera without lens attributes and render product gets the render settings' image width and
the height of its aperture aspect (square pixels).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from usdscene import __version__
from usdscene.document import stage_schema as ss
from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import (Camera, DeclaredRegion, FrameInterval, Intrinsics, LensModel, Light, LightKind, PlaceRef, Pose,
                            Provenance, Relation, RenderSettings, SceneObject, SceneSpec, canonical_json,
                            union_intervals, usd_pose_to_cv_pose)

log = logging.getLogger(__name__)

# Y-up world → Z-up world: x → x, y (up) → z, z → -y.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
_NOT_OBJECTS = ("camera", "light", "environment")
_I3 = np.eye(3)


def scene_from_stage(stage_or_path: Any) -> SceneSpec:
    """Read a USD stage (a ``pxr.Usd.Stage``, a .usd/.usda/.usdc file, or a composed stage
    folder holding ``scene.usda``).

    Returns:
        The scene; provenance names the stage (``source_format = "usd"``, sha256 of the root
        layer file).

    Raises:
        DocumentError: the stage cannot be opened or its usdscene data is malformed.
    """
    from pxr import Usd

    if isinstance(stage_or_path, Usd.Stage):
        stage = stage_or_path
    else:
        path = Path(stage_or_path)
        if path.is_dir() and (path / ss.ROOT_LAYER).is_file():
            path = path / ss.ROOT_LAYER
        if not path.is_file():
            raise DocumentError(f"USD stage {str(path)!r} not found", where=str(path))
        try:
            stage = Usd.Stage.Open(str(path))
        except Exception as exc:  # pxr raises Tf.ErrorException
            raise DocumentError(f"cannot open USD stage: {exc}", where=str(path)) from None
        if stage is None:
            raise DocumentError("cannot open USD stage", where=str(path))
    reader = _StageReader(stage)
    return reader.scene()


class _StageReader:
    def __init__(self, stage) -> None:
        from pxr import UsdGeom

        self.stage = stage
        self.problems = ProblemCollector()
        self.mpu = float(UsdGeom.GetStageMetersPerUnit(stage) or 1.0)
        self.y_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
        root = stage.GetRootLayer()
        self.root_path = root.realPath or root.identifier
        raw = root.customLayerData.get(ss.LAYER_DATA_KEY, {})
        self.data = dict(raw) if isinstance(raw, dict) else {}
        if stage.HasAuthoredTimeCodeRange():
            self.frame_start = int(math.floor(stage.GetStartTimeCode()))
            self.frame_end = max(int(math.floor(stage.GetEndTimeCode())), self.frame_start)
        else:
            self.frame_start = self.frame_end = 0
        self.frames = range(self.frame_start, self.frame_end + 1)
        self._world_cache: dict[float, Any] = {}

    # ----------------------------------------------------------------------------- helpers

    def _cache(self, time):
        from pxr import Usd, UsdGeom

        key = "default" if time is None else float(time)
        cache = self._world_cache.get(key)
        if cache is None:
            cache = UsdGeom.XformCache(Usd.TimeCode.Default() if time is None else Usd.TimeCode(time))
            self._world_cache[key] = cache
        return cache

    def _world(self, prim, time) -> tuple[float, ...]:
        """Local-to-world of ``prim`` at ``time`` (None = default) as a Gf-layout 16-tuple."""
        m = self._cache(time).GetLocalToWorldTransform(prim)
        return tuple(np.array(m).ravel().tolist())  # the buffer protocol: 40x faster than iterating

    def _to_pose(self, gf16: tuple[float, ...]) -> Pose:
        """Stage matrix (Gf row-vector layout, stage units and up axis) → metric Z-up Pose.

        Only the *world* is converted: a child frame keeps its own convention (asset frames
        are Z-up by the catalog's definition, cameras and lights look down their -Z), which is
        what Blender's exporter writes (a Y-up export rotates the root, not the objects).
        """
        m = np.asarray(gf16, dtype=np.float64).reshape(4, 4).T
        rot, t = m[:3, :3], m[:3, 3] * self.mpu
        # Remove scale/shear so the pose stays rigid.
        if np.abs(rot.T @ rot - _I3).max() > 1e-12:
            u, _, vt = np.linalg.svd(rot)
            rot = u @ vt
            if np.linalg.det(rot) < 0:
                rot = u @ np.diag([1.0, 1.0, -1.0]) @ vt
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = rot, t
        if self.y_up:
            out = _Y_TO_Z @ out
        return Pose.from_matrix(out)

    def _poses(self, prim, frames: Iterable[int]) -> tuple[tuple[float, ...], dict[int, tuple[float, ...]]]:
        """(base, frame → world) in stage layout; base = authored default if it occurs."""
        from pxr import UsdGeom

        frames = list(frames)
        moving = any(UsdGeom.Xformable(p).TransformMightBeTimeVarying()
                     for p in _self_and_ancestors(prim) if p.IsA(UsdGeom.Xformable))
        if not moving:
            # Query at a frame, not at the default time: a transform authored only as a single
            # time sample (Blender's USD export writes that) has no default value, and reading
            # it at the default time would give the identity.
            still = self._world(prim, self.frame_start)
            return still, {f: still for f in frames}
        default = self._world(prim, None)
        per_frame = {f: self._world(prim, f) for f in frames}
        if not frames or any(_same_matrix(default, v) for v in per_frame.values()):
            base = default
        else:
            base = per_frame[frames[0]]
        # USD interpolates between the two samples that bound a run of equal values, which
        # can move the last bits: values within rounding of the base are the base.
        return base, {f: base if _same_matrix(v, base) else v for f, v in per_frame.items()}

    def _visible(self, prim) -> list[bool]:
        from pxr import UsdGeom

        imageable = UsdGeom.Imageable(prim)
        if not imageable:
            return [True] * len(self.frames)
        # One time sample is no variation to ValueMightBeTimeVarying, but it holds over every
        # frame while the default says otherwise: sampled attributes are read per frame.
        varying = any(UsdGeom.Imageable(p).GetVisibilityAttr().GetNumTimeSamples() > 0
                      for p in _self_and_ancestors(prim) if p.IsA(UsdGeom.Imageable))
        if not varying:
            here = imageable.ComputeVisibility() != UsdGeom.Tokens.invisible
            return [here] * len(self.frames)
        return [imageable.ComputeVisibility(f) != UsdGeom.Tokens.invisible for f in self.frames]

    def _identity(self, prim) -> tuple[str | None, str | None, str | None]:
        def custom(key):
            value = prim.GetCustomDataByKey(key)
            return str(value) if value is not None else None

        uid = _value(prim, ss.ATTR_USER_UID) or custom(ss.CUSTOM_UID)
        cls = _value(prim, ss.ATTR_USER_CLASS) or custom(ss.CUSTOM_CLASS)
        name = _value(prim, ss.ATTR_USER_NAME) or custom(ss.CUSTOM_NAME)
        return (str(uid) if uid is not None else None, str(cls) if cls is not None else None,
                str(name) if name is not None else None)

    def _carried_text(self, text, where: str) -> dict:
        """The JSON object of carried canonical JSON text (``{}`` for none); malformed text
        (edited by hand) is a problem."""
        if text is None or text == "":
            return {}
        try:
            value = json.loads(str(text))
        except json.JSONDecodeError as exc:
            self.problems.add(where, f"malformed JSON {str(text)[:60]!r}: {exc}")
            return {}
        if not isinstance(value, dict):
            self.problems.add(where, f"expected a JSON object, got {str(text)[:60]!r}")
            return {}
        return value

    def _presence(self, prim, shown: list[bool]) -> tuple[FrameInterval, ...]:
        """The element's frame intervals: its visibility over the frame range (``shown``, per
        frame) joined with the frames outside the range of the intervals the prim carries from
        the document (``stage_schema.CUSTOM_FRAME_INTERVALS``), which the stage cannot show."""
        visible = _intervals(shown, self.frame_start)
        text = prim.GetCustomDataByKey(ss.CUSTOM_FRAME_INTERVALS)
        if not text:
            return visible
        try:
            carried = [FrameInterval(int(a), int(b)) for a, b in json.loads(str(text))]
        except (json.JSONDecodeError, TypeError, ValueError) as exc:
            self.problems.add(f"{prim.GetPath()}:customData.{ss.CUSTOM_FRAME_INTERVALS}",
                              f"expected JSON [[frame_start, frame_end], ...], got {str(text)[:60]!r}: {exc}")
            return visible
        before = [FrameInterval(iv.frame_start, min(iv.frame_end, self.frame_start - 1))
                  for iv in carried if iv.frame_start < self.frame_start]
        after = [FrameInterval(max(iv.frame_start, self.frame_end + 1), iv.frame_end)
                 for iv in carried if iv.frame_end > self.frame_end]
        return union_intervals([*before, *visible, *after])

    def _carried(self, prim) -> tuple[str, dict[int, dict]]:
        """What the prim carries for others: ``(extra, frame → carried content)``, from its
        customData (``stage_schema.CUSTOM_EXTRA``, ``CUSTOM_FRAME_EXTRA``)."""
        where = f"{prim.GetPath()}:customData"
        extra = canonical_json(self._carried_text(prim.GetCustomDataByKey(ss.CUSTOM_EXTRA),
                                                  f"{where}.{ss.CUSTOM_EXTRA}"))
        frames = {}
        for frame, value in self._carried_text(prim.GetCustomDataByKey(ss.CUSTOM_FRAME_EXTRA),
                                               f"{where}.{ss.CUSTOM_FRAME_EXTRA}").items():
            try:
                number = int(frame)
            except ValueError:
                self.problems.add(f"{where}.{ss.CUSTOM_FRAME_EXTRA}.{frame}", "expected a frame number")
                continue
            if isinstance(value, dict) and value:
                frames[number] = value
        return extra, frames

    def _json(self, key: str, default):
        text = self.data.get(key)
        if text is None:
            return default
        try:
            return json.loads(str(text))
        except json.JSONDecodeError as exc:
            self.problems.add(f"{self.root_path}:customLayerData.{ss.LAYER_DATA_KEY}.{key}",
                              f"malformed JSON {str(text)[:60]!r}: {exc}")
            return default

    # ----------------------------------------------------------------------------- scene

    def scene(self) -> SceneSpec:
        render = self._render_settings()
        cameras = self._cameras(render)
        lights = self._lights()
        objects = self._objects()
        places = tuple(PlaceRef(uid=str(p["uid"]), name=str(p["name"]), regions=tuple(
            DeclaredRegion(str(r["relation"]), Pose.from_matrix(r["matrix"]),
                           tuple(float(v) for v in r["size_m"])) for r in p.get("regions", ())),
            extra=canonical_json(self._carried_text(p.get("extra"), f"{self.root_path}:customLayerData."
                                                                    f"{ss.LAYER_DATA_KEY}.placesJson")))
            for p in self._json("placesJson", []))
        relations = tuple(
            Relation(uid=str(r["uid"]), type=str(r["type"]), subject_uid=str(r["subject"]),
                     object_uid=str(r["object"]),
                     frame_intervals=tuple(FrameInterval(int(a), int(b)) for a, b in r.get("frameIntervals", [])),
                     extra=canonical_json(self._carried_text(r.get("extra"), f"{self.root_path}:customLayerData."
                                                                             f"{ss.LAYER_DATA_KEY}.relationsJson")))
            for r in self._json("relationsJson", []))
        environment = str(self.data.get("environment", "")) or self._environment_from_prims()
        world = self._imaging(self.stage.GetPrimAtPath(ss.RENDER_SETTINGS), ss.ATTR_RENDER_WORLD, "world")
        self.problems.raise_if_any(DocumentError)
        sha = ""
        if os.path.isfile(self.root_path):
            sha = hashlib.sha256(Path(self.root_path).read_bytes()).hexdigest()
        name = str(self.data.get("sceneName", "")) or Path(self.root_path).stem
        return SceneSpec(
            name=name, frame_start=self.frame_start, frame_end=self.frame_end,
            cameras=cameras, lights=lights, objects=objects, places=places, relations=relations,
            render=render, seed=int(self.data.get("seed", render.seed)), environment=environment or None,
            asset_paths=tuple(str(p) for p in self._json("assetPathsJson", [])),
            exports=tuple(str(e) for e in self._json("exportsJson", [])),
            roi_rules={str(k): str(v) for k, v in self._json("roiRulesJson", {}).items()},
            roi_ignore=tuple(str(n) for n in self._json("roiIgnoreJson", [])),
            description=str(self.data.get("description", "")), world=world,
            extra=canonical_json(self._json(ss.LAYER_EXTRA, {})),
            # A stage that states its rate (compose writes one only for documents with fps).
            fps=(float(self.stage.GetTimeCodesPerSecond())
                 if self.stage.GetRootLayer().HasTimeCodesPerSecond() else None),
            provenance=Provenance(source=str(self.root_path), source_sha256=sha, source_format="usd",
                                  toolkit_version=__version__))

    def _environment_from_prims(self) -> str:
        prim = self.stage.GetPrimAtPath(ss.ENVIRONMENT)
        if prim:
            uid, cls, _ = self._identity(prim)
            return uid or ""
        return ""

    def _render_settings(self) -> RenderSettings:
        defaults = RenderSettings()
        prim = self.stage.GetPrimAtPath(ss.RENDER_SETTINGS)
        if not prim:
            return defaults
        values: dict[str, Any] = {}
        resolution = _value(prim, "resolution")
        if resolution is not None:
            values["resolution_px"] = (int(resolution[0]), int(resolution[1]))
        fields = (("engine", ss.ATTR_RENDER_ENGINE, str), ("device", ss.ATTR_RENDER_DEVICE, str),
                  ("samples", ss.ATTR_RENDER_SAMPLES, int),
                  ("adaptive_threshold", ss.ATTR_RENDER_ADAPTIVE_THRESHOLD, float),
                  ("denoise", ss.ATTR_RENDER_DENOISE, bool), ("denoiser", ss.ATTR_RENDER_DENOISER, str),
                  ("denoising_quality", ss.ATTR_RENDER_DENOISING_QUALITY, str),
                  ("denoising_prefilter", ss.ATTR_RENDER_DENOISING_PREFILTER, str),
                  ("adaptive_min_samples", ss.ATTR_RENDER_ADAPTIVE_MIN_SAMPLES, int),
                  ("denoising_input_passes", ss.ATTR_RENDER_DENOISING_INPUT_PASSES, str),
                  ("light_tree", ss.ATTR_RENDER_LIGHT_TREE, bool),
                  ("path_guiding", ss.ATTR_RENDER_PATH_GUIDING, bool),
                  ("clamp_indirect", ss.ATTR_RENDER_CLAMP_INDIRECT, float),
                  ("sampling_pattern", ss.ATTR_RENDER_SAMPLING_PATTERN, str),
                  ("fast_gi", ss.ATTR_RENDER_FAST_GI, bool),
                  ("fast_gi_method", ss.ATTR_RENDER_FAST_GI_METHOD, str),
                  ("fast_gi_ao_bounces", ss.ATTR_RENDER_FAST_GI_AO_BOUNCES, int),
                  ("fast_gi_distance_m", ss.ATTR_RENDER_FAST_GI_DISTANCE, float),
                  ("scrambling_distance", ss.ATTR_RENDER_SCRAMBLING_DISTANCE, float),
                  ("auto_scrambling_distance", ss.ATTR_RENDER_AUTO_SCRAMBLING_DISTANCE, bool),
                  ("max_bounces", ss.ATTR_RENDER_MAX_BOUNCES, int), ("caustics", ss.ATTR_RENDER_CAUSTICS, bool),
                  ("tile_size_px", ss.ATTR_RENDER_TILE_SIZE, int), ("seed", ss.ATTR_RENDER_SEED, int),
                  ("depth", ss.ATTR_RENDER_DEPTH, str))
        for field_name, attr, kind in fields:
            value = _value(prim, attr)
            if value is not None:
                values[field_name] = kind(value)
        value = _value(prim, ss.ATTR_RENDER_RESOLUTION)
        if value is not None:
            values["resolution_px"] = (int(value[0]), int(value[1]))
        return RenderSettings(**{**defaults.__dict__, **values})

    def _product_resolutions(self) -> dict[str, tuple[int, int]]:
        """camera prim path → resolution of the render product that uses it."""
        from pxr import Usd, UsdRender

        out: dict[str, tuple[int, int]] = {}
        for prim in Usd.PrimRange(self.stage.GetPseudoRoot()):
            if prim.IsA(UsdRender.Product):
                product = UsdRender.Product(prim)
                targets = product.GetCameraRel().GetTargets()
                res = product.GetResolutionAttr().Get()
                if targets and res is not None:
                    out[targets[0].pathString] = (int(res[0]), int(res[1]))
        return out

    # ----------------------------------------------------------------------------- cameras

    def _cameras(self, render: RenderSettings) -> tuple[Camera, ...]:
        from pxr import Usd, UsdGeom

        products = self._product_resolutions()
        cameras = []
        for prim in Usd.PrimRange(self.stage.GetPseudoRoot()):
            if not prim.IsA(UsdGeom.Camera):
                continue
            _, _, name = self._identity(prim)
            name = name or prim.GetName()
            intr = self._intrinsics(prim, products.get(prim.GetPath().pathString), render.resolution_px[0])
            base, per_frame = self._poses(prim, self.frames)
            pose = usd_pose_to_cv_pose(self._to_pose(base))
            frame_poses = tuple((f, usd_pose_to_cv_pose(self._to_pose(per_frame[f])))
                                for f in self.frames if per_frame[f] != base)
            near, far = self._clipping(prim)
            custom_text = _value(prim, ss.ATTR_CAMERA_CUSTOM)
            try:
                custom = json.loads(custom_text) if custom_text else {}
            except json.JSONDecodeError:
                self.problems.add(f"{prim.GetPath()}.{ss.ATTR_CAMERA_CUSTOM}", f"malformed JSON {custom_text!r}")
                custom = {}
            sensor = self._imaging(prim, ss.ATTR_CAMERA_SENSOR, "sensor")
            cameras.append(Camera(
                name=name, intrinsics=intr, pose=pose, frame_poses=frame_poses, clip_near_m=near, clip_far_m=far,
                model_name=str(_value(prim, ss.ATTR_CAMERA_MODEL_NAME) or ""),
                description=str(_value(prim, ss.ATTR_CAMERA_DESCRIPTION) or ""), custom=custom, sensor=sensor,
                extra=self._carried(prim)[0]))
        return tuple(cameras)

    def _imaging(self, prim, attribute: str, key: str):
        """The world (``key`` "world") or a camera's sensor ("sensor") a composed stage carries
        as JSON (``usdscene.document.imaging``), or None."""
        from usdscene.document.imaging import Sensor, World, spec_from_json

        text = _value(prim, attribute) if prim else None
        if not text:
            return None
        try:
            return spec_from_json(World if key == "world" else Sensor, json.loads(text)[key])
        except (ValueError, KeyError, TypeError) as exc:
            self.problems.add(f"{prim.GetPath()}.{attribute}", f"malformed {key} JSON: {exc}")
            return None

    def _clipping(self, prim) -> tuple[float, float]:
        from pxr import UsdGeom

        usd = UsdGeom.Camera(prim).GetClippingRangeAttr().Get()
        exact = _value(prim, ss.ATTR_CAMERA_CLIPPING)
        if exact is not None and usd is not None and _close(exact[0], usd[0]) and _close(exact[1], usd[1]):
            return float(exact[0]), float(exact[1])
        if usd is None:
            return 0.01, 1000.0
        return float(usd[0]) * self.mpu, float(usd[1]) * self.mpu

    def _intrinsics(self, prim, resolution: tuple[int, int] | None, default_width: int) -> Intrinsics:
        from pxr import UsdGeom

        from usdscene.scene.compose import camera_apertures

        geom = UsdGeom.Camera(prim)
        usd = {
            "focalLength": geom.GetFocalLengthAttr().Get(),
            "horizontalAperture": geom.GetHorizontalApertureAttr().Get(),
            "verticalAperture": geom.GetVerticalApertureAttr().Get(),
            "horizontalApertureOffset": geom.GetHorizontalApertureOffsetAttr().Get() or 0.0,
            "verticalApertureOffset": geom.GetVerticalApertureOffsetAttr().Get() or 0.0,
        }
        ortho = geom.GetProjectionAttr().Get() == UsdGeom.Tokens.orthographic
        exact = self._lens_attrs(prim)
        if exact is not None and self.mpu == 1.0:
            expected = camera_apertures(exact)
            same_projection = (exact.lens == LensModel.ORTHOGRAPHIC) == ortho
            scale = max(abs(expected["horizontalAperture"]), abs(expected["verticalAperture"]), 1e-12)
            if same_projection and all(
                    usd[k] is not None and abs(float(usd[k]) - v) <= 1e-6 * max(abs(v), scale)
                    for k, v in expected.items()):
                return exact
            log.info("%s: USD camera attributes were edited; deriving intrinsics from them", prim.GetPath())
        if exact is not None:
            width, height = exact.width_px, exact.height_px
        elif resolution is not None:
            width, height = resolution
        else:  # nothing says: square pixels over the aperture's aspect
            h_ap, v_ap = usd["horizontalAperture"] or 20.955, usd["verticalAperture"] or 15.2908
            width, height = default_width, max(1, int(round(default_width * float(v_ap) / float(h_ap))))
        derived = _derive_intrinsics(usd, ortho, width, height, self.mpu)
        if exact is not None and (exact.lens == LensModel.ORTHOGRAPHIC) == ortho:
            # Keep the lens model the attributes name; the plain USD values win for the rest.
            return Intrinsics(exact.lens, width, height, derived.fx_px, derived.fy_px, derived.cx_px,
                              derived.cy_px, exact.distortion, exact.fov_deg, derived.sensor_width_mm)
        return derived

    def _lens_attrs(self, prim) -> Intrinsics | None:
        model = _value(prim, ss.ATTR_LENS_MODEL)
        if model is None:
            return None
        where = f"{prim.GetPath()}.{ss.ATTR_LENS_MODEL}"
        try:
            lens = LensModel(str(model))
        except ValueError:
            self.problems.add(where, f"lens model {str(model)!r} is not one of {[m.value for m in LensModel]}")
            return None
        try:
            width, height = int(_value(prim, ss.ATTR_LENS_WIDTH)), int(_value(prim, ss.ATTR_LENS_HEIGHT))
            fx, fy = float(_value(prim, ss.ATTR_LENS_FX)), float(_value(prim, ss.ATTR_LENS_FY))
            cx, cy = float(_value(prim, ss.ATTR_LENS_CX)), float(_value(prim, ss.ATTR_LENS_CY))
        except (TypeError, ValueError):
            self.problems.add(str(prim.GetPath()), "incomplete usdscene:lens:* attributes (need widthPx, "
                                                   "heightPx, fxPx, fyPx, cxPx, cyPx)")
            return None
        distortion = tuple(float(v) for v in (_value(prim, ss.ATTR_LENS_DISTORTION) or ()))
        fov = _value(prim, ss.ATTR_LENS_FOV)
        sensor = _value(prim, ss.ATTR_LENS_SENSOR_WIDTH)
        return Intrinsics(lens, width, height, fx, fy, cx, cy, distortion,
                          float(fov) if fov is not None else None,
                          float(sensor) if sensor is not None else 36.0)

    # ----------------------------------------------------------------------------- lights

    def _lights(self) -> tuple[Light, ...]:
        from pxr import Usd, UsdLux

        lights = []
        for prim in Usd.PrimRange(self.stage.GetPseudoRoot()):
            if not prim.HasAPI(UsdLux.LightAPI):
                continue
            if not any(prim.IsA(t) for t in (UsdLux.SphereLight, UsdLux.DistantLight, UsdLux.RectLight,
                                              UsdLux.DiskLight)):
                # Dome (Blender exports its world as one), cylinder, portal and geometry lights
                # have no counterpart in the scene model.
                log.info("%s: %s is not a point/spot/sun/area light; skipped", prim.GetPath(), prim.GetTypeName())
                continue
            uid, _, name = self._identity(prim)
            name = name or prim.GetName()
            uid = uid or name
            kind = _light_kind(prim)
            api = UsdLux.LightAPI(prim)
            intensity = float(api.GetIntensityAttr().Get() or 0.0)
            exposure = float(api.GetExposureAttr().Get() or 0.0)
            color = api.GetColorAttr().Get()
            color = tuple(float(c) for c in color) if color is not None else (1.0, 1.0, 1.0)
            derived_power = intensity * 2.0 ** exposure * (4.0 if kind == LightKind.SUN else math.pi)
            exact_kind = _value(prim, ss.ATTR_LIGHT_KIND)
            if exact_kind is not None and _compatible_kind(str(exact_kind), kind):
                kind = LightKind(str(exact_kind))
            radius = _float(prim, "inputs:radius")
            cone = _float(prim, "inputs:shaping:cone:angle")
            softness = _float(prim, "inputs:shaping:cone:softness")
            angle = _float(prim, "inputs:angle")
            width, height = _float(prim, "inputs:width"), _float(prim, "inputs:height")
            base, _ = self._poses(prim, self.frames[:1])
            defaults = Light(uid=uid, name=name, kind=kind)
            power = _prefer(_value(prim, ss.ATTR_LIGHT_POWER_W), derived_power, rel=1e-5)
            light = Light(
                uid=uid, name=name, kind=kind, pose=self._to_pose(base),
                power_w=float(power),
                color_rgb=tuple(_prefer_vec(_value(prim, ss.ATTR_LIGHT_COLOR), color)),  # type: ignore[arg-type]
                radius_m=float(_prefer(_value(prim, ss.ATTR_LIGHT_RADIUS),
                                       radius * self.mpu if radius is not None else None, defaults.radius_m)),
                spot_angle_deg=float(_prefer(_value(prim, ss.ATTR_LIGHT_SPOT_ANGLE),
                                             2.0 * cone if cone is not None else None, defaults.spot_angle_deg)),
                spot_blend=float(_prefer(_value(prim, ss.ATTR_LIGHT_SPOT_BLEND), softness, defaults.spot_blend)),
                size_m=tuple(_prefer_vec(_value(prim, ss.ATTR_LIGHT_SIZE),
                                         (width * self.mpu, height * self.mpu)
                                         if width is not None and height is not None else None,
                                         defaults.size_m)),  # type: ignore[arg-type]
                sun_angle_deg=float(_prefer(_value(prim, ss.ATTR_LIGHT_SUN_ANGLE), angle, defaults.sun_angle_deg)),
                frame_intervals=self._presence(prim, self._visible(prim)))
            lights.append(light)
        return tuple(lights)

    # ----------------------------------------------------------------------------- objects

    def _objects(self) -> tuple[SceneObject, ...]:
        from pxr import Usd, UsdGeom

        objects = []
        it = iter(Usd.PrimRange(self.stage.GetPseudoRoot()))
        for prim in it:
            uid, cls, name = self._identity(prim)
            if uid is None or cls is None or cls in _NOT_OBJECTS or prim.IsA(UsdGeom.Camera):
                continue
            it.PruneChildren()  # the outermost prim with an identity is the object
            visible = self._visible(prim)
            present = [f for f, here in zip(self.frames, visible) if here]
            base, per_frame = self._poses(prim, present)
            pose = self._to_pose(base)
            frame_poses = tuple((f, self._to_pose(per_frame[f]))
                                for f in present if per_frame[f] != base)
            # A pose changing per frame: one child per pose (compose), visible on its frames.
            posed = [child for child in prim.GetChildren() if child.HasAttribute(ss.ATTR_USER_POSE)]
            sets = (posed[0] if posed else prim).GetVariantSets()
            appearance = None
            if sets.HasVariantSet(ss.VARIANT_SET_APPEARANCE):
                appearance = sets.GetVariantSet(ss.VARIANT_SET_APPEARANCE).GetVariantSelection() or None
            pose_variant = None
            if sets.HasVariantSet(ss.VARIANT_SET_POSE):
                pose_variant = sets.GetVariantSet(ss.VARIANT_SET_POSE).GetVariantSelection() or None
            pose_data = self._frame_poses(posed, present) if posed else {}
            if pose_data:
                pose_variant = pose_data[min(pose_data)]
            extra, carried = self._carried(prim)
            objects.append(SceneObject(
                uid=uid, name=name or uid, class_name=cls, frame_intervals=self._presence(prim, visible),
                pose=pose, frame_poses=frame_poses, appearance=appearance, pose_variant=pose_variant,
                color_rgb=self._color(prim), extra=extra, frame_extra=_frame_extra(pose_data, carried)))
        return tuple(objects)

    def _frame_poses(self, posed: list, present: list[int]) -> dict[int, str]:
        """Frame → the variant of the pose child shown on it, for each present frame that shows one."""
        shown: dict[int, str] = {}
        for child in posed:
            variant = str(_value(child, ss.ATTR_USER_POSE))
            for f, here in zip(self.frames, self._visible(child)):
                if here:
                    shown[f] = variant
        return {f: shown[f] for f in present if f in shown}

    def _color(self, prim) -> tuple[float, float, float] | None:
        exact = _value(prim, ss.ATTR_USER_COLOR)
        shown = _value(prim, ss.ATTR_COLOR)
        shown = tuple(float(c) for c in shown[0]) if shown is not None and len(shown) == 1 else None
        if exact is not None and (shown is None or all(_close(a, b) for a, b in zip(exact, shown))):
            return tuple(float(c) for c in exact)  # type: ignore[return-value]
        return shown  # type: ignore[return-value]


# --------------------------------------------------------------------------------------------


def _same_matrix(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    """Equal up to floating-point rounding (interpolating two equal samples)."""
    return a == b or all(abs(x - y) <= 1e-12 * max(1.0, abs(x)) for x, y in zip(a, b))


def _self_and_ancestors(prim):
    while prim and not prim.IsPseudoRoot():
        yield prim
        prim = prim.GetParent()


def _value(prim, name: str):
    """Authored value of an attribute; for an attribute with time samples only (Blender's
    exporter samples custom properties when it exports animation), its first sample."""
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return None
    value = attr.Get()
    if value is None and attr.GetNumTimeSamples():
        value = attr.Get(attr.GetTimeSamples()[0])
    return value


def _float(prim, name: str) -> float | None:
    value = _value(prim, name)
    return float(value) if value is not None else None


def _close(a: float, b: float, rel: float = 1e-6) -> bool:
    """Equal up to float32 rounding of ``b``."""
    return abs(float(a) - float(b)) <= rel * max(abs(float(a)), abs(float(b)), 1e-30) + 1e-12


def _prefer(exact, usd, default=None, rel: float = 1e-6):
    """The exact usdscene value while it agrees with the USD one; else the USD one."""
    if usd is None:
        return exact if exact is not None else default
    if exact is not None and _close(exact, usd, rel):
        return exact
    return usd


def _prefer_vec(exact, usd, default=None):
    if usd is None:
        return tuple(float(v) for v in exact) if exact is not None else default
    if exact is not None and len(exact) == len(usd) and all(_close(a, b) for a, b in zip(exact, usd)):
        return tuple(float(v) for v in exact)
    return tuple(float(v) for v in usd)


def _light_kind(prim) -> LightKind:
    from pxr import UsdLux

    if prim.IsA(UsdLux.DistantLight):
        return LightKind.SUN
    if prim.IsA(UsdLux.RectLight) or prim.IsA(UsdLux.DiskLight):
        return LightKind.AREA
    shaping = UsdLux.ShapingAPI(prim)
    if prim.HasAPI(UsdLux.ShapingAPI) and shaping.GetShapingConeAngleAttr().HasAuthoredValue():
        return LightKind.SPOT
    return LightKind.POINT


def _compatible_kind(exact: str, derived: LightKind) -> bool:
    """The exact kind holds while the prim still has the matching UsdLux type (and cone)."""
    return exact == derived.value


def _intervals(visible: list[bool], frame_start: int) -> tuple[FrameInterval, ...]:
    out: list[FrameInterval] = []
    start = None
    for i, here in enumerate(visible + [False]):
        if here and start is None:
            start = i
        elif not here and start is not None:
            out.append(FrameInterval(frame_start + start, frame_start + i - 1))
            start = None
    return tuple(out)


def _derive_intrinsics(usd: dict, ortho: bool, width: int, height: int, mpu: float) -> Intrinsics:
    """PERSPECTIVE/ORTHOGRAPHIC intrinsics from plain UsdGeom.Camera attributes (lengths in
    tenths of a scene unit; see usdscene.scene.compose for the offset convention)."""
    h_ap = float(usd["horizontalAperture"] or 20.955)
    v_ap = float(usd["verticalAperture"] or 15.2908)
    h_off = float(usd["horizontalApertureOffset"] or 0.0)
    v_off = float(usd["verticalApertureOffset"] or 0.0)
    tenth_m = mpu / 10.0
    if ortho:
        fx = width / (h_ap * tenth_m)
        fy = height / (v_ap * tenth_m)
        return Intrinsics(LensModel.ORTHOGRAPHIC, width, height, fx, fy,
                          (width - 1) / 2.0 - h_off * tenth_m * fx, (height - 1) / 2.0 + v_off * tenth_m * fy,
                          sensor_width_mm=h_ap * tenth_m * 1000.0)
    focal = float(usd["focalLength"] or 50.0)
    fx = focal / h_ap * width
    fy = focal / v_ap * height
    return Intrinsics(LensModel.PERSPECTIVE, width, height, fx, fy,
                      (width - 1) / 2.0 - h_off / h_ap * width, (height - 1) / 2.0 + v_off / v_ap * height,
                      sensor_width_mm=h_ap * tenth_m * 1000.0)


def _frame_extra(pose_data: dict[int, str], carried: dict[int, dict]) -> tuple[tuple[int, str], ...]:
    """``SceneObject.frame_extra``: per frame the carried content, with the pose the stage shows
    (text object data ``FRAME_POSE_DATA``, first of its kind) where pose children show one."""
    out = []
    for frame in sorted(set(pose_data) | set(carried)):
        data = carried.get(frame, {})
        if frame in pose_data:
            kinds = data.setdefault("object_data", {})
            kinds["text"] = [{"name": ss.FRAME_POSE_DATA, "val": pose_data[frame]}, *kinds.get("text", ())]
        out.append((frame, canonical_json(data)))
    return tuple(out)
