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
            out[[push.mover for push in self.active.values()]] = True
        return out

    def _directions(self, state: CrowdState, grid: NavGrid, nodes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Unit path directions (4 cells ahead on the own goal field) of agents `idx`; zero where undefined."""
        ahead = grid.node_xy(grid.lookahead(nodes[idx], state.site[idx], 4))
        offset = ahead - state.pos[idx]
        norm = np.sqrt((offset * offset).sum(1))[:, None]
        return np.where(norm > 1e-6, offset / np.maximum(norm, 1e-6), 0.0)

    def detect(self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray) -> None:
        """Start pushes for the agents (at `nodes`) stalled face to face with a blocker (see the module docstring)."""
        if self.window <= 0 or state.n < 2:
            return
        stuck = config["stuck_steps"]
        if not (state.stall >= max(stuck, 1)).any():
            return  # nobody stalled long enough: no candidate
        busy = self.busy(state.n)
        moving = state.movement != IDLE
        cand = np.flatnonzero(moving & (state.stall >= max(stuck, 1)) & ~busy)
        if not len(cand):
            return
        heading = self._directions(state, grid, nodes, cand)
        right = np.stack([heading[:, 1], -heading[:, 0]], 1)
        room = grid.is_free(state.pos[cand] + right) | grid.is_free(state.pos[cand] - right)
        ready = (state.stall[cand] >= 2 * stuck) | ~room
        cand, heading = cand[ready], heading[ready]
        if not len(cand):
            return
        offset = state.pos[None, :, :] - state.pos[cand][:, None, :]  # [k, n, 2] from each candidate to every agent
        dist = np.sqrt((offset * offset).sum(2))
        reach = state.radius[cand][:, None] + state.radius[None, :] + 2 * config["safety_margin"] + REACH_GAP
        front = np.einsum("knd,kd->kn", offset, heading) > FRONT_COS * np.maximum(dist, 1e-9)
        near = (dist < reach) & front
        near[np.arange(len(cand)), cand] = False
        for k, i in enumerate(cand.tolist()):
            if busy[i]:
                continue
            js = np.flatnonzero(near[k] & ~busy)
            if not len(js):
                continue
            j = int(js[np.argmin(dist[k, js])])
            if state.movement[j] == IDLE:
                plan, yielder, mover = self._plan(state, grid, config, nodes, j, i), j, i
            else:
                uj = self._directions(state, grid, nodes, np.array([j]))[0]
                oncoming = float(uj @ (state.pos[i] - state.pos[j])) > FRONT_COS * float(dist[k, j])
                if not (oncoming or state.stall[j] >= stuck):
                    continue
                pi, pj = self._plan(state, grid, config, nodes, i, j), self._plan(state, grid, config, nodes, j, i)
                options = [
                    (option_plan[1], -y, y, mv, option_plan)
                    for option_plan, y, mv in ((pi, i, j), (pj, j, i))
                    if option_plan is not None
                ]
                if not options:
                    continue
                _, _, yielder, mover, plan = min(options, key=lambda o: (o[0], o[1]))
            if plan is None:
                continue
            path, _, hold_field = plan
            self.active[yielder] = Push(mover, int(state.site[mover]), path, hold_field)
            busy[yielder] = busy[mover] = True
            self.started += 1

    def _plan(
        self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray, y: int, mv: int
    ) -> tuple[np.ndarray, float, float] | None:
        """Cells from yielder `y` to the nearest passing place off mover `mv`'s path, its length, and mv's field there."""
        rows, cols = grid.free.shape
        half = int(np.ceil(self.window / grid.res))
        yi, yj = (int(v) for v in grid.node_rc[nodes[y]])
        r0, r1, c0, c1 = max(yi - half, 0), min(yi + half + 1, rows), max(yj - half, 0), min(yj + half + 1, cols)
        site = int(state.site[mv])
        route = grid.node_rc[grid.path_nodes(int(nodes[mv]), site, max_steps=8 * half)]
        goal_rc = np.stack(grid.cell_of(state.goal[mv][None]), 1)
        route = np.concatenate([route, goal_rc.astype(route.dtype)])
        inside = (route[:, 0] >= r0) & (route[:, 0] < r1) & (route[:, 1] >= c0) & (route[:, 1] < c1)
        if not inside.any():
            return None
        on_route = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        on_route[route[inside, 0] - r0, route[inside, 1] - c0] = True
        to_route = ndimage.distance_transform_edt(~on_route) * grid.res
        need = state.radius[y] + state.radius[mv] + 2 * config["safety_margin"] + PASS_MARGIN
        xs = grid.origin[0] + (np.arange(c0, c1) + 0.5) * grid.res
        ys = grid.origin[1] + (np.arange(r0, r1) + 0.5) * grid.res
        to_mover = np.hypot(xs[None, :] - state.pos[mv, 0], ys[:, None] - state.pos[mv, 1])
        start_xy = grid.node_xy(np.array([nodes[y]]))[0]
        # The way out must not pass through the mover: cells closer to it than the yielder's own cell are cut.
        guard = min(need, float(np.hypot(*(start_xy - state.pos[mv]))))
        allowed = grid.free[r0:r1, c0:c1] & (to_mover >= guard)
        ids = grid.node_of[r0:r1, c0:c1][allowed]
        start = np.flatnonzero(ids == nodes[y])
        if not len(start):
            return None
        sub = grid.graph[ids][:, ids]
        dist, pred = dijkstra(sub, directed=True, indices=int(start[0]), return_predecessors=True)
        target = (to_route[allowed] >= need) & np.isfinite(dist)
        if not target.any():
            return None
        best = int(np.argmin(np.where(target, dist, np.inf)))
        chain = [best]
        while chain[-1] != start[0]:
            chain.append(int(pred[chain[-1]]))
        path = grid.node_xy(ids[np.asarray(chain[::-1])])
        hold_field = float(grid.distance(np.array([ids[best]]), np.array([site]))[0])
        return path, float(dist[best]), hold_field

    def hold(self, state: CrowdState) -> None:
        """Keep the stall counts of everyone in a push at zero: no side-step, no abandoned goal meanwhile."""
        if self.active:
            state.stall[self.busy(state.n)] = 0

    def release(self, state: CrowdState, grid: NavGrid, config: Mapping[str, Any], nodes: np.ndarray) -> None:
        """End the pushes whose mover has passed, reached or changed its goal, or that ran `regoal_steps`."""
        if not self.active:
            return
        for y in list(self.active):
            push = self.active[y]
            push.steps += 1
            mv = push.mover
            done = state.movement[mv] == IDLE or int(state.site[mv]) != push.site or push.steps > config["regoal_steps"]
            if not done:
                left = float(grid.distance(nodes[mv : mv + 1], state.site[mv : mv + 1], planned=True)[0])
                need = state.radius[y] + state.radius[mv]
                done = left < push.hold_field - need
            if done:
                del self.active[y]
                state.stall[y], state.best[y] = (
                    0,
                    np.inf,
                )  # progress toward its own goal counts afresh from the passing place
                self.finished += 1

    def steer(self, state: CrowdState, pref: np.ndarray) -> None:
        """Overwrite the yielders' preferred velocities: along their planned cells to the passing place, then stop."""
        for y, push in self.active.items():
            offset = push.path - state.pos[y]
            k = int(np.argmin((offset * offset).sum(1)))
            target = push.path[min(k + 4, len(push.path) - 1)]
            step = target - state.pos[y]
            dist = float(np.hypot(*step))
            left = float(np.hypot(*(push.path[-1] - state.pos[y])))
            if dist < 0.05 or left < 0.1:
                pref[y] = 0.0
                continue
            speed = min(AGENT_KINDS[KIND_NAMES[state.kind_idx[y]]].pref_speed, max(left, 0.3))
            pref[y] = step / dist * speed
