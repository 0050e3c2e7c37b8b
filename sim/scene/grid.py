"""The walkable grid of a scene spec: rasterisation, encoding, decoding, and object obstacle masks.

Cell (i, j) covers x in [x0 + j*res, x0 + (j+1)*res) and y in [y0 + i*res, y0 + (i+1)*res); a cell is
inside a polygon when its centre is.
"""

from __future__ import annotations

import base64
import math
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

ENCODING = "zlib+base64:uint8"
LEGEND = {"0": "not walkable", "1": "sidewalk", "2": "crosswalk", "3": "curb ramp"}
SIDEWALK, CROSSWALK, RAMP = 1, 2, 3


@dataclass(frozen=True)
class WalkableGrid:
    """Decoded walkable grid: `mask` holds the legend codes (0 = not walkable), row i is y, column j is x."""

    mask: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return self.mask.shape

    @property
    def walkable(self) -> np.ndarray:
        """Boolean mask of walkable surfaces (sidewalk, crosswalk, curb ramp)."""
        return self.mask > 0

    def world_to_cell(self, xy: np.ndarray | Sequence[float]) -> np.ndarray:
        """Integer (row, col) of world points `xy` (..., 2); may fall outside the grid (see `inside`)."""
        xy = np.asarray(xy, dtype=np.float64)
        col = np.floor((xy[..., 0] - self.origin[0]) / self.resolution)
        row = np.floor((xy[..., 1] - self.origin[1]) / self.resolution)
        return np.stack([row, col], axis=-1).astype(np.int64)

    def cell_to_world(self, rc: np.ndarray | Sequence[int]) -> np.ndarray:
        """World (x, y) of the centres of cells `rc` (..., 2) given as (row, col)."""
        rc = np.asarray(rc, dtype=np.float64)
        x = self.origin[0] + (rc[..., 1] + 0.5) * self.resolution
        y = self.origin[1] + (rc[..., 0] + 0.5) * self.resolution
        return np.stack([x, y], axis=-1)

    def inside(self, rc: np.ndarray) -> np.ndarray:
        """Whether cells `rc` (..., 2) lie inside the grid."""
        rc = np.asarray(rc)
        return (rc[..., 0] >= 0) & (rc[..., 0] < self.shape[0]) & (rc[..., 1] >= 0) & (rc[..., 1] < self.shape[1])

    def label_at(self, x: float, y: float) -> int:
        """Legend code under the world point (x, y); 0 outside the grid."""
        # world_to_cell's arithmetic on one point, without its arrays (the env asks this every step).
        if not (math.isfinite(x) and math.isfinite(y)):
            return 0
        i = math.floor((float(y) - float(self.origin[1])) / self.resolution)
        j = math.floor((float(x) - float(self.origin[0])) / self.resolution)
        if 0 <= i < self.shape[0] and 0 <= j < self.shape[1]:
            return int(self.mask[i, j])
        return 0

    def is_walkable(self, xy: np.ndarray | Sequence[float]) -> np.ndarray:
        """Whether world points `xy` (..., 2) fall on walkable cells (False outside the grid)."""
        rc = self.world_to_cell(xy)
        ok = self.inside(rc)
        out = np.zeros(ok.shape, dtype=bool)
        out[ok] = self.mask[rc[ok][:, 0], rc[ok][:, 1]] > 0
        return out


def grid_frame(bounds: Sequence[float], resolution: float) -> tuple[tuple[float, float], tuple[int, int]]:
    """Origin snapped to the resolution and the (rows, cols) covering `bounds` [xmin, ymin, xmax, ymax]."""
    x0 = math.floor(bounds[0] / resolution) * resolution
    y0 = math.floor(bounds[1] / resolution) * resolution
    cols = int(math.ceil((bounds[2] - x0) / resolution))
    rows = int(math.ceil((bounds[3] - y0) / resolution))
    return (round(x0, 4), round(y0, 4)), (rows, cols)


def _rings(poly: Polygon) -> list[np.ndarray]:
    return [np.asarray(poly.exterior.coords)] + [np.asarray(ring.coords) for ring in poly.interiors]


def paint(mask: np.ndarray, origin: tuple[float, float], resolution: float, poly: Polygon, value: int | bool) -> None:
    """Set the cells of `mask` whose centres lie inside `poly` to `value` (even-odd scanlines over its rows)."""
    paint_many(mask, origin, resolution, [poly], value)


def _polygons(polys: Iterable[Any]) -> list[Polygon]:
    """The non-empty polygons of `polys`, multi-part geometries split into their polygon parts."""
    out = []
    for poly in polys:
        if poly.is_empty:
            continue
        if isinstance(poly, Polygon):
            out.append(poly)
            continue
        out += [part for part in getattr(poly, "geoms", []) if isinstance(part, Polygon) and not part.is_empty]
    return out


def paint_many(
    mask: np.ndarray, origin: tuple[float, float], resolution: float, polys: Iterable[Any], value: int | bool
) -> None:
    """`paint` of every polygon of `polys` with one `value`, in one vectorised pass (see `_inside_cells`)."""
    idx, _ = _inside_cells(_polygons(polys), origin, resolution, mask.shape)
    if not len(idx):
        return
    if mask.flags.c_contiguous:
        mask.reshape(-1)[idx] = value
    else:
        mask[np.unravel_index(idx, mask.shape)] = value


def _inside_cells(
    parts: list[Polygon], origin: tuple[float, float], resolution: float, shape: tuple[int, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """The flat indices of the cells of a grid of `shape` whose centres lie strictly inside each polygon of `parts`,
    and the index in `parts` of the polygon each cell belongs to (a cell inside two polygons is listed twice).

    Row k's centre is y_k = y0 + (k + 0.5) * res; an edge crosses row k when min(y) <= y_k < max(y) (the
    half-open rule counts each vertex once, like a point-in-polygon test), so the rows an edge crosses are one
    `searchsorted` range. Each polygon's crossings on a row, sorted by x, pair up as inside spans; a cell is in
    when its centre is strictly inside.
    """
    none = np.zeros(0, dtype=np.int64)
    if not parts:
        return none, none
    h, w = shape
    rings = [(i, r) for i, poly in enumerate(parts) for r in _rings(poly)]
    a = np.concatenate([r[:-1] for _, r in rings])
    b = np.concatenate([r[1:] for _, r in rings])
    pid = np.repeat(np.array([i for i, _ in rings], dtype=np.int64), [len(r) - 1 for _, r in rings])
    ys = origin[1] + (np.arange(0, h) + 0.5) * resolution
    lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    k0 = np.searchsorted(ys, lo, side="left")  # first row with y_k >= lo
    cnt = np.maximum(np.searchsorted(ys, hi, side="left") - k0, 0)  # rows with lo <= y_k < hi
    total = int(cnt.sum())
    if total == 0:
        return none, none
    ends = np.cumsum(cnt)
    edges = np.repeat(np.arange(len(a)), cnt)
    rows = np.repeat(k0, cnt) + (np.arange(total) - np.repeat(ends - cnt, cnt))
    ax, ay, bx, by = a[edges, 0], a[edges, 1], b[edges, 0], b[edges, 1]
    x = ax + (ys[rows] - ay) * (bx - ax) / (by - ay)
    owner = pid[edges]
    order = np.lexsort((x, rows, owner))
    rows, x, owner = rows[order], x[order], owner[order]
    start = np.ceil((x[0::2] - origin[0]) / resolution - 0.5 + 1e-12).astype(np.int64)
    stop = np.ceil((x[1::2] - origin[0]) / resolution - 0.5 - 1e-12).astype(np.int64)
    start = np.clip(start, 0, w)
    stop = np.clip(stop, 0, w)
    keep = stop > start
    if not keep.any():
        return none, none
    r, c0, n = rows[0::2][keep], start[keep], (stop - start)[keep]
    # The cells of every span through one flat index array (span k covers r*w + c0 ... r*w + c0 + n - 1).
    ends = np.cumsum(n)
    idx = np.arange(int(ends[-1]), dtype=np.int64) + np.repeat(r * w + c0 - (ends - n), n)
    return idx, np.repeat(owner[0::2][keep], n)


def paint_reference(
    mask: np.ndarray, origin: tuple[float, float], resolution: float, poly: Polygon, value: int | bool
) -> None:
    """Slow reference of `paint`: `shapely.contains_xy` on every cell centre of the polygon's bounding box."""
    if poly.is_empty:
        return
    xmin, ymin, xmax, ymax = poly.bounds
    j0 = max(int(math.floor((xmin - origin[0]) / resolution - 0.5)), 0)
    j1 = min(int(math.ceil((xmax - origin[0]) / resolution - 0.5)) + 1, mask.shape[1])
    i0 = max(int(math.floor((ymin - origin[1]) / resolution - 0.5)), 0)
    i1 = min(int(math.ceil((ymax - origin[1]) / resolution - 0.5)) + 1, mask.shape[0])
    if j1 <= j0 or i1 <= i0:
        return
    xs = origin[0] + (np.arange(j0, j1) + 0.5) * resolution
    ys = origin[1] + (np.arange(i0, i1) + 0.5) * resolution
    X, Y = np.meshgrid(xs, ys)
    inside = shapely.contains_xy(poly, X, Y)
    mask[i0:i1, j0:j1][inside] = value


def rasterize(
    layers: Iterable[tuple[int, Iterable[Polygon]]], bounds: Sequence[float], resolution: float
) -> tuple[np.ndarray, tuple[float, float]]:
    """Paint (code, polygons) layers in order (later layers win) onto a grid covering `bounds`."""
    origin, shape = grid_frame(bounds, resolution)
    mask = np.zeros(shape, dtype=np.uint8)
    for code, polys in layers:
        # One pass per layer: its polygons all paint the same code, so their order within the layer is moot.
        paint_many(mask, origin, resolution, polys, code)
    return mask, origin


def encode_walkable(mask: np.ndarray, origin: tuple[float, float], resolution: float) -> dict[str, Any]:
    """The spec's `walkable` object for `mask`."""
    data = np.ascontiguousarray(mask, dtype=np.uint8).tobytes()
    return {
        "origin": [float(origin[0]), float(origin[1])],
        "resolution": float(resolution),
        "shape": [int(mask.shape[0]), int(mask.shape[1])],
        "encoding": ENCODING,
        "legend": dict(LEGEND),
        # Level 1: the masks are long runs, so it is ~3x faster than level 6 for ~2 KB more per scene.
        "cells": base64.b64encode(zlib.compress(data, 1)).decode("ascii"),
    }


def decode_walkable(spec: Mapping[str, Any]) -> WalkableGrid:
    """Decode the `walkable` grid of a scene spec (or of its `walkable` object itself)."""
    walk = spec.get("walkable", spec)
    if walk.get("encoding") != ENCODING:
        raise ValueError(f"walkable grid encoding {walk.get('encoding')!r} is not supported; expected {ENCODING!r}")
    missing = [k for k in ("shape", "cells", "origin", "resolution") if k not in walk]
    if missing:
        raise ValueError(f"scene spec lacks walkable.{missing[0]}; regenerate it with `curbside scenes generate`")
    rows, cols = (int(dim) for dim in walk["shape"])
    raw = zlib.decompress(base64.b64decode(walk["cells"]))
    if len(raw) != rows * cols:
        raise ValueError(f"walkable grid holds {len(raw)} cells but its shape says {rows}x{cols}; regenerate the scene")
    mask = np.frombuffer(raw, dtype=np.uint8).reshape(rows, cols).copy()
    return WalkableGrid(
        mask=mask, origin=(float(walk["origin"][0]), float(walk["origin"][1])), resolution=float(walk["resolution"])
    )


def _footprint(obj: Any) -> Polygon:
    if isinstance(obj, Polygon):
        return obj
    if isinstance(obj, dict):
        obj = obj["footprint"]
    return Polygon(obj)


def obstacle_mask(
    grid: WalkableGrid,
    objects: Iterable[Any],
    inflate: float = 0.0,
    *,
    cover_thin: bool = True,
    join_style: str | None = None,
) -> np.ndarray:
    """Boolean mask of cells covered by object footprints grown by `inflate` metres (an agent's radius).

    `objects` are spec objects (dicts with `footprint`), lists of [x, y] points, or shapely polygons. With
    `cover_thin`, an object thinner than a cell (a pole) that covers no cell centre still blocks its cell.
    `join_style` of the growth: by default mitre below 5 cm (keeps box corners) and round above.
    """
    out = np.zeros(grid.shape, dtype=bool)
    polys = [_footprint(obj) for obj in objects]
    if inflate > 0:
        join = join_style or ("mitre" if inflate < 0.05 else "round")
        polys = [polygon.buffer(inflate, join_style=join, quad_segs=4) for polygon in polys]
    if not cover_thin:
        paint_many(out, grid.origin, grid.resolution, polys, True)
        return out
    # Each object's cells in one vectorised pass, then the objects in order: one whose cells were all set already
    # (none, for a pole thinner than a cell) blocks the cell of its centroid instead.
    n_rows, n_cols = grid.shape
    parts, owners = [], []
    for k, poly in enumerate(polys):
        for part in _polygons([poly]):
            parts.append(part)
            owners.append(k)
    idx, part_of = _inside_cells(parts, grid.origin, grid.resolution, grid.shape)
    obj = np.asarray(owners, dtype=np.int64)[part_of]
    order = np.argsort(obj, kind="stable")
    idx = idx[order]
    bounds = np.searchsorted(obj[order], np.arange(len(polys) + 1))
    flat = out.reshape(-1)
    for k, poly in enumerate(polys):
        if poly.is_empty:
            continue
        cells = idx[bounds[k] : bounds[k + 1]]
        if not flat[cells].all():
            flat[cells] = True
            continue
        i, j = (int(coord) for coord in grid.world_to_cell((poly.centroid.x, poly.centroid.y)))
        if 0 <= i < n_rows and 0 <= j < n_cols:
            out[i, j] = True
    return out


def grid_graph(
    free: np.ndarray, resolution: float, *, cost: np.ndarray | None = None, corner_cutting: bool = True
) -> Any:
    """8-connected graph over the True cells of `free`, nodes numbered row-major (as np.nonzero lists them).

    An edge costs its length (resolution, or resolution * sqrt 2 on diagonals) times the mean of `cost` at
    its two cells when `cost` is given. Without `corner_cutting`, a diagonal needs both cells it passes
    between to be free too. Returns a scipy CSR matrix (scipy is imported here: the generator never needs it).
    """
    from scipy.sparse import coo_matrix

    rows, cols = free.shape
    node = np.full(free.shape, -1, dtype=np.int64)
    node[free] = np.arange(int(free.sum()))
    src, dst, weights = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        j0, j1 = max(0, -dj), cols - max(0, dj)
        node_a = node[0 : rows - di, j0:j1]
        node_b = node[di:rows, j0 + dj : j1 + dj]
        ok = (node_a >= 0) & (node_b >= 0)
        if di and dj and not corner_cutting:
            ok &= (node[di:rows, j0:j1] >= 0) & (node[0 : rows - di, j0 + dj : j1 + dj] >= 0)
        src.append(node_a[ok])
        dst.append(node_b[ok])
        length = resolution * math.hypot(di, dj)
        if cost is None:
            weights.append(np.full(int(ok.sum()), length))
        else:
            weights.append(length * (0.5 * (cost[0 : rows - di, j0:j1][ok] + cost[di:rows, j0 + dj : j1 + dj][ok])))
    src_a, dst_a, w_a = np.concatenate(src), np.concatenate(dst), np.concatenate(weights)
    num_nodes = int(free.sum())
    return coo_matrix(
        (np.concatenate([w_a, w_a]), (np.concatenate([src_a, dst_a]), np.concatenate([dst_a, src_a]))),
        shape=(num_nodes, num_nodes),
    ).tocsr()
