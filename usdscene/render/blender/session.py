"""A render session: one Blender scene holding one imported stage shard and one render camera,
driven per (frame, camera) pair from the job; :func:`render_pairs` renders a shard's pairs."""

from __future__ import annotations

import os
import time
from pathlib import Path

from usdscene.render.blender.camera import apply_intrinsics
from usdscene.render.blender.cycles import apply_settings, enable_gpu
from usdscene.render.blender.outputs import linear_to_srgb8, read_exr, write_display_outputs
from usdscene.render.blender.process import emit, import_bpy, rss_mb
from usdscene.render.blender.world import WorldNodes
from usdscene.render.job import BlendJob, JobObject, RenderJob


class Session:
    """A Blender scene holding one imported stage shard and one render camera."""

    def __init__(self, job: RenderJob | BlendJob) -> None:
        self.job = job
        self.bpy = import_bpy()
        self.scratch = Path(job.scratch_dir)
        self.scratch.mkdir(parents=True, exist_ok=True)
        self.exr_path = self.scratch / f"render-{os.getpid()}.exr"
        self.current_frame: int | None = None
        self.hidden: dict[str, bool] = {}
        self._remaps: dict[str, tuple] = {}
        self._fov_masks: dict[str, object] = {}
        # render.depth: (frame, camera) → the Z pass of a rendered image until it is written
        self.depth_format = job.settings.get("depth")
        self._depths: dict[tuple, object] = {}
        self._ray_cosines: dict[str, object] = {}
        # adapting cameras: (frame, camera) → pre-pass meter reading; → the exposure to apply
        self._meters: dict[tuple, float] = {}
        self._adapted: dict[tuple, tuple[float, float, float]] = {}
        self._setup_scene()
        # Before the import: a missing GPU is reported in a second, not after the stage loads.
        self.rendering = isinstance(job, RenderJob)
        if self.rendering and job.settings["device"] == "gpu":
            enable_gpu(self.bpy)
        self._import_stage()
        # Meshes that name a procedural surface get its node tree (blender/surface_nodes.py).
        from usdscene.render.blender.surface_nodes import apply_surfaces

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
            filepath=self.job.stage,
            prim_path_mask=self.job.prim_path_mask,
            import_cameras=False,
            import_visible_only=False,  # presence is per frame, applied below
            support_scene_instancing=False,  # realise instances: each needs its own pass index
            property_import_mode="USER",
            set_frame_range=True,
            create_collection=False,
        )
        if "FINISHED" not in result:
            raise RuntimeError(f"USD import of {self.job.stage} failed: {result}")
        # uid → Blender objects carrying it (the object and everything below it).
        wanted = {o.uid: o for o in self.job.objects}
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
                if variant is not None and wanted[uid].pose_frames is not None:
                    self.poses.setdefault(uid, {})[str(variant)] = [ob, *ob.children_recursive]
        for uid, members in self.objects.items():
            mask_id = int(wanted[uid].mask_id)
            for ob in members:
                ob.pass_index = mask_id
        # One mesh per distinct (body, pose): a crowd's people share them (blender/mesh_sharing.py).
        from usdscene.render.blender.mesh_sharing import share_equal_meshes

        meshes, shared = share_equal_meshes(bpy, [ob for members in self.objects.values() for ob in members])
        missing = sorted(set(wanted) - set(self.objects))
        emit({"event": "imported", "seconds": time.perf_counter() - started, "pid": os.getpid(),
              "objects": len(bpy.data.objects), "missing_uids": missing[:20],
              "missing_count": len(missing), "object_meshes": meshes, "shared_meshes": shared})

    def _setup_render(self) -> None:
        bpy = self.bpy
        scene = self.scene
        apply_settings(scene, self.job.settings, rendering=self.rendering, exr_path=self.exr_path,
                       threads=getattr(self.job, "threads", None))
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
        self.sensors = {name: (spec_from_json(Sensor, cam.sensor["sensor"]), int(cam.sensor["seed"]))
                        for name, cam in self.job.cameras.items() if cam.sensor is not None}
        self.ir_light = None
        self._shutter = 0.0
        world_job = self.job.world
        if world_job is None:
            return
        self.world = spec_from_json(World, world_job["world"])
        self.world_job = world_job
        self._build_world()

    def _build_world(self) -> None:
        """The document's world (:class:`WorldNodes`) and its view transform."""
        self.world_nodes = WorldNodes(self.bpy, self.scene, self.world, self.world_job)
        self.scene.world.light_settings.distance = float(self.job.settings["fast_gi_distance_m"])
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

                render_intr = self.job.cameras[name].render_intrinsics
                if render_intr.fov_deg:  # a fisheye: its image circle
                    field = math.radians(float(render_intr.fov_deg))
                else:
                    w, h, fx = render_intr.width_px, render_intr.height_px, render_intr.fx_px
                    field = 2.0 * math.atan(math.hypot(w, h) / 2.0 / fx)  # the diagonal
                self.ir_light.data.spot_size = min(math.pi, field + math.radians(10.0))
                self.ir_light.data.energy = ir_illuminator_power_w(sensor.ir_range_m)
            if self.ir_light.hide_render == ir:
                self.ir_light.hide_render = not ir

    # ---------------------------------------------------------------------------------------
    def set_frame(self, frame: int) -> None:
        """Go to ``frame`` and hide the objects absent from it (only what changed is touched)."""
        if frame == self.current_frame:
            return
        self.scene.frame_set(frame)
        for o in self.job.objects:
            members = self.objects.get(o.uid)
            if not members:
                continue
            poses = self.poses.get(o.uid)
            if poses:
                for ob, hide in member_hides(o, members, poses, frame):
                    ob.hide_render = hide
                continue
            hide = frame not in o.visible
            if self.hidden.get(o.uid) == hide:
                continue
            self.hidden[o.uid] = hide
            for ob in members:
                ob.hide_render = hide
        if self.world is not None:
            self._apply_world(frame)
        self.current_frame = frame

    def set_camera(self, name: str, frame: int) -> None:
        """Point the render camera at camera ``name``'s pose and lens for ``frame``."""
        from usdscene.render.job import usd_camera_matrix

        cam_job = self.job.cameras[name]
        pose = cam_job.pose_at(frame)
        render = cam_job.render_intrinsics
        ob, data = self.camera, self.camera.data
        import mathutils

        # Touch only what changes: every assignment tags Blender data for a Cycles update.
        key = (tuple(pose), tuple(cam_job.clip_m))
        if key != getattr(self, "_pose_key", None):
            # mathutils.Matrix takes rows; a bare nested list would be read column by column.
            ob.matrix_world = mathutils.Matrix(usd_camera_matrix(pose))
            data.clip_start, data.clip_end = cam_job.clip_m
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
            native render, and seconds: wall (``render_s``, with an adapting camera's meter
            pre-passes) and CPU time of the whole process,
            all threads (``render_cpu_s``; robust on a shared machine).
        """
        started, cpu_started = time.perf_counter(), time.process_time()
        if "warmup_frames" in (self.job.cameras[camera].sensor or {}):
            self._adapted[(frame, camera)] = self._sequence_exposure(frame, camera)
        self.set_frame(frame)
        self.set_camera(camera, frame)
        self.bpy.ops.render.render(write_still=True)
        rendered, cpu_rendered = time.perf_counter(), time.process_time()
        rgb, ids, z_pass = read_exr(self.exr_path, depth=self.depth_format is not None)
        if z_pass is not None:
            self._depths[(frame, camera)] = z_pass
        if self.world_at is not None:
            rgb = self._display(rgb)
        return rgb, ids, {"render_s": rendered - started, "render_cpu_s": cpu_rendered - cpu_started,
                          "decode_s": time.perf_counter() - rendered}

    def _sequence_exposure(self, frame: int, camera: str) -> tuple[float, float, float]:
        """``(exposure_ev, target_ev, metered)`` of an adapting camera at ``frame``
        (:func:`usdscene.sensor.exposure.sequence_ev`) from the pre-pass readings of its window,
        rendering the readings this session does not have yet (the frames before its first
        pair only as pre-passes). Counted in the pair's render time."""
        from usdscene.sensor import exposure

        window = self.job.cameras[camera].sensor
        sensor = self.sensors[camera][0]
        readings = []
        for g in exposure.meter_window(frame, window["warmup_frames"], window["first_frame"]):
            if (g, camera) not in self._meters:
                self._meters[(g, camera)] = self._meter_prepass(g, camera)
            readings.append(self._meters[(g, camera)])
        ev, target = exposure.sequence_ev(readings, float(sensor.target_grey), float(sensor.exposure_min_ev),
                                          float(sensor.exposure_max_ev), float(sensor.exposure_speed))
        return ev, target, readings[-1]

    def _meter_prepass(self, frame: int, camera: str) -> float:
        """The meter reading of (frame, camera) from a small render that depends on nothing
        but the frame: :data:`usdscene.sensor.exposure.PREPASS_SCALE_PERCENT` of the resolution,
        :data:`~usdscene.sensor.exposure.PREPASS_SAMPLES` samples, no denoising
        (:func:`usdscene.sensor.pipeline.meter_prepass`)."""
        from usdscene.sensor.exposure import PREPASS_SAMPLES, PREPASS_SCALE_PERCENT
        from usdscene.sensor.pipeline import meter_prepass

        self.set_frame(frame)
        self.set_camera(camera, frame)
        render, cycles = self.scene.render, self.scene.cycles
        saved = (render.resolution_percentage, cycles.samples, cycles.use_denoising)
        render.resolution_percentage, cycles.samples, cycles.use_denoising = PREPASS_SCALE_PERCENT, PREPASS_SAMPLES, False
        try:
            self.bpy.ops.render.render(write_still=True)
        finally:
            render.resolution_percentage, cycles.samples, cycles.use_denoising = saved
        rgb = read_exr(self.exr_path, depth=False)[0]
        if self.world_at is not None and self.world_at.exposure_ev:
            rgb = rgb * float(2.0 ** self.world_at.exposure_ev)  # the world's exposure, linear
        return meter_prepass(rgb, self.sensors[camera][0].at_frame(frame))

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
        z_pass = self._depths.pop((frame, camera), None)
        if z_pass is not None:  # before the mask: a pair counts as done once its mask exists
            from usdscene.document import output_layout as layout
            from usdscene.files import write_bytes_atomic
            from usdscene.render.depth import encode_depth

            write_bytes_atomic(layout.depth_path(self.job.out_dir, camera, frame, self.depth_format),
                               encode_depth(self._finish_depth(camera, z_pass), self.depth_format))
        rgb, ids = self._finish(camera, rgb, ids)
        clean = None
        if camera in self.sensors:
            from usdscene.document.imaging import image_seed
            from usdscene.sensor.pipeline import apply_sensor, as_linear, has_effect, process_image, uses_linear

            sensor, seed = self.sensors[camera]
            at = sensor.at_frame(frame)
            rng = np.random.default_rng(image_seed(seed, camera, frame))
        if camera in self.sensors and uses_linear(at):
            # the camera's whole chain from the linear render: auto exposure, WDR, optics
            import json

            from usdscene.document import output_layout as layout
            from usdscene.files import write_bytes_atomic

            if self.job.keep_clean:
                clean = rgb if rgb.dtype == np.uint8 else linear_to_srgb8(rgb)
            image, record = process_image(as_linear(rgb), at, rng, self._adapted.pop((frame, camera), None))
            write_bytes_atomic(layout.exposure_path(self.job.out_dir, camera, frame),
                               json.dumps(record, sort_keys=True).encode("utf-8"))
        else:
            image = rgb if rgb.dtype == np.uint8 else linear_to_srgb8(rgb)
            if camera in self.sensors and has_effect(at):
                clean = image if self.job.keep_clean else None
                image = apply_sensor(image, at, rng)
            elif camera in self.sensors and self.job.keep_clean:
                clean = image
        write_display_outputs(Path(self.job.out_dir), camera, frame, image, ids, clean=clean)
        return {"post_s": time.perf_counter() - started, "post_cpu_s": time.thread_time() - cpu_started}

    def _finish_depth(self, camera: str, z_pass):
        """Cycles' Z pass → distance to the image plane, remapped as the mask (nearest native
        pixel, the same maps)."""
        from usdscene.labels.projection import remap_grids
        from usdscene.document.model import LensModel
        from usdscene.render.depth import PANORAMIC, plane_depth, ray_cosines, remap_depth

        cam_job = self.job.cameras[camera]
        render = cam_job.render_intrinsics
        if camera not in self._ray_cosines:  # only a panoramic pass needs them (plane_depth)
            self._ray_cosines[camera] = ray_cosines(render) if LensModel(render.lens) in PANORAMIC else None
        depth = plane_depth(z_pass, render, self._ray_cosines[camera])
        if cam_job.remapped:
            if camera not in self._remaps:  # the mask's map (_finish makes the same one)
                self._remaps[camera] = remap_grids(cam_job.intrinsics, render)
            depth = remap_depth(depth, *self._remaps[camera])
        return depth

    def _finish(self, camera: str, rgb, ids):
        """Remap OpenCV lenses, black out what lies outside a fisheye's field of view."""
        import cv2

        from usdscene.labels.projection import remap_grids
        from usdscene.lens import lens_for, valid_pixels

        cam_job = self.job.cameras[camera]
        intr, render = cam_job.intrinsics, cam_job.render_intrinsics
        if cam_job.remapped:
            if camera not in self._remaps:
                self._remaps[camera] = remap_grids(intr, render)
            map_x, map_y = self._remaps[camera]
            rgb = cv2.remap(rgb, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            ids = cv2.remap(ids, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        elif lens_for(intr).radial:  # a native fisheye: black beyond its image circle
            if camera not in self._fov_masks:
                self._fov_masks[camera] = ~valid_pixels(intr)
            outside = self._fov_masks[camera]
            rgb = rgb.copy()
            ids = ids.copy()
            rgb[outside] = 0.0
            ids[outside] = 0
        return rgb, ids


def member_hides(o: JobObject, members: list, poses: dict[str, list], frame: int) -> list[tuple]:
    """``(Blender object, hide_render)`` for every member of job object ``o`` at ``frame``:
    hidden when the object is absent; with pose children (``poses``: variant → its objects),
    also the members of every pose but the one ``o.pose_frames`` shows at ``frame``."""
    hide = frame not in o.visible
    if not poses:
        return [(ob, hide) for ob in members]
    shown = set() if hide else {ob.name for variant, obs in poses.items()
                                if frame in o.pose_frames.get(variant, ()) for ob in obs}
    posed = {ob.name for obs in poses.values() for ob in obs}
    return [(ob, hide or (ob.name in posed and ob.name not in shown)) for ob in members]


def render_pairs(session: Session, pairs) -> bool:
    """Render pairs in order; each image is written by a helper thread while Cycles renders
    the next one, and reported ``done`` only once both of its files exist. False on error."""
    from concurrent.futures import ThreadPoolExecutor

    pending = None  # (frame, camera, timing, future) of the image being written

    def settle(item) -> float:
        frame, camera, timing, future = item
        post = future.result()
        emit({"event": "done", "frame": frame, "camera": camera, "rss_mb": rss_mb(), **timing, **post})
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
                emit({"event": "error", "frame": frame, "camera": camera,
                      "message": f"{type(exc).__name__}: {exc}"})
                return False
        try:
            if pending is not None:
                settle(pending)
        except Exception as exc:
            emit({"event": "error", "frame": pending[0], "camera": pending[1],
                  "message": f"{type(exc).__name__}: {exc}"})
            return False
    return True
