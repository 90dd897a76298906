"""Rendering: the driver (this process) and the Blender worker (its own process).

``render(stage_path, out_dir, RenderOptions(...)) -> RenderReport`` is the entry point; see
:mod:`usdscene.render.driver`. Only :mod:`usdscene.render.blender` (run by
:mod:`usdscene.render.worker`) imports ``bpy``, and only inside the worker process.
"""

from usdscene.render.driver import RenderOptions, RenderReport, render

__all__ = ["RenderOptions", "RenderReport", "render"]
