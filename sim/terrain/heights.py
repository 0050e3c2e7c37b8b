"""Heights of a tile grid (sim.terrain.wfc): each tile's surface sampled on a grid, steps as vertical faces.

Along x a tile's height runs by its shape between its west and east levels (`level_height` metres a level):
flat and rough stay level; a slope rises evenly across the tile; a ramp is flat for an eighth, rises over the
middle three quarters and is flat again (a steeper, shorter slope: 10 % with 2 m tiles and 0.15 m levels,
under the 1:12 = 8.3 % of ADA curb ramps plus their flares); a step rises in the middle; stairs rise
two levels in two steps. A rough tile adds smooth bumps up to `bump_height` that vanish at its edges, so its
borders stay level with its neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.terrain.wfc import SHAPES, Tile

EPS = 1e-4  # a vertical face: two samples this far apart along x


@dataclass(frozen=True)
class TileGeometry:
    """Sizes of the tiles in metres: side, height of a level, bump height of rough tiles, sample spacing."""

    size: float = 2.0
    level_height: float = 0.15
    bump_height: float = 0.06
    resolution: float = 0.1


def profile(tile: Tile, u: np.ndarray) -> np.ndarray:
    """Height in levels at fractions `u` in [0, 1] along the tile's x (before bumps)."""
    rise = SHAPES[tile.shape]
    kind = tile.shape.rsplit("_", 1)[0]
    if kind == "slope":
        frac = u
    elif kind == "ramp":
        frac = np.clip((u - 0.125) / 0.75, 0.0, 1.0)
    elif kind == "step":
        frac = (u >= 0.5).astype(np.float64)
    elif kind == "stairs":
        frac = np.floor(np.clip(u, 0.0, 1.0 - 1e-12) * 3.0) / 2.0  # thirds: level, level + 1, level + 2
    else:
        frac = np.zeros_like(u)
    return tile.level + rise * frac


def breakpoints(tile: Tile) -> list[float]:
    """The fractions along x where the tile's height jumps (a step's or a stair's face)."""
    kind = tile.shape.rsplit("_", 1)[0]
    return {"step": [0.5], "stairs": [1 / 3, 2 / 3]}.get(kind, [])


def tile_surface(tile: Tile, geo: TileGeometry, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, z): sample fractions along x and y and heights z[v, u] in metres of one tile."""
    n = max(int(round(geo.size / geo.resolution)), 2)
    u = np.linspace(0.0, 1.0, n + 1)
    for b in breakpoints(tile):
        u = np.union1d(u, [b - EPS, b])
    v = np.linspace(0.0, 1.0, n + 1)
    z = np.repeat(profile(tile, u)[None, :] * geo.level_height, len(v), axis=0)
    if tile.shape == "rough":
        # Bumps: a few random smooth waves, windowed to zero at the edges (the borders stay level).
        bumps = np.zeros_like(z)
        uu, vv = np.meshgrid(u, v)
        for _ in range(4):
            fu, fv = rng.uniform(1.0, 4.0, 2)
            pu, pv = rng.uniform(0.0, 2 * np.pi, 2)
            bumps += np.sin(2 * np.pi * fu * uu + pu) * np.sin(2 * np.pi * fv * vv + pv)
        bumps *= np.sin(np.pi * uu) * np.sin(np.pi * vv)
        peak = np.abs(bumps).max()
        z = z + geo.bump_height * np.clip(bumps / max(peak, 1e-9), 0.0, 1.0)  # bumps up from the level
    return u, v, z


def grid_mesh(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[list[list[float]], list[int]]:
    """Vertices and triangle indices (counter-clockwise seen from above) of the surface z[j, i] over x[i], y[j]."""
    xx, yy = np.meshgrid(x, y)
    verts = np.stack([xx, yy, z], axis=-1).reshape(-1, 3)
    nx = len(x)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(len(y) - 1))
    a = (j * nx + i).ravel()
    b, c, d = a + 1, a + nx + 1, a + nx
    tris = np.stack([a, b, c, a, c, d], axis=1).reshape(-1)
    return verts.tolist(), tris.astype(int).tolist()
