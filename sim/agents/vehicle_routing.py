"""Where vehicles drive next: lane successors and turn speed limits, and what happens at a lane's end."""

from __future__ import annotations

import numpy as np

from sim.agents.lanes import conflicts


class LaneRouting:
    """VehicleManager's routing part: indexes the lanes, draws next lanes, continues or ends trips."""

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
        self.all_cum = (
            np.concatenate([ln.s + o for ln, o in zip(self.lanes, self.lane_off)]) if self.lanes else np.zeros(0)
        )
        self.crossings = [(li, ci, s_in) for li, ln in enumerate(self.lanes) for ci, s_in, _ in ln.crossings]
        # The same as arrays (lane, crosswalk, arc length of its near edge) for the numba car-following kernels.
        self._cross_arrays = (
            np.array([x[0] for x in self.crossings], dtype=np.int64),
            np.array([x[1] for x in self.crossings], dtype=np.int64),
            np.array([x[2] for x in self.crossings], dtype=np.float64),
        )
        # The lane continuing each road lane (starts within 1 m of its end, heading within 30 degrees), or -1;
        # a connector continues onto its target lane.
        self.next_lane = np.full(len(self.lanes), -1, dtype=np.int64)
        self.successors: list[list[int]] = [[] for _ in self.lanes]
        if not self.lanes:
            return
        road = self.lanes[: self.n_road]
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


def _min_radius(pts: np.ndarray) -> float:
    """Smallest radius of the circles through consecutive point triples of a polyline (inf when straight)."""
    a, b, c = pts[:-2], pts[1:-1], pts[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ab * bc * ca / (2.0 * cross)
    r = r[np.isfinite(r)]
    return float(r.min()) if len(r) else float("inf")
