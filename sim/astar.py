"""A* between two cells of the route planner's grid graph (numba): `RoutePlanner.sample` and `RoutePlanner.plan`.

`RoutePlanner.sample` once ran Dijkstra from the start over every cell within 90 m (25,680 cells, 2.7 ms on the
bench scene, 1.6 tries a reset) to draw a goal among the cells it reached; an episode's reset took 5-7 ms, and in a
lock-step vector env every reset stalls the other cores that long (benchmarks/vector_envs.py). A* from start to one
drawn goal explores only the cells whose cost so far plus the octile distance left stays under the path's cost.
The octile distance (diagonal moves cost sqrt 2 cells) is the exact cost on an empty 8-connected grid, and every edge
costs at least its length (`sim.scene.grid.grid_graph`: length times a penalty >= 1), so the estimate never
overestimates and A* returns a shortest path.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numba import njit

_DIAG = math.sqrt(2.0) - 1.0
_SHRINK = 1.0 - 1e-9  # keeps the estimate below the true cost after float rounding


class CsrGraph(Protocol):
    """The arrays of a scipy CSR matrix (`sim.scene.grid.grid_graph`) that the search reads."""

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray


@njit(cache=True)
def _push(keys: np.ndarray, vals: np.ndarray, n: int, key: float, val: int) -> int:
    """Add (key, val) to the binary min-heap of size n; the new size."""
    i = n
    keys[i], vals[i] = key, val
    while i > 0:
        parent = (i - 1) // 2
        if keys[parent] <= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        vals[parent], vals[i] = vals[i], vals[parent]
        i = parent
    return n + 1


@njit(cache=True)
def _pop(keys: np.ndarray, vals: np.ndarray, n: int) -> int:
    """Remove the heap's root (read it from keys[0], vals[0] first); the new size."""
    n -= 1
    keys[0], vals[0] = keys[n], vals[n]
    i = 0
    while True:
        left, small = 2 * i + 1, i
        if left < n and keys[left] < keys[small]:
            small = left
        if left + 1 < n and keys[left + 1] < keys[small]:
            small = left + 1
        if small == i:
            return n
        keys[small], keys[i] = keys[i], keys[small]
        vals[small], vals[i] = vals[i], vals[small]
        i = small


@njit(cache=True)
def _astar(
    indptr: np.ndarray,
    indices: np.ndarray,
    weights: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    resolution: float,
    start: int,
    goal: int,
    limit: float,
    pred: np.ndarray,
) -> float:
    """Cost of a shortest path start -> goal (inf when over `limit`); `pred` (filled -1 by the caller) gets the
    predecessors along it."""
    n = rows.size
    cost = np.full(n, np.inf)
    done = np.zeros(n, dtype=np.bool_)
    keys = np.empty(weights.size + 1)
    vals = np.empty(weights.size + 1, dtype=np.int64)
    gr, gc = rows[goal], cols[goal]
    scale = resolution * _SHRINK
    cost[start] = 0.0
    size = _push(keys, vals, 0, 0.0, start)
    while size > 0:
        f, u = keys[0], vals[0]
        size = _pop(keys, vals, size)
        if done[u]:
            continue
        if f > limit:
            return np.inf
        if u == goal:
            return cost[u]
        done[u] = True
        for e in range(indptr[u], indptr[u + 1]):
            v = indices[e]
            c = cost[u] + weights[e]
            if c < cost[v]:
                cost[v] = c
                pred[v] = u
                dr, dc = abs(rows[v] - gr), abs(cols[v] - gc)
                h = scale * (max(dr, dc) + _DIAG * min(dr, dc))
                size = _push(keys, vals, size, c + h, v)
    return np.inf


def astar_chain(
    graph: CsrGraph, rows: np.ndarray, cols: np.ndarray, resolution: float, start: int, goal: int, limit: float
) -> tuple[float, list[int]]:
    """(cost, nodes start..goal) of a shortest path in the CSR `graph` over cells (rows, cols); (inf, []) when its
    cost exceeds `limit`."""
    pred = np.full(rows.size, -1, dtype=np.int64)
    cost = _astar(
        graph.indptr,
        graph.indices,
        graph.data,
        rows,
        cols,
        float(resolution),
        int(start),
        int(goal),
        float(limit),
        pred,
    )
    if not math.isfinite(cost):
        return cost, []
    chain = [int(goal)]
    while chain[-1] != start:
        chain.append(int(pred[chain[-1]]))
    return cost, chain[::-1]
