"""Vehicles on roads: IDM car following along lane polylines offset from road centerlines, yielding at crosswalks.

Lanes: `lanes` per direction (the spec's road half width is lanes * lane_width); right lanes run along the
centerline's direction, left lanes against it. Each lane is a ring: a vehicle leaving its end re-enters at
its start and follows the lane's last vehicle (MetaDrive respawns traffic the same way). A crosswalk whose
polygon (grown by `crosswalk_margin`) holds an agent or the ego becomes a standing leader at its near edge,
so IDM brakes to a stop before it (Treiber, Hennecke & Helbing 2000).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from curbside.config import merge_strict

VEHICLE_DTYPE = np.dtype([("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("yaw", "f8"),
                          ("length", "f8"), ("width", "f8")])

VEHICLE_DEFAULTS: dict[str, Any] = {
    "traffic_density": 1.0,  # vehicles per 100 m of lane
    "desired_speed": [8.0, 12.0],  # m/s (29-43 km/h, urban streets), drawn per vehicle
    "time_headway": 1.5,  # IDM T (s)
    "min_gap": 2.0,  # IDM s0 (m)
    "max_accel": 1.5,  # IDM a (m/s^2)
    "comfort_decel": 2.0,  # IDM b (m/s^2)
    "max_decel": 8.0,  # physical braking limit (m/s^2)
    "delta": 4.0,
    "length": 4.5,
    "width": 1.8,
    "crosswalk_margin": 1.0,  # agents this close to a crosswalk make vehicles yield
    "stop_gap": 1.5,  # where a yielding vehicle's front stops, before the crosswalk's near edge
}


@dataclass
class Lane:
    """One lane: its polyline, cumulative arc lengths and the crosswalk intervals [s_in, s_out] along it."""

    points: np.ndarray
    cum: np.ndarray
    crossings: list[tuple[int, float, float]]  # (crosswalk index, s_in, s_out)

    @property
    def length(self) -> float:
        """Lane length in metres."""
        return float(self.cum[-1])

    def pose(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World positions [n, 2] and headings [n] at arc lengths `s` (wrapped onto the lane)."""
        s = np.mod(s, self.length)
        k = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.points) - 2)
        seg = self.points[k + 1] - self.points[k]
        seg_len = np.maximum(self.cum[k + 1] - self.cum[k], 1e-9)
        xy = self.points[k] + seg * ((s - self.cum[k]) / seg_len)[:, None]
        return xy, np.arctan2(seg[:, 1], seg[:, 0])


def build_lanes(spec: dict[str, Any]) -> list[Lane]:
    """Lane polylines of every road in `spec`, with the crosswalks each one crosses."""
    crosswalks = [Polygon(c["polygon"]) for c in spec.get("crosswalks", [])]
    lanes = []
    for road in spec.get("roads", []):
        lw, n = float(road["lane_width"]), int(road["lanes"])
        for line in road.get("centerlines", []):
            base = LineString(line)
            for k in range(n):
                for side in (-1.0, 1.0):  # right lanes follow the centerline, left lanes run against it
                    off = base.offset_curve(side * (k + 0.5) * lw)
                    if off.is_empty or off.geom_type != "LineString":
                        continue
                    pts = np.asarray(off.coords)
                    if side > 0:
                        pts = pts[::-1]
                    lanes.append(_lane(pts, crosswalks))
    return [ln for ln in lanes if ln.length > 10.0]


def _lane(pts: np.ndarray, crosswalks: list[Polygon]) -> Lane:
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    line = LineString(pts)
    crossings = []
    for ci, poly in enumerate(crosswalks):
        inter = line.intersection(poly)
        if inter.is_empty:
            continue
        coords = np.concatenate([np.asarray(g.coords) for g in getattr(inter, "geoms", [inter])])
        s = np.array([line.project(shapely.Point(c)) for c in coords])
        crossings.append((ci, float(s.min()), float(s.max())))
    return Lane(pts, cum, crossings)


class VehicleManager:
    """Vehicles driving the lanes of one scene with IDM, stopping for agents on crosswalks."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(VEHICLE_DEFAULTS, config, name="vehicles config")
        self.n = 0

    def reset(self, spec: dict[str, Any], rng: np.random.Generator) -> np.ndarray:
        """Spawn `traffic_density` vehicles per 100 m of lane, spaced at least one IDM jam gap apart."""
        c = self.config
        self.lanes = build_lanes(spec)
        self.crosswalks = [Polygon(cw["polygon"]).buffer(c["crosswalk_margin"]) for cw in spec.get("crosswalks", [])]
        self._cw_bounds = np.array([cw.bounds for cw in self.crosswalks]).reshape(-1, 4)
        for cw in self.crosswalks:
            shapely.prepare(cw)
        self._index_lanes()
        lane_id, s = [], []
        spacing = c["length"] + c["min_gap"] + 2.0
        for li, lane in enumerate(self.lanes):
            n = min(int(round(c["traffic_density"] * lane.length / 100.0)), int(lane.length // spacing))
            if n <= 0:
                continue
            slots = np.sort(rng.choice(int(lane.length // spacing), size=n, replace=False)) * spacing
            lane_id += [li] * n
            s += list(slots + rng.uniform(0.0, 1.0, n))
        self.lane_id = np.asarray(lane_id, dtype=np.int64)
        self.s = np.asarray(s, dtype=np.float64)
        self.n = len(self.s)
        lo, hi = c["desired_speed"]
        self.v0 = rng.uniform(lo, hi, self.n)
        self.v = self.v0 * rng.uniform(0.5, 1.0, self.n)
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        return self.states()

    def _index_lanes(self) -> None:
        # All lanes laid end to end (with a gap) so poses and leaders are found for every vehicle at once.
        lengths = np.array([ln.length for ln in self.lanes])
        self.lane_len = lengths
        self.lane_off = np.concatenate([[0.0], np.cumsum(lengths + 1.0)])[:-1]
        self.all_pts = np.concatenate([ln.points for ln in self.lanes]) if self.lanes else np.zeros((0, 2))
        self.all_cum = np.concatenate([ln.cum + o for ln, o in zip(self.lanes, self.lane_off)]) if self.lanes else np.zeros(0)
        self.crossings = [(li, ci, s_in) for li, ln in enumerate(self.lanes) for ci, s_in, _ in ln.crossings]

    def step(self, dt: float, people_xy: np.ndarray | None = None) -> np.ndarray:
        """Advance every vehicle by `dt` s; `people_xy` [n, 2] are agents and the ego (they make vehicles yield)."""
        c = self.config
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        if people_xy is not None and len(people_xy) and self.crosswalks:
            xy = np.asarray(people_xy, dtype=np.float64)
            # Bounding boxes first: most ticks nobody is near a crosswalk and no polygon test runs at all.
            lo, hi = self._cw_bounds[:, None, :2], self._cw_bounds[:, None, 2:]
            near = np.all((xy[None] >= lo) & (xy[None] <= hi), axis=2)
            for ci in np.flatnonzero(near.any(axis=1)).tolist():
                pts = xy[near[ci]]
                self.occupied[ci] = bool(shapely.contains_xy(self.crosswalks[ci], pts[:, 0], pts[:, 1]).any())
        if self.n:
            order = np.lexsort((self.s, self.lane_id))
            ls, ss, v = self.lane_id[order], self.s[order], self.v[order]
            first = np.searchsorted(ls, ls, side="left")
            nxt = np.roll(np.arange(self.n), -1)
            same = ls[nxt] == ls
            lead = np.where(same, nxt, first)
            gap = np.where(same, ss[lead] - ss, ss[lead] + self.lane_len[ls] - ss) - c["length"]
            dv = v - v[lead]
            alone = lead == np.arange(self.n)
            gap[alone], dv[alone] = np.inf, 0.0
            front = ss + c["length"] / 2.0
            for li, ci, s_in in self.crossings:
                if not self.occupied[ci]:
                    continue
                # A vehicle whose front has not reached the stop line treats it as a standing leader.
                ahead = s_in - c["stop_gap"] - front
                closer = (ls == li) & (ahead > -0.5) & (ahead < gap)
                gap[closer] = np.maximum(ahead[closer], 0.0)
                dv[closer] = v[closer]
            acc = np.empty(self.n)
            acc[order] = self._idm(v, self.v0[order], gap, dv)
            self.v = np.maximum(self.v + acc * dt, 0.0)
            self.s = np.mod(self.s + self.v * dt, self.lane_len[self.lane_id])
        return self.states()

    def _idm(self, v: np.ndarray, v0: np.ndarray, gap: np.ndarray, dv: np.ndarray) -> np.ndarray:
        c = self.config
        s_star = c["min_gap"] + np.maximum(0.0, v * c["time_headway"] + v * dv / (2.0 * np.sqrt(c["max_accel"] * c["comfort_decel"])))
        with np.errstate(divide="ignore"):
            interaction = np.where(np.isfinite(gap), (s_star / np.maximum(gap, 0.1)) ** 2, 0.0)
        a = c["max_accel"] * (1.0 - (v / v0) ** c["delta"] - interaction)
        return np.clip(a, -c["max_decel"], c["max_accel"])

    def states(self) -> np.ndarray:
        """Every vehicle's centre, velocity, heading and size as a structured array of VEHICLE_DTYPE."""
        out = np.zeros(self.n, dtype=VEHICLE_DTYPE)
        if self.n:
            g = self.lane_off[self.lane_id] + self.s
            k = np.clip(np.searchsorted(self.all_cum, g, side="right") - 1, 0, len(self.all_cum) - 2)
            seg = self.all_pts[k + 1] - self.all_pts[k]
            t = (g - self.all_cum[k]) / np.maximum(self.all_cum[k + 1] - self.all_cum[k], 1e-9)
            xy = self.all_pts[k] + seg * t[:, None]
            yaw = np.arctan2(seg[:, 1], seg[:, 0])
            out["x"], out["y"], out["yaw"] = xy[:, 0], xy[:, 1], yaw
            out["vx"], out["vy"] = self.v * np.cos(yaw), self.v * np.sin(yaw)
        out["length"], out["width"] = self.config["length"], self.config["width"]
        return out

    def fronts(self) -> tuple[np.ndarray, np.ndarray]:
        """(lane index, arc length of the front bumper) of every vehicle."""
        return self.lane_id.copy(), self.s + self.config["length"] / 2.0
