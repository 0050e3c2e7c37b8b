"""ORCA (van den Berg et al. 2011) in numba: RVO2's velocity solver for many crowds in one compiled call.

The algorithm is RVO2's (`Agent::computeNewVelocity`, `linearProgram1-3`) line by line, in doubles instead of RVO2's
floats. What differs is how neighbours are found: RVO2 keeps k-d trees of agents and obstacles; here a crowd's
agents are few enough (tens) to test every pair, and a scene's obstacle edges sit in a uniform grid of buckets
(`ObstacleIndex`): an edge is filed under every bucket its bounding box, grown by `reach` metres, touches, so the
edges within `reach` of a point are in the point's own bucket. RVO2 splits the edges its tree's cutting lines cross;
these edges stay whole.

Obstacles are RVO2's: a polygon's vertices in counter-clockwise order, each vertex the start of an edge to the next
(`nxt`, `prv`), its unit direction (`direction`) and whether the polygon is convex there (`convex`); a two-vertex
obstacle is a wall seen from both sides (two edges, each way).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

EPSILON = 1e-5  # RVO_EPSILON
BUCKET = 1.0  # metres: the obstacle buckets' side
HALF_DIAGONAL = 0.7072 * BUCKET + 1e-3  # metres from a bucket's centre to its corners, and float32's slack
MAX_LINES = 256  # ORCA lines an agent can hold (obstacle edges plus neighbours)


@dataclass(frozen=True)
class ObstacleIndex:
    """A scene's obstacle edges (RVO2's Obstacle list as arrays) and their buckets.

    | array | shape | holds |
    |---|---|---|
    | point | [m, 2] | each edge's first vertex |
    | nxt, prv | [m] | the next and previous edge of its polygon |
    | direction | [m, 2] | unit vector from `point` to the next edge's point |
    | convex | [m] | whether the polygon is convex at `point` |
    | start, items | [bx * by + 1], [k] | bucket b holds edges items[start[b]:start[b + 1]] |
    """

    point: np.ndarray
    nxt: np.ndarray
    prv: np.ndarray
    direction: np.ndarray
    convex: np.ndarray
    origin: np.ndarray  # [2] the buckets' lower-left corner
    shape: tuple[int, int]  # buckets along x and y
    reach: float  # metres around an edge that its buckets cover
    start: np.ndarray
    items: np.ndarray
    item_d: np.ndarray  # [k] each listed edge's distance from its bucket's centre (a bucket's nearest first)

    @staticmethod
    def build(polygons: Sequence[Sequence[tuple[float, float]]], reach: float) -> ObstacleIndex:
        """The index of `polygons` (each two or more vertices, counter-clockwise; RVO2's addObstacle)."""
        pts: list[np.ndarray] = []
        nxt: list[int] = []
        prv: list[int] = []
        convex: list[bool] = []
        for poly in polygons:
            verts = np.asarray(poly, dtype=np.float64).reshape(-1, 2)
            n, base = len(verts), len(pts)
            if n < 2:
                continue
            for i in range(n):
                pts.append(verts[i])
                nxt.append(base + (i + 1) % n)
                prv.append(base + (i - 1) % n)
                if n == 2:
                    convex.append(True)
                else:
                    a, b, c = verts[i - 1], verts[i], verts[(i + 1) % n]
                    convex.append(_left_of(a, b, c) >= 0.0)
        point = np.array(pts, dtype=np.float64).reshape(-1, 2)
        nxt_a, prv_a = np.array(nxt, dtype=np.int64), np.array(prv, dtype=np.int64)
        d = point[nxt_a] - point if len(point) else np.zeros((0, 2))
        length = np.hypot(d[:, 0], d[:, 1]) if len(point) else np.zeros(0)
        direction = d / np.maximum(length, 1e-12)[:, None]
        lo = point.min(axis=0) - reach - BUCKET if len(point) else np.zeros(2)
        hi = point.max(axis=0) + reach + BUCKET if len(point) else np.ones(2)
        bx, by = (int(v) for v in np.maximum(np.ceil((hi - lo) / BUCKET), 1))
        start, items, item_d = _fill_buckets(point, nxt_a, lo[0], lo[1], bx, by, reach)
        return ObstacleIndex(
            point,
            nxt_a,
            prv_a,
            direction,
            np.array(convex, dtype=np.bool_),
            lo,
            (bx, by),
            float(reach),
            start,
            items,
            item_d,
        )


def _left_of(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """RVO2's leftOf: > 0 when c lies left of the line from a to b."""
    return float((a[0] - c[0]) * (b[1] - a[1]) - (a[1] - c[1]) * (b[0] - a[0]))


@njit(cache=True)
def _fill_buckets(point, nxt, x0, y0, bx, by, reach):  # pragma: no cover - numba
    """Bucket start offsets, edge lists and each listed edge's distance from its bucket's centre: each edge under
    every bucket its box grown by `reach` touches, a bucket's edges nearest its centre first."""
    m = point.shape[0]
    counts = np.zeros(bx * by + 1, dtype=np.int64)
    for pas in range(2):
        if pas == 1:
            for b in range(bx * by):
                counts[b + 1] += counts[b]
            items = np.empty(counts[bx * by], dtype=np.int64)
            item_d = np.empty(counts[bx * by], dtype=np.float32)
            fill = counts[:-1].copy()
        for e in range(m):
            ax, ay = point[e, 0], point[e, 1]
            cx, cy = point[nxt[e], 0], point[nxt[e], 1]
            i0 = max(int((min(ax, cx) - reach - x0) / BUCKET), 0)
            i1 = min(int((max(ax, cx) + reach - x0) / BUCKET), bx - 1)
            j0 = max(int((min(ay, cy) - reach - y0) / BUCKET), 0)
            j1 = min(int((max(ay, cy) + reach - y0) / BUCKET), by - 1)
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    b = j * bx + i
                    if pas == 0:
                        counts[b + 1] += 1
                    else:
                        items[fill[b]] = e
                        px, py = x0 + (i + 0.5) * BUCKET, y0 + (j + 0.5) * BUCKET
                        ex, ey = cx - ax, cy - ay
                        t = ((px - ax) * ex + (py - ay) * ey) / max(ex * ex + ey * ey, 1e-300)
                        t = min(max(t, 0.0), 1.0)
                        item_d[fill[b]] = math.sqrt((px - ax - t * ex) ** 2 + (py - ay - t * ey) ** 2)
                        fill[b] += 1
    for b in range(bx * by):
        lo, hi = counts[b], counts[b + 1]
        order = np.argsort(item_d[lo:hi], kind="mergesort")  # stable: equal distances keep the edges' order
        items[lo:hi] = items[lo:hi][order]
        item_d[lo:hi] = item_d[lo:hi][order]
    return counts, items, item_d


@njit(cache=True, inline="always")
def _det(ax, ay, bx, by):  # pragma: no cover - numba
    return ax * by - ay * bx


@njit(cache=True, inline="always")
def _bucket(x, y, x0, y0, bx, by):  # pragma: no cover - numba
    """The bucket of point (x, y), -1 off the buckets."""
    i = int(math.floor((x - x0) / BUCKET))
    j = int(math.floor((y - y0) / BUCKET))
    if i < 0 or j < 0 or i >= bx or j >= by:
        return -1
    return j * bx + i


@njit(cache=True)
def _lp1(lp, ld, line_no, radius, optx, opty, direction_opt, res):  # pragma: no cover - numba
    """linearProgram1: the optimum on line `line_no` subject to the lines before it; False when infeasible."""
    px, py = lp[line_no, 0], lp[line_no, 1]
    dx, dy = ld[line_no, 0], ld[line_no, 1]
    dot = px * dx + py * dy
    disc = dot * dot + radius * radius - (px * px + py * py)
    if disc < 0.0:
        return False  # the max speed circle fully invalidates line line_no
    sq = math.sqrt(disc)
    t_left, t_right = -dot - sq, -dot + sq
    for i in range(line_no):
        denom = _det(dx, dy, ld[i, 0], ld[i, 1])
        numer = _det(ld[i, 0], ld[i, 1], px - lp[i, 0], py - lp[i, 1])
        if abs(denom) <= EPSILON:
            if numer < 0.0:
                return False  # parallel and on the infeasible side
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return False
    if direction_opt:
        t = t_right if optx * dx + opty * dy > 0.0 else t_left
    else:
        t = dx * (optx - px) + dy * (opty - py)
        t = t_left if t < t_left else (t_right if t > t_right else t)
    res[0], res[1] = px + t * dx, py + t * dy
    return True


@njit(cache=True)
def _lp2(lp, ld, n, radius, optx, opty, direction_opt, res):  # pragma: no cover - numba
    """linearProgram2: the velocity nearest the optimum inside the speed circle and left of every line; returns the
    first line it could not satisfy (n when none)."""
    if direction_opt:
        res[0], res[1] = optx * radius, opty * radius
    elif optx * optx + opty * opty > radius * radius:
        norm = math.sqrt(optx * optx + opty * opty)
        res[0], res[1] = optx / norm * radius, opty / norm * radius
    else:
        res[0], res[1] = optx, opty
    for i in range(n):
        if _det(ld[i, 0], ld[i, 1], lp[i, 0] - res[0], lp[i, 1] - res[1]) > 0.0:
            tx, ty = res[0], res[1]
            if not _lp1(lp, ld, i, radius, optx, opty, direction_opt, res):
                res[0], res[1] = tx, ty
                return i
    return n


@njit(cache=True)
def _lp3(lp, ld, n, n_obst, begin, radius, res, proj_p, proj_d):  # pragma: no cover - numba
    """linearProgram3: where the lines leave no feasible velocity, the one that least violates the agents' lines."""
    distance = 0.0
    for i in range(begin, n):
        if _det(ld[i, 0], ld[i, 1], lp[i, 0] - res[0], lp[i, 1] - res[1]) > distance:
            m = 0
            for j in range(n_obst):
                proj_p[m, 0], proj_p[m, 1] = lp[j, 0], lp[j, 1]
                proj_d[m, 0], proj_d[m, 1] = ld[j, 0], ld[j, 1]
                m += 1
            for j in range(n_obst, i):
                determinant = _det(ld[i, 0], ld[i, 1], ld[j, 0], ld[j, 1])
                if abs(determinant) <= EPSILON:
                    if ld[i, 0] * ld[j, 0] + ld[i, 1] * ld[j, 1] > 0.0:
                        continue  # parallel, the same way
                    px, py = 0.5 * (lp[i, 0] + lp[j, 0]), 0.5 * (lp[i, 1] + lp[j, 1])
                else:
                    f = _det(ld[j, 0], ld[j, 1], lp[i, 0] - lp[j, 0], lp[i, 1] - lp[j, 1]) / determinant
                    px, py = lp[i, 0] + f * ld[i, 0], lp[i, 1] + f * ld[i, 1]
                ddx, ddy = ld[j, 0] - ld[i, 0], ld[j, 1] - ld[i, 1]
                norm = math.sqrt(ddx * ddx + ddy * ddy)
                proj_p[m, 0], proj_p[m, 1] = px, py
                proj_d[m, 0], proj_d[m, 1] = ddx / norm, ddy / norm
                m += 1
            tx, ty = res[0], res[1]
            if _lp2(proj_p, proj_d, m, radius, -ld[i, 1], ld[i, 0], True, res) < m:
                res[0], res[1] = tx, ty  # floating point error only: keep the current result
            distance = _det(ld[i, 0], ld[i, 1], lp[i, 0] - res[0], lp[i, 1] - res[1])


@njit(cache=True)
def _obstacle_neighbors(
    x, y, rng, point, nxt, ox, oy, bx, by, start, items, item_d, near, near_d
):  # pragma: no cover - numba
    """The edges within `rng` of (x, y) seen from their outer side, nearest first, into `near`; returns their count
    (RVO2's computeObstacleNeighbors; past the array's size the farthest go)."""
    range_sq = rng * rng
    count = 0
    b = _bucket(x, y, ox, oy, bx, by)
    if b < 0:
        return 0
    # A bucket lists its edges nearest its centre first: past range + the half diagonal none can be in range.
    stop = rng + HALF_DIAGONAL
    for k in range(start[b], start[b + 1]):
        if item_d[k] > stop:
            break
        e = items[k]
        ax, ay = point[e, 0], point[e, 1]
        cx, cy = point[nxt[e], 0], point[nxt[e], 1]
        if (ax - x) * (cy - ay) - (ay - y) * (cx - ax) >= 0.0:
            continue  # leftOf(a, c, agent) >= 0: RVO2 considers an edge only from its right (outer) side
        ex, ey = cx - ax, cy - ay
        r = ((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey)
        if r < 0.0:
            d = (x - ax) ** 2 + (y - ay) ** 2
        elif r > 1.0:
            d = (x - cx) ** 2 + (y - cy) ** 2
        else:
            d = (x - (ax + r * ex)) ** 2 + (y - (ay + r * ey)) ** 2
        if d >= range_sq:
            continue
        if count < near.size:
            count += 1
        elif d >= near_d[count - 1]:
            continue
        i = count - 1
        while i > 0 and d < near_d[i - 1]:
            near[i], near_d[i] = near[i - 1], near_d[i - 1]
            i -= 1
        near[i], near_d[i] = e, d
    return count


@njit(cache=True, inline="always")
def _push(lp, ld, n, px, py, dx, dy):  # pragma: no cover - numba
    """Line n := point (px, py), direction (dx, dy); returns n + 1."""
    lp[n, 0], lp[n, 1] = px, py
    ld[n, 0], ld[n, 1] = dx, dy
    return n + 1


@njit(cache=True)
def _covered(r1x, r1y, r2x, r2y, inv_tau, radius, lp, ld, n):  # pragma: no cover - numba
    """Whether the lines so far already take care of the edge between relative positions r1 and r2."""
    for j in range(n):
        if (
            _det(inv_tau * r1x - lp[j, 0], inv_tau * r1y - lp[j, 1], ld[j, 0], ld[j, 1]) - inv_tau * radius >= -EPSILON
            and _det(inv_tau * r2x - lp[j, 0], inv_tau * r2y - lp[j, 1], ld[j, 0], ld[j, 1]) - inv_tau * radius
            >= -EPSILON
        ):
            return True
    return False


@njit(cache=True)
def _legs(o1, o2, s, d1, d2, d_line, r1x, r1y, r2x, r2y, radius, direction, convex):  # pragma: no cover - numba
    """The velocity obstacle's legs of edge o1 -> o2 with no collision: (o1, o2, left leg, right leg), both legs
    from one vertex when it is seen obliquely; o1 -1 when the edge is ignored (a non-convex vertex seen so)."""
    r_sq = radius * radius
    if s < 0.0 and d_line <= r_sq:
        if not convex[o1]:
            return -1, -1, 0.0, 0.0, 0.0, 0.0
        leg = math.sqrt(d1 - r_sq)
        return (
            o1,
            o1,
            (r1x * leg - r1y * radius) / d1,
            (r1x * radius + r1y * leg) / d1,
            (r1x * leg + r1y * radius) / d1,
            (-r1x * radius + r1y * leg) / d1,
        )
    if s > 1.0 and d_line <= r_sq:
        if not convex[o2]:
            return -1, -1, 0.0, 0.0, 0.0, 0.0
        leg = math.sqrt(d2 - r_sq)
        return (
            o2,
            o2,
            (r2x * leg - r2y * radius) / d2,
            (r2x * radius + r2y * leg) / d2,
            (r2x * leg + r2y * radius) / d2,
            (-r2x * radius + r2y * leg) / d2,
        )
    if convex[o1]:
        leg = math.sqrt(d1 - r_sq)
        llx, lly = (r1x * leg - r1y * radius) / d1, (r1x * radius + r1y * leg) / d1
    else:  # left vertex non-convex: the left leg extends the cut-off line
        llx, lly = -direction[o1, 0], -direction[o1, 1]
    if convex[o2]:
        leg = math.sqrt(d2 - r_sq)
        rlx, rly = (r2x * leg + r2y * radius) / d2, (-r2x * radius + r2y * leg) / d2
    else:
        rlx, rly = direction[o1, 0], direction[o1, 1]
    return o1, o2, llx, lly, rlx, rly


@njit(cache=True)
def _edge_line(o1, x, y, vx, vy, radius, inv_tau, point, nxt, prv, direction, convex, lp, ld, n):  # pragma: no cover
    """The ORCA line of obstacle edge o1 (RVO2's computeNewVelocity, one obstacle neighbour); returns the count."""
    o2 = nxt[o1]
    r1x, r1y = point[o1, 0] - x, point[o1, 1] - y
    r2x, r2y = point[o2, 0] - x, point[o2, 1] - y
    if _covered(r1x, r1y, r2x, r2y, inv_tau, radius, lp, ld, n):
        return n
    d1 = r1x * r1x + r1y * r1y
    d2 = r2x * r2x + r2y * r2y
    r_sq = radius * radius
    ovx, ovy = point[o2, 0] - point[o1, 0], point[o2, 1] - point[o1, 1]
    s = (-r1x * ovx - r1y * ovy) / (ovx * ovx + ovy * ovy)
    dlx, dly = -r1x - s * ovx, -r1y - s * ovy
    d_line = dlx * dlx + dly * dly
    if s < 0.0 and d1 <= r_sq:  # collision with the left vertex (ignored where non-convex)
        if convex[o1]:
            norm = math.sqrt(d1)
            n = _push(lp, ld, n, 0.0, 0.0, -r1y / norm, r1x / norm)
        return n
    if s > 1.0 and d2 <= r_sq:  # collision with the right vertex (or the neighbouring edge's)
        if convex[o2] and _det(r2x, r2y, direction[o2, 0], direction[o2, 1]) >= 0.0:
            norm = math.sqrt(d2)
            n = _push(lp, ld, n, 0.0, 0.0, -r2y / norm, r2x / norm)
        return n
    if 0.0 <= s <= 1.0 and d_line <= r_sq:  # collision with the edge
        return _push(lp, ld, n, 0.0, 0.0, -direction[o1, 0], -direction[o1, 1])
    o1, o2, llx, lly, rlx, rly = _legs(o1, o2, s, d1, d2, d_line, r1x, r1y, r2x, r2y, radius, direction, convex)
    if o1 < 0:
        return n
    # A leg never points into the neighbouring edge at a convex vertex: that edge's cut-off line instead, and a
    # velocity projected on such a "foreign" leg adds no line.
    left_nb = prv[o1]
    left_foreign = right_foreign = False
    if convex[o1] and _det(llx, lly, -direction[left_nb, 0], -direction[left_nb, 1]) >= 0.0:
        llx, lly = -direction[left_nb, 0], -direction[left_nb, 1]
        left_foreign = True
    if convex[o2] and _det(rlx, rly, direction[o2, 0], direction[o2, 1]) <= 0.0:
        rlx, rly = direction[o2, 0], direction[o2, 1]
        right_foreign = True
    lcx, lcy = inv_tau * (point[o1, 0] - x), inv_tau * (point[o1, 1] - y)
    rcx, rcy = inv_tau * (point[o2, 0] - x), inv_tau * (point[o2, 1] - y)
    cvx, cvy = rcx - lcx, rcy - lcy
    same = o1 == o2
    t = 0.5 if same else ((vx - lcx) * cvx + (vy - lcy) * cvy) / (cvx * cvx + cvy * cvy)
    t_left = (vx - lcx) * llx + (vy - lcy) * lly
    t_right = (vx - rcx) * rlx + (vy - rcy) * rly
    rr = radius * inv_tau
    if (t < 0.0 and t_left < 0.0) or (same and t_left < 0.0 and t_right < 0.0):  # the left cut-off circle
        wx, wy = vx - lcx, vy - lcy
        norm = math.sqrt(wx * wx + wy * wy)
        wx, wy = wx / norm, wy / norm
        return _push(lp, ld, n, lcx + rr * wx, lcy + rr * wy, wy, -wx)
    if t > 1.0 and t_right < 0.0:  # the right cut-off circle
        wx, wy = vx - rcx, vy - rcy
        norm = math.sqrt(wx * wx + wy * wy)
        wx, wy = wx / norm, wy / norm
        return _push(lp, ld, n, rcx + rr * wx, rcy + rr * wy, wy, -wx)
    # The left leg, the right leg or the cut-off line, whichever is nearest the velocity.
    d_cut = np.inf if (t < 0.0 or t > 1.0 or same) else (vx - (lcx + t * cvx)) ** 2 + (vy - (lcy + t * cvy)) ** 2
    d_left = np.inf if t_left < 0.0 else (vx - (lcx + t_left * llx)) ** 2 + (vy - (lcy + t_left * lly)) ** 2
    d_right = np.inf if t_right < 0.0 else (vx - (rcx + t_right * rlx)) ** 2 + (vy - (rcy + t_right * rly)) ** 2
    if d_cut <= d_left and d_cut <= d_right:
        dx, dy = -direction[o1, 0], -direction[o1, 1]
        return _push(lp, ld, n, lcx + rr * -dy, lcy + rr * dx, dx, dy)
    if d_left <= d_right:
        if left_foreign:
            return n
        return _push(lp, ld, n, lcx + rr * -lly, lcy + rr * llx, llx, lly)
    if right_foreign:
        return n
    return _push(lp, ld, n, rcx + rr * rly, rcy + rr * -rlx, -rlx, -rly)


@njit(cache=True)
def _obstacle_lines(
    x,
    y,
    vx,
    vy,
    radius,
    max_speed,
    tau_obst,
    point,
    nxt,
    prv,
    direction,
    convex,
    ox,
    oy,
    bx,
    by,
    start,
    items,
    item_d,
    lp,
    ld,
    near,
    near_d,
):  # pragma: no cover - numba
    """The obstacle ORCA lines of an agent at (x, y) moving at (vx, vy) into lp, ld; returns their count."""
    count = _obstacle_neighbors(
        x, y, tau_obst * max_speed + radius, point, nxt, ox, oy, bx, by, start, items, item_d, near, near_d
    )
    n = 0
    for q in range(count):
        n = _edge_line(near[q], x, y, vx, vy, radius, 1.0 / tau_obst, point, nxt, prv, direction, convex, lp, ld, n)
    return n


@njit(cache=True)
def _crowd_step(
    lo,
    hi,
    pos,
    vel,
    pref,
    radius,
    max_speed,
    moves,
    dt,
    neighbor_dist,
    max_neighbors,
    tau,
    tau_obst,
    point,
    nxt,
    prv,
    direction,
    convex,
    ox,
    oy,
    bx,
    by,
    start,
    items,
    item_d,
    new_vel,
):  # pragma: no cover - numba
    """New velocities of the moving agents lo:hi of one crowd (`moves`; the others, the ego, are only seen)."""
    lp, ld = np.empty((MAX_LINES, 2)), np.empty((MAX_LINES, 2))
    proj_p, proj_d = np.empty((MAX_LINES, 2)), np.empty((MAX_LINES, 2))
    near, near_d = np.empty(MAX_LINES // 2, dtype=np.int64), np.empty(MAX_LINES // 2)
    nb, nb_d = np.empty(max(max_neighbors, 1), dtype=np.int64), np.empty(max(max_neighbors, 1))
    res = np.empty(2)
    inv_tau = 1.0 / tau
    for a in range(lo, hi):
        if not moves[a]:
            new_vel[a, 0], new_vel[a, 1] = vel[a, 0], vel[a, 1]
            continue
        x, y, vx, vy, r = pos[a, 0], pos[a, 1], vel[a, 0], vel[a, 1], radius[a]
        n_obst = _obstacle_lines(
            x,
            y,
            vx,
            vy,
            r,
            max_speed[a],
            tau_obst,
            point,
            nxt,
            prv,
            direction,
            convex,
            ox,
            oy,
            bx,
            by,
            start,
            items,
            item_d,
            lp,
            ld,
            near,
            near_d,
        )
        # Agent neighbours: the nearest max_neighbors within neighbor_dist (RVO2's insertAgentNeighbor).
        count = 0
        range_sq = neighbor_dist * neighbor_dist
        if max_neighbors > 0:
            for b in range(lo, hi):
                if b == a:
                    continue
                d = (x - pos[b, 0]) ** 2 + (y - pos[b, 1]) ** 2
                if d < range_sq:
                    if count < max_neighbors:
                        count += 1
                    i = count - 1
                    while i != 0 and d < nb_d[i - 1]:
                        nb[i], nb_d[i] = nb[i - 1], nb_d[i - 1]
                        i -= 1
                    nb[i], nb_d[i] = b, d
                    if count == max_neighbors:
                        range_sq = nb_d[count - 1]
        n = n_obst
        for q in range(count):
            if n >= MAX_LINES:
                break
            b = nb[q]
            rpx, rpy = pos[b, 0] - x, pos[b, 1] - y
            rvx, rvy = vx - vel[b, 0], vy - vel[b, 1]
            dist_sq = rpx * rpx + rpy * rpy
            comb = r + radius[b]
            comb_sq = comb * comb
            if dist_sq > comb_sq:
                wx, wy = rvx - inv_tau * rpx, rvy - inv_tau * rpy
                w_sq = wx * wx + wy * wy
                dot = wx * rpx + wy * rpy
                if dot < 0.0 and dot * dot > comb_sq * w_sq:
                    w_len = math.sqrt(w_sq)
                    uwx, uwy = wx / w_len, wy / w_len
                    dx, dy = uwy, -uwx
                    ux, uy = (comb * inv_tau - w_len) * uwx, (comb * inv_tau - w_len) * uwy
                else:
                    leg = math.sqrt(dist_sq - comb_sq)
                    if _det(rpx, rpy, wx, wy) > 0.0:
                        dx, dy = (rpx * leg - rpy * comb) / dist_sq, (rpx * comb + rpy * leg) / dist_sq
                    else:
                        dx, dy = -(rpx * leg + rpy * comb) / dist_sq, -(-rpx * comb + rpy * leg) / dist_sq
                    dot2 = rvx * dx + rvy * dy
                    ux, uy = dot2 * dx - rvx, dot2 * dy - rvy
            else:
                inv_dt = 1.0 / dt
                wx, wy = rvx - inv_dt * rpx, rvy - inv_dt * rpy
                w_len = math.sqrt(wx * wx + wy * wy)
                uwx, uwy = wx / w_len, wy / w_len
                dx, dy = uwy, -uwx
                ux, uy = (comb * inv_dt - w_len) * uwx, (comb * inv_dt - w_len) * uwy
            lp[n, 0], lp[n, 1] = vx + 0.5 * ux, vy + 0.5 * uy
            ld[n, 0], ld[n, 1] = dx, dy
            n += 1
        fail = _lp2(lp, ld, n, max_speed[a], pref[a, 0], pref[a, 1], False, res)
        if fail < n:
            _lp3(lp, ld, n, n_obst, fail, max_speed[a], res, proj_p, proj_d)
        new_vel[a, 0], new_vel[a, 1] = res[0], res[1]


@njit(cache=True, parallel=True)
def orca_crowds(
    crowd_start,
    scene_of,
    pos,
    vel,
    pref,
    radius,
    max_speed,
    moves,
    dt,
    neighbor_dist,
    max_neighbors,
    tau,
    tau_obst,
    points,
    nxts,
    prvs,
    directions,
    convexes,
    origins,
    shapes,
    starts,
    itemss,
    item_ds,
):  # pragma: no cover - numba
    """One ORCA step of every crowd: crowd c is agents crowd_start[c]:crowd_start[c + 1] of the flat arrays, among
    the obstacles of index scene_of[c] (typed lists of per-scene arrays); returns new positions and velocities [N, 2]
    (agents with `moves` False keep theirs)."""
    new_vel = np.empty_like(vel)
    for c in prange(crowd_start.size - 1):
        s = scene_of[c]
        _crowd_step(
            crowd_start[c],
            crowd_start[c + 1],
            pos,
            vel,
            pref,
            radius,
            max_speed,
            moves,
            dt,
            neighbor_dist,
            max_neighbors,
            tau,
            tau_obst,
            points[s],
            nxts[s],
            prvs[s],
            directions[s],
            convexes[s],
            origins[s, 0],
            origins[s, 1],
            shapes[s, 0],
            shapes[s, 1],
            starts[s],
            itemss[s],
            item_ds[s],
            new_vel,
        )
    new_pos = pos + new_vel * dt
    for a in range(pos.shape[0]):
        if not moves[a]:
            new_pos[a, 0], new_pos[a, 1] = pos[a, 0], pos[a, 1]
    return new_pos, new_vel


@njit(cache=True)
def visible_many(p, q, radius, point, nxt, ox, oy, bx, by, start, items):  # pragma: no cover - numba
    """RVO2's queryVisibility of discs of `radius` [k] from p [k, 2] to q [k, 2]: whether each moves from p to q
    without crossing an obstacle edge from its outer side or passing within its radius of an edge it crosses the
    line of. The edges asked are those filed under the buckets the query's box (grown by the radius) touches."""
    out = np.empty(p.shape[0], dtype=np.bool_)
    seen = np.zeros(point.shape[0], dtype=np.int64)
    for k in range(p.shape[0]):
        out[k] = _visible(
            p[k, 0], p[k, 1], q[k, 0], q[k, 1], radius[k], point, nxt, ox, oy, bx, by, start, items, seen, k + 1
        )
    return out


@njit(cache=True)
def _visible(px, py, qx, qy, radius, point, nxt, ox, oy, bx, by, start, items, seen, stamp):  # pragma: no cover
    """One query of `visible_many`, each edge tested once: `seen[e] == stamp` marks the edges it has tested."""
    lo_x, hi_x = min(px, qx) - radius, max(px, qx) + radius
    lo_y, hi_y = min(py, qy) - radius, max(py, qy) + radius
    i0 = max(int(math.floor((lo_x - ox) / BUCKET)), 0)
    i1 = min(int(math.floor((hi_x - ox) / BUCKET)), bx - 1)
    j0 = max(int(math.floor((lo_y - oy) / BUCKET)), 0)
    j1 = min(int(math.floor((hi_y - oy) / BUCKET)), by - 1)
    qlen = (qx - px) ** 2 + (qy - py) ** 2
    inv_q = 1.0 / qlen if qlen > 0.0 else 0.0
    r_sq = radius * radius
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            b = j * bx + i
            for k in range(start[b], start[b + 1]):
                e = items[k]
                if seen[e] == stamp:
                    continue
                seen[e] = stamp
                ax, ay = point[e, 0], point[e, 1]
                cx, cy = point[nxt[e], 0], point[nxt[e], 1]
                q1 = (ax - px) * (cy - ay) - (ay - py) * (cx - ax)  # leftOf(a, c, p)
                q2 = (ax - qx) * (cy - ay) - (ay - qy) * (cx - ax)
                if (q1 >= 0.0 and q2 >= 0.0) or (q1 <= 0.0 and q2 <= 0.0) or (q1 >= 0.0 and q2 <= 0.0):
                    continue
                p1 = (px - ax) * (qy - py) - (py - ay) * (qx - px)  # leftOf(p, q, a)
                p2 = (px - cx) * (qy - py) - (py - cy) * (qx - px)
                if not (p1 * p2 >= 0.0 and p1 * p1 * inv_q > r_sq and p2 * p2 * inv_q > r_sq):
                    return False
    return True
