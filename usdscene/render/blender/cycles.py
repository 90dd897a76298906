"""The render engine: Cycles' settings from a job, and the GPU it renders on."""

from __future__ import annotations

import sys

from usdscene.render.blender.process import emit


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


def enable_gpu(bpy) -> None:
    """Let Cycles render on every GPU of the first backend that has one.

    Raises:
        DeviceError: no backend found a GPU; the message says which backends were tried
            and what is missing (the NVIDIA driver library, or a device it accepts).
    """
    prefs = bpy.context.preferences.addons["cycles"].preferences
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
            emit({"event": "device", "backend": kind, "devices": [d.name for d in devices]})
            return
    raise DeviceError(gpu_missing_message(bpy.app.version_string, tried))


def apply_settings(scene, s: dict, *, rendering: bool, exr_path, threads: int | None) -> None:
    """Set the render engine, Cycles' knobs, colour management and the output (a multilayer
    EXR at ``exr_path`` holding the beauty and the object index) from the job's ``settings``
    ``s``; ``rendering`` is false for a .blend made for camera design.

    Raises:
        RuntimeError: the engine is not Cycles (exact instance masks need its object index).
        DeviceError: the OptiX denoiser was asked for on the CPU.
    """
    engine = ENGINES.get(s["engine"], s["engine"])
    scene.render.engine = engine
    if engine != "CYCLES":
        raise RuntimeError(f"render engine {s['engine']!r}: exact instance masks need the Cycles "
                           "object-index pass; use engine 'cycles'")
    cycles = scene.cycles
    # The GPU was enabled (or found missing) before the import; a .blend for camera design
    # keeps the document's device without needing one here.
    cycles.device = "GPU" if s["device"] == "gpu" else "CPU"
    if rendering and s["device"] == "cpu" and s["denoise"] and s["denoiser"] == "optix":
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
    _set_output(scene, s, exr_path)
    if threads:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = int(threads)


def _set_output(scene, s: dict, exr_path) -> None:
    """Colour management as rendered (Standard, no look or exposure) and the output: a
    multilayer EXR at ``exr_path`` with the beauty, the object index and (``s["depth"]``) Z."""
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.dither_intensity = 0.0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    view_layer = scene.view_layers[0]
    view_layer.use_pass_object_index = True
    # Written from the first sample with the object index: the depth of the mask's surface.
    view_layer.use_pass_z = bool(s.get("depth"))
    image = scene.render.image_settings
    image.media_type = "MULTI_LAYER_IMAGE"
    image.file_format = "OPEN_EXR_MULTILAYER"
    image.color_depth = "32"
    image.exr_codec = "NONE"  # /dev/shm: compression costs time and saves nothing
    scene.render.filepath = str(exr_path)
    scene.render.use_file_extension = False
