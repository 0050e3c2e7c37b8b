"""Taking turns where paths cross: junction connector grants, lane crossings held by one axis at a time, and the
crosswalks that people occupy."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon

from sim.agents.lanes import ConflictZones, conflicts
from sim.agents.vehicle_idm import in_boxes
from sim.agents.vehicle_state import LaneNetwork, TrafficState


class JunctionGrants:
    """Right of way in junction boxes: which front vehicles nearing their connector may enter it.

    `compatible` [lanes, lanes] says which connectors vehicles may be on at once (lanes.connector_compatibility);
    `length`, `min_gap`, `comfort_decel` and `junction_stop` are the vehicles' config values.
    """

    def __init__(
        self,
        network: LaneNetwork,
        compatible: np.ndarray,
        length: float,
        min_gap: float,
        comfort_decel: float,
        junction_stop: float,
    ) -> None:
        self.network = network
        self.compatible = compatible
        self.length = length
        self.min_gap = min_gap
        self.comfort_decel = comfort_decel
        self.junction_stop = junction_stop

    def grant(
        self,
        state: TrafficState,
        dt: float,
        ids: np.ndarray,
        nxt: np.ndarray,
        to_end: np.ndarray,
        v: np.ndarray,
        rear_s: np.ndarray,
    ) -> None:
        """Grant junction connectors to front vehicles nearing them: longest-waiting first, compatible paths only.

        `ids` are the lanes' front vehicles, `nxt` their next lanes, `to_end` the distance of their fronts to their
        lane's end and `v` their speeds; `rear_s` is each lane's rearmost vehicle's arc length (inf when empty)."""
        net = self.network
        nx = np.maximum(nxt, 0)
        reach = v * v / (2.0 * self.comfort_decel) + v * dt + 3.0 + self.junction_stop
        want = (nxt >= 0) & net.is_connector[nx] & ~state.granted[ids] & (to_end < reach)
        if not want.any():
            return
        on = state.lane_id[net.is_connector[state.lane_id]]
        tails = state.prev_lane[state.prev_lane >= 0]
        in_use = [on, tails[net.is_connector[tails]], state.next_lane[state.granted]]
        busy = list(np.unique(np.concatenate(in_use)))
        cand = np.flatnonzero(want)
        cand = cand[np.lexsort((to_end[cand], -state.waited[ids[cand]]))]
        reserved: list[int] = []
        for k in cand.tolist():
            i, conn = int(ids[k]), int(nxt[k])
            room = rear_s[net.lanes[conn].dst] - self.length / 2.0 >= self.length + self.min_gap
            if room and self.compatible[conn, busy].all() and self.compatible[conn, reserved].all():
                state.granted[i], state.waited[i] = True, 0.0
                busy.append(conn)
            else:
                # A waiting claimer reserves its path: later claimers that would cross it wait behind it.
                state.waited[i] += dt
                reserved.append(conn)


class LaneCrossings:
    """Crossings of road lanes without a junction box (`zones`), each held by one axis at a time.

    `length`, `stop_gap`, `comfort_decel` and `max_hold` are the vehicles' config values.
    """

    def __init__(
        self, zones: ConflictZones, length: float, stop_gap: float, comfort_decel: float, max_hold: float
    ) -> None:
        self.zones = zones
        self.length = length
        self.stop_gap = stop_gap
        self.comfort_decel = comfort_decel
        self.max_hold = max_hold

    def take_turns(
        self,
        state: TrafficState,
        dt: float,
        ls: np.ndarray,
        ss: np.ndarray,
        v: np.ndarray,
        gap: np.ndarray,
        dv: np.ndarray,
    ) -> None:
        """Let one axis hold each lane crossing; vehicles of other axes about to enter it stop before it.

        `ls`, `ss` and `v` are the vehicles' lanes, arc lengths and speeds sorted by (lane, s); their leaders' gaps
        `gap` and speed differences `dv` (same order) get the crossings' stop lines in place."""
        z = self.zones
        if not z.n_zones:
            return
        holder, held_for = state.crossing_holder, state.crossing_held_for
        half = self.length / 2.0
        on = ls[None, :] == z.lane[:, None]  # [entries, vehicles]
        inside = on & (ss + half > z.s_in[:, None]) & (ss - half < z.s_out[:, None])
        ahead = z.s_in[:, None] - self.stop_gap - (ss + half)
        # Claim a crossing once within comfortable braking distance (plus a margin) of its stop line.
        reach = v * v / (2.0 * self.comfort_decel) + v * dt + 3.0
        claim = on & ~inside & (ahead > -self.stop_gap) & (ahead < reach[None, :])
        for zi in range(z.n_zones):
            e = np.flatnonzero(z.zone == zi)
            axes_in = z.axis[e][inside[e].any(axis=1)]
            claiming = claim[e].any(axis=1)
            grant = holder[zi]
            dist = np.where(claim[e], ahead[e], np.inf).min(axis=1)  # nearest claimer's distance per entry
            if np.isnan(grant):
                users = claiming
            else:
                users = claiming & ~conflicts(z.axis[e], grant)
                waiting = claiming & ~users
                if waiting.any() and (held_for[zi] > self.max_hold or not (users.any() or len(axes_in))):
                    # The granted axis has kept others waiting too long, or is done: the nearest waiter is next.
                    users = waiting
                    grant = np.nan
            if np.isnan(grant):
                grant = z.axis[e][int(np.argmin(np.where(users, dist, np.inf)))] if users.any() else np.nan
            held_for[zi] = held_for[zi] + dt if grant == holder[zi] else 0.0
            holder[zi] = grant
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


class CrosswalkOccupancy:
    """The scene's crosswalks grown by `margin`, and which of them hold a person (vehicles yield to those)."""

    def __init__(self, crosswalks: Sequence[Mapping[str, Any]], margin: float) -> None:
        self.polygons = [Polygon(cw["polygon"]).buffer(margin) for cw in crosswalks]
        for cw in self.polygons:
            shapely.prepare(cw)
        self._bounds = np.array([cw.bounds for cw in self.polygons]).reshape(-1, 4)
        self._array = np.array(self.polygons, dtype=object)  # for one contains_xy call over all of them

    def occupied(self, people_xy: np.ndarray | None) -> np.ndarray:
        """bool [crosswalks]: whether any of the points `people_xy` [n, 2] (None: nobody) lies inside each one."""
        out = np.zeros(len(self.polygons), dtype=bool)
        if people_xy is None or not len(people_xy) or not self.polygons:
            return out
        xy = np.ascontiguousarray(people_xy, dtype=np.float64)
        # Bounding boxes first: most ticks nobody is near a crosswalk and no polygon test runs at all.
        box, pt = in_boxes(xy, self._bounds)
        if len(box):
            inside = shapely.contains_xy(self._array[box], xy[pt, 0], xy[pt, 1])
            out[box[inside]] = True
        return out
