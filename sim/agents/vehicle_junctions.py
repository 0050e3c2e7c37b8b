"""Taking turns where paths cross: junction connector grants and lane crossings held by one axis at a time."""

from __future__ import annotations

import numpy as np

from sim.agents.lanes import conflicts


class JunctionControl:
    """VehicleManager's right-of-way part: junction connector grants and lane crossings held by one axis."""

    def _grant(
        self, dt: float, ids: np.ndarray, nxt: np.ndarray, to_end: np.ndarray, v: np.ndarray, rear_s: np.ndarray
    ) -> None:
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

    def _crossing_leaders(
        self, dt: float, ls: np.ndarray, ss: np.ndarray, v: np.ndarray, gap: np.ndarray, dv: np.ndarray
    ) -> None:
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
