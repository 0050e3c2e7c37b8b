"""Static 2D LiDAR for many envs at once: sphere tracing through the distance grids of `sim.batched.grids`.

Every beam of every env marches from the machine's bounding circle (`Lidar.start_radius`) in one numpy pass per
iteration: a step as long as the grid's distance to the nearest obstacle (less a cell, at least half a cell),
until it lands in an occupied cell, reaches the range, or leaves the scene (the FAR ring). A hit's distance is then
bisected between the last free point and the first occupied one. The error against PyBullet's exact ray test is the
rasterisation's (a cell is occupied when its centre is inside a footprint: +-half a cell along a face, up to a
cell at corners) plus what the bisection leaves (an eighth of the last step); docs/batched.md gives the tolerance.

The grids of every scene the envs use sit in one flat array (`sim.batched.atlas.Atlas`), so that envs in different
scenes trace in the same pass.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sim.batched.atlas import Atlas
from sim.batched.grids import FAR, RING

MAX_ITERS = 120  # every beam ends well before (the least step grows after FINE_ITERS)
FINE_ITERS = 16  # iterations at the finest least step (half a cell)
GROWTH = 1.25  # then the least step grows by this factor an iteration
TOLERANCE = 0.25  # cells: a hit is bisected to within this
MAX_STEP = 32.0  # cells: the largest least step (below grids.RING, so no ray passes the ring)
assert MAX_STEP < RING


def _step_table(min_step: float) -> np.ndarray:
    """Step (cells) for each table value: 0 on an occupied cell and in the FAR ring (the ray stays), else the
    distance less one cell (a point anywhere in its cell is that far from any occupied cell), at least `min_step`."""
    e = np.arange(256, dtype=np.float32)
    lut = np.maximum(e - 1.0, np.float32(min_step))
    lut[0] = lut[FAR] = 0.0
    return lut


# The step tables of every iteration (the least step is a function of the iteration only).
STEP_TABLES = [_step_table(min(0.5 * GROWTH ** max(it - FINE_ITERS + 1, 0), MAX_STEP)) for it in range(MAX_ITERS)]


def trace(flat: np.ndarray, frame: dict[str, np.ndarray], x: np.ndarray, y: np.ndarray, angles: np.ndarray,
          start: float, range_m: float, resolution: float) -> np.ndarray:
    """Distances [n, beams] from each env's (x, y) along `angles` [n, beams] (world frame) to the first occupied
    cell, `range_m` when none; rays start `start` metres out. Every scene's grid has the same `resolution`.

    A beam that grazes a wall converges slowly (each step shrinks by the sine of the grazing angle), so after
    FINE_ITERS iterations the least step grows by GROWTH an iteration (up to MAX_STEP cells): such beams end in a
    few more iterations, and the bisection of the last step keeps their distance to a fraction of a cell.
    """
    n, beams = angles.shape
    inv = 1.0 / resolution
    a = angles.ravel()
    # Per ray: origin (cells), direction, its grid's width and start; compacted as rays end (separate 1-D arrays:
    # numpy compacts and computes on those fastest).
    ray = (np.repeat(((x - frame["x0"]) * inv).astype(np.float32), beams),
           np.repeat(((y - frame["y0"]) * inv).astype(np.float32), beams),
           np.cos(a).astype(np.float32), np.sin(a).astype(np.float32),
           np.repeat(frame["cols"].astype(np.int32), beams), np.repeat(frame["offset"].astype(np.int32), beams))
    reach = np.float32(range_m * inv)
    t = np.full(n * beams, np.float32(start * inv), dtype=np.float32)
    prev = t.copy()
    idx = np.arange(n * beams)
    act, tt, last = ray, t.copy(), prev.copy()
    for it in range(MAX_ITERS):
        step = STEP_TABLES[it][_values(flat, act, tt)]
        moving = step > 0
        last = np.where(moving, tt, last)  # the last free point (bisection starts there)
        tt = np.minimum(tt + step, reach)
        if it % 2 or it == MAX_ITERS - 1:
            done = ~moving | (tt >= reach)
            if done.any():
                t[idx], prev[idx] = tt, last
                keep = ~done
                idx = idx[keep]
                if idx.size == 0:
                    break
                act = tuple(v[keep] for v in act)
                tt, last = tt[keep], last[keep]
    else:
        t[idx], prev[idx] = tt, last
    end = _values(flat, ray, t)
    t[end == FAR] = reach  # left the scene: no hit
    hits = np.nonzero(end == 0)[0]
    k = hits[t[hits] - prev[hits] > TOLERANCE]
    _refine(flat, k, prev[k], t, tuple(v[k] for v in ray))
    return np.minimum(t.reshape(n, beams).astype(np.float64) * resolution, range_m)


def _values(flat: np.ndarray, ray: tuple[np.ndarray, ...], t: np.ndarray) -> np.ndarray:
    """Grid values at distance t (cells) along each ray."""
    gx, gy, dx, dy, cols, offset = ray
    return flat[offset + (gy + t * dy).astype(np.int32) * cols + (gx + t * dx).astype(np.int32)]


def _refine(flat: np.ndarray, k: np.ndarray, lo: np.ndarray, t: np.ndarray, ray: tuple[np.ndarray, ...]) -> None:
    """Bisect hits `k` between their last free point `lo` and their first occupied one `t[k]` until the two are
    TOLERANCE cells apart; the hit is then their midpoint (in place)."""
    hi = t[k]
    while k.size:
        mid = 0.5 * (lo + hi)
        occ = _values(flat, ray, mid) == 0
        hi = np.where(occ, mid, hi)
        lo = np.where(occ, lo, mid)
        t[k] = 0.5 * (lo + hi)
        more = hi - lo > TOLERANCE
        k, lo, hi = k[more], lo[more], hi[more]
        ray = tuple(v[more] for v in ray)


class BatchLidar:
    """One scan (high or low) of every env: beam angles, start radius, range, encoding (as `sim.sensors.Lidar`)."""

    def __init__(self, beams: int, range_m: float, start_radius: float, what: str, encoding: str = "linear") -> None:
        self.beams = beams
        self.range_m = float(range_m)
        self.start_radius = float(start_radius)
        self.what = what
        self.encoding = encoding
        self.angles = np.linspace(0.0, 2.0 * math.pi, beams, endpoint=False)

    def scan(self, atlas: Atlas, scene_ids: np.ndarray, level: np.ndarray, x: np.ndarray, y: np.ndarray,
             yaw: np.ndarray) -> np.ndarray:
        """Normalised distances [n, beams] (1 = no hit), encoded as the PyBullet env observes them."""
        frame = atlas.frames(scene_ids, level, self.what)
        d = trace(atlas.flat, frame, x, y, yaw[:, None] + self.angles[None], self.start_radius, self.range_m,
                  atlas.resolution)
        if self.encoding == "log":
            return (np.log1p(d) / math.log1p(self.range_m)).astype(np.float32)
        return (d / self.range_m).astype(np.float32)


def lidar_pair(cfg: dict[str, Any], bounding_radius: float) -> tuple[BatchLidar, BatchLidar | None]:
    """The high and (if low_beams) low scans of a PointNav config, with the start radii of `build_slot`."""
    lid = cfg["lidar"]
    r0 = bounding_radius + 0.05
    high = BatchLidar(int(lid["beams"]), float(lid["range"]), r0, "high", lid["encoding"])
    low = (BatchLidar(int(lid["low_beams"]), max(float(lid["low_range"]), r0 + 0.1), r0, "low")
           if int(lid["low_beams"]) else None)
    return high, low
