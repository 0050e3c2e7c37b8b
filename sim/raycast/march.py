"""Static 2D LiDAR rays: marching through the distance grids of `sim.raycast.grids`.

Every ray (of one env or of many) marches from the machine's bounding circle (`Lidar.start_radius`) in a numba
kernel (one loop over rays, on every core when a call has PARALLEL_RAYS or more; each ray's march is independent, so
the result does not depend on the thread count). Away from obstacles a ray jumps by its cell's distance less one
cell: no cell it passes can be occupied (a point anywhere in its cell is at least that far from any occupied cell).
Next to an obstacle (distance 1) it walks cell by cell across the grid lines (Amanatides and Woo's traversal), so
it never steps over a thin object however closely it grazes a wall. It ends in the first occupied cell it enters,
when it reaches the range, or when it leaves the scene (the FAR ring). The hit is the point where the ray enters
that cell: exact after a cell walk, bisected to within TOLERANCE cells after a jump. The error against PyBullet's
exact ray test is the rasterisation's (a cell is occupied when its centre is inside a footprint: +-half a cell along
a face, up to a cell at corners); docs/raycast.md gives the tolerance.

`trace` reads grids from one flat array with per-ray offsets: the batched env packs every scene's grids in it
(`sim.batched.atlas.Atlas`), so that envs in different scenes trace in the same call; the PyBullet env's
`sim.sensors.GridLidar` passes one scene's grid.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from sim.raycast.grids import FAR

TOLERANCE = 0.25  # cells: a hit reached by a jump is bisected to within this
PARALLEL_RAYS = 4096  # rays per call from which the march runs on every core (numba threads; each ray alone)
NUDGE = 1e-6  # cells past a grid line, so that a walk step lands inside the next cell


def trace(
    flat: np.ndarray,
    frame: dict[str, np.ndarray],
    x: np.ndarray,
    y: np.ndarray,
    angles: np.ndarray,
    start: float,
    range_m: float,
    resolution: float,
) -> np.ndarray:
    """Distances [n, beams] from each env's (x, y) along `angles` [n, beams] (world frame) to the first occupied
    cell, exactly `range_m` when none; rays start `start` metres out. Every scene's grid has the same `resolution`.
    """
    if not (np.isfinite(x).all() and np.isfinite(y).all() and np.isfinite(angles).all()):
        raise ValueError("LiDAR origin or beam angles hold NaN or inf: the machine's pose is not finite")
    n, beams = angles.shape
    inv = 1.0 / resolution
    a = angles.ravel()
    out = np.empty(n * beams, dtype=np.float64)
    kernel = _trace_parallel if n * beams >= PARALLEL_RAYS else _trace_serial
    reach = range_m * inv
    kernel(
        flat,
        np.repeat((x - frame["x0"]) * inv, beams),
        np.repeat((y - frame["y0"]) * inv, beams),
        np.cos(a),
        np.sin(a),
        np.repeat(frame["cols"].astype(np.int64), beams),
        np.repeat(frame["offset"].astype(np.int64), beams),
        start * inv,
        reach,
        out,
    )
    d = out.reshape(n, beams) * resolution
    d[out.reshape(n, beams) >= reach] = range_m  # no hit: the range itself, not its float round trip
    return d


def trace_fan(
    flat: np.ndarray,
    x0: float,
    y0: float,
    cols: int,
    x: float,
    y: float,
    cos: np.ndarray,
    sin: np.ndarray,
    start: float,
    range_m: float,
    resolution: float,
) -> np.ndarray:
    """`trace` of one origin (x, y) with the beams' direction cosines given: distances [beams] through the grid of
    origin (x0, y0) and `cols` columns at the start of `flat` (the PyBullet env's LiDAR, which also needs cos and
    sin for its moving bodies)."""
    if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(cos).all() and np.isfinite(sin).all()):
        raise ValueError("LiDAR origin or beam angles hold NaN or inf: the machine's pose is not finite")
    inv = 1.0 / resolution
    reach = range_m * inv
    out = np.empty(cos.size, dtype=np.float64)
    _trace_origin(flat, (x - x0) * inv, (y - y0) * inv, cos, sin, cols, start * inv, reach, out)
    d = out * resolution
    d[out >= reach] = range_m  # no hit: the range itself, not its float round trip
    return d


@njit(cache=True, nogil=True)
def _cell(flat: np.ndarray, gx: float, gy: float, dx: float, dy: float, cols: int, offset: int, t: float) -> int:
    """Grid value at distance t (cells) along a ray. The FAR ring keeps a ray from inside the grid in it; a point off
    the grid (a machine that has left the scene, or whose rays start past the ring) reads the nearest column of its
    row, and no read leaves `flat`, so a stray origin costs a wrong reading, never memory outside the array."""
    col = int(gx + t * dx)
    if col < 0:
        col = 0
    elif col >= cols:
        col = cols - 1
    idx = offset + int(gy + t * dy) * cols + col
    if idx < 0:
        idx = 0
    elif idx >= flat.size:
        idx = flat.size - 1
    return flat[idx]


@njit(cache=True, nogil=True)
def _next_line(g: float, d: float, t: float) -> float:
    """Distance along the ray (cells) at which coordinate g + t d next crosses a grid line (inf when d is 0)."""
    if d > 0.0:
        return (np.floor(g + t * d) + 1.0 - g) / d
    if d < 0.0:
        return (np.floor(g + t * d) - g) / d
    return np.inf


@njit(cache=True, nogil=True)
def _trace_one(
    flat: np.ndarray, gx: float, gy: float, dx: float, dy: float, cols: int, offset: int, start: float, reach: float
) -> float:
    """March one ray (in cells): the distance at which it enters its first occupied cell, `reach` for none."""
    t = start
    last = start
    walked = False  # whether the ray reached t by a cell walk (t is then the cell's entry point)
    # A jump advances at least a cell and a walk step crosses a grid line (at most 2 per cell of length): a ray
    # that has not ended after 3 reach iterations cannot hit anything within range.
    for _ in range(3 * int(reach) + 8):
        v = _cell(flat, gx, gy, dx, dy, cols, offset, t)
        if v == 0 or v == FAR:
            break
        last = t
        if v >= 2:
            t = t + (v - 1.0)
            walked = False
        else:
            t = min(_next_line(gx, dx, t), _next_line(gy, dy, t)) + NUDGE
            walked = True
        if t >= reach:
            return reach
    else:
        return reach
    if v == FAR:  # left the scene: no hit
        return reach
    if walked or t - last <= TOLERANCE:
        return t
    lo, hi = last, t  # the jump landed inside an obstacle: bisect back to where it entered
    while hi - lo > TOLERANCE:
        mid = 0.5 * (lo + hi)
        if _cell(flat, gx, gy, dx, dy, cols, offset, mid) == 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True)
def _trace_serial(
    flat: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    cols: np.ndarray,
    offset: np.ndarray,
    start: float,
    reach: float,
    out: np.ndarray,
) -> None:
    """`_trace_one` of every ray (arrays over rays) into `out`, on this thread."""
    for r in range(out.size):
        out[r] = _trace_one(flat, gx[r], gy[r], dx[r], dy[r], cols[r], offset[r], start, reach)


@njit(cache=True, nogil=True, parallel=True)
def _trace_parallel(
    flat: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    cols: np.ndarray,
    offset: np.ndarray,
    start: float,
    reach: float,
    out: np.ndarray,
) -> None:
    """`_trace_one` of every ray into `out`, the rays shared among numba's threads."""
    for r in prange(out.size):
        out[r] = _trace_one(flat, gx[r], gy[r], dx[r], dy[r], cols[r], offset[r], start, reach)


@njit(cache=True, nogil=True)
def _trace_origin(
    flat: np.ndarray,
    gx: float,
    gy: float,
    dx: np.ndarray,
    dy: np.ndarray,
    cols: int,
    start: float,
    reach: float,
    out: np.ndarray,
) -> None:
    """`_trace_one` of every ray from one origin (grid coordinates) into `out`, on this thread."""
    for r in range(out.size):
        out[r] = _trace_one(flat, gx, gy, dx[r], dy[r], cols, 0, start, reach)
