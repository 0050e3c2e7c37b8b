"""The push half of push-and-rotate for the crowd: an agent blocked face to face makes way by retreating.

Push-and-Rotate (de Wilde, ter Mors & Witteveen, AAMAS 2013) resolves deadlocks on graphs with two moves: *push*
moves an agent that stands on another's path out of the way, to the nearest vertex off that path, and *rotate*
moves agents around each other where there is room. On the continuous sidewalk the crowd does the rotate half as
a side-step (sim.agents.crowd_goals.preferred); this module is the push half, which is what a corridor one body
wide needs, where no side-step is possible:

1. Trigger (`PushResolver.detect`, every step, vectorised over the stalled agents): a moving agent that has made
   no progress for `stuck_steps` with no room to side-step (neither side 1 m away is a planning cell), or for
   `2 * stuck_steps` when the side-step did not help, and that has another agent close in front (centres
   within r_i + r_j + 2 safety_margin + 0.5 m, ahead within 60 degrees of its path direction) who is standing
   (idle), stalled, or coming toward it.
2. Who yields: a standing agent always yields to a moving one. Of two moving agents face to face, the one with
   the shorter way to a passing place yields (ties: the higher index), so the cheaper retreat happens.
3. Where to (`_plan`): within `push_window` metres, the nearest planning cell (by path length on the free-cell
   graph, not passing through the other agent) whose distance to the other agent's remaining path is at least
   r_i + r_j + 2 safety_margin + 0.1 m: backward along the corridor into the bay it came from, or one step aside
   where the sidewalk is wide. The other agent's path comes from its goal site's distance field.
4. Waiting and resuming (`release`): the yielder walks there along the planned cells and waits; the other keeps
   going with its stall count held at zero (it neither side-steps nor abandons its goal meanwhile). The yielder
   resumes its own goal once the other has passed the passing place along its path, has reached its goal or
   taken another, or after `regoal_steps`.

Everything is a pure function of the agents' state, in index order, so runs stay deterministic.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from sim.agents.crowd_state import CrowdState
from sim.agents.kinds import AGENT_KINDS, IDLE, KIND_NAMES
from sim.agents.navgrid import NavGrid

FRONT_COS = 0.5  # "in front": within 60 degrees of the path direction
REACH_GAP = 0.5  # metres between ORCA discs that still count as face to face
PASS_MARGIN = 0.1  # metres of room beyond touching between the yielder and the other's path


@dataclass
class Push:
    """One agent making way for another: where it retreats to and when it may resume."""

    mover: int
    site: int  # the mover's goal site when the push began (a new goal ends the push)
    path: np.ndarray  # [k, 2] cell centres from the yielder to its passing place
    hold_field: float  # the mover's path length to its site from the passing place
    steps: int = 0


class PushResolver:
    """Detects face-to-face blocks, sends the lower-priority agent to a passing place and releases it later.

    It keeps the pushes under way; the agents' state, the navigation grid and the agents config come in as arguments.
    """

    def __init__(self, window: float) -> None:
        self.window = float(window)
        self.active: dict[int, Push] = {}  # yielder -> push, iterated in insertion (= detection) order
        self.started = 0
        self.finished = 0

    def reset(self) -> None:
        """Forget every push (a new episode)."""
        self.active.clear()
        self.started = self.finished = 0

    def busy(self, n: int) -> np.ndarray:
        """Bool mask of agents taking part in a push, as yielder or mover."""
        out = np.zeros(n, dtype=bool)
        if self.active:
            out[list(self.active)] = True
            out[[p.mover for p in self.active.values()]] = True
        return out

    def _directions(self, state: CrowdState, grid: NavGrid, nodes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Unit path directions (4 cells ahead on the own goal field) of agents `idx`; zero where undefined."""
        g = grid
        ahead = g.node_xy(g.lookahead(nodes[idx], state.site[idx], 4))
        d = ahead - state.pos[idx]
        norm = np.sqrt((d * d).sum(1))[:, None]
        return np.where(norm > 1e-6, d / np.maximum(norm, 1e-6), 0.0)

    def detect(self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray) -> None:
        """Start pushes for the agents (at `nodes`) stalled face to face with a blocker (see the module docstring)."""
        s = state
        if self.window <= 0 or s.n < 2:
            return
        c, g = config, grid
        stuck = c["stuck_steps"]
        if not (s.stall >= max(stuck, 1)).any():
            return  # nobody stalled long enough: no candidate
        busy = self.busy(s.n)
        moving = s.movement != IDLE
        cand = np.flatnonzero(moving & (s.stall >= max(stuck, 1)) & ~busy)
        if not len(cand):
            return
        u = self._directions(s, g, nodes, cand)
        right = np.stack([u[:, 1], -u[:, 0]], 1)
        room = g.is_free(s.pos[cand] + right) | g.is_free(s.pos[cand] - right)
        ready = (s.stall[cand] >= 2 * stuck) | ~room
        cand, u = cand[ready], u[ready]
        if not len(cand):
            return
        d = s.pos[None, :, :] - s.pos[cand][:, None, :]  # [k, n, 2] from each candidate to every agent
        dist = np.sqrt((d * d).sum(2))
        reach = s.radius[cand][:, None] + s.radius[None, :] + 2 * c["safety_margin"] + REACH_GAP
        front = np.einsum("knd,kd->kn", d, u) > FRONT_COS * np.maximum(dist, 1e-9)
        near = (dist < reach) & front
        near[np.arange(len(cand)), cand] = False
        for k, i in enumerate(cand.tolist()):
            if busy[i]:
                continue
            js = np.flatnonzero(near[k] & ~busy)
            if not len(js):
                continue
            j = int(js[np.argmin(dist[k, js])])
            if s.movement[j] == IDLE:
                plan, yielder, mover = self._plan(s, g, c, nodes, j, i), j, i
            else:
                uj = self._directions(s, g, nodes, np.array([j]))[0]
                oncoming = float(uj @ (s.pos[i] - s.pos[j])) > FRONT_COS * float(dist[k, j])
                if not (oncoming or s.stall[j] >= stuck):
                    continue
                pi, pj = self._plan(s, g, c, nodes, i, j), self._plan(s, g, c, nodes, j, i)
                options = [(p[1], -y, y, mv, p) for p, y, mv in ((pi, i, j), (pj, j, i)) if p is not None]
                if not options:
                    continue
                _, _, yielder, mover, plan = min(options, key=lambda o: (o[0], o[1]))
            if plan is None:
                continue
            path, _, hold_field = plan
            self.active[yielder] = Push(mover, int(s.site[mover]), path, hold_field)
            busy[yielder] = busy[mover] = True
            self.started += 1

    def _plan(
        self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray, y: int, mv: int
    ) -> tuple[np.ndarray, float, float] | None:
        """Cells from yielder `y` to the nearest passing place off mover `mv`'s path, its length, and mv's field there."""
        s, g, c = state, grid, config
        h, w = g.free.shape
        half = int(np.ceil(self.window / g.res))
        yi, yj = (int(v) for v in g.node_rc[nodes[y]])
        r0, r1, c0, c1 = max(yi - half, 0), min(yi + half + 1, h), max(yj - half, 0), min(yj + half + 1, w)
        site = int(s.site[mv])
        route = g.node_rc[g.path_nodes(int(nodes[mv]), site, max_steps=8 * half)]
        goal_rc = np.stack(g.cell_of(s.goal[mv][None]), 1)
        route = np.concatenate([route, goal_rc.astype(route.dtype)])
        inside = (route[:, 0] >= r0) & (route[:, 0] < r1) & (route[:, 1] >= c0) & (route[:, 1] < c1)
        if not inside.any():
            return None
        on_route = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        on_route[route[inside, 0] - r0, route[inside, 1] - c0] = True
        to_route = ndimage.distance_transform_edt(~on_route) * g.res
        need = s.radius[y] + s.radius[mv] + 2 * c["safety_margin"] + PASS_MARGIN
        xs = g.origin[0] + (np.arange(c0, c1) + 0.5) * g.res
        ys = g.origin[1] + (np.arange(r0, r1) + 0.5) * g.res
        to_mover = np.hypot(xs[None, :] - s.pos[mv, 0], ys[:, None] - s.pos[mv, 1])
        start_xy = g.node_xy(np.array([nodes[y]]))[0]
        # The way out must not pass through the mover: cells closer to it than the yielder's own cell are cut.
        guard = min(need, float(np.hypot(*(start_xy - s.pos[mv]))))
        allowed = g.free[r0:r1, c0:c1] & (to_mover >= guard)
        ids = g.node_of[r0:r1, c0:c1][allowed]
        start = np.flatnonzero(ids == nodes[y])
        if not len(start):
            return None
        sub = g.graph[ids][:, ids]
        dist, pred = dijkstra(sub, directed=True, indices=int(start[0]), return_predecessors=True)
        target = (to_route[allowed] >= need) & np.isfinite(dist)
        if not target.any():
            return None
        t = int(np.argmin(np.where(target, dist, np.inf)))
        chain = [t]
        while chain[-1] != start[0]:
            chain.append(int(pred[chain[-1]]))
        path = g.node_xy(ids[np.asarray(chain[::-1])])
        hold_field = float(g.distance(np.array([ids[t]]), np.array([site]))[0])
        return path, float(dist[t]), hold_field

    def hold(self, state: CrowdState) -> None:
        """Keep the stall counts of everyone in a push at zero: no side-step, no abandoned goal meanwhile."""
        if self.active:
            state.stall[self.busy(state.n)] = 0

    def release(self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray) -> None:
        """End the pushes whose mover has passed, reached or changed its goal, or that ran `regoal_steps`."""
        if not self.active:
            return
        s, g = state, grid
        for y in list(self.active):
            p = self.active[y]
            p.steps += 1
            mv = p.mover
            done = s.movement[mv] == IDLE or int(s.site[mv]) != p.site or p.steps > config["regoal_steps"]
            if not done:
                left = float(g.distance(nodes[mv : mv + 1], s.site[mv : mv + 1], planned=True)[0])
                need = s.radius[y] + s.radius[mv]
                done = left < p.hold_field - need
            if done:
                del self.active[y]
                s.stall[y], s.best[y] = 0, np.inf  # progress toward its own goal counts afresh from the passing place
                self.finished += 1

    def steer(self, state: CrowdState, pref: np.ndarray) -> None:
        """Overwrite the yielders' preferred velocities: along their planned cells to the passing place, then stop."""
        s = state
        for y, p in self.active.items():
            d = p.path - s.pos[y]
            k = int(np.argmin((d * d).sum(1)))
            target = p.path[min(k + 4, len(p.path) - 1)]
            step = target - s.pos[y]
            dist = float(np.hypot(*step))
            left = float(np.hypot(*(p.path[-1] - s.pos[y])))
            if dist < 0.05 or left < 0.1:
                pref[y] = 0.0
                continue
            speed = min(AGENT_KINDS[KIND_NAMES[s.kind_idx[y]]].pref_speed, max(left, 0.3))
            pref[y] = step / dist * speed
