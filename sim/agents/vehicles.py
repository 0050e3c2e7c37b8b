"""Vehicles on roads: IDM car following along lane polylines offset from road centerlines, yielding at crosswalks
and taking turns at lane crossings.

Lanes: `lanes` per direction (the spec's road half width is lanes * lane_width); right lanes run along the
centerline's direction, left lanes against it (geometry in sim.agents.lanes). A vehicle whose centre reaches
its lane's end leaves it: it drives on along the lane that starts where this one ends (same heading, lanes of
consecutive blocks) when that lane's start is free, else it respawns at the start of a free lane drawn at random
(MetaDrive respawns traffic the same way); a start is free when the lane's last vehicle is at least the IDM
gap s0 + v T ahead. With no free start anywhere the vehicle waits at its lane's end. A crosswalk whose polygon
(grown by `crosswalk_margin`) holds an agent or the ego becomes a standing leader at its near edge, so IDM brakes
to a stop before it (Treiber, Hennecke & Helbing 2000). Where lanes cross (an intersection whose lanes run
through it), the crossing is a resource held by one axis at a time: vehicles of other axes stop before it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from curbside.config import merge_strict
from sim.agents.lanes import ConflictZones, Lane, build_conflict_zones, build_lanes, conflicts

__all__ = ["VEHICLE_DEFAULTS", "VEHICLE_DTYPE", "Lane", "VehicleManager", "build_lanes"]

VEHICLE_DTYPE = np.dtype([("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("yaw", "f8"),
                          ("length", "f8"), ("width", "f8")])

VEHICLE_DEFAULTS: dict[str, Any] = {
    "traffic_density": 1.0,  # vehicles per 100 m of lane (stochastic rounding per lane, so short lanes get some)
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
    "max_hold": 10.0,  # s an axis may keep a lane crossing while vehicles of another axis wait
}


class VehicleManager:
    """Vehicles driving the lanes of one scene with IDM, stopping for agents on crosswalks and at busy crossings."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(VEHICLE_DEFAULTS, config, name="vehicles config")
        self.n = 0
        self._scene: Any = None

    def reset(self, spec: dict[str, Any], rng: np.random.Generator) -> np.ndarray:
        """Spawn `traffic_density` vehicles per 100 m of lane, spaced at least one IDM jam gap apart."""
        c = self.config
        self.rng = rng
        if spec is not self._scene:  # lanes, crossings and zones are pure functions of the spec: build once
            self.lanes = build_lanes(spec)
            self.crosswalks = [Polygon(cw["polygon"]).buffer(c["crosswalk_margin"]) for cw in spec.get("crosswalks", [])]
            for cw in self.crosswalks:
                shapely.prepare(cw)
            self._cw_bounds = np.array([cw.bounds for cw in self.crosswalks]).reshape(-1, 4)
            self.zones: ConflictZones = build_conflict_zones(self.lanes, c["width"])
            self._index_lanes()
            self._scene = spec
        lane_id, s = [], []
        spacing = c["length"] + c["min_gap"] + 2.0
        for li, lane in enumerate(self.lanes):
            slots = np.arange(int(lane.length // spacing)) * spacing + 0.5 * c["length"]
            # No vehicle starts inside a lane crossing: two axes could otherwise begin inside one.
            z = self.zones.lane == li
            for lo, hi in zip(self.zones.s_in[z], self.zones.s_out[z]):
                slots = slots[(slots + c["length"] < lo) | (slots - c["length"] > hi)]
            want = c["traffic_density"] * lane.length / 100.0
            n = min(int(want) + int(rng.random() < want - int(want)), len(slots))
            if n <= 0:
                continue
            lane_id += [li] * n
            s += list(np.sort(rng.choice(slots, size=n, replace=False)) + rng.uniform(0.0, 1.0, n))
        self.lane_id = np.asarray(lane_id, dtype=np.int64)
        self.s = np.asarray(s, dtype=np.float64)
        self.n = len(self.s)
        lo, hi = c["desired_speed"]
        self.v0 = rng.uniform(lo, hi, self.n)
        self.v = self.v0 * rng.uniform(0.5, 1.0, self.n)
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        self.holder = np.full(self.zones.n_zones, np.nan)  # axis holding each crossing, nan when free
        self.held_for = np.zeros(self.zones.n_zones)
        self.respawns = self.continued = 0
        self.jumped = np.zeros(self.n, dtype=bool)
        return self.states()

    def _index_lanes(self) -> None:
        # All lanes laid end to end (with a gap) so poses and leaders are found for every vehicle at once.
        lengths = np.array([ln.length for ln in self.lanes])
        self.lane_len = lengths
        self.lane_off = np.concatenate([[0.0], np.cumsum(lengths + 1.0)])[:-1]
        self.all_pts = np.concatenate([ln.points for ln in self.lanes]) if self.lanes else np.zeros((0, 2))
        self.all_cum = np.concatenate([ln.cum + o for ln, o in zip(self.lanes, self.lane_off)]) if self.lanes else np.zeros(0)
        self.crossings = [(li, ci, s_in) for li, ln in enumerate(self.lanes) for ci, s_in, _ in ln.crossings]
        # The lane continuing each lane (starts within 1 m of its end, heading within 30 degrees), or -1.
        self.next_lane = np.full(len(self.lanes), -1, dtype=np.int64)
        if not self.lanes:
            return
        starts = np.array([ln.points[0] for ln in self.lanes])
        head0 = np.array([np.arctan2(*(ln.points[1] - ln.points[0])[::-1]) for ln in self.lanes])
        for li, ln in enumerate(self.lanes):
            h1 = np.arctan2(*(ln.points[-1] - ln.points[-2])[::-1])
            ok = (np.linalg.norm(starts - ln.points[-1], axis=1) < 1.0) & (np.cos(head0 - h1) > np.cos(np.pi / 6))
            ok[li] = False
            if ok.any():
                self.next_lane[li] = int(np.flatnonzero(ok)[0])

    def step(self, dt: float, people_xy: np.ndarray | None = None) -> np.ndarray:
        """Advance every vehicle by `dt` s; `people_xy` [n, 2] are agents and the ego (they make vehicles yield)."""
        c = self.config
        self.occupied = np.zeros(len(self.crosswalks), dtype=bool)
        if self.n and people_xy is not None and len(people_xy) and self.crosswalks:
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
            nxt = np.minimum(np.arange(1, self.n + 1), self.n - 1)
            same = (ls[nxt] == ls) & (np.arange(self.n) < self.n - 1)
            # A lane's front vehicle drives freely to the lane's end (no ring: it leaves the lane there).
            gap = np.where(same, ss[nxt] - ss - c["length"], np.inf)
            dv = np.where(same, v - v[nxt], 0.0)
            front = ss + c["length"] / 2.0
            for li, ci, s_in in self.crossings:
                if not self.occupied[ci]:
                    continue
                # A vehicle whose front has not reached the stop line treats it as a standing leader.
                ahead = s_in - c["stop_gap"] - front
                closer = (ls == li) & (ahead > -0.5) & (ahead < gap)
                gap[closer] = np.maximum(ahead[closer], 0.0)
                dv[closer] = v[closer]
            if self.zones.n_zones:
                self._crossing_leaders(dt, ls, ss, v, gap, dv)
            acc = np.empty(self.n)
            acc[order] = self._idm(v, self.v0[order], gap, dv)
            self.v = np.maximum(self.v + acc * dt, 0.0)
            self.s = self.s + self.v * dt
            self.jumped = np.zeros(self.n, dtype=bool)  # respawned this step (the only discontinuous moves)
            for i in np.flatnonzero(self.s >= self.lane_len[self.lane_id]).tolist():
                self._leave_lane(i)
        return self.states()

    def _crossing_leaders(self, dt: float, ls: np.ndarray, ss: np.ndarray, v: np.ndarray, gap: np.ndarray,
                          dv: np.ndarray) -> None:
        """Let one axis hold each lane crossing; vehicles of other axes about to enter it stop before it."""
        c, z = self.config, self.zones
        half = c["length"] / 2.0
        on = ls[None, :] == z.lane[:, None]  # [entries, vehicles], in the sorted order of step()
        inside = on & (ss + half > z.s_in[:, None]) & (ss - half < z.s_out[:, None])
        ahead = z.s_in[:, None] - c["stop_gap"] - (ss + half)
        # Claim a crossing once within comfortable braking distance (plus a margin) of its stop line.
        reach = v * v / (2.0 * c["comfort_decel"]) + v * dt + 3.0
        claim = on & ~inside & (ahead > -c["stop_gap"]) & (ahead < reach[None, :])
        for zi in range(z.n_zones):
            e = np.flatnonzero(z.zone == zi)
            axes_in = z.axis[e][inside[e].any(axis=1)]
            claiming = claim[e].any(axis=1)
            grant = self.holder[zi]
            dist = np.where(claim[e], ahead[e], np.inf).min(axis=1)  # nearest claimer's distance per entry
            if np.isnan(grant):
                users = claiming
            else:
                users = claiming & ~conflicts(z.axis[e], grant)
                waiting = claiming & ~users
                if waiting.any() and (self.held_for[zi] > c["max_hold"] or not (users.any() or len(axes_in))):
                    # The granted axis has kept others waiting too long, or is done: the nearest waiter is next.
                    users = waiting
                    grant = np.nan
            if np.isnan(grant):
                grant = z.axis[e][int(np.argmin(np.where(users, dist, np.inf)))] if users.any() else np.nan
            self.held_for[zi] = self.held_for[zi] + dt if grant == self.holder[zi] else 0.0
            self.holder[zi] = grant
            if np.isnan(grant) and not len(axes_in):
                continue
            # Stop before the crossing when another axis holds the grant, or is still inside it.
            for k in e.tolist():
                ax = z.axis[k]
                blocked = (not np.isnan(grant) and bool(conflicts(ax, grant))) or bool(conflicts(ax, axes_in).any())
                if blocked:
                    stop = claim[k] & (ahead[k] < gap)
                    gap[stop] = np.maximum(ahead[k][stop], 0.0)
                    dv[stop] = v[stop]

    def _leave_lane(self, i: int) -> None:
        """Move vehicle `i`, whose centre passed its lane's end, to the continuing lane or a free lane start."""
        c = self.config
        li, over = int(self.lane_id[i]), float(self.s[i] - self.lane_len[self.lane_id[i]])
        others = np.arange(self.n) != i
        first = np.full(len(self.lanes), np.inf)  # arc length of each lane's last (rearmost) vehicle
        np.minimum.at(first, self.lane_id[others], self.s[others])
        start_gap = first - c["length"]  # bumper gap to a vehicle entering at s = 0
        free = start_gap >= c["min_gap"] + self.v[i] * c["time_headway"]
        # Lanes that start inside a crossing another axis holds are not free either.
        for k in np.flatnonzero(self.zones.s_in < c["length"]).tolist():
            h = self.holder[self.zones.zone[k]]
            if not np.isnan(h) and conflicts(self.zones.axis[k], h):
                free[self.zones.lane[k]] = False
        nxt = int(self.next_lane[li])
        if nxt >= 0 and free[nxt]:
            self.lane_id[i], self.s[i] = nxt, min(over, 0.5 * start_gap[nxt])
            self.continued += 1
            return
        free[li] = free[li] and nxt < 0  # re-entering its own lane's start would be the old ring jump
        if free.any():
            self.lane_id[i], self.s[i] = int(self.rng.choice(np.flatnonzero(free))), 0.0
            self.respawns += 1
            self.jumped[i] = True
            return
        self.s[i], self.v[i] = self.lane_len[li] - 1e-6, 0.0  # no free start: wait at the lane's end

    def _idm(self, v: np.ndarray, v0: np.ndarray, gap: np.ndarray, dv: np.ndarray) -> np.ndarray:
        c = self.config
        s_star = c["min_gap"] + np.maximum(0.0, v * c["time_headway"] + v * dv / (2.0 * np.sqrt(c["max_accel"] * c["comfort_decel"])))
        with np.errstate(divide="ignore"):
            interaction = np.where(np.isfinite(gap), (s_star / np.maximum(gap, 0.1)) ** 2, 0.0)
        a = c["max_accel"] * (1.0 - (v / v0) ** c["delta"] - interaction)
        return a.clip(-c["max_decel"], c["max_accel"])

    def states(self) -> np.ndarray:
        """Every vehicle's centre, velocity, heading and size as a structured array of VEHICLE_DTYPE."""
        out = np.zeros(self.n, dtype=VEHICLE_DTYPE)
        if self.n:
            g = self.lane_off[self.lane_id] + np.minimum(self.s, self.lane_len[self.lane_id] - 1e-6)
            k = (np.searchsorted(self.all_cum, g, side="right") - 1).clip(0, len(self.all_cum) - 2)
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
