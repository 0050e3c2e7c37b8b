"""Car following: the IDM law, each vehicle's desired speed and the leaders a lane's front vehicle sees."""

from __future__ import annotations

import numpy as np


class CarFollowing:
    """VehicleManager's IDM part: desired speeds, next-lane leaders and the acceleration law itself."""

    def _desired_speed(self) -> np.ndarray:
        """Each vehicle's IDM v0: its own, capped by its lane's turn speed and, near the end, by the next lane's
        (the speed from which comfortable braking reaches that limit at the lane's end)."""
        b = self.config["comfort_decel"]
        lim_next = np.where(self.next >= 0, self.vlim[np.maximum(self.next, 0)], np.inf)
        to_end = np.maximum(self.lane_len[self.lane_id] - self.s, 0.0)
        return np.minimum(np.minimum(self.v0, self.vlim[self.lane_id]), np.sqrt(lim_next ** 2 + 2.0 * b * to_end))

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

    def _idm(self, v: np.ndarray, v0: np.ndarray, gap: np.ndarray, dv: np.ndarray) -> np.ndarray:
        c = self.config
        s_star = c["min_gap"] + np.maximum(0.0, v * c["time_headway"] + v * dv / (2.0 * np.sqrt(c["max_accel"] * c["comfort_decel"])))
        with np.errstate(divide="ignore"):
            interaction = np.where(np.isfinite(gap), (s_star / np.maximum(gap, 0.1)) ** 2, 0.0)
        a = c["max_accel"] * (1.0 - (v / v0) ** c["delta"] - interaction)
        return a.clip(-c["max_decel"], c["max_accel"])
