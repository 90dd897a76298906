"""The shipped reusable layers are the generator's output and mean what they say."""

from pathlib import Path

import pytest

from usdscene.document.model import RenderSettings

pytestmark = pytest.mark.usd

LAYERS = Path(__file__).resolve().parent.parent / "layers"


def test_render_defaults_layer_is_up_to_date():
    from usdscene.scene.compose import render_settings_layer

    committed = (LAYERS / "render_defaults.usda").read_text(encoding="utf-8")
    assert committed == render_settings_layer(RenderSettings()), "run python layers/generate.py"


def test_render_defaults_layer_reads_back_as_the_defaults(tmp_path):
    from pxr import Sdf, Usd

    from usdscene.render.stage_reader import read_stage_plan

    root = Sdf.Layer.CreateNew(str(tmp_path / "scene.usda"))
    root.subLayerPaths.append(str(LAYERS / "render_defaults.usda"))
    root.Save()
    assert Usd.Stage.Open(str(tmp_path / "scene.usda")).GetPrimAtPath("/Render/Settings")
    assert read_stage_plan(tmp_path / "scene.usda").settings == RenderSettings()
