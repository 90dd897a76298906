"""The document's world as a Blender world (colour, physical sky or environment image) and
the ``bake_world`` mode: a world alone rendered into an equirectangular image."""

from __future__ import annotations

import math

from usdscene.render.blender.process import emit, import_bpy
from usdscene.render.job import BakeWorldJob


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


def bake_world(job: BakeWorldJob) -> None:
    """Render a document's world alone, as Cycles sees it, into an equirectangular radiance
    image (linear RGB, the Background's colour times its strength; longitude along the width,
    the zenith at the top), laid out as the environment images of a world's ``hdri`` are read.

    The job's fields (:class:`~usdscene.render.job.BakeWorldJob`): the stage's world, the
    frame whose per-frame values apply, the image size, the samples and the ``.hdr`` path.
    """
    from usdscene.document.imaging import World, spec_from_json

    bpy = import_bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = spec_from_json(World, job.world["world"])
    WorldNodes(bpy, scene, world, job.world).apply(world.at_frame(int(job.frame)))
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
    scene.cycles.samples = int(job.samples)
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.filter_width = 0.01  # each pixel its own direction: no blur across pixels
    scene.render.resolution_x, scene.render.resolution_y = (int(v) for v in job.size_px)
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "HDR"
    scene.render.filepath = str(job.out)
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    emit({"event": "baked", "path": str(job.out)})
