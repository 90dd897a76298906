"""The Blender worker process: the only module of usdscene that imports ``bpy``.

Run as ``python -m usdscene.render.worker JOB.json`` (or with ``--wait-for-job``: import bpy
first, then read the job file's path from stdin, for a worker started before its job exists,
see :func:`usdscene.render.worker_process.prestart_workers`); never imported by the parent (bpy breaks
``multiprocessing`` and owns process-wide state). The job file (written by
:mod:`usdscene.render.driver`, see :mod:`usdscene.render.job`) says which stage to import,
which prims the shard needs, which objects are visible on which frames with which mask ids, the
calibrated cameras and their poses per frame, the render settings and the (frame, camera)
pairs to render, in order.

What happens:

1. Factory-empty scene; a black world is created *before* the USD import so that a dome light
   of the stage can replace it (the importer drops dome lights without a world).
2. ``wm.usd_import`` once, of the prims the shard needs only (``prim_path_mask``), instances
   realised (instanced prims would share the prototype's pass index), no cameras (one render
   camera of our own is driven from the job; switching ``scene.camera`` forces a full re-sync
   with persistent data).
3. Per frame: ``scene.frame_set`` (transform caches follow the stage's time samples), then
   ``hide_render`` for objects absent on that frame and ``pass_index`` = mask id.
4. Per camera: the render camera takes the camera's pose and intrinsics; Cycles renders a
   multilayer EXR on ``/dev/shm`` holding the beauty and the object-index pass of the *same*
   render; the worker converts the linear beauty to an 8-bit sRGB PNG and the object index to a
   uint16 PNG, remaps both with one shared map for OpenCV lens models (bilinear for the image,
   nearest for the mask), and writes them atomically.
5. After each pair a line ``@usdscene {json}`` goes to stdout (the driver parses those and
   ignores Blender's own chatter).
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

PROGRESS_PREFIX = "@usdscene "


def _emit(event: dict) -> None:
    sys.stdout.write(PROGRESS_PREFIX + json.dumps(event) + "\n")
    sys.stdout.flush()


def _import_bpy():
    try:
        import bpy  # noqa: F401  (the one place usdscene imports bpy)
    except ImportError as exc:  # pragma: no cover - environment problem
        raise ImportError("usdscene's renderer needs the 'bpy' package (pip install bpy==5.0.1) "
                          f"in this Python ({sys.executable}): {exc}") from exc
    return bpy


ENGINES = {"cycles": "CYCLES", "eevee": "BLENDER_EEVEE", "workbench": "BLENDER_WORKBENCH"}
# Cycles GPU backends in the order tried: OptiX (NVIDIA RTX path, hardware ray tracing) before
# CUDA (every NVIDIA GPU Cycles supports), then AMD and Intel.
GPU_BACKENDS = ("OPTIX", "CUDA", "HIP", "ONEAPI")


class DeviceError(RuntimeError):
    """The requested render device cannot be used; its message is complete for the user."""


def gpu_missing_message(blender_version: str, tried: list[str]) -> str:
    """Why ``render.device: gpu`` cannot run here: the backends tried and, for NVIDIA, whether
    the driver library that Cycles' CUDA and OptiX backends load at run time exists."""
    import ctypes

    try:
        ctypes.CDLL("libcuda.so.1" if sys.platform.startswith("linux") else "nvcuda.dll")
        nvidia = ("the NVIDIA driver library loads but Cycles accepts none of its GPUs (CUDA needs "
                  "compute capability 5.0 or newer, OptiX an RTX-class GPU and a recent driver)")
    except OSError as exc:
        nvidia = f"the NVIDIA driver library that CUDA and OptiX need cannot be loaded ({exc})"
    return (f"render.device 'gpu': Cycles (bpy {blender_version}) found no GPU: no "
            f"{' / '.join(tried)} device; {nvidia}. Install the GPU driver or set render.device to 'cpu'")



class Session:
    """A Blender scene holding one imported stage shard and one render camera."""

    def __init__(self, job: dict) -> None:
        self.job = job
        self.bpy = _import_bpy()
        self.scratch = Path(job["scratch_dir"])
        self.scratch.mkdir(parents=True, exist_ok=True)
        self.exr_path = self.scratch / f"render-{os.getpid()}.exr"
        self.current_frame: int | None = None
        self.hidden: dict[str, bool] = {}
        self._remaps: dict[str, tuple] = {}
        self._fov_masks: dict[str, object] = {}
        self._setup_scene()
        # Before the import: a missing GPU is reported in a second, not after the stage loads.
        self.rendering = job.get("mode", "render") == "render"
        if self.rendering and job["settings"]["device"] == "gpu":
            self._enable_gpu()
        self._import_stage()
        # Meshes that name a procedural surface get its node tree (render/surface_nodes.py).
        from usdscene.render.surface_nodes import apply_surfaces

        apply_surfaces(self.bpy)
        self._setup_render()
        self._setup_imaging()

    # ---------------------------------------------------------------------------------------
    def _setup_scene(self) -> None:
        bpy = self.bpy
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        world = bpy.data.worlds.new("World")
        scene.world = world
        # Black unless the stage brings a dome light (the importer rebuilds the world then).
        background = world.node_tree.nodes.get("Background") if world.node_tree else None
        if background is not None:
            background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        world.color = (0.0, 0.0, 0.0)
        self.scene = scene

    def _import_stage(self) -> None:
        bpy = self.bpy
        started = time.perf_counter()
        result = bpy.ops.wm.usd_import(
            filepath=self.job["stage"],
            prim_path_mask=self.job.get("prim_path_mask", ""),
            import_cameras=False,
            import_visible_only=False,  # presence is per frame, applied below
            support_scene_instancing=False,  # realise instances: each needs its own pass index
            property_import_mode="USER",
            set_frame_range=True,
            create_collection=False,
        )
        if "FINISHED" not in result:
            raise RuntimeError(f"USD import of {self.job['stage']} failed: {result}")
        # uid → Blender objects carrying it (the object and everything below it).
        wanted = {o["uid"]: o for o in self.job["objects"]}
        self.objects: dict[str, list] = {}
        for ob in bpy.data.objects:
            uid = ob.get("usdscene_uid")
            if uid is None and ob.data is not None and hasattr(ob.data, "get"):
                uid = ob.data.get("usdscene_uid")
            if uid is None or uid not in wanted:
                continue
            members = [ob, *ob.children_recursive]
            self.objects.setdefault(str(uid), []).extend(members)
        # uid → pose variant → the Blender objects of that pose child (objects whose pose
        # changes per frame, stage_schema.POSE_CHILD_PREFIX); only those show per frame.
        self.poses: dict[str, dict[str, list]] = {}
        for uid, members in self.objects.items():
            for ob in members:
                variant = ob.get("usdscene_pose")
                if variant is not None and "pose_frames" in wanted[uid]:
                    self.poses.setdefault(uid, {})[str(variant)] = [ob, *ob.children_recursive]
        for uid, members in self.objects.items():
            mask_id = int(wanted[uid]["mask_id"])
            for ob in members:
                ob.pass_index = mask_id
        missing = sorted(set(wanted) - set(self.objects))
        _emit({"event": "imported", "seconds": time.perf_counter() - started, "pid": os.getpid(),
               "objects": len(bpy.data.objects), "missing_uids": missing[:20],
               "missing_count": len(missing)})

    def _setup_render(self) -> None:
        bpy = self.bpy
        scene = self.scene
        s = self.job["settings"]
        engine = ENGINES.get(s["engine"], s["engine"])
        scene.render.engine = engine
        if engine != "CYCLES":
            raise RuntimeError(f"render engine {s['engine']!r}: exact instance masks need the Cycles "
                               "object-index pass; use engine 'cycles'")
        cycles = scene.cycles
        # The GPU was enabled (or found missing) before the import; a .blend for camera design
        # keeps the document's device without needing one here.
        cycles.device = "GPU" if s["device"] == "gpu" else "CPU"
        if self.rendering and s["device"] == "cpu" and s["denoise"] and s["denoiser"] == "optix":
            raise DeviceError("render.denoiser 'optix' runs on an NVIDIA GPU only and render.device is 'cpu'; "
                              "use denoiser 'openimagedenoise' or device 'gpu'")
        cycles.samples = int(s["samples"])
        cycles.use_adaptive_sampling = float(s["adaptive_threshold"]) > 0
        if cycles.use_adaptive_sampling:
            cycles.adaptive_threshold = float(s["adaptive_threshold"])
            cycles.adaptive_min_samples = int(s["adaptive_min_samples"])
        cycles.use_denoising = bool(s["denoise"])
        if cycles.use_denoising:
            cycles.denoiser = "OPTIX" if s["denoiser"] == "optix" else "OPENIMAGEDENOISE"
            cycles.denoising_quality = str(s["denoising_quality"]).upper()
            cycles.denoising_prefilter = str(s["denoising_prefilter"]).upper()
            cycles.denoising_input_passes = str(s["denoising_input_passes"]).upper()
        cycles.use_light_tree = bool(s["light_tree"])
        cycles.sample_clamp_indirect = float(s["clamp_indirect"])
        cycles.sampling_pattern = str(s["sampling_pattern"]).upper()
        # Cycles reads the fast GI factor and distance from the world, which the import may
        # have rebuilt for a dome light: set after it. Both bounce fields are written so that a
        # .blend for camera design previews in the viewport what the render gets.
        cycles.use_fast_gi = bool(s["fast_gi"])
        cycles.fast_gi_method = str(s["fast_gi_method"]).upper()
        cycles.ao_bounces = cycles.ao_bounces_render = int(s["fast_gi_ao_bounces"])
        if scene.world is not None:
            scene.world.light_settings.distance = float(s["fast_gi_distance_m"])
        cycles.scrambling_distance = float(s["scrambling_distance"])
        cycles.auto_scrambling_distance = bool(s["auto_scrambling_distance"])
        # Path guiding exists on the CPU only; Cycles ignores it on a GPU.
        cycles.use_guiding = bool(s["path_guiding"])
        cycles.use_surface_guiding = True
        cycles.use_volume_guiding = False
        bounces = int(s["max_bounces"])
        cycles.max_bounces = bounces
        cycles.diffuse_bounces = bounces
        cycles.glossy_bounces = bounces
        cycles.transmission_bounces = max(bounces, 0)
        cycles.volume_bounces = 0
        cycles.caustics_reflective = bool(s["caustics"])
        cycles.caustics_refractive = bool(s["caustics"])
        cycles.use_auto_tile = True
        cycles.tile_size = int(s["tile_size_px"])
        cycles.seed = int(s["seed"])
        cycles.use_animated_seed = False
        scene.render.use_persistent_data = True
        scene.render.resolution_percentage = 100
        scene.render.film_transparent = False
        scene.render.dither_intensity = 0.0
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.view_settings.exposure = 0.0
        scene.view_settings.gamma = 1.0
        view_layer = scene.view_layers[0]
        view_layer.use_pass_object_index = True
        image = scene.render.image_settings
        image.media_type = "MULTI_LAYER_IMAGE"
        image.file_format = "OPEN_EXR_MULTILAYER"
        image.color_depth = "32"
        image.exr_codec = "NONE"  # /dev/shm: compression costs time and saves nothing
        scene.render.filepath = str(self.exr_path)
        scene.render.use_file_extension = False
        threads = self.job.get("threads")
        if threads:
            scene.render.threads_mode = "FIXED"
            scene.render.threads = int(threads)
        data = bpy.data.cameras.new("usdscene_render_camera")
        self.camera = bpy.data.objects.new("usdscene_render_camera", data)
        scene.collection.objects.link(self.camera)
        scene.camera = self.camera

    def _setup_imaging(self) -> None:
        """The document's world (background, sky or HDRI, view transform) and the cameras'
        render-time sensor parts (shutter, IR illuminator). Nothing is touched for a stage
        without them, so its images stay byte-identical to before they existed."""
        from usdscene.document.imaging import Sensor, World, spec_from_json

        self.world = None
        self.world_at = None
        self.display_png = self.scratch / f"display-{os.getpid()}.png"
        self.sensors = {name: (spec_from_json(Sensor, cam["sensor"]["sensor"]), int(cam["sensor"]["seed"]))
                        for name, cam in self.job["cameras"].items() if "sensor" in cam}
        self.ir_light = None
        self._shutter = 0.0
        world_job = self.job.get("world")
        if world_job is None:
            return
        self.world = spec_from_json(World, world_job["world"])
        self.world_job = world_job
        self._build_world()

    def _build_world(self) -> None:
        """The document's world (:class:`WorldNodes`) and its view transform."""
        self.world_nodes = WorldNodes(self.bpy, self.scene, self.world, self.world_job)
        self.scene.world.light_settings.distance = float(self.job["settings"]["fast_gi_distance_m"])
        view = self.scene.view_settings
        if self.world.view_transform != "standard":
            from usdscene.document.imaging import VIEW_TRANSFORMS

            view.view_transform = VIEW_TRANSFORMS[self.world.view_transform]
        self._apply_world(self.current_frame if self.current_frame is not None else 0)

    def _apply_world(self, frame: int) -> None:
        """Set the world's per-frame values (only what changed: each change re-syncs the world)."""
        at = self.world.at_frame(frame)
        if at == self.world_at:
            return
        self.world_nodes.apply(at)
        if at.view_transform != "standard":
            self.scene.view_settings.exposure = at.exposure_ev
        self.world_at = at

    def _apply_camera_sensor(self, name: str) -> None:
        """Shutter (Cycles motion blur, centred on the frame: labels are at the frame time) and
        the IR illuminator of the camera about to render; reset for cameras without them."""
        from usdscene.document.imaging import ir_illuminator_power_w

        sensor = self.sensors.get(name, (None, 0))[0]
        shutter = sensor.shutter_frames if sensor is not None else 0.0
        if shutter != self._shutter:
            render = self.scene.render
            render.use_motion_blur = shutter > 0
            if shutter > 0:
                render.motion_blur_shutter = shutter
                render.motion_blur_position = "CENTER"
            self._shutter = shutter
        ir = sensor is not None and sensor.ir_night
        if ir and self.ir_light is None:
            data = self.bpy.data.lights.new("usdscene_ir_illuminator", type="SPOT")
            data.shadow_soft_size = 0.02
            self.ir_light = self.bpy.data.objects.new("usdscene_ir_illuminator", data)
            self.scene.collection.objects.link(self.ir_light)
            # At the camera, shining along its view axis (-Z of both).
            self.ir_light.parent = self.camera
        if self.ir_light is not None:
            if ir:
                import math

                render_intr = self.job["cameras"][name]["render_intrinsics"]
                if render_intr.get("fov_deg"):  # a fisheye: its image circle
                    field = math.radians(float(render_intr["fov_deg"]))
                else:
                    w, h, fx = render_intr["width_px"], render_intr["height_px"], render_intr["fx_px"]
                    field = 2.0 * math.atan(math.hypot(w, h) / 2.0 / fx)  # the diagonal
                self.ir_light.data.spot_size = min(math.pi, field + math.radians(10.0))
                self.ir_light.data.energy = ir_illuminator_power_w(sensor.ir_range_m)
            if self.ir_light.hide_render == ir:
                self.ir_light.hide_render = not ir

    def _enable_gpu(self) -> None:
        """Let Cycles render on every GPU of the first backend that has one.

        Raises:
            DeviceError: no backend found a GPU; the message says which backends were tried
                and what is missing (the NVIDIA driver library, or a device it accepts).
        """
        prefs = self.bpy.context.preferences.addons["cycles"].preferences
        tried = []
        for kind in GPU_BACKENDS:
            try:
                prefs.compute_device_type = kind
            except TypeError:  # a backend this build of Blender lacks
                continue
            tried.append(kind)
            prefs.refresh_devices()
            devices = [d for d in prefs.devices if d.type == kind]
            if devices:
                for d in prefs.devices:
                    # The CPU stays out: mixed CPU + GPU rendering is slower on small tiles.
                    d.use = d.type == kind
                _emit({"event": "device", "backend": kind, "devices": [d.name for d in devices]})
                return
        raise DeviceError(gpu_missing_message(self.bpy.app.version_string, tried))

    # ---------------------------------------------------------------------------------------
    def set_frame(self, frame: int) -> None:
        """Go to ``frame`` and hide the objects absent from it (only what changed is touched)."""
        if frame == self.current_frame:
            return
        self.scene.frame_set(frame)
        for o in self.job["objects"]:
            members = self.objects.get(o["uid"])
            if not members:
                continue
            poses = self.poses.get(o["uid"])
            if poses:
                for ob, hide in member_hides(o, members, poses, frame):
                    ob.hide_render = hide
                continue
            hide = frame not in o["_visible"]
            if self.hidden.get(o["uid"]) == hide:
                continue
            self.hidden[o["uid"]] = hide
            for ob in members:
                ob.hide_render = hide
        if self.world is not None:
            self._apply_world(frame)
        self.current_frame = frame

    def set_camera(self, name: str, frame: int) -> None:
        """Point the render camera at camera ``name``'s pose and lens for ``frame``."""
        from usdscene.render.job import intrinsics_from_json, usd_camera_matrix

        cam_job = self.job["cameras"][name]
        pose = cam_job["poses"].get(str(frame), cam_job["pose"])
        render = intrinsics_from_json(cam_job["render_intrinsics"])
        ob, data = self.camera, self.camera.data
        import mathutils

        # Touch only what changes: every assignment tags Blender data for a Cycles update.
        key = (tuple(pose), tuple(cam_job["clip_m"]))
        if key != getattr(self, "_pose_key", None):
            # mathutils.Matrix takes rows; a bare nested list would be read column by column.
            ob.matrix_world = mathutils.Matrix(usd_camera_matrix(pose))
            data.clip_start, data.clip_end = cam_job["clip_m"]
            self._pose_key = key
        if render != getattr(self, "_lens", None):
            apply_intrinsics(self.scene, data, render)
            self._lens = render
        if self.sensors or self._shutter or self.ir_light is not None:
            self._apply_camera_sensor(name)

    def render_image(self, frame: int, camera: str):
        """Render one (frame, camera) and decode it.

        Returns:
            ``(rgb, ids, timing)``: (H, W, 3) float32 linear beauty and (H, W) uint16 ids of the
            native render, and seconds: wall (``render_s``) and CPU time of the whole process,
            all threads (``render_cpu_s``; robust on a shared machine).
        """
        self.set_frame(frame)
        self.set_camera(camera, frame)
        started, cpu_started = time.perf_counter(), time.process_time()
        self.bpy.ops.render.render(write_still=True)
        rendered, cpu_rendered = time.perf_counter(), time.process_time()
        rgb, ids = read_exr(self.exr_path)
        if self.world_at is not None:
            rgb = self._display(rgb)
        return rgb, ids, {"render_s": rendered - started, "render_cpu_s": cpu_rendered - cpu_started,
                          "decode_s": time.perf_counter() - rendered}

    def _display(self, rgb):
        """The world's exposure and view transform: Standard is the sRGB curve of
        :func:`linear_to_srgb8` after ``2^exposure_ev``; AgX and Filmic come from Blender's
        colour management (the render result saved as an 8-bit PNG, read back).

        Returns:
            (H, W, 3) float32 linear (Standard) or uint8 sRGB (AgX, Filmic).
        """
        at = self.world_at
        if at.view_transform == "standard":
            return rgb * float(2.0 ** at.exposure_ev) if at.exposure_ev else rgb
        import cv2

        image = self.scene.render.image_settings
        saved = (image.media_type, image.file_format, image.color_depth)
        image.media_type, image.file_format, image.color_depth = "IMAGE", "PNG", "8"
        try:
            self.bpy.data.images["Render Result"].save_render(str(self.display_png), scene=self.scene)
        finally:
            image.media_type, image.file_format = saved[0], saved[1]
            image.color_depth = saved[2]
        display = cv2.imread(str(self.display_png), cv2.IMREAD_COLOR)
        if display is None:
            raise RuntimeError(f"{self.display_png}: the view-transformed image could not be read back")
        return display[:, :, ::-1].copy()

    def write_image(self, frame: int, camera: str, rgb, ids) -> dict:
        """Remap / mask out, apply the camera's sensor, encode and write atomically (runs
        beside the next render)."""
        import numpy as np

        started, cpu_started = time.perf_counter(), time.thread_time()
        rgb, ids = self._finish(camera, rgb, ids)
        image = rgb if rgb.dtype == np.uint8 else linear_to_srgb8(rgb)
        clean = None
        if camera in self.sensors:
            from usdscene.document.imaging import image_seed
            from usdscene.render.sensor import apply_sensor, has_effect

            sensor, seed = self.sensors[camera]
            at = sensor.at_frame(frame)
            if has_effect(at):
                clean = image if self.job.get("keep_clean") else None
                image = apply_sensor(image, at, np.random.default_rng(image_seed(seed, camera, frame)))
            elif self.job.get("keep_clean"):
                clean = image
        write_display_outputs(Path(self.job["out_dir"]), camera, frame, image, ids, clean=clean)
        return {"post_s": time.perf_counter() - started, "post_cpu_s": time.thread_time() - cpu_started}

    def render_pair(self, frame: int, camera: str) -> dict:
        """Render, decode and write one pair in sequence; returns its timings."""
        rgb, ids, timing = self.render_image(frame, camera)
        return {**timing, **self.write_image(frame, camera, rgb, ids)}

    def _finish(self, camera: str, rgb, ids):
        """Remap OpenCV lenses, black out what lies outside a fisheye's field of view."""
        import cv2
        import numpy as np

        from usdscene.document.model import LensModel
        from usdscene.labels.projection import pixel_rays, remap_grids
        from usdscene.render.job import intrinsics_from_json

        cam_job = self.job["cameras"][camera]
        intr = intrinsics_from_json(cam_job["intrinsics"])
        render = intrinsics_from_json(cam_job["render_intrinsics"])
        if cam_job["render_intrinsics"] != cam_job["intrinsics"]:
            if camera not in self._remaps:
                self._remaps[camera] = remap_grids(intr, render)
            map_x, map_y = self._remaps[camera]
            rgb = cv2.remap(rgb, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            ids = cv2.remap(ids, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        elif intr.lens in (LensModel.FISHEYE_EQUIDISTANT, LensModel.FISHEYE_EQUISOLID):
            if camera not in self._fov_masks:
                vs, us = np.mgrid[0:intr.height_px, 0:intr.width_px]
                _, valid = pixel_rays(intr, np.stack([us.ravel(), vs.ravel()], 1).astype(float))
                self._fov_masks[camera] = ~valid.reshape(intr.height_px, intr.width_px)
            outside = self._fov_masks[camera]
            rgb = rgb.copy()
            ids = ids.copy()
            rgb[outside] = 0.0
            ids[outside] = 0
        return rgb, ids


# Width of the importance map of a physical sky (its height is half): see WorldNodes.
SKY_MAP_RESOLUTION = 512


class WorldNodes:
    """A document's world as a Blender world of our own, made ``scene.world`` (it replaces a
    dome light's world: the document's world is what the user asked for): Background ← colour,
    sky texture or environment image. The render session and :func:`bake_world` build it alike.

    Args:
        bpy: the imported module.
        scene: the Blender scene whose world it becomes.
        world: :class:`usdscene.document.imaging.World`.
        world_job: the stage's world (:func:`usdscene.document.imaging.world_stage_json`
            decoded): its ``sun`` places and scales a sky, its ``hdri_path`` is the image.
    """

    def __init__(self, bpy, scene, world, world_job: dict) -> None:
        from usdscene.document.imaging import SKY_KINDS, SKY_PER_SUN_IRRADIANCE

        bworld = bpy.data.worlds.new("usdscene_world")
        scene.world = bworld
        nodes, links = bworld.node_tree.nodes, bworld.node_tree.links
        self.background = nodes["Background"]
        self.sky_node = self.env_mapping = None
        self.strength_scale = 1.0
        if world.sky:
            sky = nodes.new("ShaderNodeTexSky")
            sky.sky_type = SKY_KINDS[world.sky]
            # The sun light lights the scene; a sun disc in the sky too would light it twice.
            sky.sun_disc = False
            sun = world_job["sun"]
            sky.sun_elevation = float(sun["elevation_rad"])
            sky.sun_rotation = float(sun["rotation_rad"])
            links.new(sky.outputs["Color"], self.background.inputs["Color"])
            self.sky_node = sky
            self.strength_scale = float(sun["irradiance_w_m2"]) * SKY_PER_SUN_IRRADIANCE
        elif world.hdri:
            env = nodes.new("ShaderNodeTexEnvironment")
            env.image = bpy.data.images.load(world_job["hdri_path"], check_existing=True)
            coords = nodes.new("ShaderNodeTexCoord")
            mapping = nodes.new("ShaderNodeMapping")
            links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
            links.new(mapping.outputs["Vector"], env.inputs["Vector"])
            links.new(env.outputs["Color"], self.background.inputs["Color"])
            self.env_mapping = mapping
        else:
            self.background.inputs["Color"].default_value = (*world.color_rgb, 1.0)
            bworld.color = world.color_rgb
        if world.sky or world.hdri:
            # Cycles' automatic importance map of a world without a sun disc is 4096 x 2048:
            # 8 M evaluations of the world each time it changes (every frame when its strength
            # is randomised), and a 64 MB table that every light sample searches. The sky (its
            # sun is a light) is smooth, 512 x 256 resolves it; an HDRI gets its own width, 64 to
            # 4096 (what Cycles gave an environment image before that rule).
            width = SKY_MAP_RESOLUTION if world.sky else min(max(int(env.image.size[0]), 64), 4096)
            bworld.cycles.sampling_method = "MANUAL"
            bworld.cycles.sample_map_resolution = width

    def apply(self, at) -> None:
        """Set the values of ``at`` (the world at one frame) that differ from the nodes' (each
        change re-syncs the world)."""
        strength = at.strength * self.strength_scale
        if self.background.inputs["Strength"].default_value != strength:
            self.background.inputs["Strength"].default_value = strength
        if self.sky_node is not None:
            for name, value in (("air_density", at.air_density), ("aerosol_density", at.aerosol_density),
                                ("ozone_density", at.ozone_density), ("altitude", at.altitude_m)):
                if getattr(self.sky_node, name) != value:
                    setattr(self.sky_node, name, value)
        if self.env_mapping is not None:
            self.env_mapping.inputs["Rotation"].default_value[2] = math.radians(at.hdri_rotation_deg)


def bake_world(job: dict) -> None:
    """Render a document's world alone, as Cycles sees it, into an equirectangular radiance
    image (linear RGB, the Background's colour times its strength; longitude along the width,
    the zenith at the top), laid out as the environment images of a world's ``hdri`` are read.

    Job fields: ``world`` (the stage's world, as in a render job), ``frame`` (whose per-frame
    values apply), ``size_px`` ([width, height]), ``samples`` and ``out`` (a ``.hdr`` path).
    """
    from usdscene.document.imaging import World, spec_from_json

    bpy = _import_bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = spec_from_json(World, job["world"]["world"])
    WorldNodes(bpy, scene, world, job["world"]).apply(world.at_frame(int(job["frame"])))
    data = bpy.data.cameras.new("usdscene_bake_camera")
    data.type = "PANO"
    data.panorama_type = "EQUIRECTANGULAR"
    camera = bpy.data.objects.new("usdscene_bake_camera", data)
    # Looking along +X with +Z up: the image's columns run as an environment texture's do.
    camera.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(job["samples"])
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.filter_width = 0.01  # each pixel its own direction: no blur across pixels
    scene.render.resolution_x, scene.render.resolution_y = (int(v) for v in job["size_px"])
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "HDR"
    scene.render.filepath = str(job["out"])
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    _emit({"event": "baked", "path": str(job["out"])})


def apply_intrinsics(scene, data, intr) -> None:
    """Set the render resolution and the Blender camera data for ``intr`` (a native lens).

    Blender measures lens shift in units of the fitted sensor dimension (the width with
    ``sensor_fit = 'HORIZONTAL'``) and puts an unshifted optical axis at the image centre,
    ``((W - 1) / 2, (H - 1) / 2)`` in OpenCV pixel coordinates; y shift points up.
    """
    from usdscene.document.model import LensModel

    w, h = intr.width_px, intr.height_px
    scene.render.resolution_x = w
    scene.render.resolution_y = h
    # Square pixels only: the driver renders other cameras through a square-pixel native lens
    # and remaps (usdscene.labels.projection.native_renderable).
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    sensor_w = intr.sensor_width_mm
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = sensor_w
    data.sensor_height = sensor_w * h / w
    data.shift_x = ((w - 1) / 2.0 - intr.cx_px) / w
    data.shift_y = (intr.cy_px - (h - 1) / 2.0) / w
    lens = LensModel(intr.lens)
    if lens is LensModel.PERSPECTIVE:
        data.type = "PERSP"
        data.lens = intr.fx_px * sensor_w / w
    elif lens is LensModel.ORTHOGRAPHIC:
        data.type = "ORTHO"
        data.ortho_scale = w / intr.fx_px  # metres across the image width
    elif lens is LensModel.FISHEYE_EQUISOLID:
        data.type = "PANO"
        data.panorama_type = "FISHEYE_EQUISOLID"
        data.fisheye_lens = intr.fx_px * sensor_w / w
        data.fisheye_fov = math.radians(min(intr.fov_deg or 360.0, 360.0))
    elif lens is LensModel.FISHEYE_EQUIDISTANT:
        # θ = -(k0 + k1·r) with r in millimetres on the sensor: equidistant is k1 = -1/f.
        data.type = "PANO"
        data.panorama_type = "FISHEYE_LENS_POLYNOMIAL"
        data.fisheye_polynomial_k0 = 0.0
        data.fisheye_polynomial_k1 = -w / (intr.fx_px * sensor_w)
        data.fisheye_polynomial_k2 = 0.0
        data.fisheye_polynomial_k3 = 0.0
        data.fisheye_polynomial_k4 = 0.0
        data.fisheye_fov = math.radians(min(intr.fov_deg or 360.0, 360.0))
    else:
        raise ValueError(f"lens {lens.value!r} is not native to Blender")


def read_exr(path: Path):
    """Read the beauty and object index of a multilayer EXR written by Blender.

    Returns:
        ``(rgb, ids)``: (H, W, 3) float32 linear RGB and (H, W) uint16 object indices.
    """
    import numpy as np
    import OpenEXR

    rgb = ids = None
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                if name.endswith("Combined.R"):
                    r = channel.pixels
                elif name.endswith("Combined.G"):
                    g = channel.pixels
                elif name.endswith("Combined.B"):
                    b = channel.pixels
                elif name.endswith("IndexOB.X") or name.endswith("Object Index.X"):
                    ids = channel.pixels
        rgb = np.stack([r, g, b], axis=-1).astype(np.float32)
    if ids is None:
        raise RuntimeError(f"{path}: no object-index channel")
    # The pass stores pass_index as float from the first sample only: exact small integers.
    return rgb, np.rint(ids).astype(np.uint16)


def linear_to_srgb8(rgb):
    """(H, W, 3) linear float → (H, W, 3) uint8 sRGB (IEC 61966-2-1 OETF, round to nearest)."""
    import numpy as np

    x = np.clip(rgb, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.floor(srgb * 255.0 + 0.5).astype(np.uint8)


def write_outputs(out_dir: Path, camera: str, frame: int, rgb, ids) -> None:
    """Write the image (8-bit sRGB PNG of the (H, W, 3) linear ``rgb``) and the mask (uint16
    PNG) atomically."""
    write_display_outputs(out_dir, camera, frame, linear_to_srgb8(rgb), ids)


def write_display_outputs(out_dir: Path, camera: str, frame: int, image, ids, *, clean=None) -> None:
    """Write the image ((H, W, 3) uint8 sRGB, RGB order), the mask (uint16 PNG) and, when
    given, the clean image before the sensor's effects, atomically."""
    import cv2

    from usdscene.document import output_layout as layout
    from usdscene.files import write_bytes_atomic

    ok, image_png = cv2.imencode(".png", image[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
    ok2, mask_png = cv2.imencode(".png", ids, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not (ok and ok2):
        raise RuntimeError(f"PNG encoding failed for {camera} frame {frame}")
    if clean is not None:
        ok3, clean_png = cv2.imencode(".png", clean[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok3:
            raise RuntimeError(f"PNG encoding failed for {camera} frame {frame}")
        write_bytes_atomic(layout.clean_image_path(out_dir, camera, frame), clean_png.tobytes())
    # Mask first: a pair counts as done only when both exist, and the driver records it only
    # after this returns.
    write_bytes_atomic(layout.mask_path(out_dir, camera, frame), mask_png.tobytes())
    write_bytes_atomic(layout.image_path(out_dir, camera, frame), image_png.tobytes())


def build_blend(job: dict) -> None:
    """Write a Blender project of the whole stage: every object (presence keyframed per frame,
    pass index = mask id), one Blender camera per stage camera (pose keyframed when it moves,
    exact intrinsics kept as custom properties), render settings as for rendering; the scene's
    document (``job["document"]``) as a custom property of the Blender scene."""
    from usdscene.document import stage_schema as ss
    from usdscene.render.job import intrinsics_from_json, usd_camera_matrix

    job = dict(job, pairs=[])
    session = Session(job)
    import mathutils  # importable only once bpy is
    bpy, scene = session.bpy, session.scene
    bpy.data.objects.remove(session.camera, do_unlink=True)
    frames = range(int(job["frame_start"]), int(job["frame_end"]) + 1)
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    if job.get("document"):
        scene[ss.BLEND_DOCUMENT] = job["document"]
    for o in job["objects"]:
        members = session.objects.get(o["uid"], [])
        poses = session.poses.get(o["uid"])
        hides = [dict((ob.name, h) for ob, h in member_hides(o, members, poses or {}, f)) for f in frames]
        for ob in members:
            previous = None
            for f, hidden in zip(frames, hides):
                hide = hidden[ob.name]
                if hide != previous:
                    # Render visibility only: an object hidden in the viewport leaves the
                    # depsgraph and its matrix goes stale (the USD exporter would write it).
                    ob.hide_render = hide
                    ob.keyframe_insert("hide_render", frame=f)
                    previous = hide
    collection = bpy.data.collections.new("Cameras")
    scene.collection.children.link(collection)
    first = None
    for name, cam_job in job["cameras"].items():
        data = bpy.data.cameras.new(name)
        ob = bpy.data.objects.new(name, data)
        collection.objects.link(ob)
        render = intrinsics_from_json(cam_job["render_intrinsics"])
        apply_intrinsics(scene, data, render)
        data.clip_start, data.clip_end = cam_job["clip_m"]
        ob[ss.BLEND_CAMERA_NAME] = name
        ob["usdscene_lens"] = json.dumps(cam_job["intrinsics"])
        ob["usdscene_render_lens"] = json.dumps(cam_job["render_intrinsics"])
        ob["usdscene_blender_lens"] = json.dumps(camera_data_json(data))
        ob.rotation_mode = "QUATERNION"
        ob.matrix_world = mathutils.Matrix(usd_camera_matrix(cam_job["pose"]))
        for f, pose in sorted(cam_job["poses"].items(), key=lambda kv: int(kv[0])):
            ob.matrix_world = mathutils.Matrix(usd_camera_matrix(pose))
            ob.keyframe_insert("location", frame=int(f))
            ob.keyframe_insert("rotation_quaternion", frame=int(f))
        first = first or (ob, render)
    if first is not None:
        scene.camera = first[0]
        apply_intrinsics(scene, first[0].data, first[1])
    scene.frame_set(frames[0])
    out = Path(job["blend"])
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp), relative_remap=True)
    os.replace(tmp, out)
    _emit({"event": "blend_written", "path": str(out)})


def member_hides(o: dict, members: list, poses: dict[str, list], frame: int) -> list[tuple]:
    """``(Blender object, hide_render)`` for every member of job object ``o`` at ``frame``:
    hidden when the object is absent; with pose children (``poses``: variant → its objects),
    also the members of every pose but the one ``o["pose_frames"]`` shows at ``frame``."""
    hide = frame not in o["_visible"]
    if not poses:
        return [(ob, hide) for ob in members]
    shown = set() if hide else {ob.name for variant, obs in poses.items()
                                if frame in o["pose_frames"].get(variant, ()) for ob in obs}
    posed = {ob.name for obs in poses.values() for ob in obs}
    return [(ob, hide or (ob.name in posed and ob.name not in shown)) for ob in members]


def camera_data_json(data) -> dict:
    """The Blender camera settings that determine the image (to detect edits in Blender)."""
    return {"type": data.type, "lens": round(data.lens, 6), "sensor_width": round(data.sensor_width, 6),
            "shift_x": round(data.shift_x, 6), "shift_y": round(data.shift_y, 6),
            "ortho_scale": round(data.ortho_scale, 6), "panorama_type": data.panorama_type,
            "fisheye_lens": round(data.fisheye_lens, 6), "fisheye_fov": round(data.fisheye_fov, 6),
            "k1": round(data.fisheye_polynomial_k1, 9)}


def export_blend_usd(job: dict) -> None:
    """Export a .blend to a USD file (``job["usd"]``): Z up, metres, custom properties as
    ``userProperties:*`` (where place markers keep their ``usdscene_place``), default prim
    ``/root``; for ``usdscene assets add FILE.blend``."""
    bpy = _import_bpy()
    bpy.ops.wm.open_mainfile(filepath=job["blend"])
    result = bpy.ops.wm.usd_export(filepath=job["usd"], export_custom_properties=True, export_materials=True,
                                   export_cameras=False, export_lights=False, convert_orientation=False,
                                   root_prim_path="/root", check_existing=False)
    if "FINISHED" not in result:
        raise RuntimeError(f"USD export of {job['blend']} failed: {result}")
    _emit({"event": "exported"})


def inspect_blend(job: dict) -> None:
    """Export a .blend to USD and dump its cameras (pose per frame, lens data, custom
    properties), the presence and matrices of its usdscene objects and the scene's document
    (custom property ``stage_schema.BLEND_DOCUMENT``, null when absent) as JSON: Blender's USD
    exporter writes only perspective cameras, and no customData or customLayerData."""
    from usdscene.document import stage_schema as ss

    bpy = _import_bpy()
    bpy.ops.wm.open_mainfile(filepath=job["blend"])
    scene = bpy.context.scene
    result = bpy.ops.wm.usd_export(filepath=job["usd"], export_animation=True, export_cameras=True,
                                   export_custom_properties=True, export_materials=True,
                                   root_prim_path="", convert_orientation=False, check_existing=False)
    if "FINISHED" not in result:
        raise RuntimeError(f"USD export of {job['blend']} failed: {result}")
    document = scene.get(ss.BLEND_DOCUMENT)
    frames = range(scene.frame_start, scene.frame_end + 1)
    cameras = {ob.name: {"data": camera_data_json(ob.data), "poses": {},
                         "custom": {k: ob[k] for k in ob.keys() if k.startswith("usdscene_")},
                         "clip_m": [ob.data.clip_start, ob.data.clip_end]}
               for ob in scene.objects if ob.type == "CAMERA"}
    presence: dict[str, list[int]] = {}
    matrices: dict[str, dict[str, list]] = {}
    tagged = []
    for ob in scene.objects:
        uid = ob.get("usdscene_uid")
        if uid is None and ob.data is not None and hasattr(ob.data, "get"):
            uid = ob.data.get("usdscene_uid")
        if uid is not None:
            tagged.append((str(uid), ob))
            presence.setdefault(str(uid), [])
    # Parents before children, so the object's root carries its pose.
    tagged.sort(key=lambda item: len(_ancestors(item[1])))
    for f in frames:
        scene.frame_set(f)
        for ob in scene.objects:
            if ob.type == "CAMERA":
                cameras[ob.name]["poses"][str(f)] = [list(row) for row in ob.matrix_world]
        for uid, ob in tagged:
            if not ob.hide_render and (not presence[uid] or presence[uid][-1] != f):
                presence[uid].append(f)
            if uid not in matrices.setdefault(str(f), {}):  # the outermost tagged object wins
                matrices[str(f)][uid] = [list(row) for row in ob.matrix_world]
    Path(job["json"]).write_text(json.dumps({
        "presence": presence,
        "object_matrices": matrices,
        "frame_start": scene.frame_start, "frame_end": scene.frame_end,
        "resolution_px": [scene.render.resolution_x, scene.render.resolution_y],
        "cameras": cameras,
        # Text as saved; anything else (a user's group property) reads back as malformed.
        "document": None if document is None else str(document)}))
    _emit({"event": "inspected"})


def _rss_mb() -> float:
    """Resident memory of this process in MiB (Linux; 0 elsewhere)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def _ancestors(ob) -> list:
    out = []
    while ob.parent is not None:
        ob = ob.parent
        out.append(ob)
    return out


def render_pairs(session: Session, pairs) -> bool:
    """Render pairs in order; each image is written by a helper thread while Cycles renders
    the next one, and reported ``done`` only once both of its files exist. False on error."""
    from concurrent.futures import ThreadPoolExecutor

    pending = None  # (frame, camera, timing, future) of the image being written

    def settle(item) -> float:
        frame, camera, timing, future = item
        post = future.result()
        _emit({"event": "done", "frame": frame, "camera": camera, "rss_mb": _rss_mb(), **timing, **post})
        return post["post_cpu_s"]

    with ThreadPoolExecutor(max_workers=1) as pool:
        for frame, camera in pairs:
            try:
                rgb, ids, timing = session.render_image(int(frame), camera)
                if pending is not None:
                    # The previous image was written during this render: its CPU time is not
                    # path tracing.
                    timing["render_cpu_s"] = max(0.0, timing["render_cpu_s"] - settle(pending))
                    pending = None
                pending = (frame, camera, timing, pool.submit(session.write_image, int(frame), camera, rgb, ids))
            except Exception as exc:
                _emit({"event": "error", "frame": frame, "camera": camera,
                       "message": f"{type(exc).__name__}: {exc}"})
                return False
        try:
            if pending is not None:
                settle(pending)
        except Exception as exc:
            _emit({"event": "error", "frame": pending[0], "camera": pending[1],
                   "message": f"{type(exc).__name__}: {exc}"})
            return False
    return True


def _die_with_parent(parent_pid: int | None) -> None:
    """Linux: have the kernel SIGKILL this worker when the process that started it dies, so a
    killed driver or Ray task leaves no renderer running. Elsewhere nothing happens."""
    if not parent_pid or not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        import signal

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != int(parent_pid):  # the parent died before prctl took effect
        os._exit(1)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the Blender worker process (``JOB.json`` or ``--wait-for-job``); returns the exit
    status (2 bad usage, 1 on a reported error)."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        sys.stderr.write("usage: python -m usdscene.render.worker JOB.json | --wait-for-job\n")
        return 2
    if argv[0] == "--wait-for-job":  # pre-started (worker_process.prestart_workers): bpy first
        _import_bpy()
        job_path = sys.stdin.readline().strip()
        if not job_path:  # not needed after all
            return 0
        argv = [job_path]
    job = json.loads(Path(argv[0]).read_text())
    _die_with_parent(job.get("parent_pid"))
    for o in job.get("objects", ()):
        o["_visible"] = set(o["visible_frames"])
        if "pose_frames" in o:
            o["pose_frames"] = {v: set(fs) for v, fs in o["pose_frames"].items()}
    mode = job.get("mode", "render")
    if mode in ("blend", "inspect_blend", "export_usd", "bake_world"):
        try:
            {"blend": build_blend, "inspect_blend": inspect_blend, "export_usd": export_blend_usd,
             "bake_world": bake_world}[mode](job)
        except Exception as exc:
            _emit({"event": "error", "message": f"{type(exc).__name__}: {exc}"})
            return 1
        return 0
    try:
        session = Session(job)
    except Exception as exc:  # reported to the driver as one line, then exit non-zero
        # a missing GPU is the user's setting, not a crash: its message stands alone
        message = str(exc) if isinstance(exc, DeviceError) else f"{type(exc).__name__}: {exc}"
        _emit({"event": "error", "message": message})
        return 1
    if not render_pairs(session, job["pairs"]):
        return 1
    try:
        session.exr_path.unlink()
    except FileNotFoundError:
        pass
    _emit({"event": "finished", "process_cpu_s": time.process_time()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
