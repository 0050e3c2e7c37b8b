"""Terrain tiles joined by Wave Function Collapse (Gumin 2016; MetaUrban Sec. 3.1), so heights match at borders.

A terrain is a grid of square tiles, columns along x (the runway's direction), rows along y. Every tile has a
height level on its west and east edges and a profile on its north and south edges (how its height runs along
x: flat, slope, ramp, step, stairs). Two tiles may sit side by side along x when the west tile's east level is
the east tile's west level, and along y when their profiles are equal: then the surface has no seam anywhere.
Each tile also carries a surface (asphalt, concrete, pavers, grass, gravel, wet), which any neighbour accepts.

`collapse(rows, cols, rng, ...)` is the solver: repeatedly fix the undecided cell with the fewest options
(ties broken by the generator), drawing its tile by weight, and remove from its neighbours every tile that
cannot sit next to what remains (arc consistency), restarting on a contradiction.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from kernel.config import ConfigError

# Surfaces and their friction coefficients (rubber tyre on the surface; dry unless named):
# asphalt 0.7-0.8, concrete 0.7-0.8, pavers 0.6-0.7, grass 0.35-0.45, gravel 0.5-0.6, wet asphalt 0.4-0.5
# (road-engineering handbooks' tyre-road friction tables; Wong, Theory of Ground Vehicles).
SURFACES: dict[str, float] = {
    "asphalt": 0.75,
    "concrete": 0.75,
    "pavers": 0.65,
    "grass": 0.4,
    "gravel": 0.55,
    "wet": 0.45,
}
# Tile shapes: how many levels a tile rises along +x, and how its height runs between its edges.
SHAPES: dict[str, int] = {
    "flat": 0,
    "rough": 0,
    "slope_up": 1,
    "slope_down": -1,
    "ramp_up": 1,
    "ramp_down": -1,
    "step_up": 1,
    "step_down": -1,
    "stairs_up": 2,
    "stairs_down": -2,
}


@dataclass(frozen=True)
class Tile:
    """One tile: its shape, the level of its west edge, and its surface."""

    shape: str
    level: int
    surface: str

    @property
    def west(self) -> int:
        """The height level along the tile's west edge."""
        return self.level

    @property
    def east(self) -> int:
        """The height level along the tile's east edge."""
        return self.level + SHAPES[self.shape]

    @property
    def profile(self) -> tuple[str, int, int]:
        """What the north and south edges look like: how the height runs along x from the west level to the east
        level (rough tiles are flat there)."""
        kind = self.shape.rsplit("_", 1)[0]
        return ("flat" if kind == "rough" else kind, self.west, self.east)


def tile_set(
    levels: int, shapes: Sequence[str] = tuple(SHAPES), surfaces: Sequence[str] = tuple(SURFACES)
) -> list[Tile]:
    """Every tile whose edges stay within levels 0 .. levels - 1."""
    bad = [s for s in shapes if s not in SHAPES] + [s for s in surfaces if s not in SURFACES]
    if bad:
        raise ConfigError(
            f"unknown terrain shapes or surfaces {bad}; shapes: {', '.join(SHAPES)}; surfaces: {', '.join(SURFACES)}"
        )
    return [
        Tile(shape, k, surf)
        for shape in shapes
        for k in range(levels)
        for surf in surfaces
        if 0 <= k + SHAPES[shape] < levels
    ]


def allowed_east(a: Tile, b: Tile) -> bool:
    """Whether `b` may sit east of `a` (the west tile's east level is the east tile's west level)."""
    return a.east == b.west


def allowed_north(a: Tile, b: Tile) -> bool:
    """Whether `b` may sit north of `a` (their edges along x run the same way)."""
    return a.profile == b.profile


class Contradiction(RuntimeError):
    """A cell ran out of tiles: the solver restarts."""


def collapse(
    rows: int,
    cols: int,
    rng: np.random.Generator,
    tiles: Sequence[Tile],
    weights: Mapping[str, float] | None = None,
    west_level: int | None = 0,
    start_flat: bool = False,
    attempts: int = 20,
) -> list[list[Tile]]:
    """A `rows` x `cols` grid of `tiles` in which every neighbouring pair is allowed; `weights` per shape
    (default 1), `west_level` the level of the first column's west edge (None: any), `start_flat` a flat first
    column (a runway's lead-in)."""
    if rows < 1 or cols < 1:
        raise ConfigError(f"terrain needs at least one row and one column, got {rows} x {cols}")
    w = np.array([float((weights or {}).get(t.shape, 1.0)) for t in tiles])
    if (w < 0).any() or not np.isfinite(w).all() or w.sum() <= 0:
        raise ConfigError("terrain shape weights must be finite, non-negative and not all zero")
    n = len(tiles)
    east = np.array([[allowed_east(a, b) for b in tiles] for a in tiles])
    north = np.array([[allowed_north(a, b) for b in tiles] for a in tiles])
    for _ in range(attempts):
        try:
            return _attempt(rows, cols, rng, tiles, w, east, north, west_level, start_flat, n)
        except Contradiction:
            continue
    raise ConfigError(
        f"no {rows} x {cols} terrain satisfies the tile rules after {attempts} attempts; allow more levels or shapes"
    )


def _attempt(
    rows: int,
    cols: int,
    rng: np.random.Generator,
    tiles: Sequence[Tile],
    w: np.ndarray,
    east: np.ndarray,
    north: np.ndarray,
    west_level: int | None,
    start_flat: bool,
    n: int,
) -> list[list[Tile]]:
    """One run of the solver; raises Contradiction when a cell has no tile left."""
    dom = np.ones((rows, cols, n), dtype=bool)
    dom &= w > 0
    if west_level is not None:
        dom[:, 0] &= np.array([t.west == west_level for t in tiles])
    if start_flat:
        dom[:, 0] &= np.array([t.shape == "flat" for t in tiles])
    _propagate(dom, [(r, 0) for r in range(rows)], east, north)
    while True:
        count = dom.sum(axis=2)
        open_cells = count > 1
        if not open_cells.any():
            break
        least = count[open_cells].min()
        cand = np.argwhere(open_cells & (count == least))
        r, c = (int(v) for v in cand[int(rng.integers(len(cand)))])
        p = np.where(dom[r, c], w, 0.0)
        k = int(rng.choice(n, p=p / p.sum()))
        dom[r, c] = False
        dom[r, c, k] = True
        _propagate(dom, [(r, c)], east, north)
    return [[tiles[int(np.argmax(dom[r, c]))] for c in range(cols)] for r in range(rows)]


def _propagate(dom: np.ndarray, start: list[tuple[int, int]], east: np.ndarray, north: np.ndarray) -> None:
    """Remove from the cells around `start` (and onwards) the tiles no remaining neighbour tile supports."""
    rows, cols, _ = dom.shape
    queue = deque(start)
    while queue:
        r, c = queue.popleft()
        here = dom[r, c]
        if not here.any():
            raise Contradiction
        for dr, dc, rule in ((0, 1, east), (0, -1, east.T), (1, 0, north), (-1, 0, north.T)):
            rr, cc = r + dr, c + dc
            if not (0 <= rr < rows and 0 <= cc < cols):
                continue
            ok = rule[here].any(axis=0)  # tiles the neighbour may hold given what this cell still may
            new = dom[rr, cc] & ok
            if (new != dom[rr, cc]).any():
                if not new.any():
                    raise Contradiction
                dom[rr, cc] = new
                queue.append((rr, cc))
