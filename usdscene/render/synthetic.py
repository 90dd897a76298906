"""Small synthetic stages in the composed-stage layout, for render tests and benchmarks.

They follow :mod:`usdscene.document.stage_schema` exactly (cameras at ``/World/Cameras/<name>`` with the
``usdscene:lens:*`` attributes, objects at ``/World/Objects/<class>_<uid>`` as ``UsdGeom.Mesh``
with ``userProperties:usdscene_uid``, ``usdscene:maskId`` and time-sampled visibility, root
layer Z up, 1 metre per unit, start/end time codes) but in one layer, without assets.

Objects are UV spheres with a flat emissive colour (``UsdPreviewSurface`` with black diffuse),
so without lights every object pixel of the image has exactly the object's colour.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from usdscene.document import stage_schema as names
from usdscene.document.model import Camera, RenderSettings, cv_pose_to_usd_pose


@dataclass(frozen=True)
class SphereSpec:
    """One sphere object.

    Attributes:
        uid: OpenLABEL uid.
        centre_m: (x, y, z) world position in metres (or per-frame via ``frame_centres``).
        radius_m: radius in metres.
        color_rgb: emissive linear colour.
        mask_id: the ``usdscene:maskId`` value.
        frames: frames where the sphere is visible; empty = always.
        frame_centres: per-frame positions ``(frame, (x, y, z))`` (time-sampled translate).
        class_name: class part of the prim name.
        opacity: UsdPreviewSurface opacity (1 = opaque).
        emissive: flat emissive colour (True) or a diffuse surface of that colour (False).
    """

    uid: str
    centre_m: tuple[float, float, float]
    radius_m: float
    color_rgb: tuple[float, float, float]
    mask_id: int
    frames: tuple[int, ...] = ()
    frame_centres: tuple[tuple[int, tuple[float, float, float]], ...] = ()
    class_name: str = "sphere"
    opacity: float = 1.0
    emissive: bool = True


@dataclass(frozen=True)
class BoxSpec:
    """A static environment box (a room, a floor) with a diffuse colour; background in masks.
    ``surface`` names a procedural surface (``usdscene.document.surfaces``) drawn on that colour."""

    name: str
    centre_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    color_rgb: tuple[float, float, float] = (0.5, 0.5, 0.5)
    inward: bool = False
    surface: str | None = None


@dataclass(frozen=True)
class PointLightSpec:
    """A point light of a synthetic test scene: position in metres, intensity as UsdLux
    ``inputs:intensity``, radius in metres."""

    name: str
    position_m: tuple[float, float, float]
    intensity: float = 50.0
    radius_m: float = 0.05


@dataclass(frozen=True)
class SyntheticScene:
    """A small scene built in code for tests: cameras, emissive spheres, boxes, point lights and render
    settings."""

    cameras: tuple[Camera, ...]
    spheres: tuple[SphereSpec, ...]
    frame_start: int = 0
    frame_end: int = 0
    boxes: tuple[BoxSpec, ...] = ()
    lights: tuple[PointLightSpec, ...] = ()
    render: RenderSettings | None = None
    sphere_segments: tuple[int, int] = (32, 16)
    extra: dict = field(default_factory=dict)


def uv_sphere(radius_m: float, segments: int = 32, rings: int = 16):
    """(points (N, 3), face_vertex_counts (F,), face_vertex_indices (M,)) of a UV sphere with
    outward, counter-clockwise faces."""
    points = [(0.0, 0.0, radius_m)]
    for i in range(1, rings):
        phi = math.pi * i / rings
        for j in range(segments):
            t = 2 * math.pi * j / segments
            points.append((radius_m * math.sin(phi) * math.cos(t), radius_m * math.sin(phi) * math.sin(t),
                           radius_m * math.cos(phi)))
    points.append((0.0, 0.0, -radius_m))
    bottom = len(points) - 1
    counts, indices = [], []

    def ring(i, j):
        return 1 + (i - 1) * segments + (j % segments)

    for j in range(segments):
        counts.append(3)
        indices += [0, ring(1, j), ring(1, j + 1)]
    for i in range(1, rings - 1):
        for j in range(segments):
            counts.append(4)
            indices += [ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)]
    for j in range(segments):
        counts.append(3)
        indices += [ring(rings - 1, j), bottom, ring(rings - 1, j + 1)]
    return np.asarray(points), np.asarray(counts), np.asarray(indices)


def box_mesh(size_m, inward: bool):
    """(points, face_vertex_counts, face_vertex_indices) of an axis-aligned box of ``size_m``
    centred on the origin; faces point outward (inward: into the box)."""
    sx, sy, sz = (s / 2 for s in size_m)
    pts = [(-sx, -sy, -sz), (sx, -sy, -sz), (sx, sy, -sz), (-sx, sy, -sz),
           (-sx, -sy, sz), (sx, -sy, sz), (sx, sy, sz), (-sx, sy, sz)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    if inward:
        faces = [tuple(reversed(f)) for f in faces]
    return pts, [4] * 6, [i for f in faces for i in f]


def _material(stage, path: str, *, emissive=None, diffuse=(0.0, 0.0, 0.0), opacity: float = 1.0):
    from pxr import Gf, Sdf, UsdShade

    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*diffuse))
    if emissive is not None:
        shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*emissive))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    if opacity < 1.0:
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(opacity))
    shader.CreateInput("specular", Sdf.ValueTypeNames.Float).Set(0.0)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def write_camera(stage, camera: Camera, frames: Sequence[int] = ()) -> None:
    """Author ``/World/Cameras/<name>`` as the composer does: UsdGeom.Camera (USD axes),
    aperture/focal length in millimetres and the ``usdscene:lens:*`` attributes."""
    from pxr import Gf, Sdf, UsdGeom

    intr = camera.intrinsics
    cam = UsdGeom.Camera.Define(stage, names.camera_prim_path(camera.name))
    op = cam.AddTransformOp()

    def usd_matrix(pose):
        return Gf.Matrix4d(cv_pose_to_usd_pose(pose).as_array().T.tolist())

    if camera.frame_poses:
        for f, pose in camera.frame_poses:
            op.Set(usd_matrix(pose), f)
    else:
        op.Set(usd_matrix(camera.pose))
    cam.CreateFocalLengthAttr(intr.focal_length_mm)
    cam.CreateHorizontalApertureAttr(intr.sensor_width_mm)
    cam.CreateVerticalApertureAttr(intr.sensor_height_mm)
    cam.CreateClippingRangeAttr(Gf.Vec2f(camera.clip_near_m, camera.clip_far_m))
    if intr.lens.value == "orthographic":
        cam.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    prim = cam.GetPrim()
    prim.CreateAttribute(names.ATTR_LENS_MODEL, Sdf.ValueTypeNames.Token).Set(intr.lens.value)
    prim.CreateAttribute(names.ATTR_LENS_WIDTH, Sdf.ValueTypeNames.Int).Set(intr.width_px)
    prim.CreateAttribute(names.ATTR_LENS_HEIGHT, Sdf.ValueTypeNames.Int).Set(intr.height_px)
    prim.CreateAttribute(names.ATTR_LENS_FX, Sdf.ValueTypeNames.Double).Set(intr.fx_px)
    prim.CreateAttribute(names.ATTR_LENS_FY, Sdf.ValueTypeNames.Double).Set(intr.fy_px)
    prim.CreateAttribute(names.ATTR_LENS_CX, Sdf.ValueTypeNames.Double).Set(intr.cx_px)
    prim.CreateAttribute(names.ATTR_LENS_CY, Sdf.ValueTypeNames.Double).Set(intr.cy_px)
    prim.CreateAttribute(names.ATTR_LENS_DISTORTION, Sdf.ValueTypeNames.DoubleArray).Set(list(intr.distortion))
    if intr.fov_deg is not None:
        prim.CreateAttribute(names.ATTR_LENS_FOV, Sdf.ValueTypeNames.Double).Set(intr.fov_deg)
    prim.CreateAttribute(names.ATTR_LENS_SENSOR_WIDTH, Sdf.ValueTypeNames.Double).Set(intr.sensor_width_mm)


def write_render_settings(stage, settings: RenderSettings) -> None:
    """Author ``settings`` as the render settings prim of ``stage`` (the attributes the stage reader reads
    back)."""
    from pxr import Gf, Sdf, UsdRender

    prim = UsdRender.Settings.Define(stage, names.RENDER_SETTINGS).GetPrim()
    t = Sdf.ValueTypeNames
    prim.CreateAttribute(names.ATTR_RENDER_ENGINE, t.Token).Set(settings.engine)
    prim.CreateAttribute(names.ATTR_RENDER_DEVICE, t.Token).Set(settings.device)
    prim.CreateAttribute(names.ATTR_RENDER_SAMPLES, t.Int).Set(settings.samples)
    prim.CreateAttribute(names.ATTR_RENDER_ADAPTIVE_THRESHOLD, t.Float).Set(settings.adaptive_threshold)
    prim.CreateAttribute(names.ATTR_RENDER_DENOISE, t.Bool).Set(settings.denoise)
    prim.CreateAttribute(names.ATTR_RENDER_DENOISER, t.Token).Set(settings.denoiser)
    prim.CreateAttribute(names.ATTR_RENDER_DENOISING_QUALITY, t.Token).Set(settings.denoising_quality)
    prim.CreateAttribute(names.ATTR_RENDER_DENOISING_PREFILTER, t.Token).Set(settings.denoising_prefilter)
    prim.CreateAttribute(names.ATTR_RENDER_ADAPTIVE_MIN_SAMPLES, t.Int).Set(settings.adaptive_min_samples)
    prim.CreateAttribute(names.ATTR_RENDER_DENOISING_INPUT_PASSES, t.Token).Set(settings.denoising_input_passes)
    prim.CreateAttribute(names.ATTR_RENDER_LIGHT_TREE, t.Bool).Set(settings.light_tree)
    prim.CreateAttribute(names.ATTR_RENDER_PATH_GUIDING, t.Bool).Set(settings.path_guiding)
    prim.CreateAttribute(names.ATTR_RENDER_CLAMP_INDIRECT, t.Float).Set(settings.clamp_indirect)
    prim.CreateAttribute(names.ATTR_RENDER_SAMPLING_PATTERN, t.Token).Set(settings.sampling_pattern)
    prim.CreateAttribute(names.ATTR_RENDER_FAST_GI, t.Bool).Set(settings.fast_gi)
    prim.CreateAttribute(names.ATTR_RENDER_FAST_GI_METHOD, t.Token).Set(settings.fast_gi_method)
    prim.CreateAttribute(names.ATTR_RENDER_FAST_GI_AO_BOUNCES, t.Int).Set(settings.fast_gi_ao_bounces)
    prim.CreateAttribute(names.ATTR_RENDER_FAST_GI_DISTANCE, t.Float).Set(settings.fast_gi_distance_m)
    prim.CreateAttribute(names.ATTR_RENDER_SCRAMBLING_DISTANCE, t.Float).Set(settings.scrambling_distance)
    prim.CreateAttribute(names.ATTR_RENDER_AUTO_SCRAMBLING_DISTANCE, t.Bool).Set(settings.auto_scrambling_distance)
    prim.CreateAttribute(names.ATTR_RENDER_MAX_BOUNCES, t.Int).Set(settings.max_bounces)
    prim.CreateAttribute(names.ATTR_RENDER_CAUSTICS, t.Bool).Set(settings.caustics)
    prim.CreateAttribute(names.ATTR_RENDER_TILE_SIZE, t.Int).Set(settings.tile_size_px)
    prim.CreateAttribute(names.ATTR_RENDER_RESOLUTION, t.Int2).Set(Gf.Vec2i(*settings.resolution_px))
    prim.CreateAttribute(names.ATTR_RENDER_SEED, t.Int).Set(settings.seed)


def write_synthetic_stage(scene: SyntheticScene, stage_dir: Path) -> Path:
    """Write ``stage_dir/scene.usda`` for ``scene`` and return its path."""
    from pxr import Gf, Usd, UsdGeom, UsdLux

    stage_dir = Path(stage_dir)
    stage_dir.mkdir(parents=True, exist_ok=True)
    path = stage_dir / names.ROOT_LAYER
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(scene.frame_start)
    stage.SetEndTimeCode(scene.frame_end)
    stage.SetFramesPerSecond(24)
    stage.SetTimeCodesPerSecond(24)
    world = UsdGeom.Xform.Define(stage, names.WORLD)
    stage.SetDefaultPrim(world.GetPrim())
    UsdGeom.Scope.Define(stage, names.CAMERAS)
    UsdGeom.Scope.Define(stage, names.OBJECTS)
    UsdGeom.Xform.Define(stage, names.ENVIRONMENT)
    frames = range(scene.frame_start, scene.frame_end + 1)
    for camera in scene.cameras:
        write_camera(stage, camera, frames)
    for sphere in scene.spheres:
        _write_sphere(stage, sphere, frames, scene.sphere_segments)
    for box in scene.boxes:
        _write_box(stage, box)
    if scene.lights:
        UsdGeom.Scope.Define(stage, names.LIGHTS)
    for light in scene.lights:
        lux = UsdLux.SphereLight.Define(stage, names.light_prim_path(light.name))
        lux.CreateIntensityAttr(light.intensity)
        lux.CreateRadiusAttr(light.radius_m)
        lux.AddTranslateOp().Set(Gf.Vec3d(*light.position_m))
    write_render_settings(stage, scene.render or RenderSettings())
    stage.GetRootLayer().Save()
    return path


def _write_sphere(stage, sphere: SphereSpec, frames: range, segments: tuple[int, int]) -> None:
    """One sphere object: its mesh (``segments``: longitude and latitude steps), per-frame
    position and visibility over ``frames``, ids and material."""
    from pxr import Gf, Sdf, UsdGeom, Vt

    prim_path = names.object_prim_path(sphere.class_name, sphere.uid)
    mesh = UsdGeom.Mesh.Define(stage, prim_path)
    pts, counts, idx = uv_sphere(sphere.radius_m, *segments)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts.tolist()]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts.tolist()))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx.tolist()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr([Gf.Vec3f(-sphere.radius_m), Gf.Vec3f(sphere.radius_m)])
    translate = mesh.AddTranslateOp()
    if sphere.frame_centres:
        for f, c in sphere.frame_centres:
            translate.Set(Gf.Vec3d(*c), f)
    else:
        translate.Set(Gf.Vec3d(*sphere.centre_m))
    prim = mesh.GetPrim()
    prim.SetCustomDataByKey(names.CUSTOM_UID, sphere.uid)
    prim.SetCustomDataByKey(names.CUSTOM_CLASS, sphere.class_name)
    prim.CreateAttribute(names.ATTR_USER_UID, Sdf.ValueTypeNames.String).Set(sphere.uid)
    prim.CreateAttribute(names.ATTR_USER_CLASS, Sdf.ValueTypeNames.String).Set(sphere.class_name)
    prim.CreateAttribute(names.ATTR_MASK_ID, Sdf.ValueTypeNames.Int).Set(sphere.mask_id)
    if sphere.frames:
        vis = mesh.CreateVisibilityAttr()
        for f in frames:
            vis.Set(UsdGeom.Tokens.inherited if f in sphere.frames else UsdGeom.Tokens.invisible, f)
    if sphere.emissive:
        material = _material(stage, f"{prim_path}/Looks/Flat", emissive=sphere.color_rgb,
                             opacity=sphere.opacity)
    else:
        material = _material(stage, f"{prim_path}/Looks/Flat", diffuse=sphere.color_rgb,
                             opacity=sphere.opacity)
    from pxr import UsdShade
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)


def _write_box(stage, box: BoxSpec) -> None:
    """One environment box: its mesh, its diffuse material and its procedural surface."""
    from pxr import Gf, Sdf, UsdGeom

    prim_path = f"{names.ENVIRONMENT}/{names.prim_name(box.name)}"
    mesh = UsdGeom.Mesh.Define(stage, prim_path)
    pts, counts, idx = box_mesh(box.size_m, box.inward)
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.AddTranslateOp().Set(Gf.Vec3d(*box.centre_m))
    material = _material(stage, f"{prim_path}/Looks/Diffuse", diffuse=box.color_rgb)
    if box.surface is not None:
        from usdscene.document.surfaces import SURFACE_ATTRIBUTE

        mesh.GetPrim().CreateAttribute(SURFACE_ATTRIBUTE, Sdf.ValueTypeNames.String, custom=True).Set(box.surface)
    from pxr import UsdShade
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


@dataclass(frozen=True)
class CabinLike:
    """Sizes of :func:`cabin_like_scene`.

    Attributes:
        frames: frames of the sequence (from 0).
        cameras: ceiling cameras looking down the aisle.
        objects: diffuse spheres (bag and passenger stand-ins).
        rows: seat rows (two seat boxes each, 0.8 m apart).
        width_px, height_px: every camera's image size, pixels.
        seed: the seed of the spheres' sizes, places, colours and appearances.
        sphere_segments: longitude and latitude steps of each sphere's mesh.
    """

    frames: int = 5
    cameras: int = 4
    objects: int = 60
    rows: int = 20
    width_px: int = 640
    height_px: int = 480
    seed: int = 0
    sphere_segments: tuple[int, int] = (48, 24)


def cabin_like_scene(sizes: CabinLike = CabinLike()) -> SyntheticScene:
    """An enclosed, cabin-like benchmark scene: a 3.6 m wide, 2.2 m high tube of ``rows`` seat
    rows (boxes), 16 ceiling point lights, ``objects`` diffuse spheres of assorted colours
    (bags and passengers stand-ins; some appear mid-sequence, some move) and ``cameras``
    ceiling cameras looking down the aisle at ``width_px`` × ``height_px`` (``sizes``).

    Deterministic for a given ``seed``.
    """
    frames, cameras, objects, rows = sizes.frames, sizes.cameras, sizes.objects, sizes.rows
    width_px, height_px, seed, sphere_segments = sizes.width_px, sizes.height_px, sizes.seed, sizes.sphere_segments
    from usdscene.document.model import Intrinsics, LensModel, Pose

    rng = np.random.default_rng(seed)
    length = rows * 0.8 + 2.0
    boxes = [BoxSpec("cabin", (length / 2 - 1.0, 0.0, 1.1), (length, 3.6, 2.2), (0.75, 0.74, 0.7), inward=True)]
    for r in range(rows):
        for side, y in (("L", -1.05), ("R", 1.05)):
            boxes.append(BoxSpec(f"seat_{r:02d}{side}", (r * 0.8, y, 0.45), (0.5, 1.4, 0.9), (0.2, 0.25, 0.4)))
    lights = tuple(PointLightSpec(f"lamp_{i:02d}", (i * length / 16, 0.0, 2.05), 40.0, 0.05) for i in range(16))
    spheres = []
    for i in range(objects):
        r = float(rng.uniform(0.12, 0.3))
        x = float(rng.uniform(0.0, (rows - 1) * 0.8))
        y = float(rng.choice([-1.3, -0.8, 0.0, 0.8, 1.3]))
        z = 0.9 + r if y != 0.0 else r
        color = tuple(float(c) for c in rng.uniform(0.1, 0.9, 3))
        first = int(rng.integers(0, max(1, frames // 2))) if i % 3 == 0 else 0
        visible = tuple(range(first, frames)) if first else ()
        centres = tuple((f, (x + 0.1 * f, y, z)) for f in range(frames)) if i % 5 == 0 else ()
        spheres.append(SphereSpec(f"obj{i:03d}", (x, y, z), r, color, i + 1, frames=visible,
                                  frame_centres=centres, emissive=False, class_name="bag"))
    intr = Intrinsics(LensModel.PERSPECTIVE, width_px, height_px, width_px * 0.55, width_px * 0.55,
                      (width_px - 1) / 2, (height_px - 1) / 2)
    cams = []
    for c in range(cameras):
        x = c * (rows * 0.8) / max(1, cameras)
        # Looking along +x and 20° down: OpenCV axes x = world -y, z = forward.
        t = np.radians(20.0)
        fwd = np.array([np.cos(t), 0.0, -np.sin(t)])
        right = np.array([0.0, -1.0, 0.0])
        down = np.cross(fwd, right)
        cams.append(Camera(f"cam_{c:02d}", intr, Pose.from_rotation_translation(
            np.stack([right, down, fwd], 1), [x - 0.5, 0.0, 2.0])))
    return SyntheticScene(cameras=tuple(cams), spheres=tuple(spheres), frame_start=0, frame_end=frames - 1,
                          boxes=tuple(boxes), lights=lights, sphere_segments=sphere_segments)
