"""An open-air car park for the camera planner: writes ``assets/open_car_park.usda`` and
``assets/catalog.json`` (the environment and its places).

    python examples/open_car_park/make_assets.py

A 44 x 30 m surface lot under the open sky: 12 parking bays in two rows either side of a
driving lane, a footpath along the north edge, a kiosk (a small building) at the east end,
four 6 m lamp posts and three trees whose crowns overhang the bays. Nothing is marked
mountable by hand: the planner's rule (docs/camera-design.md) keeps the trees free of
cameras, and the posts and the kiosk carry them. Deterministic: the same bytes every run.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent

GROUND_M = (44.0, 30.0)
BAY_X_M = (-12.5, -7.5, -2.5, 2.5, 7.5, 12.5)     # bay centres along x
BAY_SIZE_M = (2.5, 5.0)                           # width x length of a bay
ROW_Y_M = {"A": 5.0, "B": -5.0}                   # bay rows either side of the lane (y = 0)
FOOTPATH_Y_M = 10.5                               # north footpath centre line
KIOSK = ((18.5, 0.0), (3.0, 4.0, 3.0))            # centre (x, y), size (m)
POSTS_M = ((-16.0, 0.0), (-4.0, 8.7), (6.0, -8.7), (16.0, 8.7))
TREES_M = ((-10.0, 9.0), (0.0, -9.0), (10.0, 9.0))  # crowns 4 x 4 m, 3 to 6 m above the ground


def _box(stage, path: str, lo, hi) -> None:
    from pxr import Gf, UsdGeom

    (x0, y0, z0), (x1, y1, z1) = lo, hi
    pts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1),
           (x0, y1, z1)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)


def write_environment(path: Path) -> None:
    from pxr import Usd, UsdGeom

    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/OpenCarPark")
    stage.SetDefaultPrim(root.GetPrim())
    gx, gy = GROUND_M[0] / 2, GROUND_M[1] / 2
    _box(stage, "/OpenCarPark/Ground", (-gx, -gy, -0.2), (gx, gy, 0.0))
    _box(stage, "/OpenCarPark/Footpath", (-gx, FOOTPATH_Y_M - 1.25, 0.0), (gx, FOOTPATH_Y_M + 1.25, 0.15))
    (kx, ky), (sx, sy, sz) = KIOSK
    _box(stage, "/OpenCarPark/Kiosk", (kx - sx / 2, ky - sy / 2, 0.0), (kx + sx / 2, ky + sy / 2, sz))
    for i, (x, y) in enumerate(POSTS_M):
        _box(stage, f"/OpenCarPark/LampPost_{i}", (x - 0.1, y - 0.1, 0.0), (x + 0.1, y + 0.1, 6.0))
    for i, (x, y) in enumerate(TREES_M):
        UsdGeom.Xform.Define(stage, f"/OpenCarPark/Tree_{i}")
        _box(stage, f"/OpenCarPark/Tree_{i}/Trunk", (x - 0.2, y - 0.2, 0.0), (x + 0.2, y + 0.2, 3.0))
        _box(stage, f"/OpenCarPark/Tree_{i}/Crown", (x - 2.0, y - 2.0, 3.0), (x + 2.0, y + 2.0, 6.0))
    path.write_text(stage.GetRootLayer().ExportToString(), encoding="utf-8")


def places() -> dict:
    """Bays (``bay_<row><n>``, region ``on``: a bay up to 2 m) and footpath spots
    (``walkway_<n>``, 2.5 x 2 m)."""
    out = {}
    for row, y in ROW_Y_M.items():
        for n, x in enumerate(BAY_X_M, start=1):
            out[f"bay_{row}{n}"] = {"kind": "bay", "regions": {"is_on": {
                "matrix": [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, 0, 0, 0, 0, 1], "size_m": [*BAY_SIZE_M, 2.0]}}}
    for n, x in enumerate(BAY_X_M, start=1):
        out[f"walkway_{n}"] = {"kind": "walkway", "regions": {"is_on": {
            "matrix": [1, 0, 0, x, 0, 1, 0, FOOTPATH_Y_M, 0, 0, 1, 0.15, 0, 0, 0, 1], "size_m": [2.5, 2.0, 2.0]}}}
    return out


def main() -> None:
    assets = HERE / "assets"
    write_environment(assets / "open_car_park.usda")
    gx, gy = GROUND_M[0] / 2, GROUND_M[1] / 2
    catalog = {"format": "usdscene-catalog", "version": 1, "classes": {"open_car_park": {
        "kind": "environment", "usd": "open_car_park.usda",
        "description": "Open-air car park (44 x 30 m): 12 bays, a footpath, a kiosk, four 6 m lamp posts, "
                       "three trees; places bay_<row><n> (on) and walkway_<n> (on)",
        "extent_m": [[-gx, -gy, -0.2], [gx, gy, 6.0]], "relations": [], "places": places()}}}
    (assets / "catalog.json").write_text(json.dumps(catalog, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
