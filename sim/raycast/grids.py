"""A scene's static obstacles as distance grids at the heights the machine's LiDARs and body see (built once a scene).

The PyBullet world's static bodies that stop a horizontal ray at height H above the ground (sim/world.py): buildings
(6-18 m tall), objects (a box from their base z to z + height) when base <= H <= top, and raised sidewalks (0 to the
curb height, minus the curb ramps) when H <= curb height. Roads and crosswalks are visual only; the ground is below
every ray. Terrain patches (sim.terrain.patches) stop a scan below their top (a stair's steps; rough ground's bumps
stay below the scans) and a body at a stair (rough and slick ground is driven over). The machine's base sits on the
sidewalk top (the curb height) or on the road (0), its `level`; the high scan runs at base + `lidar.height`, the low
scan at base + `lidar.low_height`, and the body spans base to base + the machine's height. Each (level, what) is an
occupancy grid at `resolution` whose cells hold the distance to the nearest occupied cell in cells (chessboard,
`scipy.ndimage.distance_transform_cdt`: never more than the Euclidean distance, so a march step stays safe, and 3-4x
faster to build; 0 = occupied, capped at 254); a ring of RING cells around the grid holds 255, the value rays read
once they leave the scene (`sim.raycast.march`).

The batched env uses all three grids of both levels; the PyBullet env's `sim.sensors.GridLidar` the two scans only
(`body_height` None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np
from numba import njit
from scipy import ndimage
from shapely.geometry import Polygon

from sim.scene.grid import CROSSWALK, WalkableGrid, obstacle_mask, paint_many
from sim.scene.scene import Scene
from sim.terrain import patches
from sim.world import sidewalk_solids

FREE, OBJECT, BUILDING, CURB = 0, 1, 2, 3
# A free cell of a curb ramp whose surface lies more than the machine's wheel radius below the sidewalk top: from
# there the raised sidewalk beside the ramp (Bullet's wedge has flanks) is a step the wheels cannot climb, a curb as
# from the road (`build_grids`' step_max).
LOW_RAMP = 4
KIND_NAMES = {OBJECT: "object", BUILDING: "building", CURB: "curb"}
SIDEWALK_LEVEL, ROAD_LEVEL = 0, 1
WHAT = ("high", "low", "body")  # the grids of one level: high scan, low scan, the machine's body
MARGIN = 2.0  # metres of free grid around the scene's bounds
FAR = 255  # the ring's value: beyond the scene
RING = 2  # cells of FAR around the grid: a march reads them once it leaves the scene (it never jumps past the edge)


@dataclass
class SceneGrids:
    """The distance grids of one scene: `tables[level][k]` for k in WHAT (uint8, ring included)."""

    origin: tuple[float, float]  # world (x, y) of the ring's lower-left corner
    shape: tuple[int, int]  # rows, cols, ring included
    resolution: float
    kinds: np.ndarray  # FREE / OBJECT / BUILDING / CURB per cell (what a body contact there touches), or LOW_RAMP
    tables: list[list[np.ndarray]]
    walkable: WalkableGrid  # the scene's walkable grid (level, off-walkable)
    curb_height: float


def _footprints(
    scene: Scene,
) -> tuple[list[Polygon], list[tuple[float, float]], list[Polygon], list[Polygon], list[tuple[np.ndarray, np.ndarray]]]:
    """(object footprints, their (base, top) heights, building footprints, raised sidewalk slabs, ramp wedges)."""
    objects = [Polygon(o["footprint"]) for o in scene.objects]
    spans = []
    for o in scene.objects:
        z = float(o["position"][2])
        spans.append((z, z + max(float(o["size"][2]), 0.02)))
    buildings = [
        Polygon(z["polygon"]).buffer(0)
        for sw in scene.sidewalks
        for z in sw.get("zones", [])
        if z.get("kind") == "building"
    ]
    slabs, wedges = sidewalk_solids(scene, float(scene.curb_height))
    return objects, spans, buildings, [poly for polys in slabs for poly in polys], wedges


def _ramp_tops(grid: WalkableGrid, wedges: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Per cell, the height of the ramp surface above it (-inf where there is no ramp).

    A wedge is Bullet's convex hull of its top vertices (and their feet): its top over a point is the largest
    interpolation of the vertex heights over any triangle of vertices that holds the point."""
    top = np.full(grid.shape, -np.inf, dtype=np.float32)
    res, (x0, y0) = grid.resolution, grid.origin
    for pts, z in wedges:
        for tri in combinations(range(len(pts)), 3):
            p3, z3 = pts[list(tri)], z[list(tri)]
            m = np.column_stack([p3, np.ones(3)])
            if abs(np.linalg.det(m)) < 1e-9:
                continue
            plane = np.linalg.solve(m, z3)
            c0, r0 = (int(math.floor((v - o) / res)) - 1 for v, o in ((p3[:, 0].min(), x0), (p3[:, 1].min(), y0)))
            c1, r1 = (int(math.ceil((v - o) / res)) + 1 for v, o in ((p3[:, 0].max(), x0), (p3[:, 1].max(), y0)))
            r0, c0 = max(r0, 0), max(c0, 0)
            r1, c1 = min(r1, top.shape[0]), min(c1, top.shape[1])
            if r1 <= r0 or c1 <= c0:
                continue
            window = np.zeros((r1 - r0, c1 - c0), dtype=bool)
            paint_many(window, (x0 + c0 * res, y0 + r0 * res), res, [Polygon(p3)], True)
            rr, cc = np.nonzero(window)
            h = plane[0] * (x0 + (cc + c0 + 0.5) * res) + plane[1] * (y0 + (rr + r0 + 0.5) * res) + plane[2]
            view = top[r0:r1, c0:c1]
            view[rr, cc] = np.maximum(view[rr, cc], h)
    return top


def _terrain_tops(grid: WalkableGrid, scene: Scene) -> list[tuple[tuple[slice, slice], np.ndarray, bool]]:
    """Per terrain patch: its window of the grid, the height of its surface over each cell there (-inf off it),
    and whether it is a stair."""
    out = []
    res, (x0, y0), (h, w) = grid.resolution, grid.origin, grid.mask.shape
    for rec in scene.terrain:
        fp = np.asarray(rec["footprint"], dtype=np.float64)
        c0, r0 = (max(int(math.floor((v - o) / res)) - 1, 0) for v, o in ((fp[:, 0].min(), x0), (fp[:, 1].min(), y0)))
        c1 = min(int(math.ceil((fp[:, 0].max() - x0) / res)) + 1, w)
        r1 = min(int(math.ceil((fp[:, 1].max() - y0) / res)) + 1, h)
        if r1 <= r0 or c1 <= c0:
            continue
        parts = patches.tops(rec)  # lowest first: a stair's higher parts paint over its lower ones
        ids = np.full((r1 - r0, c1 - c0), len(parts), dtype=np.int8)
        for k, (corners, _) in enumerate(parts):
            paint_many(ids, (x0 + c0 * res, y0 + r0 * res), res, [Polygon(corners)], k)
        heights = np.array([top for _, top in parts] + [-np.inf], dtype=np.float32)
        out.append(((slice(r0, r1), slice(c0, c1)), heights[ids], rec["kind"] == "steps"))
    return out


def _distance(occupied: np.ndarray) -> np.ndarray:
    """uint8 distance (cells) to the nearest occupied cell or the grid's edge, capped below FAR, in the FAR ring.

    The edge counts as an obstacle so that steps shrink near it and every ray that leaves the scene stops in the
    ring instead of jumping past it."""
    free = ~occupied
    free[0, :] = free[-1, :] = False
    free[:, 0] = free[:, -1] = False
    # Chessboard distance: never more than the Euclidean one, so steps stay safe, and 3-4x faster to compute.
    d = ndimage.distance_transform_cdt(free, metric="chessboard")
    d = np.minimum(d, FAR - 1).astype(np.uint8)
    d[0, :] = d[-1, :] = 1  # the edge cells themselves are free
    d[:, 0] = d[:, -1] = 1
    d[occupied] = 0
    return np.pad(d, RING, constant_values=FAR)


def build_grids(
    scene: Scene,
    *,
    resolution: float,
    lidar: dict[str, Any],
    body_height: float | None,
    step_max: float | None = None,
    clearance: float = 0.0,
) -> SceneGrids:
    """The grids of `scene` for LiDAR heights `lidar["height"]`, `lidar["low_height"]` and (unless None) a body
    `body_height` tall whose wheels climb steps up to `step_max` (None: no LOW_RAMP cells in `kinds`) and whose
    colliding parts start `clearance` above the surface (a raycast vehicle's chassis floor: it drives over what is
    lower, curbs included)."""
    xmin, ymin, xmax, ymax = scene.bounds
    x0 = math.floor((xmin - MARGIN) / resolution) * resolution
    y0 = math.floor((ymin - MARGIN) / resolution) * resolution
    shape = (int(math.ceil((ymax + MARGIN - y0) / resolution)), int(math.ceil((xmax + MARGIN - x0) / resolution)))
    grid = WalkableGrid(mask=np.zeros(shape, dtype=np.uint8), origin=(x0, y0), resolution=resolution)
    objects, spans, buildings, raised, wedges = _footprints(scene)
    ramp_top = _ramp_tops(grid, wedges)
    kinds = np.zeros(shape, dtype=np.uint8)
    raised_mask = np.zeros(shape, dtype=bool)
    paint_many(raised_mask, grid.origin, resolution, raised, True)
    kinds[raised_mask] = CURB
    terrain = _terrain_tops(grid, scene)  # on the slab: a body meets a stair's riser as a curb (sim.world.touching)
    building_mask = np.zeros(shape, dtype=bool)
    paint_many(building_mask, grid.origin, resolution, buildings, True)
    kinds[building_mask] = BUILDING
    curb = float(scene.curb_height)

    def occupied(lo: float, hi: float) -> np.ndarray:
        """Cells blocked for anything between heights lo and hi (inclusive) above the ground."""
        occ = building_mask.copy()
        if lo <= curb:
            occ |= raised_mask
        if lo == hi:  # a scan: the ramps' slopes stop it where they are higher; a body drives up them
            occ |= ramp_top >= lo
        for win, top, stair in terrain:  # a scan stops at terrain above it, a body at a stair above its base
            if lo == hi or stair:
                occ[win] |= top >= lo if lo == hi else top > lo
        chosen = [p for p, (b, t) in zip(objects, spans) if b <= hi and lo <= t]
        if chosen:
            occ |= obstacle_mask(grid, chosen)
        return occ

    built: list[tuple[np.ndarray, np.ndarray]] = []

    def distance(occ: np.ndarray) -> np.ndarray:
        """`_distance` of `occ`, shared with an identical grid built before (the high scan usually sees the same
        solids from the sidewalk and from the road: one transform and one table fewer)."""
        for other, table in built:
            if np.array_equal(other, occ):
                return table
        built.append((occ, _distance(occ)))
        return built[-1][1]

    tables = []
    for base in (curb, 0.0):  # SIDEWALK_LEVEL, ROAD_LEVEL
        high = base + float(lidar["height"])
        low = base + float(lidar["low_height"])
        # The body rests on the surface (from base + 1 mm): a raised sidewalk under a sidewalk-level machine is its
        # floor, not a wall.
        level = [distance(occupied(high, high)), distance(occupied(low, low))]
        if body_height is not None:
            level.append(distance(occupied(base + max(clearance, 1e-3), base + body_height)))
        tables.append(level)
    objects_mask = obstacle_mask(grid, objects) if objects else np.zeros(shape, dtype=bool)
    kinds[objects_mask] = OBJECT
    if step_max is not None:
        kinds[(ramp_top < curb - step_max) & (ramp_top > -np.inf) & (kinds == FREE)] = LOW_RAMP
    return SceneGrids(
        origin=(x0 - RING * resolution, y0 - RING * resolution),
        shape=(shape[0] + 2 * RING, shape[1] + 2 * RING),
        resolution=resolution,
        kinds=np.pad(kinds, RING),
        tables=tables,
        walkable=scene.walkable,
        curb_height=curb,
    )


def levels(grids: SceneGrids, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The level of machines at (x, y): ROAD_LEVEL on a crosswalk, else SIDEWALK_LEVEL (ramps count as sidewalk)."""
    labels = walkable_labels(grids.walkable, x, y)
    return np.where(labels == CROSSWALK, ROAD_LEVEL, SIDEWALK_LEVEL)


@njit(cache=True)
def labels_at(
    masks: Any, origins: np.ndarray, resolutions: np.ndarray, scene_of: np.ndarray, x: np.ndarray, y: np.ndarray
) -> np.ndarray:  # pragma: no cover - numba
    """`walkable_labels` of many scenes in one pass: point k in the walkable grid masks[scene_of[k]] (a numba typed
    list of masks; origin origins[s], cell resolutions[s]); 0 off the grid or at a non-finite point."""
    out = np.zeros(x.size, dtype=np.int64)
    for k in range(x.size):
        s = scene_of[k]
        if not (np.isfinite(x[k]) and np.isfinite(y[k])):
            continue
        col = math.floor((x[k] - origins[s, 0]) / resolutions[s])
        row = math.floor((y[k] - origins[s, 1]) / resolutions[s])
        mask = masks[s]
        if 0 <= row < mask.shape[0] and 0 <= col < mask.shape[1]:
            out[k] = mask[int(row), int(col)]
    return out


def walkable_labels(walkable: WalkableGrid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Legend codes of the walkable grid under (x, y) (`WalkableGrid.label_at` for arrays; 0 outside)."""
    rc = walkable.world_to_cell(np.stack([x, y], -1))
    inside = walkable.inside(rc)
    rc = np.where(inside[:, None], rc, 0)
    return np.where(inside, walkable.mask[rc[:, 0], rc[:, 1]], 0)
