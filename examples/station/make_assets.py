"""Stand-in for the modelling tool: writes the station's concourse as a DCC tool would.

    python examples/station/make_assets.py        # writes examples/station/source/station.glb

A concourse of 60 x 30 m (x from -30 to 30, y from -15 to 15, floor at z = 0): doors in the
west and east walls and a wide entrance in the north wall, a row of ticket gates across the
concourse at x = 8 (the paid side east of it), a kiosk with its counter, benches, two rows of
pillars carrying departure boards (hung 2.6 m up: people walk under them), and stairs down to
a platform 4 m below in the south-east corner, behind a balustrade. Places are boxes named
``place.<place>.on`` (Y up, metres, as glTF exporters write them), the only usdscene-specific
part: ``concourse_*`` (walk places), ``entrance_*`` and ``stairs_platform`` (entrances),
``queue_gate_*`` and ``queue_kiosk`` (queues), ``waiting_board_*`` (waiting places),
``bench_*`` (benches). Deterministic: the same script writes the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent

FLOOR = (172, 168, 160)
WALL = (205, 200, 190)
STEEL = (90, 94, 100)
GATE = (60, 64, 72)
WOOD = (140, 96, 60)
BOARD = (20, 24, 32)
KIOSK = (170, 40, 35)
TRACK = (70, 62, 55)

Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
WALL_H_M = 6.0
GATE_X_M = 8.0
GATE_Y_M = tuple(-4.5 + 1.3 * k for k in range(8))  # passage centres: 0.8 m passages between 0.5 m housings
PILLAR_X_M = (-20.0, -10.0, 0.0, 18.0)
PILLAR_Y_M = (-6.0, 6.0)
STAIRS = (20.0, 28.0, -14.0, -10.0)  # x0, x1, y0, y1 of the stairwell (down towards +x)
PLATFORM_Z_M = -4.0


def _box(size_m, centre_m, colour) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=size_m)
    box.apply_translation(centre_m)
    box.visual.face_colors = [*colour, 255]
    return box


def _span(a: float, b: float) -> tuple[float, float]:
    return b - a, (a + b) / 2.0


def environment_parts() -> tuple[list[tuple[str, trimesh.Trimesh]], list[tuple[str, tuple, tuple]]]:
    """(scenery, place boxes) in Z-up metres: (name, mesh) and (name, size, bottom centre)."""
    sx0, sx1, sy0, sy1 = STAIRS
    parts = []
    # The floor around the stairwell (four slabs), 0.3 m thick.
    for name, (x0, x1, y0, y1) in {"floor_west": (-30, sx0, -15, 15), "floor_east": (sx1, 30, -15, 15),
                                   "floor_north": (sx0, sx1, sy1, 15), "floor_south": (sx0, sx1, -15, sy0)}.items():
        (w, cx), (d, cy) = _span(x0, x1), _span(y0, y1)
        parts.append((name, _box((w, d, 0.3), (cx, cy, -0.15), FLOOR)))
    # Walls with doors: west and east 4 m doors at y in [-2, 2], a 6 m entrance in the north wall.
    for name, (x0, x1, y0, y1) in {"wall_west_s": (-30.3, -30, -15, -2), "wall_west_n": (-30.3, -30, 2, 15),
                                   "wall_east_s": (30, 30.3, -15, -2), "wall_east_n": (30, 30.3, 2, 15),
                                   "wall_north_w": (-30.3, -3, 15, 15.3), "wall_north_e": (3, 30.3, 15, 15.3),
                                   "wall_south": (-30.3, 30.3, -15.3, -15)}.items():
        (w, cx), (d, cy) = _span(x0, x1), _span(y0, y1)
        parts.append((name, _box((w, d, WALL_H_M), (cx, cy, WALL_H_M / 2), WALL)))
    # Ticket gates: housings 0.5 m wide between 0.8 m passages, a glass barrier beyond them.
    edges = [GATE_Y_M[0] - 0.65] + [y + 0.65 for y in GATE_Y_M]
    for k, y in enumerate(edges):
        parts.append((f"gate_housing_{k}", _box((1.4, 0.5, 1.05), (GATE_X_M, y, 0.525), GATE)))
    low, high = edges[0] - 0.25, edges[-1] + 0.25
    parts.append(("gate_barrier_s", _box((0.1, low + 15.0, 1.1), (GATE_X_M, (low - 15.0) / 2, 0.55), STEEL)))
    parts.append(("gate_barrier_n", _box((0.1, 15.0 - high, 1.1), (GATE_X_M, (high + 15.0) / 2, 0.55), STEEL)))
    # The kiosk and its counter (north-west), benches (south-west).
    parts.append(("kiosk", _box((4.0, 2.5, 2.6), (-16.0, 11.5, 1.3), KIOSK)))
    parts.append(("kiosk_counter", _box((4.0, 0.5, 1.05), (-16.0, 10.0, 0.525), WOOD)))
    for k, x in enumerate((-24.0, -18.0, -12.0)):
        parts.append((f"bench_{k}_seat", _box((2.4, 0.5, 0.08), (x, -12.0, 0.42), WOOD)))
        for side in (-1.0, 1.0):
            parts.append((f"bench_{k}_leg_{int(side > 0)}", _box((0.08, 0.45, 0.38), (x + side * 1.1, -12.0, 0.19), STEEL)))
    # Pillars, the departure boards on the row at y = 6 (2.6 m to 3.4 m up, facing south).
    for i, x in enumerate(PILLAR_X_M):
        for j, y in enumerate(PILLAR_Y_M):
            parts.append((f"pillar_{i}{j}", _box((0.6, 0.6, WALL_H_M), (x, y, WALL_H_M / 2), WALL)))
    for i, x in enumerate(PILLAR_X_M[:3]):
        parts.append((f"departure_board_{i}", _box((3.0, 0.15, 0.8), (x, PILLAR_Y_M[1] - 0.4, 3.0), BOARD)))
    # Stairs down (+x) to the platform, a balustrade on three sides of the well.
    steps = 16
    run = (sx1 - sx0) / steps
    for k in range(steps):
        top = -(k + 1) * (-PLATFORM_Z_M) / steps
        parts.append((f"step_{k:02d}", _box((run, sy1 - sy0, 0.2), (sx0 + (k + 0.5) * run, (sy0 + sy1) / 2, top - 0.1),
                                            FLOOR)))
    parts.append(("balustrade_n", _box((sx1 - sx0, 0.08, 1.1), ((sx0 + sx1) / 2, sy1, 0.55), STEEL)))
    parts.append(("balustrade_s", _box((sx1 - sx0, 0.08, 1.1), ((sx0 + sx1) / 2, sy0, 0.55), STEEL)))
    parts.append(("balustrade_e", _box((0.08, sy1 - sy0, 1.1), (sx1, (sy0 + sy1) / 2, 0.55), STEEL)))
    parts.append(("platform", _box((6.0, 4.0, 0.3), (sx1 + 3.0 - 6.0, sy0 - 2.0 + 2.0, PLATFORM_Z_M - 0.15), FLOOR)))
    parts.append(("track", _box((10.0, 1.5, 0.2), (sx1 - 2.0, sy0 - 0.75, PLATFORM_Z_M - 0.9), TRACK)))
    places = [
        # walk places: the unpaid concourse west of the gates, the paid one east of them, the passages
        ("place.concourse_unpaid.on", (37.6, 30.0, 2.2), (-11.2, 0.0, 0.0)),
        ("place.concourse_paid.on", (21.4, 30.0, 2.2), (19.3, 0.0, 0.0)),
        ("place.concourse_gateline.on", (1.6, 30.0, 2.2), (GATE_X_M, 0.0, 0.0)),
        # entrances: doors (1 m deep inside the walls), the stairs' head
        ("place.entrance_west.on", (1.0, 4.0, 2.2), (-29.5, 0.0, 0.0)),
        ("place.entrance_east.on", (1.0, 4.0, 2.2), (29.5, 0.0, 0.0)),
        ("place.entrance_north.on", (6.0, 1.0, 2.2), (0.0, 14.5, 0.0)),
        ("place.stairs_platform.on", (1.0, sy1 - sy0 - 0.4, 2.2), (sx0 - 0.5, (sy0 + sy1) / 2, 0.0)),
        # queues in front of (west of) the middle gates and of the kiosk's counter
        ("place.queue_gate_3.on", (4.0, 0.6, 2.2), (GATE_X_M - 2.9, GATE_Y_M[3], 0.0)),
        ("place.queue_gate_4.on", (4.0, 0.6, 2.2), (GATE_X_M - 2.9, GATE_Y_M[4], 0.0)),
        ("place.queue_kiosk.on", (0.8, 4.0, 2.2), (-16.0, 7.3, 0.0)),
        # waiting places: under the departure boards, and on the paid side by the stairs
        ("place.waiting_board_0.on", (3.0, 2.0, 2.2), (PILLAR_X_M[0], PILLAR_Y_M[1] - 2.0, 0.0)),
        ("place.waiting_board_1.on", (3.0, 2.0, 2.2), (PILLAR_X_M[1], PILLAR_Y_M[1] - 2.0, 0.0)),
        ("place.waiting_paid.on", (4.0, 3.0, 2.2), (16.0, -6.0, 0.0)),
    ]
    for k, x in enumerate((-24.0, -18.0, -12.0)):
        places.append((f"place.bench_{k}.on", (2.4, 0.5, 0.6), (x, -12.0, 0.46)))
    return parts, places


def write_environment(path: Path) -> Path:
    """The station as a Y-up glTF binary with its place boxes."""
    parts, places = environment_parts()
    scene = trimesh.Scene()
    for name, mesh in parts:
        scene.add_geometry(mesh.copy().apply_transform(Z_UP_TO_Y_UP), node_name=name, geom_name=name)
    for name, size, bottom in places:
        box = trimesh.creation.box(extents=size)
        box.apply_transform(Z_UP_TO_Y_UP)
        placed = np.eye(4)
        placed[:3, 3] = (bottom[0], bottom[1], bottom[2] + size[2] / 2)
        scene.add_geometry(box, node_name=name, geom_name=name, transform=Z_UP_TO_Y_UP @ placed @ Z_UP_TO_Y_UP.T)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def main() -> None:
    out = HERE / "source"
    out.mkdir(exist_ok=True)
    written = write_environment(out / "station.glb")
    print(f"wrote {written.relative_to(HERE)} ({written.stat().st_size / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()
