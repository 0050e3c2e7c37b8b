"""Where vehicles drive next: lane successors, the next lane drawn on entering a lane, and what happens at a lane's
end (onto the next lane, or the trip ends and the vehicle respawns at a free lane start)."""

from __future__ import annotations

import numpy as np

from sim.agents.lanes import ConflictZones, conflicts
from sim.agents.vehicle_state import LaneNetwork, TrafficState


class LaneRouting:
    """The successors of every lane of `network`, and the moves of vehicles whose centre passed their lane's end.

    `zones` are the network's lane crossings (no trip starts inside one another axis holds); `length`, `min_gap`
    (IDM s0) and `time_headway` (IDM T) decide whether a lane start has room for a new trip.
    """

    def __init__(
        self, network: LaneNetwork, zones: ConflictZones, length: float, min_gap: float, time_headway: float
    ) -> None:
        self.network = network
        self.zones = zones
        self.length = length
        self.min_gap = min_gap
        self.time_headway = time_headway
        lanes = network.lanes
        # The lane continuing each road lane (starts within 1 m of its end, heading within 30 degrees), or -1;
        # a connector continues onto its target lane.
        self.continuation = np.full(len(lanes), -1, dtype=np.int64)
        # Per lane, the lanes a vehicle may drive onto from it: its continuation first, then its connectors.
        self.successors: list[list[int]] = [[] for _ in lanes]
        road = lanes[: network.n_road]
        starts = np.array([ln.points[0] for ln in road])
        head0 = np.array([np.arctan2(*(ln.points[1] - ln.points[0])[::-1]) for ln in road])
        for li, ln in enumerate(road):
            h1 = np.arctan2(*(ln.points[-1] - ln.points[-2])[::-1])
            ok = (np.linalg.norm(starts - ln.points[-1], axis=1) < 1.0) & (np.cos(head0 - h1) > np.cos(np.pi / 6))
            ok[li] = False
            if ok.any():
                self.continuation[li] = int(np.flatnonzero(ok)[0])
                self.successors[li].append(int(self.continuation[li]))
        self.start_xy = np.array([ln.points[0] for ln in lanes])  # where a respawned vehicle's centre starts
        # A connector is a turn when its heading changes by more than 45 degrees (counted in `turns`).
        self.is_turn = np.zeros(len(lanes), dtype=bool)
        for ci in np.flatnonzero(network.is_connector).tolist():
            ln = lanes[ci]
            d0, d1 = ln.points[1] - ln.points[0], ln.points[-1] - ln.points[-2]
            self.is_turn[ci] = abs(np.arctan2(d0[0] * d1[1] - d0[1] * d1[0], d0 @ d1)) > np.pi / 4
            self.continuation[ci] = ln.dst
            self.successors[ci].append(ln.dst)
            self.successors[ln.src].append(ci)
        fed = {li for succ in self.successors for li in succ}
        # Road lanes nothing feeds: traffic arriving from the scene's edge starts its trips there.
        self.is_entry = np.array([li < network.n_road and li not in fed for li in range(len(lanes))], dtype=bool)

    def draw_next(self, lane: int, rng: np.random.Generator) -> int:
        """The lane a vehicle entering `lane` drives onto after it: one of its successors, or -1 (trip ends)."""
        succ = self.successors[lane]
        if not succ:
            return -1
        return succ[0] if len(succ) == 1 else int(succ[int(rng.integers(len(succ)))])

    def leave_lane(self, state: TrafficState, i: int, rng: np.random.Generator) -> None:
        """Move vehicle `i`, whose centre passed its lane's end, onto its next lane, or respawn it (trip ended);
        without a grant for its connector or room on its next lane it waits, stopped, at the lane's end."""
        net = self.network
        li, over = int(state.lane_id[i]), float(state.s[i] - net.lane_len[state.lane_id[i]])
        others = np.arange(state.n) != i
        first = np.full(len(net.lanes), np.inf)  # arc length of each lane's last (rearmost) vehicle
        np.minimum.at(first, state.lane_id[others], state.s[others])
        start_gap = first - self.length  # bumper gap to a vehicle entering at s = 0
        nxt = int(state.next_lane[i])
        if nxt < 0:
            self._end_trip(state, i, rng, li, others, start_gap)
            return
        if (net.is_connector[nxt] and not state.granted[i]) or start_gap[nxt] < 0.0:
            state.s[i], state.speed[i] = net.lane_len[li] - 1e-6, 0.0  # no grant or no room: wait at the end
            return
        state.prev_lane[i] = li
        state.lane_id[i], state.s[i] = nxt, min(over, 0.5 * start_gap[nxt])
        state.granted[i] = False
        if net.is_connector[nxt]:
            state.turns += int(self.is_turn[nxt])
        elif not net.is_connector[li]:
            state.continued += 1
        state.next_lane[i] = self.draw_next(nxt, rng)

    def _end_trip(
        self,
        state: TrafficState,
        i: int,
        rng: np.random.Generator,
        li: int,
        others: np.ndarray,
        start_gap: np.ndarray,
    ) -> None:
        """Respawn vehicle `i` (on lane `li`) at the start of a free road lane, or stop it at its lane's end when
        none is free; `others` masks the other vehicles, `start_gap` is each lane's room at its start."""
        net, z, length, min_gap = self.network, self.zones, self.length, self.min_gap
        free = start_gap >= min_gap + state.speed[i] * self.time_headway
        free[net.is_connector] = False  # trips start on road lanes, never inside a junction box
        # Nor lanes another vehicle is about to drive onto, or still has its rear on.
        nxt, prev = state.next_lane, state.prev_lane
        entering = others & (nxt >= 0) & (net.lane_len[state.lane_id] - state.s < length + min_gap)
        free[nxt[entering]] = False
        free[prev[others & (prev >= 0)]] = False
        # Lanes that start inside a crossing another axis holds are not free either.
        for k in np.flatnonzero(z.s_in < length).tolist():
            h = state.crossing_holder[z.zone[k]]
            if not np.isnan(h) and conflicts(z.axis[k], h):
                free[z.lane[k]] = False
        # Nor lanes whose start is within a vehicle length (plus the jam gap) of another vehicle's centre.
        xy = net.points(state.lane_id, state.s)[0]
        d = np.hypot(self.start_xy[:, None, 0] - xy[None, :, 0], self.start_xy[:, None, 1] - xy[None, :, 1])
        free &= ~(d[:, others] < length + min_gap).any(axis=1)
        # New trips enter from the scene's edge (lanes nothing feeds) when one is free, like arriving traffic.
        pick = free & self.is_entry if (free & self.is_entry).any() else free
        if pick.any():
            new = int(rng.choice(np.flatnonzero(pick)))
            state.lane_id[i], state.s[i] = new, 0.0
            state.granted[i], state.prev_lane[i] = False, -1
            state.next_lane[i] = self.draw_next(new, rng)
            state.respawns += 1
            state.jumped[i] = True
            return
        state.s[i], state.speed[i] = net.lane_len[li] - 1e-6, 0.0  # no free start: wait at the lane's end
