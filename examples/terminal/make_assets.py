"""A terminal hall for planning cameras at scale: writes ``assets/terminal.usda`` and
``assets/catalog.json`` (the environment and its places).

    python examples/terminal/make_assets.py [--out DIR]

A 210 x 100 m hall under an 8 m ceiling (21,000 m² of floor): a security line at the west
end (eight lanes between 1 m barriers, a scanner in each lane), a concourse with a grid of
pillars, a row of shops along the north wall and three gate areas along the south wall (rows
of benches and a desk each). The ceiling and the walls carry the cameras (the planner finds
them); nothing is marked by hand. The places are three large floor areas, 1.8 m tall (a
standing person), which the planner splits into cells (``--cell``). Deterministic: the same
bytes every run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent

HALL_M = (210.0, 100.0)          # floor size x, y; the hall spans [-105, 105] x [-50, 50]
CEILING_M = 8.0
WALL_M = 0.3                     # wall and slab thickness
SECURITY_X_M = (-105.0, -75.0)   # the security zone along x
LANE_Y_M = tuple(-42.0 + 12.0 * i for i in range(8))  # lane centres (y)
LANE_WIDTH_M = 3.0
PILLARS_X_M = tuple(-60.0 + 20.0 * i for i in range(9))
PILLARS_Y_M = (-20.0, 0.0, 20.0)
PILLAR_M = 0.8
SHOPS_X_M = tuple(-70.0 + 14.0 * i for i in range(12))  # west edges of the shops
SHOP_M = (10.0, 8.0, 4.0)        # width, depth, height; shops stand against the north wall
GATES_X_M = (-40.0, 20.0, 80.0)  # gate-area centres along the south wall
PERSON_HEIGHT_M = 1.8
CONCOURSE_Y_M = (-30.0, 42.0)    # between the gate areas and the shop row


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
    root = UsdGeom.Xform.Define(stage, "/Terminal")
    stage.SetDefaultPrim(root.GetPrim())
    gx, gy, t = HALL_M[0] / 2, HALL_M[1] / 2, WALL_M
    _box(stage, "/Terminal/Floor", (-gx - t, -gy - t, -t), (gx + t, gy + t, 0.0))
    _box(stage, "/Terminal/Ceiling", (-gx - t, -gy - t, CEILING_M), (gx + t, gy + t, CEILING_M + t))
    _box(stage, "/Terminal/WallWest", (-gx - t, -gy, 0.0), (-gx, gy, CEILING_M))
    _box(stage, "/Terminal/WallEast", (gx, -gy, 0.0), (gx + t, gy, CEILING_M))
    _box(stage, "/Terminal/WallSouth", (-gx - t, -gy - t, 0.0), (gx + t, -gy, CEILING_M))
    _box(stage, "/Terminal/WallNorth", (-gx - t, gy, 0.0), (gx + t, gy + t, CEILING_M))
    x0, x1 = SECURITY_X_M
    UsdGeom.Xform.Define(stage, "/Terminal/Security")
    for i, y in enumerate(LANE_Y_M):
        for side, edge in (("S", y - LANE_WIDTH_M / 2), ("N", y + LANE_WIDTH_M / 2)):
            _box(stage, f"/Terminal/Security/Barrier_{i}{side}", (x0 + 8.0, edge - 0.05, 0.0),
                 (x1 - 4.0, edge + 0.05, 1.0))
        _box(stage, f"/Terminal/Security/Scanner_{i}", (-88.0, y - 0.6, 0.0), (-86.0, y + 0.6, 1.8))
    UsdGeom.Xform.Define(stage, "/Terminal/Pillars")
    for i, x in enumerate(PILLARS_X_M):
        for j, y in enumerate(PILLARS_Y_M):
            h = PILLAR_M / 2
            _box(stage, f"/Terminal/Pillars/Pillar_{i}_{j}", (x - h, y - h, 0.0), (x + h, y + h, CEILING_M))
    UsdGeom.Xform.Define(stage, "/Terminal/Shops")
    w, d, h = SHOP_M
    for i, x in enumerate(SHOPS_X_M):
        _box(stage, f"/Terminal/Shops/Shop_{i:02d}", (x, gy - d, 0.0), (x + w, gy, h))
    UsdGeom.Xform.Define(stage, "/Terminal/Gates")
    for i, cx in enumerate(GATES_X_M):
        for r in range(4):
            y = -44.0 + 3.0 * r
            for b in range(3):
                bx = cx - 12.0 + 8.0 * b
                _box(stage, f"/Terminal/Gates/Bench_{i}_{r}_{b}", (bx, y, 0.0), (bx + 6.0, y + 0.6, 0.5))
        _box(stage, f"/Terminal/Gates/Desk_{i}", (cx + 16.0, -40.0, 0.0), (cx + 18.0, -39.0, 1.1))
    path.write_text(stage.GetRootLayer().ExportToString(), encoding="utf-8")


def _floor_place(kind: str, lo, hi) -> dict:
    """A floor area ``lo``-``hi`` (x, y) as a place with one region ``on``, a person tall."""
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    return {"kind": kind, "regions": {"is_on": {
        "matrix": [1, 0, 0, cx, 0, 1, 0, cy, 0, 0, 1, 0, 0, 0, 0, 1],
        "size_m": [hi[0] - lo[0], hi[1] - lo[1], PERSON_HEIGHT_M]}}}


def places() -> dict:
    """``security`` (the west end), ``concourse`` (the middle, pillars and shop fronts),
    ``gates`` (the south strip with the benches): 19,560 m² of floor together."""
    gx, gy = HALL_M[0] / 2, HALL_M[1] / 2
    east = SECURITY_X_M[1]
    return {"security": _floor_place("walkway", (-gx, -gy), (east, gy)),
            "concourse": _floor_place("walkway", (east, CONCOURSE_Y_M[0]), (gx, CONCOURSE_Y_M[1])),
            "gates": _floor_place("walkway", (east, -gy), (gx, CONCOURSE_Y_M[0]))}


SETUP = {"openlabel": {"metadata": {
    "schema_version": "1.0.0", "name": "terminal_setup",
    "comment": "Terminal hall for plan-cameras: environment and places only (the planner adds the cameras), "
               "a sun through the roof.",
    "usdscene": {"seed": 7, "environment": "terminal", "asset_paths": ["assets"],
                 "render": {"samples": 4, "denoise": False, "max_bounces": 2, "resolution_px": [640, 480]}}},
    "objects": {"0": {"name": "ceiling_light", "type": "light", "object_data": {
        "text": [{"name": "kind", "val": "sun"}], "num": [{"name": "power_w", "val": 3.0},
                                                          {"name": "sun_angle_deg", "val": 0.53}],
        "vec": [{"name": "color_rgb", "val": [1.0, 1.0, 1.0]}, {"name": "position_m", "val": [0.0, 0.0, 7.5]},
                {"name": "rotation_xyz_deg", "val": [0.0, 0.0, 0.0]}]}}}}}


def main(argv=None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=HERE, help="folder for assets/ and setup.openlabel.json")
    args = parser.parse_args(argv)
    assets = args.out / "assets"
    write_environment(assets / "terminal.usda")
    gx, gy = HALL_M[0] / 2, HALL_M[1] / 2
    catalog = {"format": "usdscene-catalog", "version": 1, "classes": {"terminal": {
        "kind": "environment", "usd": "terminal.usda",
        "description": "Terminal hall (210 x 100 m, 8 m ceiling): security lanes, 27 pillars, 12 shops, "
                       "3 gate areas with benches; places security, concourse, gates (on, 1.8 m tall)",
        "extent_m": [[-gx - WALL_M, -gy - WALL_M, -WALL_M], [gx + WALL_M, gy + WALL_M, CEILING_M + WALL_M]],
        "relations": [], "places": places()}}}
    (assets / "catalog.json").write_text(json.dumps(catalog, indent=1) + "\n", encoding="utf-8")
    setup = args.out / "setup.openlabel.json"
    setup.write_text(json.dumps(SETUP, indent=1) + "\n", encoding="utf-8")
    return setup


if __name__ == "__main__":
    main()
