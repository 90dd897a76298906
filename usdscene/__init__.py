"""usdscene: OpenLABEL scene descriptions → layered USD stages → labeled multi-camera datasets.

The public Python API (``docs/python-api.md``) is re-exported here lazily: ``import usdscene``
loads only the error classes, and each function's module (pxr for composition, cv2 for labels,
...) is imported the first time the name is used. Blender (``bpy``) is never imported in this
process: rendering runs in worker processes.

::

    import usdscene

    summary = usdscene.run_pipeline("scene.openlabel.json", "out/")   # the whole job
    scene = usdscene.read_openlabel("scene.openlabel.json")           # or step by step
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

from usdscene.errors import (  # noqa: E402
    AssetError,
    CompositionError,
    DocumentError,
    OutputError,
    RenderError,
    UsdSceneError,
)

# public name → (module, attribute in that module)
_LAZY = {
    # documents: OpenLABEL 1.0.0 / VCD 4.3 ↔ SceneSpec
    "load_document": ("usdscene.converters.openlabel", "load_document"),
    "read_openlabel": ("usdscene.converters.openlabel", "read_openlabel"),
    "write_openlabel": ("usdscene.converters.openlabel", "write_openlabel"),
    "write_document": ("usdscene.converters.openlabel", "write_document"),
    "validate_document": ("usdscene.validation", "validate_document"),
    "SceneSpec": ("usdscene.document.model", "SceneSpec"),
    # assets and the USD stage
    "load_catalog": ("usdscene.scene.catalog", "load_catalog"),
    "compose_stage": ("usdscene.scene.compose", "compose_stage"),
    "compose_document": ("usdscene.pipeline", "compose_document"),
    "scene_from_stage": ("usdscene.converters.stage.usd_stage", "scene_from_stage"),
    # rendering (Blender worker processes), labels, training sets
    "render_stage": ("usdscene.render.driver", "render"),
    "annotate_output": ("usdscene.dataset.annotation", "annotate_output"),
    "write_annotations": ("usdscene.dataset.annotation", "write_annotations"),
    "export_formats": ("usdscene.dataset.export", "export_formats"),
    "export_dataset": ("usdscene.dataset.export", "export_dataset"),
    "ExportOptions": ("usdscene.dataset.export", "ExportOptions"),
    "carried_split": ("usdscene.dataset.export", "carried_split"),
    "parse_split": ("usdscene.document.splits", "parse_split"),
    "build_report": ("usdscene.dataset.report", "build_report"),
    # the whole job
    "run_pipeline": ("usdscene.pipeline", "run_pipeline"),
    "RunSummary": ("usdscene.pipeline", "RunSummary"),
    "RunOptions": ("usdscene.pipeline", "RunOptions"),
    # design time: sequence documents and camera systems
    "generate_document": ("usdscene.generate.sequences", "generate_document"),
    "generate_sequence": ("usdscene.generate.sequences", "generate_sequence"),
    "GenerateOptions": ("usdscene.generate.sequences", "GenerateOptions"),
    "balance_report": ("usdscene.generate.balance", "balance_report"),
    "plan_cameras": ("usdscene.design.camera_design", "plan_cameras"),
    "PlanRequest": ("usdscene.design.plan_request", "PlanRequest"),
    "verify_plan": ("usdscene.design.plan_verify", "verify_plan"),
}

__all__ = ["__version__", "AssetError", "CompositionError", "DocumentError", "OutputError",
           "RenderError", "UsdSceneError", *_LAZY]


def __getattr__(name: str):
    try:
        module, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'usdscene' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
