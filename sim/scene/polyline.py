"""The one arc-length polyline: road centerlines (`sim.scene.geometry`), the ego's reference route (`sim.route.Route`)
and vehicle lanes (`sim.agents.lanes.Lane`) are all `Polyline`s.

Road coordinates (s, d): arc length s along the line from its first vertex, lateral offset d (left positive).
"""

from __future__ import annotations

import math
from bisect import bisect_left
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import LineString


class Polyline:
    """Vertices `points` [n, 2], segments `seg` [n - 1, 2] and their lengths `seg_len`, cumulative arc lengths `s`
    at the vertices and the total `length`; points, headings and offsets at arc length; projection onto the line.
    """

    def __init__(self, points: np.ndarray, seg_len: np.ndarray | None = None) -> None:
        self.points = np.asarray(points, dtype=np.float64)
        self.seg = np.diff(self.points, axis=0)
        # A user that measures its segments its own way passes the lengths (Route floors them, Lane takes
        # np.linalg.norm): np.hypot differs from both in the last bit, and every episode depends on these doubles.
        self.seg_len = np.hypot(self.seg[:, 0], self.seg[:, 1]) if seg_len is None else seg_len
        self.s = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.length = float(self.s[-1])

    @cached_property
    def heading(self) -> np.ndarray:
        """Tangent heading at each vertex (radians, unwrapped along the line)."""
        headings = np.unwrap(np.arctan2(self.seg[:, 1], self.seg[:, 0]))
        hv = np.empty(len(self.points))
        hv[0], hv[-1] = headings[0], headings[-1]
        if len(headings) > 1:
            # On uniformly sampled arcs the end tangent is the end chord turned back by half a step; using the
            # chord itself tilts end cross-sections and opens gaps between sidewalks at block seams.
            hv[0] -= 0.5 * (headings[1] - headings[0])
            hv[-1] += 0.5 * (headings[-1] - headings[-2])
        # The average of adjacent chord headings is the true tangent for uniformly sampled arcs.
        hv[1:-1] = 0.5 * (headings[:-1] + headings[1:])
        return hv

    @cached_property
    def normals(self) -> np.ndarray:
        """Left unit normals at the vertices (built once: every band, zone and building strip offsets along them)."""
        return np.stack([-np.sin(self.heading), np.cos(self.heading)], axis=1)

    @cached_property
    def _lists(self) -> tuple[list[float], list[float], list[float], list[float]]:
        # Plain-float copies for `point_xy` (called for every placement candidate): list indexing and float
        # arithmetic give the same doubles as the numpy scalars, without their per-operation overhead.
        return self.s.tolist(), self.points[:, 0].tolist(), self.points[:, 1].tolist(), self.heading.tolist()

    @cached_property
    def line(self) -> LineString:
        """The polyline as a shapely LineString (built once)."""
        return LineString(self.points)

    def point_at(self, s: np.ndarray | float) -> np.ndarray:
        """Point(s) at arc length `s` (clamped onto the line): [2] for a number, [n, 2] for n arc lengths."""
        s = np.clip(s, 0.0, self.length)
        return np.stack([np.interp(s, self.s, self.points[:, 0]), np.interp(s, self.s, self.points[:, 1])], -1)

    def heading_at(self, s: float) -> float:
        """Heading (radians) of the segment at arc length `s` (the chord, not the vertex tangent)."""
        k = min(max(int(np.searchsorted(self.s, s, side="right")) - 1, 0), len(self.seg) - 1)
        return math.atan2(self.seg[k, 1], self.seg[k, 0])

    def offset(self, d: float) -> np.ndarray:
        """Vertices shifted sideways by `d` (left positive)."""
        return self.points + d * self.normals

    def frame(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Points [n, 2] and vertex-tangent headings [n] at arc lengths `s` (linear between vertices)."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        # np.interp already holds the end values beyond the ends, so point_at's clamp changes no double here.
        return self.point_at(s), np.interp(s, self.s, self.heading)

    def to_world(self, s: np.ndarray | float, d: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """World points at road coordinates (s, d) and the line's heading there."""
        point, heading = self.frame(s)
        d = np.asarray(d, dtype=np.float64)
        return point + d[..., None] * np.stack([-np.sin(heading), np.cos(heading)], axis=1), heading

    def point_xy(self, s: float, d: float) -> tuple[float, float, float]:
        """World point (x, y) at road coordinates (s, d) and the heading there, as plain floats (`to_world`'s
        interpolation for one point, clamped onto the line)."""
        sl, xl, yl, hl = self._lists
        i = min(max(bisect_left(sl, s) - 1, 0), len(sl) - 2)  # np.searchsorted(self.s, s) - 1, clamped
        s0, s1 = sl[i], sl[i + 1]
        frac = min(max((s - s0) / (s1 - s0), 0.0), 1.0) if s1 > s0 else 0.0
        x = xl[i] + frac * (xl[i + 1] - xl[i])
        y = yl[i] + frac * (yl[i + 1] - yl[i])
        heading = hl[i] + frac * (hl[i + 1] - hl[i])
        return float(x - d * math.sin(heading)), float(y + d * math.cos(heading)), float(heading)

    def points_xy(self, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`point_xy` for arrays of road coordinates: x, y and the heading there (math's sin and cos, so the
        doubles do not depend on which SIMD kernels numpy picks on this CPU)."""
        i = np.clip(np.searchsorted(self.s, s) - 1, 0, len(self.s) - 2)
        s0, s1 = self.s[i], self.s[i + 1]
        span = s1 - s0
        frac = np.where(span > 0, np.clip((s - s0) / np.where(span > 0, span, 1.0), 0.0, 1.0), 0.0)
        p0, p1 = self.points[i], self.points[i + 1]
        heading = self.heading[i] + frac * (self.heading[i + 1] - self.heading[i])
        hl = heading.tolist()
        sin = np.array([math.sin(v) for v in hl])
        cos = np.array([math.cos(v) for v in hl])
        return (
            p0[:, 0] + frac * (p1[:, 0] - p0[:, 0]) - d * sin,
            p0[:, 1] + frac * (p1[:, 1] - p0[:, 1]) + d * cos,
            heading,
        )

    def project(self, xy: np.ndarray) -> np.ndarray:
        """Arc length of the closest point of the line to each of the points `xy` [n, 2] (shapely, all at once)."""
        return shapely.line_locate_point(self.line, shapely.points(np.asarray(xy)))

    def locate(
        self, x: float, y: float, s_hint: float | None = None, window: tuple[float, float] = (3.0, 8.0)
    ) -> tuple[float, float]:
        """(arc length, signed lateral offset; left positive) of the closest point to (x, y), searched only on
        the segments from `window[0]` before to `window[1]` after `s_hint` when given (a tracker's next step)."""
        if s_hint is None:
            k0, k1 = 0, len(self.seg)
        else:
            k0 = max(int(np.searchsorted(self.s, s_hint - window[0])) - 1, 0)
            k1 = min(int(np.searchsorted(self.s, s_hint + window[1])) + 1, len(self.seg))
        if k1 <= k0:
            raise ValueError(f"no segment of the line lies near arc length {s_hint} (length {self.length:.1f})")
        # numba is imported by the envs only, not by scene building.
        from sim.scene.locate import locate_on_segments

        return locate_on_segments(self.points, self.seg, self.seg_len, self.s, k0, k1, float(x), float(y))
