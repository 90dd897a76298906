"""Asset library figures: generation time, file sizes, triangle counts, Blender import time.

    python benchmarks/assets_build.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def _timed(fn, repeat: int) -> tuple[float, float]:
    runs = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - start)
    return min(runs), statistics.median(runs)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from pxr import Usd, UsdGeom

    from usdscene.assetgen.library import build_library
    from usdscene.shipped import default_asset_folder

    with tempfile.TemporaryDirectory() as tmp:
        best, median = _timed(lambda: build_library(Path(tmp)), args.repeat)
    print(f"build_library (24 assets + catalog): best {best:.2f} s, median {median:.2f} s")
    cabin = default_asset_folder() / "environments" / "aircraft_cabin.usda"
    size_mb = sum(p.stat().st_size for p in default_asset_folder().rglob("*.usda")) / 1e6
    print(f"library size: {size_mb:.1f} MB of .usda, cabin {cabin.stat().st_size / 1e6:.1f} MB")
    stage = Usd.Stage.Open(str(cabin))
    triangles = sum(int(sum(c - 2 for c in UsdGeom.Mesh(p).GetFaceVertexCountsAttr().Get()))
                    for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    print(f"cabin triangles (composed, bins open): {triangles}")

    import bpy

    def import_cabin() -> None:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.usd_import(filepath=str(cabin))

    best, median = _timed(import_cabin, args.repeat)
    print(f"Blender usd_import of the cabin: best {best:.2f} s, median {median:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
