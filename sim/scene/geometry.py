"""Road-frame geometry: centerlines parametrised by arc length s and lateral offset d (left positive)."""

from __future__ import annotations

import math
from bisect import bisect_left
from functools import cached_property

import numpy as np
import shapely
from shapely import lib
from shapely.creation import HandleNaN
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.polygon import orient

_ALLOW_NAN = np.intc(HandleNaN.get_value("allow"))  # shapely.linearrings' default handle_nan
_NO_HOLES = np.empty((0,), dtype=object)


def unit(angle: float) -> np.ndarray:
    """Unit vector pointing at `angle` (radians)."""
    return np.array([math.cos(angle), math.sin(angle)])


class Centerline:
    """A polyline with cumulative arc length and vertex headings; maps (s, d) road coordinates to the world."""

    def __init__(self, pts: np.ndarray) -> None:
        self.pts = np.asarray(pts, dtype=np.float64)
        d = np.diff(self.pts, axis=0)
        seg = np.hypot(d[:, 0], d[:, 1])
        self.s = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.s[-1])
        h = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        hv = np.empty(len(self.pts))
        hv[0], hv[-1] = h[0], h[-1]
        if len(h) > 1:
            # On uniformly sampled arcs the end tangent is the end chord turned back by half a step; using the
            # chord itself tilts end cross-sections and opens gaps between sidewalks at block seams.
            hv[0] -= 0.5 * (h[1] - h[0])
            hv[-1] += 0.5 * (h[-1] - h[-2])
        # The average of adjacent chord headings is the true tangent for uniformly sampled arcs.
        hv[1:-1] = 0.5 * (h[:-1] + h[1:])
        self.heading = hv
        # Left normals at the vertices, computed once: every band, zone and building strip offsets along them.
        self.normals = np.stack([-np.sin(hv), np.cos(hv)], axis=1)
        # Plain-float copies for `point_xy` (called for every placement candidate): list indexing and float
        # arithmetic give the same doubles as the numpy scalars, without their per-operation overhead.
        self._lists = (self.s.tolist(), self.pts[:, 0].tolist(), self.pts[:, 1].tolist(), hv.tolist())

    def offset(self, d: float) -> np.ndarray:
        """Vertices shifted sideways by `d` (left positive)."""
        return self.pts + d * self.normals

    def frame(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Points and headings at arc lengths `s` (linear interpolation between vertices)."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        x = np.interp(s, self.s, self.pts[:, 0])
        y = np.interp(s, self.s, self.pts[:, 1])
        return np.stack([x, y], axis=1), np.interp(s, self.s, self.heading)

    def to_world(self, s: np.ndarray | float, d: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """World points at road coordinates (s, d) and the road heading there."""
        p, h = self.frame(s)
        d = np.asarray(d, dtype=np.float64)
        return p + d[..., None] * np.stack([-np.sin(h), np.cos(h)], axis=1), h

    def point_xy(self, s: float, d: float) -> tuple[float, float, float]:
        """World point (x, y) at road coordinates (s, d) and the heading there, as plain floats (`to_world`'s
        interpolation for one point, clamped onto the centerline)."""
        sl, xl, yl, hl = self._lists
        i = min(max(bisect_left(sl, s) - 1, 0), len(sl) - 2)  # np.searchsorted(self.s, s) - 1, clamped
        s0, s1 = sl[i], sl[i + 1]
        t = min(max((s - s0) / (s1 - s0), 0.0), 1.0) if s1 > s0 else 0.0
        x = xl[i] + t * (xl[i + 1] - xl[i])
        y = yl[i] + t * (yl[i + 1] - yl[i])
        h = hl[i] + t * (hl[i + 1] - hl[i])
        return float(x - d * math.sin(h)), float(y + d * math.cos(h)), float(h)

    def project(self, xy: np.ndarray) -> np.ndarray:
        """Arc length of the closest centerline point to each of `xy`."""
        return shapely.line_locate_point(self.line, shapely.points(np.asarray(xy)))

    @cached_property
    def line(self) -> LineString:
        """The centerline as a shapely LineString (built once)."""
        return LineString(self.pts)


def straight(p: np.ndarray, h: float, length: float) -> Centerline:
    """Straight centerline from `p` along heading `h`."""
    return Centerline(np.stack([p, p + length * unit(h)]))


def arc_about(c: np.ndarray, radius: float, a0: float, a1: float, step: float = 2.0) -> Centerline:
    """Circular arc about centre `c` from polar angle a0 to a1 (counter-clockwise when a1 > a0)."""
    n = max(8, int(math.ceil(abs(a1 - a0) * radius / step)) + 1)
    a = np.linspace(a0, a1, n)
    return Centerline(c + radius * np.stack([np.cos(a), np.sin(a)], axis=1))


def arc(p: np.ndarray, h: float, radius: float, angle: float) -> Centerline:
    """Arc leaving `p` at heading `h`, turning by signed `angle` (positive: left) on `radius`."""
    sign = 1.0 if angle > 0 else -1.0
    c = p + sign * radius * unit(h + math.pi / 2)
    a0 = h - sign * math.pi / 2
    return arc_about(c, radius, a0, a0 + angle)


def strip(cl: Centerline, d0: float, d1: float, s0: float | None = None, s1: float | None = None) -> Polygon:
    """Polygon between lateral offsets d0 and d1, optionally restricted to arc lengths [s0, s1]."""
    if s0 is None and s1 is None:
        a, b = cl.offset(d0), cl.offset(d1)
    else:
        s0 = 0.0 if s0 is None else s0
        s1 = cl.length if s1 is None else s1
        inner = cl.s[(cl.s > s0) & (cl.s < s1)]
        s = np.concatenate([[s0], inner, [s1]])
        # to_world(s, d0) and to_world(s, d1), sharing the frame and the normals (the same elementwise math).
        p, h = cl.frame(s)
        n = np.stack([-np.sin(h), np.cos(h)], axis=1)
        a = p + np.full(len(s), d0, dtype=np.float64)[:, None] * n
        b = p + np.full(len(s), d1, dtype=np.float64)[:, None] * n
    ring = np.concatenate([a, b[::-1]])
    x, y = ring[:, 0], ring[:, 1]
    # Shoelace sign instead of shapely's orient(): one polygon construction per strip, not two.
    if float(x[:-1] @ y[1:] - y[:-1] @ x[1:] + x[-1] * y[0] - y[-1] * x[0]) < 0:
        ring = ring[::-1]
    # shapely.polygons(ring) without its argument handling: the same ring (closed by linearrings), no holes.
    return lib.polygons(lib.linearrings(ring, _ALLOW_NAN), _NO_HOLES)


def largest(geom: shapely.Geometry) -> Polygon | None:
    """The largest polygon in `geom` (None when it has no area)."""
    if geom.is_empty:
        return None
    if isinstance(geom, Polygon):
        return geom if geom.area > 1e-6 else None
    parts = [g for g in getattr(geom, "geoms", []) if isinstance(g, (Polygon, MultiPolygon)) and g.area > 1e-6]
    polys = [p for g in parts for p in (g.geoms if isinstance(g, MultiPolygon) else [g])]
    return max(polys, key=lambda p: p.area) if polys else None


def clean(geom: shapely.Geometry, eps: float = 0.005) -> Polygon | None:
    """Largest polygon of `geom` after removing slivers and zero-width spikes left by boolean operations."""
    if geom.is_empty:
        return None
    opened = geom.buffer(-eps, join_style="mitre").buffer(eps, join_style="mitre")
    poly = largest(opened)
    return None if poly is None else largest(shapely.make_valid(poly.simplify(1e-4)))


def longest_line(geom: shapely.Geometry) -> LineString | None:
    """The longest LineString in `geom` (merging touching pieces first)."""
    if geom.is_empty:
        return None
    if isinstance(geom, LineString):
        return geom
    lines = [g for g in getattr(geom, "geoms", []) if isinstance(g, LineString)]
    if not lines:
        return None
    merged = shapely.line_merge(shapely.MultiLineString(lines))
    if isinstance(merged, LineString):
        return merged
    return max(merged.geoms, key=lambda g: g.length)


def ring_coords(poly: Polygon) -> list[list[float]]:
    """Exterior of `poly` counter-clockwise, without the closing point."""
    return np.asarray(orient(poly, 1.0).exterior.coords)[:-1].tolist()
