"""Static 2D LiDAR rays: sphere tracing through the distance grids of `sim.raycast.grids`.

Every ray (of one env or of many) marches from the machine's bounding circle (`Lidar.start_radius`) in a numba kernel (one
loop over rays, on every core when a call has PARALLEL_RAYS or more; each ray's march is independent, so the result
does not depend on the thread count): a step as long as the grid's distance to the nearest obstacle (less a cell, at
least half a cell),
until it lands in an occupied cell, reaches the range, or leaves the scene (the FAR ring). A hit's distance is then
bisected between the last free point and the first occupied one. The error against PyBullet's exact ray test is the
rasterisation's (a cell is occupied when its centre is inside a footprint: +-half a cell along a face, up to a
cell at corners) plus what the bisection leaves (an eighth of the last step); docs/raycast.md gives the tolerance.

`trace` reads grids from one flat array with per-ray offsets: the batched env packs every scene's grids in it
(`sim.batched.atlas.Atlas`), so that envs in different scenes trace in the same call; the PyBullet env's
`sim.sensors.GridLidar` passes one scene's grid.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from sim.raycast.grids import FAR, RING

MAX_ITERS = 120  # every beam ends well before (the least step grows after FINE_ITERS)
FINE_ITERS = 16  # iterations at the finest least step (half a cell)
GROWTH = 1.25  # then the least step grows by this factor an iteration
TOLERANCE = 0.25  # cells: a hit is bisected to within this
PARALLEL_RAYS = 4096  # rays per call from which the march runs on every core (numba threads; each ray alone)
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
    out = np.empty(n * beams, dtype=np.float32)
    kernel = _trace_parallel if n * beams >= PARALLEL_RAYS else _trace_serial
    kernel(flat, STEP_TABLE,
                np.repeat(((x - frame["x0"]) * inv).astype(np.float32), beams),
                np.repeat(((y - frame["y0"]) * inv).astype(np.float32), beams),
                np.cos(a).astype(np.float32), np.sin(a).astype(np.float32),
                np.repeat(frame["cols"].astype(np.int64), beams), np.repeat(frame["offset"].astype(np.int64), beams),
                np.float32(start * inv), np.float32(range_m * inv), out)
    return np.minimum(out.reshape(n, beams).astype(np.float64) * resolution, range_m)


STEP_TABLE = np.stack(STEP_TABLES)  # [MAX_ITERS, 256]: the kernel's view of the step tables


@njit(cache=True, nogil=True)
def _cell(flat: np.ndarray, gx: float, gy: float, dx: float, dy: float, cols: int, offset: int, t: float) -> int:
    """Grid value at distance t (cells) along a ray (coordinates are positive: the FAR ring keeps rays inside)."""
    return flat[offset + np.int64(gy + t * dy) * cols + np.int64(gx + t * dx)]


@njit(cache=True, nogil=True)
def _trace_one(flat: np.ndarray, table: np.ndarray, gx: float, gy: float, dx: float, dy: float, cols: int,
               offset: int, start: np.float32, reach: np.float32) -> np.float32:
    """Sphere-trace one ray (in cells): the march, then the bisection of a hit's last step down to TOLERANCE cells
    (the hit is the final bracket's midpoint); `reach` when it hits nothing in range."""
    t = start
    last = start
    for it in range(MAX_ITERS):
        step = table[it, _cell(flat, gx, gy, dx, dy, cols, offset, t)]
        if step <= 0:
            break
        last = t
        t = min(t + step, reach)
        if t >= reach:
            return reach
    end = _cell(flat, gx, gy, dx, dy, cols, offset, t)
    if end == FAR:  # left the scene: no hit
        return reach
    tol = np.float32(TOLERANCE)
    if end == 0 and t - last > tol:
        lo, hi = last, t
        while hi - lo > tol:
            mid = np.float32(0.5) * (lo + hi)
            if _cell(flat, gx, gy, dx, dy, cols, offset, mid) == 0:
                hi = mid
            else:
                lo = mid
        t = np.float32(0.5) * (lo + hi)
    return t


@njit(cache=True, nogil=True)
def _trace_serial(flat: np.ndarray, table: np.ndarray, gx: np.ndarray, gy: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                  cols: np.ndarray, offset: np.ndarray, start: np.float32, reach: np.float32, out: np.ndarray) -> None:
    """`_trace_one` of every ray (arrays over rays) into `out`, on this thread."""
    for r in range(out.size):
        out[r] = _trace_one(flat, table, gx[r], gy[r], dx[r], dy[r], cols[r], offset[r], start, reach)


@njit(cache=True, nogil=True, parallel=True)
def _trace_parallel(flat: np.ndarray, table: np.ndarray, gx: np.ndarray, gy: np.ndarray, dx: np.ndarray,
                    dy: np.ndarray, cols: np.ndarray, offset: np.ndarray, start: np.float32, reach: np.float32,
                    out: np.ndarray) -> None:
    """`_trace_one` of every ray into `out`, the rays shared among numba's threads."""
    for r in prange(out.size):
        out[r] = _trace_one(flat, table, gx[r], gy[r], dx[r], dy[r], cols[r], offset[r], start, reach)
