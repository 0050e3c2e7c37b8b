"""The reference routes of many envs in one padded array: `sim.scene.polyline.Polyline`'s `locate`, `point_at` and
`heading_at` for every env at once.

Row i holds env i's route: its vertices, arc lengths, segments (padding repeats the last vertex; padded segments
are never chosen). Arc lengths are searched in one flat array where row i is shifted by i * `span` (longer than any
route), so one `np.searchsorted` serves every env.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from sim.route import Route

WINDOW = (3.0, 8.0)  # metres searched behind and ahead of the last projection (Polyline.locate's window)


class RouteBatch:
    """Routes of `n` envs; `set(i, route)` at a reset, then array queries for all envs."""

    # Padded per-env arrays (`_alloc` makes them, `cap` columns wide) and the shifted arc lengths (`_flat`).
    points: np.ndarray
    s: np.ndarray
    seg: np.ndarray
    seg_len: np.ndarray
    seg_heading: np.ndarray
    flat_s: np.ndarray

    def __init__(self, n: int) -> None:
        self.n = n
        self.cap = 0
        self.routes: list[Route | None] = [None] * n
        self.count = np.zeros(n, dtype=np.int64)  # vertices per route
        self.length = np.zeros(n)
        self.goal = np.zeros((n, 2))
        self.span = 1.0
        self._alloc(16)

    def _alloc(self, cap: int) -> None:
        old = (self.points, self.s, self.seg, self.seg_len, self.seg_heading) if self.cap else None
        self.points = np.zeros((self.n, cap, 2))
        self.s = np.zeros((self.n, cap))
        self.seg = np.zeros((self.n, cap - 1, 2))
        self.seg_len = np.ones((self.n, cap - 1))
        self.seg_heading = np.zeros((self.n, cap - 1))
        if old is not None:
            k = self.cap
            self.points[:, :k], self.s[:, :k] = old[0], old[1]
            self.seg[:, : k - 1], self.seg_len[:, : k - 1], self.seg_heading[:, : k - 1] = old[2], old[3], old[4]
            for i in range(self.n):  # pad the new columns with the last vertex
                n_points = max(int(self.count[i]), 1)
                self.points[i, k:], self.s[i, k:] = self.points[i, n_points - 1], self.s[i, n_points - 1]
        self.cap = cap
        self._flat()

    def _flat(self) -> None:
        self.span = float(self.length.max(initial=0.0)) + 2.0 * (WINDOW[1] + 1.0)
        self.flat_s = (self.s + self.span * np.arange(self.n)[:, None]).ravel()

    def set(self, i: int, route: Route) -> None:
        """Env i's new route."""
        n_points = len(route.points)
        if n_points > self.cap:
            self._alloc(max(n_points, 2 * self.cap))
        self.routes[i] = route
        self.count[i] = n_points
        self.length[i] = route.length
        self.goal[i] = route.goal
        self.points[i, :n_points], self.points[i, n_points:] = route.points, route.points[-1]
        self.s[i, :n_points], self.s[i, n_points:] = route.s, route.s[-1]
        self.seg[i, : n_points - 1], self.seg[i, n_points - 1 :] = route.seg, 0.0
        self.seg_len[i, : n_points - 1], self.seg_len[i, n_points - 1 :] = route.seg_len, 1.0
        self.seg_heading[i, : n_points - 1] = np.arctan2(route.seg[:, 1], route.seg[:, 0])
        self.seg_heading[i, n_points - 1 :] = self.seg_heading[i, n_points - 2]
        if route.length + 2.0 * (WINDOW[1] + 1.0) > self.span:
            self._flat()
        else:
            self.flat_s[i * self.cap : (i + 1) * self.cap] = self.s[i] + self.span * i

    def _search(self, s: np.ndarray, side: Literal["left", "right"]) -> np.ndarray:
        """np.searchsorted(route.s, s[i], side) of every env's own route."""
        rows = np.arange(self.n)
        query = np.clip(s, -WINDOW[0] - 1.0, self.length + WINDOW[1] + 1.0) + self.span * rows
        return np.searchsorted(self.flat_s, query, side=side) - rows * self.cap

    def locate(self, x: np.ndarray, y: np.ndarray, s_hint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(arc length, signed lateral offset) of every env's (x, y) on its route, searched within WINDOW of
        `s_hint` (`Polyline.locate` with a hint)."""
        nseg = self.count - 1
        k0 = np.maximum(self._search(s_hint - WINDOW[0], "left") - 1, 0)
        k1 = np.minimum(self._search(s_hint + WINDOW[1], "left") + 1, nseg)
        width = int((k1 - k0).max())
        ks = k0[:, None] + np.arange(width)[None]
        valid = ks < k1[:, None]
        ks = np.minimum(ks, self.cap - 2)
        rows = np.arange(self.n)[:, None]
        start = self.points[rows, ks]
        seg = self.seg[rows, ks]
        ln = self.seg_len[rows, ks]
        qx, qy = x[:, None] - start[..., 0], y[:, None] - start[..., 1]
        frac = np.clip((qx * seg[..., 0] + qy * seg[..., 1]) / (ln**2), 0.0, 1.0)
        ex, ey = qx - frac * seg[..., 0], qy - frac * seg[..., 1]
        dist2 = np.where(valid, ex * ex + ey * ey, np.inf)
        j = np.argmin(dist2, axis=1)
        env_idx = np.arange(self.n)
        k = ks[env_idx, j]
        cross = seg[env_idx, j, 0] * qy[env_idx, j] - seg[env_idx, j, 1] * qx[env_idx, j]
        lateral = np.sqrt(dist2[env_idx, j]) * np.where(cross >= 0, 1.0, -1.0)
        return self.s[env_idx, k] + frac[env_idx, j] * self.seg_len[env_idx, k], lateral

    def point_at(self, s: np.ndarray) -> np.ndarray:
        """Points [n, m, 2] at arc lengths s [n, m] of every env's route (clamped onto it, as `Polyline.point_at`)."""
        s = np.clip(s, 0.0, self.length[:, None])
        i = np.clip(self._search_many(s) - 1, 0, self.cap - 2)
        rows = np.arange(self.n)[:, None]
        s0, s1 = self.s[rows, i], self.s[rows, i + 1]
        span = s1 - s0
        frac = np.where(span > 0, (s - s0) / np.where(span > 0, span, 1.0), 0.0)
        p0, p1 = self.points[rows, i], self.points[rows, i + 1]
        return p0 + frac[..., None] * (p1 - p0)

    def _search_many(self, s: np.ndarray) -> np.ndarray:
        rows = np.arange(self.n)[:, None]
        return np.searchsorted(self.flat_s, s + self.span * rows, side="right") - rows * self.cap

    def heading_at(self, s: np.ndarray) -> np.ndarray:
        """Heading of the segment at arc length s of every env's route (`Polyline.heading_at`)."""
        k = np.clip(self._search(s, "right") - 1, 0, self.count - 2)
        return self.seg_heading[np.arange(self.n), k]
