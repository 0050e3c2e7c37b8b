"""Car following: same-lane leaders, the leaders a lane's front vehicle sees on its next lane, each vehicle's
desired speed and the IDM law, as numba kernels over the vehicles of one tick.

A tick of ~10 vehicles was ~150 small numpy calls (~0.3 ms); these loops are ~0.02 ms. They do the float
operations of the numpy code they replaced in the same order (no fastmath), so vehicles move bit for bit as
before (tests/sim/agents/test_socialnav_golden.py holds them to it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def leaders(
    order: np.ndarray,
    lane_id: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    nxt_lane: np.ndarray,
    lane_len: np.ndarray,
    is_connector: np.ndarray,
    granted: np.ndarray,
    occupied: np.ndarray,
    cross_lane: np.ndarray,
    cross_cw: np.ndarray,
    cross_s: np.ndarray,
    length: float,
    stop_gap: float,
    dt: float,
    comfort_decel: float,
    junction_stop: float,
    n_lanes: int,
):  # pragma: no cover - numba
    """Vehicles sorted by (lane, s): same-lane gaps and speed differences (stop lines of occupied crosswalks on
    the own lane included), each lane's rearmost vehicle, the lanes' front vehicles and whether one wants a grant.

    Returns (ls, ss, vs, same, gap, dv, rear_s, rear_v, front, to_end, want_grant)."""
    n = order.size
    ls, ss, vs = lane_id[order], s[order], v[order]
    same = np.zeros(n, dtype=np.bool_)
    gap = np.full(n, np.inf)
    dv = np.zeros(n)
    for k in range(n - 1):
        if ls[k + 1] == ls[k]:
            same[k] = True
            gap[k] = ss[k + 1] - ss[k] - length
            dv[k] = vs[k] - vs[k + 1]
    half = length / 2.0
    for e in range(cross_lane.size):
        if not occupied[cross_cw[e]]:
            continue
        line = cross_s[e] - stop_gap
        for k in range(n):
            ahead = line - (ss[k] + half)
            if ls[k] == cross_lane[e] and ahead > -0.5 and ahead < gap[k]:
                gap[k] = max(ahead, 0.0)
                dv[k] = vs[k]
    rear_s = np.full(n_lanes, np.inf)
    rear_v = np.zeros(n_lanes)
    for k in range(n):
        if k == 0 or ls[k] != ls[k - 1]:
            rear_s[ls[k]], rear_v[ls[k]] = ss[k], vs[k]
    front = np.flatnonzero(~same)
    to_end = np.empty(front.size)
    want = False
    for m in range(front.size):
        k = front[m]
        to_end[m] = lane_len[ls[k]] - (ss[k] + half)
        nx = nxt_lane[order[k]]
        if nx >= 0 and is_connector[nx] and not granted[order[k]]:
            reach = vs[k] * vs[k] / (2.0 * comfort_decel) + vs[k] * dt + 3.0 + junction_stop
            want = want or to_end[m] < reach
    return ls, ss, vs, same, gap, dv, rear_s, rear_v, front, to_end, want


@njit(cache=True, nogil=True, error_model="numpy")
def follow(
    order: np.ndarray,
    ls: np.ndarray,
    vs: np.ndarray,
    gap: np.ndarray,
    dv: np.ndarray,
    front: np.ndarray,
    to_end: np.ndarray,
    rear_s: np.ndarray,
    rear_v: np.ndarray,
    lane_id: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    v0: np.ndarray,
    nxt_lane: np.ndarray,
    prev_lane: np.ndarray,
    lane_len: np.ndarray,
    vlim: np.ndarray,
    is_connector: np.ndarray,
    granted: np.ndarray,
    occupied: np.ndarray,
    cross_lane: np.ndarray,
    cross_cw: np.ndarray,
    cross_s: np.ndarray,
    length: float,
    stop_gap: float,
    junction_stop: float,
    comfort_decel: float,
):  # pragma: no cover - numba
    """The front vehicles' leaders on their next lanes (its rearmost vehicle, a vehicle whose rear is still on the
    own lane, an occupied crosswalk, a junction without a grant), into `gap` and `dv` in place; returns each
    vehicle's speed over its desired speed (sorted order)."""
    n_lanes = lane_len.size
    half = length / 2.0
    tail_s = np.full(n_lanes, np.inf)
    tail_v = np.zeros(n_lanes)
    for i in range(s.size):  # per lane left, the rearmost vehicle (ties: the lower index)
        pl = prev_lane[i]
        if pl >= 0 and s[i] < tail_s[pl]:
            tail_s[pl], tail_v[pl] = s[i], v[i]
    for m in range(front.size):
        k = front[m]
        nxt = nxt_lane[order[k]]
        has = nxt >= 0
        nx = max(nxt, 0)
        blocked = has and is_connector[nx] and not granted[order[k]]
        cand = to_end[m] - junction_stop if blocked else np.inf
        cand_dv = vs[k]
        ahead = to_end[m] + rear_s[nx] - half
        if has and not blocked and ahead < cand:
            cand, cand_dv = ahead, vs[k] - rear_v[nx]
        tail = to_end[m] + tail_s[ls[k]] - half
        if tail < cand:
            cand, cand_dv = tail, vs[k] - tail_v[ls[k]]
        for ci in range(occupied.size):
            if not occupied[ci]:
                continue
            for e in range(cross_lane.size):
                if cross_cw[e] != ci:
                    continue
                stop = to_end[m] + cross_s[e] - stop_gap
                if has and not blocked and nxt == cross_lane[e] and stop < cand:
                    cand, cand_dv = stop, vs[k]
        if cand < gap[k]:
            gap[k], dv[k] = max(cand, 0.0), cand_dv
    ratio = np.empty(s.size)  # v / v0 in sorted order: numpy raises it to delta (its pow is not libm's)
    for k in range(s.size):
        i = order[k]
        # Desired speed: the own, capped by the lane's turn speed and by braking to the next lane's limit.
        lim_next = vlim[max(nxt_lane[i], 0)] if nxt_lane[i] >= 0 else np.inf
        end = max(lane_len[lane_id[i]] - s[i], 0.0)
        ratio[k] = vs[k] / min(min(v0[i], vlim[lane_id[i]]), math.sqrt(lim_next * lim_next + 2.0 * comfort_decel * end))
    return ratio


@njit(cache=True, nogil=True, error_model="numpy")
def idm(
    order: np.ndarray,
    vs: np.ndarray,
    gap: np.ndarray,
    dv: np.ndarray,
    free_term: np.ndarray,
    v: np.ndarray,
    s: np.ndarray,
    min_gap: float,
    time_headway: float,
    max_accel: float,
    comfort_decel: float,
    max_decel: float,
    dt: float,
):  # pragma: no cover - numba
    """IDM accelerations (`free_term` = (v / v0) ** delta, sorted order) and one Euler step: (new v, new s)."""
    n = s.size
    root = 2.0 * math.sqrt(max_accel * comfort_decel)
    new_v = np.empty(n)
    new_s = np.empty(n)
    for k in range(n):
        i = order[k]
        vk = vs[k]
        s_star = min_gap + max(0.0, vk * time_headway + vk * dv[k] / root)
        interaction = (s_star / max(gap[k], 0.1)) ** 2 if np.isfinite(gap[k]) else 0.0
        a = max_accel * (1.0 - free_term[k] - interaction)
        a = min(max(a, -max_decel), max_accel)
        new_v[i] = max(v[i] + a * dt, 0.0)
        new_s[i] = s[i] + new_v[i] * dt
    return new_v, new_s


@njit(cache=True, nogil=True, error_model="numpy")
def lane_points(
    lane_id: np.ndarray,
    s: np.ndarray,
    lane_off: np.ndarray,
    lane_len: np.ndarray,
    all_cum: np.ndarray,
    all_pts: np.ndarray,
):  # pragma: no cover - numba
    """Centres [n, 2] of vehicles at arc length `s` on their lanes (all lanes laid end to end in `all_pts` at
    `all_cum`), and the direction [n, 2] of the segment each is on."""
    n = s.size
    xy = np.empty((n, 2))
    seg = np.empty((n, 2))
    for i in range(n):
        g = lane_off[lane_id[i]] + min(s[i], lane_len[lane_id[i]] - 1e-6)
        k = min(max(np.searchsorted(all_cum, g, side="right") - 1, 0), all_cum.size - 2)
        sx, sy = all_pts[k + 1, 0] - all_pts[k, 0], all_pts[k + 1, 1] - all_pts[k, 1]
        t = (g - all_cum[k]) / max(all_cum[k + 1] - all_cum[k], 1e-9)
        xy[i, 0], xy[i, 1] = all_pts[k, 0] + sx * t, all_pts[k, 1] + sy * t
        seg[i, 0], seg[i, 1] = sx, sy
    return xy, seg


@njit(cache=True, nogil=True, error_model="numpy")
def in_boxes(xy: np.ndarray, bounds: np.ndarray):  # pragma: no cover - numba
    """(box, point) index pairs of the points [n, 2] inside the boxes [m, 4] (min x, min y, max x, max y)."""
    box, pt = [], []
    for b in range(bounds.shape[0]):
        for i in range(xy.shape[0]):
            if (
                xy[i, 0] >= bounds[b, 0]
                and xy[i, 1] >= bounds[b, 1]
                and xy[i, 0] <= bounds[b, 2]
                and xy[i, 1] <= bounds[b, 3]
            ):
                box.append(b)
                pt.append(i)
    return np.array(box, dtype=np.int64), np.array(pt, dtype=np.int64)
