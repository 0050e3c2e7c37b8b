"""Road-frame geometry: straight and arc centerlines (`Polyline`s in road coordinates s, d), strips between
lateral offsets, and the polygon clean-ups the scene generator needs."""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely import lib
from shapely.creation import HandleNaN
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from sim.scene.polyline import Polyline

_ALLOW_NAN = np.intc(HandleNaN.get_value("allow"))  # shapely.linearrings' default handle_nan
_NO_HOLES = np.empty((0,), dtype=object)


def unit(angle: float) -> np.ndarray:
    """Unit vector pointing at `angle` (radians)."""
    return np.array([math.cos(angle), math.sin(angle)])


def straight(p: np.ndarray, h: float, length: float) -> Polyline:
    """Straight centerline from `p` along heading `h`."""
    return Polyline(np.stack([p, p + length * unit(h)]))


def arc_about(c: np.ndarray, radius: float, a0: float, a1: float, step: float = 2.0) -> Polyline:
    """Circular arc about centre `c` from polar angle a0 to a1 (counter-clockwise when a1 > a0)."""
    num_pts = max(8, int(math.ceil(abs(a1 - a0) * radius / step)) + 1)
    angles = np.linspace(a0, a1, num_pts)
    return Polyline(c + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1))


def arc(p: np.ndarray, h: float, radius: float, angle: float) -> Polyline:
    """Arc leaving `p` at heading `h`, turning by signed `angle` (positive: left) on `radius`."""
    sign = 1.0 if angle > 0 else -1.0
    centre = p + sign * radius * unit(h + math.pi / 2)
    a0 = h - sign * math.pi / 2
    return arc_about(centre, radius, a0, a0 + angle)


def strip(cl: Polyline, d0: float, d1: float, s0: float | None = None, s1: float | None = None) -> Polygon:
    """Polygon between lateral offsets d0 and d1, optionally restricted to arc lengths [s0, s1]."""
    if s0 is None and s1 is None:
        edge0, edge1 = cl.offset(d0), cl.offset(d1)
    else:
        s0 = 0.0 if s0 is None else s0
        s1 = cl.length if s1 is None else s1
        inner = cl.s[(cl.s > s0) & (cl.s < s1)]
        s = np.concatenate([[s0], inner, [s1]])
        # to_world(s, d0) and to_world(s, d1), sharing the frame and the normals (the same elementwise math).
        points, headings = cl.frame(s)
        normal = np.stack([-np.sin(headings), np.cos(headings)], axis=1)
        edge0 = points + np.full(len(s), d0, dtype=np.float64)[:, None] * normal
        edge1 = points + np.full(len(s), d1, dtype=np.float64)[:, None] * normal
    ring = np.concatenate([edge0, edge1[::-1]])
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
    parts = [
        part for part in getattr(geom, "geoms", []) if isinstance(part, (Polygon, MultiPolygon)) and part.area > 1e-6
    ]
    polys = [poly for part in parts for poly in (part.geoms if isinstance(part, MultiPolygon) else [part])]
    return max(polys, key=lambda poly: poly.area) if polys else None


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
    lines = [part for part in getattr(geom, "geoms", []) if isinstance(part, LineString)]
    if not lines:
        return None
    merged = shapely.line_merge(shapely.MultiLineString(lines))
    if isinstance(merged, LineString):
        return merged
    return max(merged.geoms, key=lambda part: part.length)


def ring_coords(poly: Polygon) -> list[list[float]]:
    """Exterior of `poly` counter-clockwise, without the closing point."""
    return np.asarray(orient(poly, 1.0).exterior.coords)[:-1].tolist()
