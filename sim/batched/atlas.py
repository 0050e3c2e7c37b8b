"""The grids of every scene the envs use, packed in one flat uint8 array with per-scene offsets and frames, so that
one numpy gather reads any env's cells whatever its scene (`sim.batched.lidar` traces through it via `sim.raycast.march`, the env's
collision test reads the body and kind grids through it).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sim.raycast.grids import WHAT, SceneGrids

KINDS = len(WHAT)  # the kind grid's index after the level tables


class Atlas:
    """Scene slots (`add` returns one, `remove` frees it) and, per slot, where each grid starts in `flat`.

    Each scene's tables are copied once into a region of `flat` (the first free gap that fits, else the end, the
    buffer growing in place by at least half its size); the scene's own arrays are not kept, so a scene's grids are held once.
    Scenes of different sizes coming and going leave gaps too small for the next one: when a scene would end past
    the cells the tracer can index, the regions in use are first moved down together (`_compact`), so only the
    scenes in use count against that limit.
    """

    max_cells = 2**31 - 1  # the tracer indexes `flat` with int32 offsets

    def __init__(self, resolution: float) -> None:
        self.resolution = float(resolution)
        self.flat = np.zeros(0, dtype=np.uint8)
        self.used = 0  # cells of `flat` up to the end of the last region
        self.regions: list[tuple[int, int] | None] = []  # per slot: (start, cells), None when free
        self.offset = np.zeros((0, 2, KINDS + 1), dtype=np.int64)  # slot, level, table (KINDS: the kind grid)
        self.x0 = np.zeros(0)
        self.y0 = np.zeros(0)
        self.cols = np.ones(0, dtype=np.int64)
        self.rows = np.ones(0, dtype=np.int64)

    def add(self, grids: SceneGrids) -> int:
        """A slot for one scene's grids (a freed slot first); the grids are copied into `flat`."""
        if grids.resolution != self.resolution:
            raise ValueError(f"grids at {grids.resolution} m in an atlas of {self.resolution} m cells")
        tables = [
            (level, j, table) for level, level_tables in enumerate(grids.tables) for j, table in enumerate(level_tables)
        ] + [(0, KINDS, grids.kinds)]
        cells = sum(t.size for _, _, t in tables)
        start = self._place(cells)
        free = [k for k, r in enumerate(self.regions) if r is None]
        slot = free[0] if free else self._grow_slots()
        self.regions[slot] = (start, cells)
        at = start
        for level, j, table in tables:
            self.flat[at : at + table.size] = table.ravel()
            self.offset[slot, level, j] = at
            at += table.size
        self.offset[slot, 1, KINDS] = self.offset[slot, 0, KINDS]  # one kind grid for both levels
        self.x0[slot], self.y0[slot] = grids.origin
        self.rows[slot], self.cols[slot] = grids.shape
        return slot

    def remove(self, slot: int) -> None:
        """Free a slot (its scene is no longer used by any env); its region is reused by later scenes."""
        self.regions[slot] = None
        self.used = max((s + n for r in self.regions if r is not None for s, n in [r]), default=0)

    def _grow_slots(self) -> int:
        self.regions.append(None)
        self.offset = np.concatenate([self.offset, np.zeros((1, 2, KINDS + 1), dtype=np.int64)])
        self.x0, self.y0 = np.append(self.x0, 0.0), np.append(self.y0, 0.0)
        self.cols, self.rows = np.append(self.cols, 1), np.append(self.rows, 1)
        return len(self.regions) - 1

    def _place(self, cells: int) -> int:
        """The start of a free region of `cells` cells (first fit between the regions in use, else at the end)."""
        at = self._first_fit(cells)
        if at + cells > self.max_cells:
            self._compact()
            at = self.used
        if at + cells > self.max_cells:
            raise MemoryError(
                f"the scenes' grids hold {at + cells} cells, past the {self.max_cells + 1} the tracer indexes; use "
                "fewer scenes (scene_cache) or a coarser lidar.resolution"
            )
        if at + cells > self.flat.size:
            # In place (realloc: the kernel remaps a large buffer's pages instead of copying them, ~4x faster than a
            # copy into a new array at paper scale). No view of `flat` outlives a call: the tracer and the gathers
            # receive it afresh each time.
            self.flat.resize(min(max(at + cells, self.flat.size * 3 // 2), self.max_cells), refcheck=False)
        self.used = max(self.used, at + cells)
        return at

    def _first_fit(self, cells: int) -> int:
        """The start of the first gap between the regions in use that holds `cells` cells, else their end."""
        at = 0
        for start, n in sorted(r for r in self.regions if r is not None):
            if start - at >= cells:
                return at
            at = max(at, start + n)
        return at

    def _compact(self) -> None:
        """Move the regions in use down to the start of `flat`, in order, closing the gaps; each moved slot's table
        offsets move with it (frames are read from `offset` at every call, so none goes stale)."""
        at = 0
        for start, n, slot in sorted((r[0], r[1], k) for k, r in enumerate(self.regions) if r is not None):
            if start != at:
                self.flat[at : at + n] = self.flat[start : start + n]  # numpy copies overlapping slices safely
                self.offset[slot] += at - start
                self.regions[slot] = (at, n)
            at += n
        self.used = at

    def frames(self, slots: np.ndarray, level: np.ndarray, what: str) -> dict[str, np.ndarray]:
        """Per-env frames of grid `what` (a WHAT name or "kinds") at each env's slot and level."""
        k = KINDS if what == "kinds" else WHAT.index(what)
        return {
            "offset": self.offset[slots, level, k],
            "x0": self.x0[slots],
            "y0": self.y0[slots],
            "cols": self.cols[slots],
            "rows": self.rows[slots],
        }

    def footprints(
        self,
        body: dict[str, np.ndarray],
        kinds: dict[str, np.ndarray],
        x: np.ndarray,
        y: np.ndarray,
        cos: np.ndarray,
        sin: np.ndarray,
        u: np.ndarray,
        w: np.ndarray,
        near: float,
        kind_bits: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(blocked, bits) of footprints at (x, y) with heading (cos, sin) [n]: blocked when a point (u, w) of the
        footprint's frame lies on a 0 cell of grid `body` (frames as `frames` gives), bits the OR of `kind_bits`
        [256] of the `kinds` grid's codes under those points. A footprint whose centre's cell holds more than
        `near` metres is clear (the body grid holds the distance to the nearest occupied cell)."""
        return _footprints(
            self.flat,
            body["offset"],
            kinds["offset"],
            body["x0"],
            body["y0"],
            body["cols"],
            body["rows"],
            1.0 / self.resolution,
            self.resolution,
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(y, dtype=np.float64),
            np.ascontiguousarray(cos, dtype=np.float64),
            np.ascontiguousarray(sin, dtype=np.float64),
            u,
            w,
            float(near),
            kind_bits,
        )

    def lookup(self, frame: dict[str, np.ndarray], x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Grid values at world points x, y [n, k] of n envs (clamped onto each grid: its ring outside)."""
        if x.shape != y.shape:
            x, y = np.broadcast_arrays(x, y)
        return _gather(
            self.flat,
            frame["offset"],
            frame["x0"],
            frame["y0"],
            frame["cols"],
            frame["rows"],
            1.0 / self.resolution,
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(y, dtype=np.float64),
        )


@njit(cache=True)
def _gather(
    flat: np.ndarray,
    offset: np.ndarray,
    x0: np.ndarray,
    y0: np.ndarray,
    cols: np.ndarray,
    rows: np.ndarray,
    inv: float,
    x: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """`Atlas.lookup` in one pass (numpy's clip and fancy indexing cost ~20 us a call on the collision test's sizes):
    cells truncated toward zero as numpy's astype, clamped onto the grid."""
    n, k = x.shape
    out = np.empty((n, k), dtype=flat.dtype)
    for i in range(n):
        c_max, r_max = cols[i] - 1, rows[i] - 1
        for j in range(k):
            c = int((x[i, j] - x0[i]) * inv)
            r = int((y[i, j] - y0[i]) * inv)
            c = 0 if c < 0 else (c_max if c > c_max else c)
            r = 0 if r < 0 else (r_max if r > r_max else r)
            out[i, j] = flat[offset[i] + r * cols[i] + c]
    return out


@njit(cache=True, inline="always")
def _at(
    flat: np.ndarray, offset: int, x0: float, y0: float, cols: int, rows: int, inv: float, x: float, y: float
) -> int:
    """The index into `flat` of world point (x, y) in one grid (`_gather`'s truncation and clamping)."""
    c = int((x - x0) * inv)
    r = int((y - y0) * inv)
    c = 0 if c < 0 else (cols - 1 if c > cols - 1 else c)
    r = 0 if r < 0 else (rows - 1 if r > rows - 1 else r)
    return offset + r * cols + c


@njit(cache=True)
def _footprints(
    flat: np.ndarray,
    body_offset: np.ndarray,
    kind_offset: np.ndarray,
    x0: np.ndarray,
    y0: np.ndarray,
    cols: np.ndarray,
    rows: np.ndarray,
    inv: float,
    resolution: float,
    x: np.ndarray,
    y: np.ndarray,
    cos: np.ndarray,
    sin: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    near: float,
    kind_bits: np.ndarray,
):  # pragma: no cover - numba
    """`Atlas.footprints` in one pass: the points in numpy's order of operations ((x + cos u) - sin w), so a
    footprint reads the cells the numpy expression reads."""
    n = x.size
    blocked = np.zeros(n, dtype=np.bool_)
    bits = np.zeros(n, dtype=np.int64)
    for i in range(n):
        centre = flat[_at(flat, body_offset[i], x0[i], y0[i], cols[i], rows[i], inv, x[i], y[i])]
        if float(centre) * resolution > near:
            continue
        for j in range(u.size):
            px = x[i] + cos[i] * u[j] - sin[i] * w[j]
            py = y[i] + sin[i] * u[j] + cos[i] * w[j]
            at = _at(flat, 0, x0[i], y0[i], cols[i], rows[i], inv, px, py)
            if flat[body_offset[i] + at] == 0:
                blocked[i] = True
                bits[i] |= kind_bits[flat[kind_offset[i] + at]]
    return blocked, bits


@njit(cache=True)
def touched_objects(
    flat: np.ndarray,
    body_offset: int,
    kind_offset: int,
    x0: float,
    y0: float,
    cols: int,
    rows: int,
    inv: float,
    x: float,
    y: float,
    cos: float,
    sin: float,
    u: np.ndarray,
    w: np.ndarray,
    object_code: int,
    centres: np.ndarray,
    radii: np.ndarray,
) -> np.ndarray:  # pragma: no cover - numba
    """The objects one footprint touches: for each of its points (u, w) on an occupied body cell of kind
    `object_code`, the object whose bounding circle (`centres` [m, 2], `radii` [m]) it lies deepest in (the first
    on a tie); sorted, each once."""
    hit = np.zeros(centres.shape[0], dtype=np.bool_)
    for j in range(u.size):
        px = x + cos * u[j] - sin * w[j]
        py = y + sin * u[j] + cos * w[j]
        at = _at(flat, 0, x0, y0, cols, rows, inv, px, py)
        if flat[body_offset + at] != 0 or flat[kind_offset + at] != object_code:
            continue
        best, arg = np.inf, 0
        for m in range(centres.shape[0]):
            depth = np.hypot(px - centres[m, 0], py - centres[m, 1]) - radii[m]
            if depth < best:
                best, arg = depth, m
        hit[arg] = True
    return np.flatnonzero(hit)
