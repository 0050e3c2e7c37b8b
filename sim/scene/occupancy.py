"""The space objects already take: footprints grown by GAP and keep-out areas, in a spatial hash.

Placement asks one question per candidate, `Occupancy.free`: does the candidate meet a placed footprint or a
keep-out? Bounds that do not meet prove two shapes disjoint, so most candidates never reach GEOS; those whose
bounds meet get the exact shapely predicate.
"""

from __future__ import annotations

import struct

import numpy as np
import shapely
from shapely import lib
from shapely.geometry import LineString, Polygon
from shapely.io import DecodingErrorOptions

from sim.scene.sidewalks import Sidewalk

CELL = 5.0  # spatial-hash cell size (m)
GAP = 0.02  # clearance kept between footprints so rounding to 0.1 mm never makes them touch
Bounds = tuple[float, float, float, float]

_WKB_RAISE = np.uint8(DecodingErrorOptions.get_value("raise"))  # as shapely.from_wkb(..., on_invalid="raise")
_WKB_RECT = struct.Struct("<bIII10d")  # little-endian WKB polygon: one ring of 5 XY points
_intersects_scalar = lib.intersects_scalar  # what Polygon.intersects calls for one geometry


def quad_polygon(pts: list[list[float]]) -> Polygon:
    """The polygon shapely.polygons(pts) builds for four corners (the ring closed on the first), read from
    WKB: the same doubles in the same order, without the array round trip."""
    (ax, ay), (bx, by), (cx, cy), (dx, dy) = pts
    return lib.from_wkb(_WKB_RECT.pack(1, 3, 1, 5, ax, ay, bx, by, cx, cy, dx, dy, ax, ay), _WKB_RAISE)


def rect(x: float, y: float, c: float, s: float, depth: float, width: float) -> tuple[list[list[float]], Bounds]:
    """The corners of a depth x width rectangle centred at (x, y) with c, s = cos(yaw), sin(yaw), and their
    bounds (the extremes of the coordinates, as shapely's bounds of their polygon)."""
    ax, ay = c * depth / 2, s * depth / 2
    bx, by = -s * width / 2, c * width / 2
    px, py = x - ax - bx, y - ay - by
    qx, qy = x + ax - bx, y + ay - by
    rx, ry = x + ax + bx, y + ay + by
    tx, ty = x - ax + bx, y - ay + by
    return (
        [[px, py], [qx, qy], [rx, ry], [tx, ty]],
        (min(px, qx, rx, tx), min(py, qy, ry, ty), max(px, qx, rx, tx), max(py, qy, ry, ty)),
    )


def rects(
    x: np.ndarray, y: np.ndarray, c: np.ndarray, s: np.ndarray, depth: np.ndarray, width: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """`rect` for n rectangles at once: corners [n, 4, 2] in the same order and doubles, and bounds [n, 4]."""
    ax, ay = c * depth / 2, s * depth / 2
    bx, by = -s * width / 2, c * width / 2
    xs = np.stack([x - ax - bx, x + ax - bx, x + ax + bx, x - ax + bx], axis=1)
    ys = np.stack([y - ay - by, y + ay - by, y + ay + by, y - ay + by], axis=1)
    return np.stack([xs, ys], axis=2), np.stack([xs.min(1), ys.min(1), xs.max(1), ys.max(1)], axis=1)


def corridor(sw: Sidewalk, width: float, extend: float = 4.0) -> Polygon:
    """Keep-out band of `width` along the clear path, extended past both ends so corners stay open."""
    pts = np.asarray(sw.clear_path.coords)
    dir0, dir1 = pts[1] - pts[0], pts[-1] - pts[-2]
    dir0 /= max(np.hypot(*dir0), 1e-9)
    dir1 /= max(np.hypot(*dir1), 1e-9)
    ext = np.concatenate([[pts[0] - extend * dir0], pts, [pts[-1] + extend * dir1]])
    return LineString(ext).buffer(width / 2, cap_style="flat", quad_segs=2)


def _cells(b: Bounds) -> list[tuple[int, int]]:
    x0, y0, x1, y1 = b
    return [
        (i, j) for i in range(int(x0 // CELL), int(x1 // CELL) + 1) for j in range(int(y0 // CELL), int(y1 // CELL) + 1)
    ]


class Occupancy:
    """Placed footprints (grown by GAP) and keep-outs, with the exact overlap test placement needs."""

    def __init__(self) -> None:
        # Per placed footprint: corners, bounds and the shapely polygon, built only when a candidate's bounds meet.
        self.corners: list[list[list[float]]] = []
        self.bounds: list[Bounds] = []
        self.polys: list[Polygon | None] = []
        self.cells: dict[tuple[int, int], list[int]] = {}
        self.keep_polys: list[Polygon] = []
        self.keep_bounds: list[Bounds] = []
        self.keep_cells: dict[tuple[int, int], list[int]] = {}
        self.keep_tree: shapely.STRtree | None = None

    def set_keep_out(self, polys: list[Polygon]) -> None:
        """Areas no object may touch (clear-path corridors, ramp approaches)."""
        self.keep_polys = polys
        if polys:
            shapely.prepare(polys)
        self.keep_bounds = (
            [(x0, y0, x1, y1) for x0, y0, x1, y1 in shapely.bounds(np.asarray(polys, dtype=object)).tolist()]
            if polys
            else []
        )
        self.keep_cells = {}
        self.keep_tree = shapely.STRtree(polys) if polys else None
        for k, box in enumerate(self.keep_bounds):
            for cell in _cells(box):
                self.keep_cells.setdefault(cell, []).append(k)

    def add(self, check: list[list[float]], cb: Bounds) -> None:
        """Record a placed footprint by its grown corners `check` and their bounds `cb`."""
        k = len(self.polys)
        self.polys.append(None)
        self.corners.append(check)
        self.bounds.append(cb)
        for cell in _cells(cb):
            self.cells.setdefault(cell, []).append(k)

    def _poly(self, k: int) -> Polygon:
        poly = self.polys[k]
        if poly is None:
            poly = self.polys[k] = quad_polygon(self.corners[k])
        return poly

    def keep_out_hits(self, polys: np.ndarray) -> np.ndarray:
        """Which of the footprints `polys` meet a keep-out (one bulk query; the predicate `free` applies one by one)."""
        hit = np.zeros(len(polys), dtype=bool)
        if self.keep_tree is not None and len(polys):
            hit[self.keep_tree.query(polys, predicate="intersects")[0]] = True
        return hit

    def free(self, poly: Polygon, pb: Bounds, check: list[list[float]], cb: Bounds, keep_out: bool) -> bool:
        """No placed footprint meets `check` and (with `keep_out`) no keep-out meets the footprint `poly`."""
        if not self.clear_of_placed(check, cb):
            return False
        if not keep_out or not self.keep_polys:
            return True
        x0, y0, x1, y1 = pb
        kb, kc, kp = self.keep_bounds, self.keep_cells, self.keep_polys
        for i in range(int(x0 // CELL), int(x1 // CELL) + 1):
            for j in range(int(y0 // CELL), int(y1 // CELL) + 1):
                for k in kc.get((i, j), ()):
                    box = kb[k]
                    # Keep-outs whose bounds meet the footprint's get the exact (prepared) GEOS predicate.
                    if not (box[2] < x0 or box[0] > x1 or box[3] < y0 or box[1] > y1) and _intersects_scalar(
                        kp[k], poly
                    ):
                        return False
        return True

    def clear_of_placed(self, check: list[list[float]], cb: Bounds) -> bool:
        """No placed footprint meets the grown footprint with corners `check` and bounds `cb`."""
        x0, y0, x1, y1 = cb
        cells, bounds = self.cells, self.bounds
        cp = None
        seen: set[int] = set()
        for i in range(int(x0 // CELL), int(x1 // CELL) + 1):
            for j in range(int(y0 // CELL), int(y1 // CELL) + 1):
                for k in cells.get((i, j), ()):
                    if k in seen:
                        continue
                    seen.add(k)
                    box = bounds[k]
                    if box[2] < x0 or box[0] > x1 or box[3] < y0 or box[1] > y1:
                        continue
                    # Bounds meet: the exact GEOS predicate decides; any hit refuses, so the order is moot.
                    if cp is None:
                        cp = quad_polygon(check)
                    if _intersects_scalar(cp, self._poly(k)):
                        return False
        return True
