"""The pure modules must import without pxr and bpy (dependency direction of the design)."""

import subprocess
import sys

import pytest

PURE_MODULES = [
    "usdscene.document.model",
    "usdscene.errors",
    "usdscene.document.stage_schema",
    "usdscene.document.output_layout",
    "usdscene.files",
    "usdscene.bulk",
    "usdscene.scene.catalog",
    "usdscene.cli",
    "usdscene.scene.placement",
    "usdscene.generate.sequences",
    "usdscene.labels.pixel_density",
    "usdscene.design.lenses",
    "usdscene.design.targets",
    "usdscene.design.occluders",
    "usdscene.design.candidates",
    "usdscene.design.visibility",
    "usdscene.design.selection",
    "usdscene.design.plan_picture",
    "usdscene.design.plan_request",
    "usdscene.design.mount_surfaces",
    "usdscene.design.user_mounts",
    "usdscene.labels.pixel_box",
    "usdscene.labels.amodal",
    "usdscene.scene.place_discovery",
    "usdscene.document.splits",
    "usdscene.labels.cross_camera",
    "usdscene.labels.projection",
    "usdscene.lens",
    "usdscene.labels.image_labels",
    "usdscene.validation",
    "usdscene.dataset.annotation",
    "usdscene.dataset.export",
    "usdscene.dataset.statistics",
    "usdscene.dataset.contact_sheet",
    "usdscene.dataset.report",
    "usdscene.dataset.report_pictures",
    "usdscene.shipped",
    "usdscene.converters.openlabel",
    "usdscene.converters.openlabel.annotations",
    "usdscene.converters.openlabel.imaging",
    "usdscene.document.imaging",
    "usdscene.sensor.pipeline",
    "usdscene.sensor.exposure",
    "usdscene.sensor.tone",
    "usdscene.sensor.optics",
    "usdscene.document.camera_profiles",
    "usdscene.document.surfaces",
    "usdscene.render.blender.surface_nodes",
    "usdscene.converters.exports.coco",
    "usdscene.converters.exports.yolo",
    "usdscene.render.executors",
    "usdscene.render.worker_process",
    "usdscene.render.shards",
    "usdscene.render.scratch",
    "usdscene.render.ray_executor",
]


@pytest.mark.parametrize("module", PURE_MODULES)
def test_pure_module_imports_without_pxr_and_bpy(module):
    code = (
        "import sys, importlib\n"
        "sys.modules['bpy'] = None\n"
        "sys.modules['pxr'] = None\n"
        f"importlib.import_module({module!r})\n"
        "loaded = [m for m in ('bpy', 'pxr') if sys.modules.get(m) is not None]\n"
        "assert not loaded, loaded\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_help_is_fast_and_light():
    code = (
        "import sys\n"
        "from usdscene.cli import main\n"
        "try:\n"
        "    main(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = [m for m in ('bpy', 'pxr', 'cv2', 'trimesh', 'jsonschema') if m in sys.modules]\n"
        "print(heavy)\n"
        "assert not heavy, heavy\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
