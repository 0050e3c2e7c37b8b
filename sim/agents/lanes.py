"""Lane geometry for vehicles: lane polylines offset from road centerlines, the crosswalks they cross, the
conflict zones where lanes of different directions cross, which only one axis may hold at a time, and the
connectors that carry vehicles through intersections (straight on, left and right turns).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from shapely.geometry import LineString, Polygon

from sim.scene.polyline import Polyline
from sim.scene.scene import Scene, as_scene


class Lane(Polyline):
    """One lane: its polyline (arc lengths `s`), the crosswalk intervals [s_in, s_out] along it, its road and rank,
    and for connectors the lanes it joins."""

    def __init__(
        self,
        points: np.ndarray,
        crossings: list[tuple[int, float, float]] | None = None,
        road: int = -1,
        rank: int = 0,
        src: int = -1,
        dst: int = -1,
    ) -> None:
        pts = np.asarray(points, dtype=np.float64)
        # Lanes have always measured their segments with np.linalg.norm; Polyline's np.hypot differs in the
        # last bit, and traffic would then drift from the episodes recorded so far.
        super().__init__(pts, np.linalg.norm(np.diff(pts, axis=0), axis=1))
        self.crossings = [] if crossings is None else crossings  # (crosswalk index, s_in, s_out)
        self.road = road  # index of the spec road the lane belongs to
        self.rank = rank  # 0 for the lane next to the centerline, 1 for the next one out, ...
        self.src = src  # connectors only: the lane it leaves ...
        self.dst = dst  # ... and the lane it joins

    @property
    def is_connector(self) -> bool:
        """Whether this lane is a path through an intersection between two road lanes."""
        return self.src >= 0

    def pose(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World positions [n, 2] and headings [n] at arc lengths `s` (clipped onto the lane)."""
        s = np.clip(s, 0.0, self.length)
        k = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.points) - 2)
        seg = self.seg[k]
        seg_len = np.maximum(self.s[k + 1] - self.s[k], 1e-9)
        xy = self.points[k] + seg * ((s - self.s[k]) / seg_len)[:, None]
        return xy, np.arctan2(seg[:, 1], seg[:, 0])


@dataclass
class ConflictZones:
    """Entries of lanes into conflict zones: per entry its lane, zone, [s_in, s_out] and the lane's axis there."""

    lane: np.ndarray  # int64 [e]
    zone: np.ndarray  # int64 [e]
    s_in: np.ndarray  # arc length where a vehicle's front enters the zone
    s_out: np.ndarray  # arc length where its rear has left it
    axis: np.ndarray  # lane heading at the zone, radians; axes within 30 degrees (or opposite) do not conflict
    n_zones: int


def build_lanes(scene: Scene | Mapping[str, Any]) -> list[Lane]:
    """Lane polylines of every road in `scene` (a dict is parsed), with the crosswalks each one crosses."""
    scene = as_scene(scene)
    crosswalks = [Polygon(crosswalk["polygon"]) for crosswalk in scene.crosswalks]
    lanes = []
    for ri, road in enumerate(scene.roads):
        lw, n_lanes = float(road["lane_width"]), int(road["lanes"])
        for line in road.get("centerlines", []):
            base = LineString(line)
            for k in range(n_lanes):
                for side in (-1.0, 1.0):  # right lanes follow the centerline, left lanes run against it
                    off = base.offset_curve(side * (k + 0.5) * lw)
                    if off.is_empty or off.geom_type != "LineString":
                        continue
                    pts = np.asarray(off.coords)
                    if side > 0:
                        pts = pts[::-1]
                    lane = _lane(pts, crosswalks)
                    lane.road, lane.rank = ri, k
                    lanes.append(lane)
    return [ln for ln in lanes if ln.length > 10.0]


JUNCTIONS = ("X", "T")


def build_connectors(
    scene: Scene | Mapping[str, Any], lanes: list[Lane], max_turn: float = math.radians(100.0)
) -> list[Lane]:
    """Paths through every intersection and T-junction: from each lane ending at the junction's box to each lane
    of another arm starting there (straight on, left, right; no U-turns), as cubic Bezier curves tangent to both.

    A lane end and a lane start belong to the junction when both lie within a metre of the box's circumscribed
    circle and the start lies ahead of the end; lane k (counted from the centerline) joins lane k.
    """
    scene = as_scene(scene)
    crosswalks = [Polygon(crosswalk["polygon"]) for crosswalk in scene.crosswalks]
    roads = scene.roads
    out: list[Lane] = []
    for ri, road in enumerate(roads):
        if road.get("block") not in JUNCTIONS:
            continue
        hw = int(road["lanes"]) * float(road["lane_width"])
        # The box centre lies half a road width beyond the end of the first arm (the block's entry arm).
        arm = np.asarray(road["centerlines"][0], dtype=np.float64)
        direction = arm[-1] - arm[-2]
        centre = arm[-1] + hw * direction / np.hypot(*direction)
        near = math.sqrt(2.0) * hw + 1.0  # the box's circumscribed circle plus a metre
        ids = [i for i, ln in enumerate(lanes) if ln.road == ri]
        ends = [i for i in ids if np.hypot(*(lanes[i].points[-1] - centre)) <= near]
        starts = [i for i in ids if np.hypot(*(lanes[i].points[0] - centre)) <= near]
        for a in ends:
            end, h_end = lanes[a].points[-1], _heading(lanes[a], lanes[a].length)
            for b in starts:
                start, h_start = lanes[b].points[0], _heading(lanes[b], 0.0)
                gap = start - end
                dist = float(np.hypot(*gap))
                turn = math.atan2(math.sin(h_start - h_end), math.cos(h_start - h_end))
                ahead = float(gap @ np.array([math.cos(h_end), math.sin(h_end)]))
                # Lane k feeds lane k of the other arm (no lane changes inside the box).
                if a == b or lanes[a].rank != lanes[b].rank or dist <= 1.0 or abs(turn) > max_turn or ahead <= 0.5:
                    continue
                lane = _lane(_bezier(end, h_end, start, h_start), crosswalks)
                lane.road, lane.src, lane.dst = ri, a, b
                out.append(lane)
    return out


def _bezier(p0: np.ndarray, h0: float, p3: np.ndarray, h3: float, n: int = 17) -> np.ndarray:
    """Points of the cubic Bezier from p0 (heading h0) to p3 (heading h3), control arms 0.4 x the chord."""
    k = 0.4 * float(np.hypot(*(p3 - p0)))
    p1 = p0 + k * np.array([math.cos(h0), math.sin(h0)])
    p2 = p3 - k * np.array([math.cos(h3), math.sin(h3)])
    frac = np.linspace(0.0, 1.0, n)[:, None]
    return (1 - frac) ** 3 * p0 + 3 * (1 - frac) ** 2 * frac * p1 + 3 * (1 - frac) * frac * frac * p2 + frac**3 * p3


def connector_compatibility(lanes: list[Lane], width: float, margin: float = 0.3) -> np.ndarray:
    """[n, n] bool: whether vehicles may be on connectors i and j at once (same junction, disjoint swept paths,
    different source and target lanes); always True between lanes of different junctions or for i == j.
    """
    n_lanes = len(lanes)
    ok = np.ones((n_lanes, n_lanes), dtype=bool)
    conn = [i for i, ln in enumerate(lanes) if ln.is_connector]
    swept = {i: lanes[i].line.buffer(0.5 * width + margin) for i in conn}
    for i in conn:
        for j in conn:
            lane_a, lane_b = lanes[i], lanes[j]
            if i >= j or lane_a.road != lane_b.road:
                continue
            clash = lane_a.src == lane_b.src or lane_a.dst == lane_b.dst or swept[i].intersects(swept[j])
            ok[i, j] = ok[j, i] = not clash
    return ok


def _lane(pts: np.ndarray, crosswalks: list[Polygon]) -> Lane:
    lane = Lane(pts)
    line = lane.line
    crossings = lane.crossings
    for ci, poly in enumerate(crosswalks):
        inter = line.intersection(poly)
        if inter.is_empty:
            continue
        coords = np.concatenate([np.asarray(geom.coords) for geom in getattr(inter, "geoms", [inter])])
        arclen = np.array([line.project(shapely.Point(coord)) for coord in coords])
        crossings.append((ci, float(arclen.min()), float(arclen.max())))
    return lane


def conflicts(axis_a: np.ndarray | float, axis_b: np.ndarray | float) -> np.ndarray:
    """Whether lanes heading `axis_a` and `axis_b` cross (more than 30 degrees apart, in either direction)."""
    return np.abs(np.sin(np.asarray(axis_a) - np.asarray(axis_b))) > 0.5


def build_conflict_zones(lanes: list[Lane], width: float, merge: float = 12.0) -> ConflictZones:
    """Find where lanes cross at more than 30 degrees and group nearby crossings (one intersection) into zones.

    Each lane's interval around a crossing is grown so that a vehicle of `width` outside it cannot touch one
    inside the crossing lane's interval: half a width across the other lane, stretched by 1/sin of the angle.
    """
    lines = [ln.line for ln in lanes]
    tree = shapely.STRtree(lines)
    pts: list[tuple[int, float, float, float, float]] = []  # lane, s, grow, x, y
    for a, b in zip(*tree.query(lines, predicate="crosses")):
        if a >= b:
            continue
        inter = lines[a].intersection(lines[b])
        for g in getattr(inter, "geoms", [inter]):
            if g.geom_type != "Point":
                continue
            sa, sb = lines[a].project(g), lines[b].project(g)
            ha, hb = _heading(lanes[a], sa), _heading(lanes[b], sb)
            sin = abs(math.sin(ha - hb))
            if sin <= 0.5:
                continue  # a continuation or a merge, not a crossing
            cos = abs(math.cos(ha - hb))
            grow = 0.5 * width * (1.0 + cos) / sin + 0.5
            pts += [(a, sa, grow, g.x, g.y), (b, sb, grow, g.x, g.y)]
    if not pts:
        none = np.zeros(0)
        return ConflictZones(none.astype(np.int64), none.astype(np.int64), none, none, none, 0)
    arr = np.array(pts)
    # Crossings closer than `merge` belong to one intersection: connected components of the "close" graph,
    # numbered in the order of their first point.
    xy = arr[:, 3:5]
    close = np.linalg.norm(xy[:, None] - xy[None], axis=2) < merge
    zone_of = connected_components(csr_matrix(close), directed=False)[1]
    lane_ids = arr[:, 0].astype(np.int64)
    keys = sorted({(int(zone_of[i]), int(lane_ids[i])) for i in range(len(arr))})
    lane, zone, s_in, s_out, axis = [], [], [], [], []
    for z, li in keys:
        m = (zone_of == z) & (lane_ids == li)
        lo, hi = float(np.min(arr[m, 1] - arr[m, 2])), float(np.max(arr[m, 1] + arr[m, 2]))
        lane.append(li)
        zone.append(z)
        s_in.append(max(lo, 0.0))
        s_out.append(min(hi, lanes[li].length))
        axis.append(_heading(lanes[li], 0.5 * (lo + hi)))
    return ConflictZones(
        np.array(lane, dtype=np.int64),
        np.array(zone, dtype=np.int64),
        np.array(s_in),
        np.array(s_out),
        np.array(axis),
        int(zone_of.max()) + 1,
    )


def _heading(lane: Lane, s: float) -> float:
    return float(lane.pose(np.array([s]))[1][0])
