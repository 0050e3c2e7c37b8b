"""Vehicles on roads: IDM car following along lane polylines offset from road centerlines, turning through
intersections, yielding at crosswalks and taking turns where paths cross.

Lanes: `lanes` per direction (the spec's road half width is lanes * lane_width); right lanes run along the
centerline's direction, left lanes against it; connectors are Bezier paths through X and T junctions from
each arriving lane to each leaving lane of another arm (geometry in sim.agents.lanes). Every vehicle carries
its next lane, drawn when it enters a lane among the lane's successors (its continuation into the next
block, or the junction's connectors: straight on, left, right), and IDM looks one lane ahead: the rearmost
vehicle and any occupied crosswalk on the next lane are leaders too (Treiber, Hennecke & Helbing 2000).
A junction is entered on a grant: a vehicle nearing the box claims its connector, which is granted when it
is compatible (disjoint swept path, other source and target lanes) with every connector in use or granted
and the leaving lane has room for the vehicle; claimers are served longest-waiting first, and a waiting
claimer reserves its connector so that later, compatible streams cannot starve it. Without a grant the box
edge is a standing leader. A lane without successors ends the vehicle's trip: it respawns at the start of a
free road lane (MetaDrive respawns traffic the same way), or waits when none is free. A crosswalk whose
polygon (grown by `crosswalk_margin`) holds an agent or the ego becomes a standing leader at its near edge.
Where road lanes cross without a junction box, the crossing is a resource held by one axis at a time.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from curbside.config import merge_strict
from sim.agents.lanes import (ConflictZones, Lane, build_conflict_zones, build_connectors, build_lanes, conflicts,
                              connector_compatibility)

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
    "junction_stop": 1.0,  # m before the box edge where a vehicle without a grant stops
    "turn_accel": 3.0,  # m/s^2 lateral acceleration through turns: speed limit sqrt(a R) on connectors
    "turning": True,  # drive through X/T junctions on connectors (False: lanes end at the box, vehicles respawn)
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
            road = build_lanes(spec)
            self.n_road = len(road)
            self.lanes = road + (build_connectors(spec, road) if c["turning"] else [])
            self.is_connector = np.array([ln.is_connector for ln in self.lanes], dtype=bool)
            self.compatible = connector_compatibility(self.lanes, c["width"])
            self.crosswalks = [Polygon(cw["polygon"]).buffer(c["crosswalk_margin"]) for cw in spec.get("crosswalks", [])]
            for cw in self.crosswalks:
                shapely.prepare(cw)
            self._cw_bounds = np.array([cw.bounds for cw in self.crosswalks]).reshape(-1, 4)
            self.zones: ConflictZones = build_conflict_zones(road, c["width"])
            self._index_lanes()
            self._scene = spec
        lane_id, s = [], []
        spacing = c["length"] + c["min_gap"] + 2.0
        for li, lane in enumerate(self.lanes[:self.n_road]):  # nobody starts inside a junction box
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
        self.respawns = self.continued = self.turns = 0
        self.jumped = np.zeros(self.n, dtype=bool)
        self.granted = np.zeros(self.n, dtype=bool)  # holds a grant for the junction connector it is heading to
        self.waited = np.zeros(self.n)  # s spent claiming a connector without a grant
        self.prev_lane = np.full(self.n, -1, dtype=np.int64)  # the lane a vehicle's rear may still be on
        self.next = np.array([self._draw_next(int(li)) for li in self.lane_id], dtype=np.int64)
        return self.states()

    def _draw_next(self, lane: int) -> int:
        """The lane a vehicle entering `lane` drives onto after it: one of its successors, or -1 (trip ends)."""
        succ = self.successors[lane]
        if not succ:
            return -1
        return succ[0] if len(succ) == 1 else int(succ[int(self.rng.integers(len(succ)))])

    def _index_lanes(self) -> None:
        # All lanes laid end to end (with a gap) so poses and leaders are found for every vehicle at once.
        lengths = np.array([ln.length for ln in self.lanes])
        self.lane_len = lengths
        self.lane_off = np.concatenate([[0.0], np.cumsum(lengths + 1.0)])[:-1]
        self.all_pts = np.concatenate([ln.points for ln in self.lanes]) if self.lanes else np.zeros((0, 2))
        self.all_cum = np.concatenate([ln.cum + o for ln, o in zip(self.lanes, self.lane_off)]) if self.lanes else np.zeros(0)
        self.crossings = [(li, ci, s_in) for li, ln in enumerate(self.lanes) for ci, s_in, _ in ln.crossings]
        # The lane continuing each road lane (starts within 1 m of its end, heading within 30 degrees), or -1;
        # a connector continues onto its target lane.
        self.next_lane = np.full(len(self.lanes), -1, dtype=np.int64)
        self.successors: list[list[int]] = [[] for _ in self.lanes]
        if not self.lanes:
            return
        road = self.lanes[:self.n_road]
        starts = np.array([ln.points[0] for ln in road])
        head0 = np.array([np.arctan2(*(ln.points[1] - ln.points[0])[::-1]) for ln in road])
        for li, ln in enumerate(road):
            h1 = np.arctan2(*(ln.points[-1] - ln.points[-2])[::-1])
            ok = (np.linalg.norm(starts - ln.points[-1], axis=1) < 1.0) & (np.cos(head0 - h1) > np.cos(np.pi / 6))
            ok[li] = False
            if ok.any():
                self.next_lane[li] = int(np.flatnonzero(ok)[0])
                self.successors[li].append(int(self.next_lane[li]))
        self.start_xy = np.array([ln.points[0] for ln in self.lanes])
        self.cw_lanes: list[list[tuple[int, float]]] = [[] for _ in self.crosswalks]
        for li, ci, s_in in self.crossings:
            self.cw_lanes[ci].append((li, s_in))
        # A connector is a turn when its heading changes by more than 45 degrees (counted in `turns`).
        self.turn = np.zeros(len(self.lanes), dtype=bool)
        self.vlim = np.full(len(self.lanes), np.inf)
        for ci in np.flatnonzero(self.is_connector).tolist():
            ln = self.lanes[ci]
            self.vlim[ci] = np.sqrt(self.config["turn_accel"] * _min_radius(ln.points))
            d0, d1 = ln.points[1] - ln.points[0], ln.points[-1] - ln.points[-2]
            self.turn[ci] = abs(np.arctan2(d0[0] * d1[1] - d0[1] * d1[0], d0 @ d1)) > np.pi / 4
            self.next_lane[ci] = self.lanes[ci].dst
            self.successors[ci].append(self.lanes[ci].dst)
            self.successors[self.lanes[ci].src].append(ci)
        fed = {li for succ in self.successors for li in succ}
        self.entry = np.array([li < self.n_road and li not in fed for li in range(len(self.lanes))], dtype=bool)

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
            self._look_ahead(dt, order, ls, ss, v, same, gap, dv)
            acc = np.empty(self.n)
            acc[order] = self._idm(v, self._desired_speed()[order], gap, dv)
            self.v = np.maximum(self.v + acc * dt, 0.0)
            self.s = self.s + self.v * dt
            self.jumped = np.zeros(self.n, dtype=bool)  # respawned this step (the only discontinuous moves)
            for i in np.flatnonzero(self.s >= self.lane_len[self.lane_id]).tolist():
                self._leave_lane(i)
            self.prev_lane[self.s >= c["length"]] = -1  # its rear has left the lane behind it
        return self.states()

    def _desired_speed(self) -> np.ndarray:
        """Each vehicle's IDM v0: its own, capped by its lane's turn speed and, near the end, by the next lane's
        (the speed from which comfortable braking reaches that limit at the lane's end)."""
        b = self.config["comfort_decel"]
        lim_next = np.where(self.next >= 0, self.vlim[np.maximum(self.next, 0)], np.inf)
        to_end = np.maximum(self.lane_len[self.lane_id] - self.s, 0.0)
        return np.minimum(np.minimum(self.v0, self.vlim[self.lane_id]), np.sqrt(lim_next ** 2 + 2.0 * b * to_end))

    def add(self, lane: int, s: float, speed: float = 0.0, next_lane: int | None = None) -> int:
        """Put one more vehicle on `lane` at arc length `s` (scripted scenarios); returns its index."""
        if not 0 <= lane < len(self.lanes):
            raise ValueError(f"lane {lane} does not exist; this scene has lanes 0..{len(self.lanes) - 1}")
        if next_lane is not None and next_lane not in self.successors[lane]:
            raise ValueError(f"lane {next_lane} does not follow lane {lane}; its successors are {self.successors[lane]}")
        lo, hi = self.config["desired_speed"]
        self.lane_id = np.append(self.lane_id, lane)
        self.s = np.append(self.s, float(s))
        self.v0 = np.append(self.v0, 0.5 * (lo + hi))
        self.v = np.append(self.v, float(speed))
        self.jumped = np.append(self.jumped, False)
        self.granted = np.append(self.granted, False)
        self.waited = np.append(self.waited, 0.0)
        self.prev_lane = np.append(self.prev_lane, -1)
        self.next = np.append(self.next, self._draw_next(lane) if next_lane is None else next_lane)
        self.n += 1
        return self.n - 1

    def _look_ahead(self, dt: float, order: np.ndarray, ls: np.ndarray, ss: np.ndarray, v: np.ndarray,
                    same: np.ndarray, gap: np.ndarray, dv: np.ndarray) -> None:
        """Give each lane's front vehicle the leaders of its next lane, and stop it at a junction without a grant."""
        c = self.config
        half = c["length"] / 2.0
        rear_s, rear_v = np.full(len(self.lanes), np.inf), np.zeros(len(self.lanes))
        first = np.flatnonzero(np.r_[True, ls[1:] != ls[:-1]])  # sorted by (lane, s): each lane's rearmost
        rear_s[ls[first]], rear_v[ls[first]] = ss[first], v[first]
        front = np.flatnonzero(~same)
        ids, nxt = order[front], self.next[order[front]]
        to_end = self.lane_len[ls[front]] - (ss[front] + half)
        has = nxt >= 0
        nx = np.maximum(nxt, 0)
        self._grant(dt, ids, nxt, to_end, v[front], rear_s)
        blocked = has & self.is_connector[nx] & ~self.granted[ids]
        cand = np.where(blocked, to_end - c["junction_stop"], np.inf)
        cand_dv = v[front].copy()
        ahead = to_end + rear_s[nx] - half
        use = has & ~blocked & (ahead < cand)
        cand[use], cand_dv[use] = ahead[use], v[front][use] - rear_v[nx][use]
        # A vehicle that just left a lane still has its rear on it: it leads that lane's front vehicle.
        left = np.flatnonzero(self.prev_lane >= 0)
        if len(left):
            k = left[np.lexsort((self.s[left], self.prev_lane[left]))]  # per lane left, the rearmost first
            k = k[np.r_[True, self.prev_lane[k][1:] != self.prev_lane[k][:-1]]]
            tail_s, tail_v = np.full(len(self.lanes), np.inf), np.zeros(len(self.lanes))
            tail_s[self.prev_lane[k]], tail_v[self.prev_lane[k]] = self.s[k], self.v[k]
            tail = to_end + tail_s[ls[front]] - half
            hit = tail < cand
            cand[hit], cand_dv[hit] = tail[hit], v[front][hit] - tail_v[ls[front]][hit]
        for ci in np.flatnonzero(self.occupied).tolist():
            for li, s_in in self.cw_lanes[ci]:
                stop = to_end + s_in - c["stop_gap"]
                hit = has & ~blocked & (nxt == li) & (stop < cand)
                cand[hit], cand_dv[hit] = stop[hit], v[front][hit]
        closer = cand < gap[front]
        k = front[closer]
        gap[k], dv[k] = np.maximum(cand[closer], 0.0), cand_dv[closer]

    def _grant(self, dt: float, ids: np.ndarray, nxt: np.ndarray, to_end: np.ndarray, v: np.ndarray,
               rear_s: np.ndarray) -> None:
        """Grant junction connectors to front vehicles nearing them: longest-waiting first, compatible paths only."""
        c = self.config
        nx = np.maximum(nxt, 0)
        reach = v * v / (2.0 * c["comfort_decel"]) + v * dt + 3.0 + c["junction_stop"]
        want = (nxt >= 0) & self.is_connector[nx] & ~self.granted[ids] & (to_end < reach)
        if not want.any():
            return
        on = self.lane_id[self.is_connector[self.lane_id]]
        tails = self.prev_lane[self.prev_lane >= 0]
        busy = list(np.unique(np.concatenate([on, tails[self.is_connector[tails]], self.next[self.granted]])))
        cand = np.flatnonzero(want)
        cand = cand[np.lexsort((to_end[cand], -self.waited[ids[cand]]))]
        reserved: list[int] = []
        for k in cand.tolist():
            i, conn = int(ids[k]), int(nxt[k])
            room = rear_s[self.lanes[conn].dst] - c["length"] / 2.0 >= c["length"] + c["min_gap"]
            if room and self.compatible[conn, busy].all() and self.compatible[conn, reserved].all():
                self.granted[i], self.waited[i] = True, 0.0
                busy.append(conn)
            else:
                # A waiting claimer reserves its path: later claimers that would cross it wait behind it.
                self.waited[i] += dt
                reserved.append(conn)

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
        """Move vehicle `i`, whose centre passed its lane's end, onto its next lane, or respawn it (trip ended)."""
        c = self.config
        li, over = int(self.lane_id[i]), float(self.s[i] - self.lane_len[self.lane_id[i]])
        others = np.arange(self.n) != i
        first = np.full(len(self.lanes), np.inf)  # arc length of each lane's last (rearmost) vehicle
        np.minimum.at(first, self.lane_id[others], self.s[others])
        start_gap = first - c["length"]  # bumper gap to a vehicle entering at s = 0
        nxt = int(self.next[i])
        if nxt >= 0:
            if (self.is_connector[nxt] and not self.granted[i]) or start_gap[nxt] < 0.0:
                self.s[i], self.v[i] = self.lane_len[li] - 1e-6, 0.0  # no grant or no room: wait at the end
                return
            self.prev_lane[i] = li
            self.lane_id[i], self.s[i] = nxt, min(over, 0.5 * start_gap[nxt])
            self.granted[i] = False
            if self.is_connector[nxt]:
                self.turns += int(self.turn[nxt])
            elif not self.is_connector[li]:
                self.continued += 1
            self.next[i] = self._draw_next(nxt)
            return
        free = start_gap >= c["min_gap"] + self.v[i] * c["time_headway"]
        free[self.is_connector] = False  # trips start on road lanes, never inside a junction box
        # Nor lanes another vehicle is about to drive onto, or still has its rear on.
        entering = others & (self.next >= 0) & (self.lane_len[self.lane_id] - self.s < c["length"] + c["min_gap"])
        free[self.next[entering]] = False
        free[self.prev_lane[others & (self.prev_lane >= 0)]] = False
        # Lanes that start inside a crossing another axis holds are not free either.
        for k in np.flatnonzero(self.zones.s_in < c["length"]).tolist():
            h = self.holder[self.zones.zone[k]]
            if not np.isnan(h) and conflicts(self.zones.axis[k], h):
                free[self.zones.lane[k]] = False
        # Nor lanes whose start is within a vehicle length (plus the jam gap) of another vehicle's centre.
        st = self.states()
        d = np.hypot(self.start_xy[:, None, 0] - st["x"][None], self.start_xy[:, None, 1] - st["y"][None])
        free &= ~(d[:, others] < c["length"] + c["min_gap"]).any(axis=1)
        # New trips enter from the scene's edge (lanes nothing feeds) when one is free, like arriving traffic.
        pick = free & self.entry if (free & self.entry).any() else free
        if pick.any():
            new = int(self.rng.choice(np.flatnonzero(pick)))
            self.lane_id[i], self.s[i] = new, 0.0
            self.granted[i], self.prev_lane[i] = False, -1
            self.next[i] = self._draw_next(new)
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


def _min_radius(pts: np.ndarray) -> float:
    """Smallest radius of the circles through consecutive point triples of a polyline (inf when straight)."""
    a, b, c = pts[:-2], pts[1:-1], pts[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ab * bc * ca / (2.0 * cross)
    r = r[np.isfinite(r)]
    return float(r.min()) if len(r) else float("inf")
