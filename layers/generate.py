"""Write the reusable USD layers of this folder from code (byte-identical on every run).

* ``render_defaults.usda`` — ``/Render/Settings`` with usdscene's default Cycles settings
  (``usdscene.document.model.RenderSettings()``) as ``usdscene:render:*`` attributes. Sublayer it into a
  stage authored by hand (or in a DCC tool) to render it with ``usdscene render`` at the
  defaults; edit the values there to change them.

Usage: ``python layers/generate.py``
"""

from __future__ import annotations

from pathlib import Path

from usdscene.scene.compose import render_settings_layer
from usdscene.files import write_text_atomic
from usdscene.document.model import RenderSettings

HERE = Path(__file__).resolve().parent
LAYERS = {"render_defaults.usda": lambda: render_settings_layer(RenderSettings())}


def main() -> int:
    for name, make in LAYERS.items():
        write_text_atomic(HERE / name, make())
        print(f"wrote {HERE / name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
