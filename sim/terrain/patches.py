"""Terrain patches inside scenes (docs/terrain.md): the geometry of one spec record of a scene's `terrain` list.

A patch is a rectangle on the sidewalk slab (`position` its centre on the slab top, `yaw` the direction of its
local x, `size` = [depth along x, width, height]) of one kind: `roots` (tree-root heave) and `rough` (uneven
pavers) are a rough tile's bumps (sim.terrain.heights) up to `height`; `slick` is a flat tile of a low-friction
surface; `steps` is a stair of `steps` step tiles (`tread` metres each, a riser of height / steps in the middle
of each) and a flat landing, rising along x towards the building. The world builds each as a static mesh `LIFT`
above the slab (so its colour shows) with skirts down to the slab, with its surface's friction
(sim.terrain.wfc.SURFACES); the grid LiDAR rasterises `tops`; `FrictionIndex` answers what lies under a wheel.
`sim.scene.terrain` places the patches.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sim.terrain.heights import TileGeometry, grid_mesh, tile_surface
from sim.terrain.wfc import SURFACES, Tile

KINDS = ("roots", "rough", "steps", "slick")
ROUGH_KINDS = ("roots", "rough")  # bumps over the whole patch, drivable
LIFT = 0.005  # metres between the slab top and a patch's edges: its colour shows over the slab, a wheel rolls over it
RESOLUTION = 0.1  # metres between the samples of a rough patch's bumps (as the runways')
MAX_SIDE, MAX_STEPS = 50.0, 50  # a record's depth and width (m) and steps: the mesh grows with them (generated: 3 m, 3)
_COARSE = TileGeometry(size=1.0, resolution=0.5)  # flat and step tiles: exact with three samples a side
Record = Mapping[str, Any]
Piece = tuple[np.ndarray, np.ndarray, np.ndarray]  # local x [nx], local y [ny], heights z [ny, nx] above the slab


def pieces(rec: Record) -> list[Piece]:
    """The patch's surface as tile grids in its local frame (x along `yaw`, centred), heights above the slab."""
    depth, width, height = (float(v) for v in rec["size"])
    kind, surface = rec["kind"], rec["surface"]
    rng = np.random.default_rng(int(rec.get("seed", 0)))
    if kind in ROUGH_KINDS:
        geo = TileGeometry(size=max(depth, width), bump_height=height, resolution=RESOLUTION)
        u, v, z = tile_surface(Tile("rough", 0, surface), geo, rng)
        return [((u - 0.5) * depth, (v - 0.5) * width, z)]
    if kind == "steps":
        n, tread = int(rec["steps"]), float(rec["tread"])
        geo = TileGeometry(size=1.0, level_height=height / n, resolution=0.5)
        out, x = [], -0.5 * depth
        for k in range(n):  # a step tile's riser is in its middle: the first tread starts half a tread in
            u, v, z = tile_surface(Tile("step_up", k, surface), geo, rng)
            out.append((x + u * tread, (v - 0.5) * width, z))
            x += tread
        u, v, z = tile_surface(Tile("flat", n, surface), geo, rng)
        out.append((x + u * (0.5 * depth - x), (v - 0.5) * width, z))
        return out
    u, v, z = tile_surface(Tile("flat", 0, surface), _COARSE, rng)
    return [((u - 0.5) * depth, (v - 0.5) * width, z)]


def _skirt(nx: int, ny: int, first: int) -> tuple[np.ndarray, list[int]]:
    """The border of an ny x nx grid (vertex j * nx + i), counter-clockwise seen from above, and the triangles of
    walls from it down to its feet (vertex `first` + k is the foot of the border's k-th vertex), facing outwards."""
    ring = (
        [(0, i) for i in range(nx)]
        + [(j, nx - 1) for j in range(1, ny)]
        + [(ny - 1, i) for i in range(nx - 2, -1, -1)]
        + [(j, 0) for j in range(ny - 2, 0, -1)]
    )
    border = np.array([j * nx + i for j, i in ring])
    tris: list[int] = []
    for k in range(len(ring)):  # outwards is to the right of a counter-clockwise border
        kk = (k + 1) % len(ring)
        a, b = int(border[k]), int(border[kk])
        tris += [a, first + k, first + kk, a, first + kk, b]
    return border, tris


def mesh(rec: Record) -> tuple[list[list[float]], list[int]]:
    """World vertices and triangles of the patch: its tile surfaces `LIFT` above the slab, with skirts."""
    base = float(rec["position"][2])
    verts: list[np.ndarray] = []
    tris: list[int] = []
    n = 0
    for x, y, z in pieces(rec):
        top, idx = grid_mesh(x, y, z)
        top_a = np.asarray(top, dtype=np.float64)
        border, walls = _skirt(len(x), len(y), len(top_a))
        foot = top_a[border]
        foot[:, 2] = -LIFT  # down to the slab top
        tris += [n + k for k in idx] + [n + k for k in walls]
        verts += [top_a, foot]
        n += len(top_a) + len(foot)
    v = np.concatenate(verts)
    world = np.column_stack([to_world(rec, v[:, :2]), base + LIFT + v[:, 2]])
    return world.tolist(), tris


def to_world(rec: Record, local: np.ndarray) -> np.ndarray:
    """World [N, 2] of points [N, 2] in the patch's local frame (x along `yaw`, origin at its centre)."""
    x0, y0 = float(rec["position"][0]), float(rec["position"][1])
    c, s = math.cos(float(rec["yaw"])), math.sin(float(rec["yaw"]))
    return np.column_stack([x0 + local[:, 0] * c - local[:, 1] * s, y0 + local[:, 0] * s + local[:, 1] * c])


def _corners(rec: Record, x_lo: float, x_hi: float) -> np.ndarray:
    """World corners [4, 2] of the part of the patch between local x_lo and x_hi (its whole width)."""
    hw = 0.5 * float(rec["size"][1])
    return to_world(rec, np.array([[x_lo, -hw], [x_hi, -hw], [x_hi, hw], [x_lo, hw]]))


def risers(rec: Record) -> list[float]:
    """Local x of a stair's risers, bottom up (none for other kinds)."""
    if rec["kind"] != "steps":
        return []
    x = -0.5 * float(rec["size"][0])
    tread = float(rec["tread"])
    return [x + (k + 0.5) * tread for k in range(int(rec["steps"]))]


def riser_lines(rec: Record) -> list[np.ndarray]:
    """World end points [2, 2] of each riser's top edge (the lines a map draws across a stair)."""
    return [_corners(rec, r, r)[[0, 3]] for r in risers(rec)]


def tops(rec: Record) -> list[tuple[np.ndarray, float]]:
    """(world corners [4, 2], height of the surface's highest point above the ground) of nested parts of the patch,
    lowest first: the whole patch, then for a stair the part above each riser. What a horizontal ray at a height
    below that top meets (the grid LiDAR's solids); a rough patch counts at its highest bump."""
    depth = float(rec["size"][0])
    base = float(rec["position"][2]) + LIFT
    bumps = float(rec["size"][2]) if rec["kind"] in ROUGH_KINDS else 0.0
    out = [(_corners(rec, -0.5 * depth, 0.5 * depth), base + bumps)]
    rs = risers(rec)
    for k, r in enumerate(rs, 1):
        out.append((_corners(rec, r, 0.5 * depth), base + k * float(rec["size"][2]) / len(rs)))
    return out


def friction(rec: Record) -> float:
    """The tyre friction coefficient of the patch's surface (sim.terrain.wfc.SURFACES)."""
    return SURFACES[rec["surface"]]


def check(rec: Any) -> str | None:
    """What is wrong with a terrain record (None when nothing): kind, surface, finite numbers, a stair's fields."""
    if not isinstance(rec, Mapping):
        return "must be a JSON object"
    if rec.get("kind") not in KINDS:
        return f"kind must be one of {', '.join(KINDS)}, got {rec.get('kind')!r}"
    if rec.get("surface") not in SURFACES:
        return f"surface must be one of {', '.join(SURFACES)}, got {rec.get('surface')!r}"
    try:
        pos, size = np.asarray(rec["position"], dtype=np.float64), np.asarray(rec["size"], dtype=np.float64)
        yaw = float(rec["yaw"])
    except (KeyError, TypeError, ValueError):
        return "needs position [x, y, z], yaw and size [depth, width, height] as numbers"
    if (
        pos.shape != (3,)
        or size.shape != (3,)
        or not (np.isfinite(pos).all() and np.isfinite(size).all() and math.isfinite(yaw))
        or size.min() < 0
    ):
        return "needs finite position [x, y, z], yaw and size [depth, width, height] (size >= 0)"
    if max(size[0], size[1]) > MAX_SIDE:
        return f"size must be at most {MAX_SIDE:g} m deep and wide, got {size[0]:g} x {size[1]:g}"
    seed = rec.get("seed", 0)
    if rec["kind"] in ROUGH_KINDS and (not isinstance(seed, int) or isinstance(seed, bool) or seed < 0):
        return f"seed (of the bumps) must be an integer >= 0, got {seed!r}"
    if rec["kind"] == "steps":
        n, tread = rec.get("steps"), rec.get("tread")
        if (
            not isinstance(n, int)
            or isinstance(n, bool)
            or not 1 <= n <= MAX_STEPS
            or not isinstance(tread, (int, float))
            or not 0 < tread
            or n * tread > size[0] + 1e-3
        ):
            return f"a stair needs steps (an integer 1 to {MAX_STEPS}) and a tread > 0 with steps x tread <= its depth"
    return None


class FrictionIndex:
    """The friction coefficient under a point: its patch's, or `default` off every patch (a 2 m cell hash)."""

    CELL = 2.0

    def __init__(self, records: Sequence[Record], default: float = math.inf) -> None:
        self.default = default
        self.rects: list[tuple[float, float, float, float, float, float, float]] = []
        self.cells: dict[tuple[int, int], list[int]] = {}
        for k, rec in enumerate(records):
            x, y = float(rec["position"][0]), float(rec["position"][1])
            d, w = 0.5 * float(rec["size"][0]), 0.5 * float(rec["size"][1])
            yaw = float(rec["yaw"])
            self.rects.append((x, y, math.cos(yaw), math.sin(yaw), d, w, friction(rec)))
            r = math.hypot(d, w)
            for i in range(int((x - r) // self.CELL), int((x + r) // self.CELL) + 1):
                for j in range(int((y - r) // self.CELL), int((y + r) // self.CELL) + 1):
                    self.cells.setdefault((i, j), []).append(k)

    def __call__(self, x: float, y: float) -> float:
        """The friction coefficient of the surface under (x, y)."""
        for k in self.cells.get((int(x // self.CELL), int(y // self.CELL)), ()):
            cx, cy, c, s, d, w, mu = self.rects[k]
            dx, dy = x - cx, y - cy
            if abs(dx * c + dy * s) <= d and abs(-dx * s + dy * c) <= w:
                return mu
        return self.default
