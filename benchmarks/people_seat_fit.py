"""How far the seated people reach into the cabin's seats: every body of the shipped
``passenger`` class in every pose, seated on ``seat_03B`` (a middle seat: armrests on both
sides, a seat in front) and ``seat_03A`` (by the window).

    python benchmarks/people_seat_fit.py

For each passenger vertex inside a closed seat mesh (its own seat, the neighbours, the row in
front), the depth is its distance to that mesh's surface: the smallest distance to the
triangles' planes where the foot of the perpendicular falls inside the triangle, else to the
clamped point (exact for faces, an upper bound near edges). Vertices sinking into the cushion under the buttocks and thighs (within its
footprint, up to 3 cm below its top) are reported apart: that is the cushion giving way, not
an arm or a leg inside a seat back or an armrest. Prints the worst depth per pose and the
share of (body, pose) pairs within 1 cm.
"""

from __future__ import annotations

import numpy as np

SEATS = ("seat_03B", "seat_03A")
NEIGHBOURS = ("Seat_02A", "Seat_02B", "Seat_02C", "Seat_03A", "Seat_03B", "Seat_03C")
CUSHION_SINK_M = 0.03


def seat_meshes():
    """Closed seat meshes near the measured seats, world frame: list of (name, points, tris)."""
    import trimesh
    from pxr import Usd, UsdGeom

    from usdscene.scene.catalog import load_catalog
    from usdscene.scene.stage_geometry import triangulate

    stage = Usd.Stage.Open(str(load_catalog()["aircraft_cabin"].usd_path))
    cache = UsdGeom.XformCache()
    out = []
    for seat in NEIGHBOURS:
        for prim in Usd.PrimRange(stage.GetPrimAtPath(f"/AircraftCabin/Seats/{seat}")):
            if not prim.IsA(UsdGeom.Mesh):
                continue
            mesh = UsdGeom.Mesh(prim)
            pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
            tris = triangulate(np.asarray(mesh.GetFaceVertexCountsAttr().Get()),
                               np.asarray(mesh.GetFaceVertexIndicesAttr().Get())).reshape(-1, 3)
            m = np.asarray(cache.GetLocalToWorldTransform(prim))
            world = pts @ m[:3, :3] + m[3, :3]
            tm = trimesh.Trimesh(world, tris, process=True)  # merged vertices: closed shells
            if tm.is_watertight:
                out.append((f"{seat}/{prim.GetName()}", tm))
    return out


def _surface_distance(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(P,) distance from each point to the closest of (T, 3, 3) triangles (clamped
    barycentric projection on every triangle)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e0, e1 = b - a, c - a
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    den = np.where(np.abs(d00 * d11 - d01 * d01) > 1e-18, d00 * d11 - d01 * d01, 1e-18)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        d = p - a
        d20, d21 = (d * e0).sum(1), (d * e1).sum(1)
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        bc = np.clip(np.stack([1 - v - w, v, w], axis=1), 0.0, None)
        bc /= bc.sum(axis=1, keepdims=True)
        proj = bc[:, :1] * a + bc[:, 1:2] * b + bc[:, 2:] * c
        out[i] = np.linalg.norm(proj - p, axis=1).min()
    return out


def main() -> int:
    from pxr import Usd, UsdGeom
    from usdscene.document import stage_schema as ss
    from usdscene.scene.catalog import load_catalog

    catalog = load_catalog()
    entry = catalog["passenger"]
    cabin = catalog["aircraft_cabin"]
    meshes = seat_meshes()
    trees = [(name, tm, None) for name, tm in meshes]
    stage = Usd.Stage.Open(str(entry.usd_path))
    root = stage.GetDefaultPrim()
    body_mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{root.GetPath()}/Geom/Body"))
    worst: dict[str, float] = {}
    sink: dict[str, float] = {}
    within = total = 0
    offenders: list[tuple[float, str, str, str, str]] = []
    for seat in SEATS:
        region = cabin.places[seat].regions["is_on"]
        to_world = region.pose.as_array()
        size = np.asarray(region.size_m)
        for body in entry.variants[ss.VARIANT_SET_APPEARANCE]:
            root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_APPEARANCE).SetVariantSelection(body)
            for pose in entry.variants[ss.VARIANT_SET_POSE]:
                root.GetVariantSets().GetVariantSet(ss.VARIANT_SET_POSE).SetVariantSelection(pose)
                local = np.asarray(body_mesh.GetPointsAttr().Get(), dtype=np.float64)
                world = local @ to_world[:3, :3].T + to_world[:3, 3]
                on_cushion = ((np.abs(local[:, 0]) <= size[0] / 2) & (np.abs(local[:, 1]) <= size[1] / 2)
                              & (local[:, 2] >= -CUSHION_SINK_M) & (local[:, 2] <= 0.02))
                depth = sunk = 0.0
                where = ""
                for name, tm, tree in trees:
                    inside = tm.contains(world)
                    if not inside.any():
                        continue
                    dist = _surface_distance(world[inside], tm.triangles)
                    cushion = on_cushion[inside]
                    if (~cushion).any() and dist[~cushion].max() > depth:
                        depth, where = float(dist[~cushion].max()), name
                    if cushion.any():
                        sunk = max(sunk, float(dist[cushion].max()))
                worst[pose] = max(worst.get(pose, 0.0), depth)
                sink[pose] = max(sink.get(pose, 0.0), sunk)
                within += depth <= 0.01
                total += 1
                if depth > 0.01:
                    offenders.append((depth, seat, body, pose, where))
    print(f"{'pose':10s} {'worst depth into a seat (cm)':>30s} {'cushion sink (cm)':>18s}")
    for pose in entry.variants[ss.VARIANT_SET_POSE]:
        print(f"{pose:10s} {100 * worst[pose]:30.1f} {100 * sink[pose]:18.1f}")
    print(f"(body, pose, seat) within 1 cm: {within}/{total}")
    for depth, seat, body, pose, where in sorted(offenders, reverse=True)[:8]:
        print(f"  {100 * depth:.1f} cm  {seat} {body} {pose} into {where}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
