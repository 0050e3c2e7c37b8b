"""Numba kernels of the crowd's tick: grid look-ups, goal progress and the carrot each agent steers at.

With ~20 agents a tick was ~200 small numpy calls (~0.4 ms); these loops do the float operations of the numpy
code they replaced in the same order (no fastmath), so agents move bit for bit as before
(tests/sim/agents/test_socialnav_golden.py holds them to it). Branches that run rarely (arrivals, new goals,
side-steps, pushes) stay in numpy/Python beside them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _cell(x: float, y: float, ox: float, oy: float, res: float, h: int, w: int):  # pragma: no cover - numba
    """(row, col, inside) of world point (x, y): floor of its grid coordinates, clipped to the grid."""
    fx, fy = (x - ox) / res, (y - oy) / res
    inside = fx >= 0 and fx < w and fy >= 0 and fy < h
    j = int(min(max(math.floor(fx), 0.0), w - 1.0))
    i = int(min(max(math.floor(fy), 0.0), h - 1.0))
    return i, j, inside


@njit(cache=True, nogil=True, error_model="numpy")
def nearest_nodes(
    xy: np.ndarray, ox: float, oy: float, res: float, nearest_rc: np.ndarray, node_of: np.ndarray
) -> np.ndarray:  # pragma: no cover - numba
    """Graph node nearest to each world point [n, 2] (NavGrid.nearest_node)."""
    h, w = node_of.shape
    out = np.empty(xy.shape[0], dtype=node_of.dtype)
    for k in range(xy.shape[0]):
        i, j, _ = _cell(xy[k, 0], xy[k, 1], ox, oy, res, h, w)
        out[k] = node_of[nearest_rc[0, i, j], nearest_rc[1, i, j]]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def cell_values(xy: np.ndarray, ox: float, oy: float, res: float, grid: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Values of `grid` at the cells holding world points [n, 2], clipped to the grid (NavGrid.cell_of)."""
    h, w = grid.shape
    out = np.empty(xy.shape[0], dtype=grid.dtype)
    for k in range(xy.shape[0]):
        i, j, _ = _cell(xy[k, 0], xy[k, 1], ox, oy, res, h, w)
        out[k] = grid[i, j]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def on_mask(xy: np.ndarray, ox: float, oy: float, res: float, mask: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Whether world points [n, 2] lie inside the grid on a True cell of `mask` (NavGrid.is_walkable / is_free)."""
    h, w = mask.shape
    out = np.empty(xy.shape[0], dtype=np.bool_)
    for k in range(xy.shape[0]):
        i, j, inside = _cell(xy[k, 0], xy[k, 1], ox, oy, res, h, w)
        out[k] = inside and mask[i, j]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def idle_tick(movement: np.ndarray, idle_left: np.ndarray, dt: float, idle: int) -> np.ndarray:  # pragma: no cover
    """Count `dt` off the idle agents' `idle_left` (in place); returns the idle agents whose time is up."""
    done = np.zeros(movement.size, dtype=np.bool_)
    for i in range(movement.size):
        if movement[i] == idle:
            idle_left[i] -= dt
            done[i] = idle_left[i] <= 0
    return np.flatnonzero(done)


@njit(cache=True, nogil=True, error_model="numpy")
def progress(
    moving: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    nodes: np.ndarray,
    site: np.ndarray,
    dist_table: np.ndarray,
    stall: np.ndarray,
    best: np.ndarray,
    arrive_radius: float,
    crowded_radius: float,
    stuck_steps: int,
    stuck_progress: float,
    regoal_steps: int,
):  # pragma: no cover
    """Arrivals, progress and stall counts of the moving agents (crowd_goals.update_goals): updates `stall` and
    `best` in place; returns (arrived, abandon) masks over `moving`."""
    k_n = moving.size
    arrived = np.zeros(k_n, dtype=np.bool_)
    abandon = np.zeros(k_n, dtype=np.bool_)
    for k in range(k_n):
        i = moving[k]
        dx, dy = pos[i, 0] - goal[i, 0], pos[i, 1] - goal[i, 1]
        to_goal = math.sqrt(dx * dx + dy * dy)
        st = stall[i]
        arr = to_goal < arrive_radius or (to_goal < crowded_radius and st >= stuck_steps // 2)
        d = dist_table[site[i], nodes[i]]
        progressed = d < best[i] - stuck_progress
        if not arr and progressed:
            stall[i], best[i] = 0, d
        elif not arr:  # held: no progress
            stall[i] = st + 1
            if st + 1 == stuck_steps:  # the side-step begins: its progress counts from here
                best[i] = d
            abandon[k] = st + 1 >= regoal_steps
        arrived[k] = arr
    return arrived, abandon


@njit(cache=True, nogil=True, error_model="numpy")
def carrots(
    idx: np.ndarray,
    nodes: np.ndarray,
    pos: np.ndarray,
    site: np.ndarray,
    jump: np.ndarray,
    centres: np.ndarray,
    keep_right: float,
    ox: float,
    oy: float,
    res: float,
    free: np.ndarray,
) -> np.ndarray:  # pragma: no cover - numba
    """The carrot of agents `idx` (at `nodes`): the cell `jump` steps ahead on the own goal field, shifted
    `keep_right` m to the right of the way there when that point is a planning cell."""
    h, w = free.shape
    out = np.empty((idx.size, 2))
    for k in range(idx.size):
        i = idx[k]
        c = centres[jump[site[i], nodes[k]]]
        cx, cy = c[0], c[1]
        dx, dy = cx - pos[i, 0], cy - pos[i, 1]
        norm = max(math.sqrt(dx * dx + dy * dy), 1e-6)
        sx, sy = cx + dy / norm * keep_right, cy + -dx / norm * keep_right
        ci, cj, inside = _cell(sx, sy, ox, oy, res, h, w)
        if inside and free[ci, cj]:
            cx, cy = sx, sy
        out[k, 0], out[k, 1] = cx, cy
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def headings(
    idx: np.ndarray,
    nodes: np.ndarray,
    pos: np.ndarray,
    carrot: np.ndarray,
    goal: np.ndarray,
    site: np.ndarray,
    dist_table: np.ndarray,
    speed: np.ndarray,
    near_goal: float,
):  # pragma: no cover
    """Unit directions [k, 2] at the carrots (at the own goal near the goal site) and speeds (slowing within
    0.3 m of the goal) of agents `idx`."""
    direction = np.empty((idx.size, 2))
    out_speed = np.empty(idx.size)
    for k in range(idx.size):
        i = idx[k]
        gx, gy = goal[i, 0], goal[i, 1]
        cx, cy = carrot[k, 0], carrot[k, 1]
        if dist_table[site[i], nodes[k]] < near_goal:
            cx, cy = gx, gy
        dx, dy = cx - pos[i, 0], cy - pos[i, 1]
        norm = math.sqrt(dx * dx + dy * dy)
        if norm > 1e-6:
            m = max(norm, 1e-6)
            direction[k, 0], direction[k, 1] = dx / m, dy / m
        else:
            direction[k, 0], direction[k, 1] = 0.0, 0.0
        ex, ey = gx - pos[i, 0], gy - pos[i, 1]
        out_speed[k] = min(speed[i], max(math.sqrt(ex * ex + ey * ey), 0.3))
    return direction, out_speed


@njit(cache=True, nogil=True, error_model="numpy")
def rungs(nodes: np.ndarray, sites: np.ndarray, jump: np.ndarray, centres: np.ndarray, top: int) -> np.ndarray:
    """Path cells [rung, k, 2] 2^top, ..., 2, 1 cells ahead of `nodes` toward `sites` (jump: [2^j, site, node])."""
    out = np.empty((top + 1, nodes.size, 2))
    for r in range(top + 1):
        for k in range(nodes.size):
            c = centres[jump[top - r, sites[k], nodes[k]]]
            out[r, k, 0], out[r, k, 1] = c[0], c[1]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def box_gaps(pos: np.ndarray, x: float, y: float, c: float, s: float, half_l: float, half_w: float):  # pragma: no cover
    """Per point [n, 2], its distances (ex, ey) outside a rectangle centred at (x, y) with axes (c, s) and half
    sizes (half_l, half_w), along the rectangle's axes (0 inside its extent)."""
    n = pos.shape[0]
    ex, ey = np.empty(n), np.empty(n)
    for k in range(n):
        dx, dy = pos[k, 0] - x, pos[k, 1] - y
        ex[k] = max(abs(c * dx + s * dy) - half_l, 0.0)
        ey[k] = max(abs(-s * dx + c * dy) - half_w, 0.0)
    return ex, ey
