"""A scene's static obstacles as distance grids at the heights the machine's LiDARs and body see (built once a scene).

The PyBullet world's static bodies that stop a horizontal ray at height H above the ground (sim/world.py): buildings
(6-18 m tall), objects (a box from their base z to z + height) when base <= H <= top, and raised sidewalks (0 to the
curb height, minus the curb ramps) when H <= curb height. Roads and crosswalks are visual only; the ground is below
every ray. The machine's base sits on the sidewalk top (the curb height) or on the road (0), its `level`; the high
scan runs at base + `lidar.height`, the low scan at base + `lidar.low_height`, and the body spans base to base +
the machine's height. Each (level, what) is an occupancy grid at `resolution` whose cells hold the distance to the
nearest occupied cell in cells (Euclidean, `scipy.ndimage.distance_transform_edt`; 0 = occupied, capped at 254);
a one-cell ring around the grid holds 255, the value rays read once they leave the scene (`sim.batched.lidar`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage
from shapely.geometry import Polygon

from sim.scene.grid import CROSSWALK, WalkableGrid, obstacle_mask, paint_many
from sim.scene.scene import Scene

FREE, OBJECT, BUILDING, CURB = 0, 1, 2, 3
KIND_NAMES = {OBJECT: "object", BUILDING: "building", CURB: "curb"}
SIDEWALK_LEVEL, ROAD_LEVEL = 0, 1
WHAT = ("high", "low", "body")  # the grids of one level: high scan, low scan, the machine's body
MARGIN = 2.0  # metres of free grid around the scene's bounds
FAR = 255  # the ring's value: beyond the scene
RING = 48  # cells of FAR around the grid: deeper than any step (`sim.batched.lidar.MAX_STEP`), so no ray passes it


@dataclass
class SceneGrids:
    """The distance grids of one scene: `tables[level][k]` for k in WHAT (uint8, ring included)."""

    origin: tuple[float, float]  # world (x, y) of the ring's lower-left corner
    shape: tuple[int, int]  # rows, cols, ring included
    resolution: float
    kinds: np.ndarray  # FREE / OBJECT / BUILDING / CURB per cell (what a body contact there touches)
    tables: list[list[np.ndarray]]
    walkable: WalkableGrid  # the scene's walkable grid (level, off-walkable)
    curb_height: float


def _footprints(scene: Scene) -> tuple[list[Polygon], list[tuple[float, float]], list[Polygon], list[Polygon]]:
    """(object footprints, their (base, top) heights, building footprints, raised sidewalk footprints)."""
    objects = [Polygon(o["footprint"]) for o in scene.objects]
    spans = []
    for o in scene.objects:
        z = float(o["position"][2])
        spans.append((z, z + max(float(o["size"][2]), 0.02)))
    buildings = [Polygon(z["polygon"]).buffer(0) for sw in scene.sidewalks for z in sw.get("zones", [])
                 if z.get("kind") == "building"]
    ramps = [Polygon(r["polygon"]).buffer(0.06, join_style="mitre") for cw in scene.crosswalks for r in cw.get("ramps", [])]
    raised = []
    for sw in scene.sidewalks:
        geom = Polygon(sw["polygon"]).buffer(0)
        for ramp in ramps:
            geom = geom.difference(ramp)
        raised.append(geom)
    return objects, spans, buildings, raised


def _distance(occupied: np.ndarray) -> np.ndarray:
    """uint8 distance (cells) to the nearest occupied cell or the grid's edge, capped below FAR, in the FAR ring.

    The edge counts as an obstacle so that steps shrink near it and every ray that leaves the scene stops in the
    ring instead of jumping past it."""
    free = ~occupied
    free[0, :] = free[-1, :] = False
    free[:, 0] = free[:, -1] = False
    d = ndimage.distance_transform_edt(free)
    d = np.minimum(np.floor(d), FAR - 1).astype(np.uint8)
    d[0, :] = d[-1, :] = 1  # the edge cells themselves are free
    d[:, 0] = d[:, -1] = 1
    d[occupied] = 0
    return np.pad(d, RING, constant_values=FAR)


def build_grids(scene: Scene, *, resolution: float, lidar: dict[str, Any], body_height: float) -> SceneGrids:
    """The grids of `scene` for LiDAR heights `lidar["height"]`, `lidar["low_height"]` and a body `body_height` tall."""
    xmin, ymin, xmax, ymax = scene.bounds
    x0 = math.floor((xmin - MARGIN) / resolution) * resolution
    y0 = math.floor((ymin - MARGIN) / resolution) * resolution
    shape = (int(math.ceil((ymax + MARGIN - y0) / resolution)), int(math.ceil((xmax + MARGIN - x0) / resolution)))
    grid = WalkableGrid(mask=np.zeros(shape, dtype=np.uint8), origin=(x0, y0), resolution=resolution)
    objects, spans, buildings, raised = _footprints(scene)
    kinds = np.zeros(shape, dtype=np.uint8)
    raised_mask = np.zeros(shape, dtype=bool)
    paint_many(raised_mask, grid.origin, resolution, raised, True)
    kinds[raised_mask] = CURB
    building_mask = np.zeros(shape, dtype=bool)
    paint_many(building_mask, grid.origin, resolution, buildings, True)
    kinds[building_mask] = BUILDING
    curb = float(scene.curb_height)

    def occupied(lo: float, hi: float) -> np.ndarray:
        """Cells blocked for anything between heights lo and hi (inclusive) above the ground."""
        occ = building_mask.copy()
        if lo <= curb:
            occ |= raised_mask
        chosen = [p for p, (b, t) in zip(objects, spans) if b <= hi and lo <= t]
        if chosen:
            occ |= obstacle_mask(grid, chosen)
        return occ

    tables = []
    for base in (curb, 0.0):  # SIDEWALK_LEVEL, ROAD_LEVEL
        high = base + float(lidar["height"])
        low = base + float(lidar["low_height"])
        # The body rests on the surface: a raised sidewalk under a sidewalk-level machine is its floor, not a wall.
        body = occupied(base + 1e-3, base + body_height)
        tables.append([_distance(occupied(high, high)), _distance(occupied(low, low)), _distance(body)])
    objects_mask = obstacle_mask(grid, objects) if objects else np.zeros(shape, dtype=bool)
    kinds[objects_mask] = OBJECT
    return SceneGrids(origin=(x0 - RING * resolution, y0 - RING * resolution),
                      shape=(shape[0] + 2 * RING, shape[1] + 2 * RING),
                      resolution=resolution, kinds=np.pad(kinds, RING), tables=tables, walkable=scene.walkable,
                      curb_height=curb)


def levels(grids: SceneGrids, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The level of machines at (x, y): ROAD_LEVEL on a crosswalk, else SIDEWALK_LEVEL (ramps count as sidewalk)."""
    labels = walkable_labels(grids.walkable, x, y)
    return np.where(labels == CROSSWALK, ROAD_LEVEL, SIDEWALK_LEVEL)


def walkable_labels(walkable: WalkableGrid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Legend codes of the walkable grid under (x, y) (`WalkableGrid.label_at` for arrays; 0 outside)."""
    rc = walkable.world_to_cell(np.stack([x, y], -1))
    inside = walkable.inside(rc)
    rc = np.where(inside[:, None], rc, 0)
    return np.where(inside, walkable.mask[rc[:, 0], rc[:, 1]], 0)
