"""Goal following on the navigation grid: drawing goals, arrival, progress, stalls, preferred velocities."""

from __future__ import annotations

import numpy as np

from sim.agents.crowd_kernels import carrots, headings, idle_tick, progress, rungs
from sim.agents.kinds import AGENT_KINDS, IDLE, KIND_NAMES, RUNNING, WALKING
from sim.agents.navgrid import JUMPS


class GoalFollowing:
    """AgentManager's goal-following part: picks goals, tracks progress and steers at a carrot."""

    def _new_goal(
        self,
        i: int,
        node: int,
        abandon: bool = False,
        site: int | None = None,
        goal_xy: np.ndarray | None = None,
        speed: float | None = None,
    ) -> None:
        """Send agent i (at `node`) to a random goal, or to `site` (its cell nearest `goal_xy`) walking at `speed`."""
        c, g, rng = self.config, self.grid, self.rng
        spread = c["goal_spread"]
        self.crossing[i] = False
        # cross_prob 0 draws nothing, so runs without crossings keep their random stream.
        if site is None and c["cross_prob"] > 0 and rng.random() < c["cross_prob"]:
            site = self.crossings.pick(self.pos[i])
            if site is not None:
                self.crossing[i] = True
                self.cross_counts["started"] += 1
                spread = min(spread, 1.0)  # stay by the crosswalk's far end, not 2.5 m around it
        if site is None:
            spread_sites = g.sites[: g.n_spread]  # crossing sites are goals of crossings only
            here = int(np.argmin(np.linalg.norm(g.node_xy(spread_sites) - self.pos[i], axis=1)))
            choices = np.delete(np.arange(len(spread_sites)), here) if len(spread_sites) > 1 else np.arange(1)
            site = int(rng.choice(choices))
        if abandon:
            self.counts["abandoned"] += 1
        if speed is None:
            kind = AGENT_KINDS[KIND_NAMES[self.kind_idx[i]]]
            run = kind.run_speed is not None and rng.random() < c["run_prob"]
            self.movement[i] = RUNNING if run else WALKING
            self.speed[i] = kind.sample_speed(rng, "running" if run else "walking")
        else:
            self.movement[i], self.speed[i] = WALKING, speed
        dist = g.field(site)
        if goal_xy is None:
            near_nodes = self._goal_cells(site, spread, dist)
            goal_node = int(rng.choice(near_nodes)) if len(near_nodes) else int(g.sites[site])
        else:
            goal_node = int(g.nearest_node(np.asarray(goal_xy, dtype=np.float64)[None])[0])
        self.site[i] = site
        self.goal[i] = g.node_xy(np.array([goal_node]))[0]
        length = float(dist[node]) + c["goal_spread"]
        self.goal_t0[i] = self.time
        self.budget[i] = c["budget_factor"] * length / max(self.speed[i], 0.1) + c["budget_slack"]
        self.best[i] = np.inf
        self.stall[i] = 0

    def _goal_cells(self, site: int, spread: float, dist: np.ndarray) -> np.ndarray:
        """Nodes within `spread` m of goal site `site` (and within 1.5 spread along its field `dist`), cached: goals
        are drawn among them every time an agent heads there."""
        key = (id(self.grid), site, spread)
        cells = self._goal_cell_cache.get(key)
        if cells is None:
            g = self.grid
            centre = g.node_xy(np.array([g.sites[site]]))[0]
            cand = np.flatnonzero(dist < spread * 1.5)
            cells = cand[np.flatnonzero(np.linalg.norm(g.node_xy(cand) - centre, axis=1) < spread)]
            self._goal_cell_cache[key] = cells
        return cells

    def _walking_speed(self, i: int) -> float:
        """A fresh walking speed for agent i's kind."""
        return AGENT_KINDS[KIND_NAMES[self.kind_idx[i]]].sample_speed(self.rng, "walking")

    def _update_goals(self, dt: float, nodes: np.ndarray) -> None:
        c, g = self.config, self.grid
        for i in idle_tick(self.movement, self.idle_left, float(dt), IDLE).tolist():
            if self.movement[i] != IDLE:
                continue  # its group's decision already sent it off
            if self.groups.of[i] >= 0:
                self.groups.stand_over(self, i, nodes)
            else:
                self._new_goal(i, int(nodes[i]))
        moving = np.flatnonzero(self.movement != IDLE)
        if not len(moving):
            return
        arrived, abandon = progress(
            moving,
            self.pos,
            self.goal,
            nodes,
            self.site,
            g._dist,
            self.stall,
            self.best,
            float(c["arrive_radius"]),
            float(c["crowded_arrive_radius"]),
            int(c["stuck_steps"]),
            float(c["stuck_progress"]),
            int(c["regoal_steps"]),
        )  # _new_goal planned every field
        if arrived.any():
            for i in moving[arrived].tolist():
                late = self.time - self.goal_t0[i] > self.budget[i]
                self.counts["late" if late else "in_time"] += 1
                self.cross_counts["done"] += int(self.crossing[i])
                self.crossing[i] = False
                if self.groups.of[i] >= 0:
                    self.groups.arrived(self, i)
                elif self.rng.random() < c["idle_prob"]:
                    self.movement[i] = IDLE
                    self.idle_left[i] = self.rng.uniform(*c["idle_time"])
                else:
                    self._new_goal(i, int(nodes[i]))
        for i in moving[abandon].tolist():
            if self.groups.of[i] >= 0:
                self.groups.dissolve(self, int(self.groups.of[i]))
            self._new_goal(i, int(nodes[i]), abandon=True)

    def _preferred(self, nodes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        g, c = self.grid, self.config
        sites = self.site[idx]
        pos = self.pos[idx]
        steps = c["lookahead_cells"]
        ox, oy = float(g.origin[0]), float(g.origin[1])
        # Keep right: shortest paths hug the same inner edges in both directions, so opposing flows would meet
        # head-on in one lane (ORCA then herds the weaker side backwards); a right offset forms two lanes.
        carrot = carrots(
            idx,
            nodes,
            self.pos,
            self.site,
            g._jump[JUMPS.index(steps)],
            g.centres,
            float(c["keep_right"]),
            ox,
            oy,
            float(g.res),
            g.free,
        )
        # A carrot behind a concave corner (a crosswalk mouth) would press the agent into the curb: fall back
        # to nearer points of the path (steps, steps/2, ..., 1 cells; the last without a check) until one is in
        # sight. The rungs are looked up at once for the few agents that need them.
        visible = self.sim.query_visibility
        pos_l, rad_l = pos.tolist(), self.radius[idx].tolist()
        blocked = [k for k, (p, q, r) in enumerate(zip(pos_l, carrot.tolist(), rad_l)) if not visible(p, q, r)]
        if blocked:
            b = np.asarray(blocked)
            ladder = rungs(nodes[b], sites[b], g._jump, g.centres, JUMPS.index(steps)).tolist()
            for m, k in enumerate(blocked):
                for rung in ladder[:-1]:
                    if visible(pos_l[k], rung[m], rad_l[k]):
                        carrot[k] = rung[m]
                        break
                else:
                    carrot[k] = ladder[-1][m]
        # Close to the site the field's single target cell would pull everyone to one point: aim at the own goal.
        direction, speed = headings(
            idx, nodes, self.pos, carrot, self.goal, self.site, g._dist, self.speed, 1.5 * c["goal_spread"]
        )
        stall = self.stall[idx]
        stuck = stall >= c["stuck_steps"]
        if stuck.any():
            # Side-step (the rotate half of push-and-rotate): to the right when there is room, else to the left,
            # switching sides every `stuck_steps` so an agent pinned against a curb or a wall gets out.
            dx, dy = direction[stuck, 0].copy(), direction[stuck, 1].copy()
            right = np.stack([dy, -dx], 1)
            probe = pos[stuck] + right * 1.0
            sign = np.where(g.is_free(probe), 1.0, -1.0)
            phase = (stall[stuck] - c["stuck_steps"]) // c["stuck_steps"]
            sign = np.where(phase % 2 == 1, -sign, sign)
            ang = -1.2 * sign
            cs, sn = np.cos(ang), np.sin(ang)
            direction[stuck, 0], direction[stuck, 1] = cs * dx - sn * dy, sn * dx + cs * dy
        return direction * speed[:, None]
