"""AgentManager: cohabitants that plan over the walkable grid and avoid each other, objects, curbs and the ego with ORCA.

Each agent steers at a carrot a few cells ahead on its goal site's distance field (sim.agents.navgrid) and
pyrvo (RVO2) turns that preferred velocity into a collision-free one. The ego is one more ORCA agent whose
position and velocity the simulator overwrites every step, so agents react to it but ORCA never moves it.
Deadlocks are resolved by push-and-rotate (de Wilde et al. 2013) adapted to the continuous sidewalk, then by
giving up: an agent that makes no progress for `stuck_steps` side-steps, right when there is room, else left
(the *rotate* half: it breaks symmetric face-offs where two can pass); one stalled face to face with another
agent, after `stuck_steps` when there is no room to side-step (a corridor one body wide) or after
`2 * stuck_steps` otherwise, triggers the *push* half (sim.agents.deadlock): the lower-priority agent of the two
retreats to the nearest cell off the other's path, waits until it has passed, then resumes its goal; one still
stuck after `regoal_steps` gives up its goal and picks another.

Movements: idle, walking, running (sim.agents.kinds), standing groups and road crossings (sim.agents.behaviours).

AgentManager composes explicit parts around one CrowdState (sim.agents.crowd_state), the per-episode arrays
of every agent, and hands each part the state and the inputs it reads:
- configuration: the agents' Keys, AGENT_DEFAULTS and AGENTS_TABLE (crowd_config);
- spawning: the spawn region, the agents' kinds and start positions (crowd_spawning functions);
- ORCA: OrcaCrowd (crowd_orca), one per scene, owning its obstacles, a pyrvo simulator per agent capacity, the
  ego's slot and the ORCA radii as last set;
- goal following: new goals, arrivals, stalls and preferred velocities (crowd_goals functions, GoalCells);
- behaviours: Groups and Crossings (behaviours; groups set goals through the GoalSetter the manager passes) and
  the push half of push-and-rotate (deadlock.PushResolver).
The manager keeps what spans episodes (the scene, its navigation grid, the ORCA part, the goal-cell cache) and
this episode's random generator; read-only properties expose the state's public arrays (`pos`, `vel`, `n`, ...).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kernel.config import ConfigError, merge_strict
from sim.agents.behaviours import Crossings, Groups
from sim.agents.crowd_config import AGENT_DEFAULTS, AGENTS_TABLE
from sim.agents.crowd_goals import GoalCells, new_goal, preferred, update_goals, walking_speed
from sim.agents.crowd_kernels import nearest_nodes, on_mask
from sim.agents.crowd_orca import EgoState, OrcaCrowd, as_ego
from sim.agents.crowd_spawning import SPAWN_AREAS, draw_kinds, sidewalk_length, spawn_positions, spawn_region
from sim.agents.crowd_state import AGENT_DTYPE, CrowdState
from sim.agents.deadlock import PushResolver
from sim.agents.kinds import AGENT_KINDS, IDLE, agent_kind
from sim.agents.navgrid import NavGrid, build_navgrid
from sim.scene.scene import Scene, as_scene
from sim.schema import check_table

# Names other modules import from here, though the crowd_* modules define them.
__all__ = ["AGENT_DEFAULTS", "AGENT_DTYPE", "SPAWN_AREAS", "AgentManager", "EgoState", "sidewalk_length"]


class AgentManager:
    """Spawns, plans and moves cohabitants on one scene; `reset` then `step` every simulator tick."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(AGENT_DEFAULTS, config, name="agents config")
        check_table(self.config, AGENTS_TABLE, name="agents config")
        for kind in self.config["counts"]:
            agent_kind(kind)
        if any(v < 0 for v in self.config["mix"].values()) or sum(self.config["mix"].values()) <= 0:
            raise ConfigError("agents config mix needs non-negative shares with a positive sum")
        # The counts are known now; a density's agent count depends on the scene, but none fits in max_agents 0.
        c = self.config
        asked = sum(int(v) for v in c["counts"].values()) if c["counts"] else None
        if asked is not None and asked > c["max_agents"]:
            raise ConfigError(
                f"agents config counts ask for {asked} agents but max_agents is {c['max_agents']}; "
                "lower the counts or raise max_agents"
            )
        if asked is None and c["dynamic_density"] > 0 and c["max_agents"] < 1:
            raise ConfigError(
                f"agents config max_agents is 0 with dynamic_density {c['dynamic_density']:g}; set "
                "dynamic_density 0 for no agents, or raise max_agents"
            )
        self.grid: NavGrid | None = None  # the navigation grid of the scene last reset on
        self.orca: OrcaCrowd | None = None  # the ORCA part of that scene
        self._scene: Scene | None = None  # the scene the grid and the ORCA part were built for
        self.goal_cells = GoalCells()  # goal cells around each site of the grid, drawn from at every new goal
        self.rng: np.random.Generator | None = None  # the generator reset was given: this episode's draws
        self.state = CrowdState.empty()
        self.push = PushResolver(self.config["push_window"])
        self.groups = Groups()
        self.crossings = Crossings()

    # ------------------------------------------------------------------ the state's public arrays
    @property
    def n(self) -> int:
        """Number of agents this episode (0 before reset)."""
        return self.state.n

    @property
    def pos(self) -> np.ndarray:
        """[n, 2] agent positions: the state's own array (writing into it leaves the ORCA slot where it was; place()
        moves both)."""
        return self.state.pos

    @property
    def vel(self) -> np.ndarray:
        """[n, 2] agent velocities from the last step."""
        return self.state.vel

    @property
    def radius(self) -> np.ndarray:
        """[n] agent body radii."""
        return self.state.radius

    @property
    def kind_idx(self) -> np.ndarray:
        """[n] index of each agent's kind in sim.agents.kinds.KIND_NAMES."""
        return self.state.kind_idx

    @property
    def trail(self) -> np.ndarray:
        """[trail_length, n, 2] recent agent positions, oldest first."""
        return self.state.trail

    @property
    def time(self) -> float:
        """Seconds since reset."""
        return self.state.time

    def _parts(self, what: str) -> tuple[NavGrid, OrcaCrowd, np.random.Generator]:
        """The scene's grid and ORCA part and the episode's generator; RuntimeError naming `what` before reset."""
        if self.grid is None or self.orca is None or self.rng is None:
            raise RuntimeError(f"AgentManager.{what} called before reset(scene, rng)")
        return self.grid, self.orca, self.rng

    # ------------------------------------------------------------------ reset
    def reset(
        self,
        scene: Scene | Mapping[str, Any],
        rng: np.random.Generator,
        ego: EgoState | None = None,
        keep_clear: Sequence[tuple[float, float, float]] = (),
        route: np.ndarray | None = None,
    ) -> np.ndarray:
        """Build the planner for `scene` (a dict is parsed), spawn agents away from `keep_clear` discs (x, y, r)
        and return states().

        `route` (N, 2): the ego's route, for `spawn_area: "route"` (agents per 100 m of route, along it).
        """
        c = self.config
        self.rng = rng
        scene = as_scene(scene, self._scene)
        grid, orca = self.grid, self.orca
        if grid is None or orca is None or scene is not self._scene:
            grid = build_navgrid(scene, plan_radius=c["plan_radius"], n_sites=c["n_goal_sites"])
            self.goal_cells.clear()
            self.crossings.setup(scene, grid)
            # Processing the scene's obstacles costs ~0.2 s, more than a short episode: each scene keeps its part.
            orca = OrcaCrowd(scene, grid)
            self.grid, self.orca, self._scene = grid, orca, scene
        area = spawn_region(scene, c, route)
        route_length = 0.0  # only spawn_area "route" reads it, and spawn_region has checked the route is there
        if route is not None and len(route) >= 2:
            route_length = float(np.linalg.norm(np.diff(np.asarray(route)[:, :2], axis=0), axis=1).sum())
        kinds = draw_kinds(scene, c, area, route_length, rng)
        radius = np.array([AGENT_KINDS[k].radius for k in kinds])
        ego = as_ego(ego)
        clear = list(keep_clear) + ([(ego.x, ego.y, ego.radius + 1.0)] if ego else [])
        pos = spawn_positions(grid, area, radius, c, rng, clear)
        self.state = s = CrowdState.start(kinds, radius, pos)
        self.push.window = float(c["push_window"])
        self.push.reset()
        self.groups.reset(s, grid, area, c, rng, clear)
        orca.start(s, c)
        nodes = grid.nearest_node(s.pos)
        for i in range(s.n):
            if self.groups.of[i] >= 0:
                continue  # standing in its group already
            if rng.random() < c["idle_prob"]:
                s.movement[i] = IDLE
                s.idle_left[i] = rng.uniform(0.0, c["idle_time"][1])
            else:
                self._set_goal(i, int(nodes[i]))
        s.trail = np.repeat(s.pos[None], c["trail_length"], axis=0)
        orca.set_ego(ego, c["ego_margin"])
        return self.states()

    def _set_goal(
        self,
        i: int,
        node: int,
        *,
        abandon: bool = False,
        site: int | None = None,
        goal_xy: np.ndarray | None = None,
        speed: float | None = None,
    ) -> None:
        """crowd_goals.new_goal on this manager's parts: the GoalSetter the goal updates and the groups call."""
        grid, _, rng = self._parts("new goal")
        new_goal(
            self.state,
            grid,
            rng,
            self.config,
            self.crossings,
            self.goal_cells,
            i,
            node,
            abandon=abandon,
            site=site,
            goal_xy=goal_xy,
            speed=speed,
        )

    # ------------------------------------------------------------------ step
    def step(self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
        """Advance every agent by `dt` seconds around the ego (None: no ego) and return states()."""
        self.advance(dt, ego)
        return self.states()

    def advance(self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None = None) -> None:
        """step() without building its states (the env reads `pos` directly)."""
        g, orca, rng = self._parts("step")
        c, s = self.config, self.state
        orca.set_ego(as_ego(ego), c["ego_margin"])
        s.time += dt
        pref = np.zeros((s.n, 2))
        pinned = np.zeros(s.n, dtype=bool)
        ox, oy, res = float(g.origin[0]), float(g.origin[1]), float(g.res)
        if s.n:
            nodes = nearest_nodes(s.pos, ox, oy, res, g.nearest_rc, g.node_of)
            self.push.release(s, g, c, nodes)
            update_goals(s, g, rng, c, self.groups, self._set_goal, dt, nodes)
            self.push.hold(s)
            self.push.detect(s, g, c, nodes)
            moving = s.movement != IDLE
            if moving.any():
                pref[moving] = preferred(s, g, c, orca.sim.query_visibility, nodes[moving], np.flatnonzero(moving))
            self.push.steer(s, pref)
            pinned = self.groups.standing(s) & ~self.push.busy(s.n)
            orca.set_radii(s.radius, c["safety_margin"], pinned)
        new_pos, new_vel = orca.step(dt, pref)
        # ORCA's obstacle handling is not a hard guarantee at concave corners: an agent whose step would leave
        # the walkable area stays put instead; so do members standing in a group (see sim.agents.behaviours).
        bad = (~on_mask(new_pos, ox, oy, res, g.walkable) | pinned) if s.n else pinned
        for i in np.flatnonzero(bad):
            orca.place(int(i), (float(s.pos[i, 0]), float(s.pos[i, 1])))
            new_pos[i], new_vel[i] = s.pos[i], 0.0
        s.pos, s.vel = new_pos, new_vel
        s.trail[:-1] = s.trail[1:]  # oldest first; in place, no new [trail, n, 2] array per step
        s.trail[-1] = s.pos

    # ------------------------------------------------------------------ outputs
    def states(self) -> np.ndarray:
        """Every agent's x, y, vx, vy, radius and kind as a structured array of AGENT_DTYPE."""
        s = self.state
        out = s.template.copy()  # radius and kind never change within an episode
        if s.n:
            out["x"], out["y"] = s.pos[:, 0], s.pos[:, 1]
            out["vx"], out["vy"] = s.vel[:, 0], s.vel[:, 1]
        return out

    def goal_stats(self) -> dict[str, float]:
        """Goals reached within budget, late and abandoned so far, and the in-time fraction of finished goals."""
        counts = self.state.counts
        done = sum(counts.values())
        return {**counts, "finished": done, "in_time_fraction": counts["in_time"] / done if done else 1.0}

    def behaviour_stats(self) -> dict[str, int]:
        """Standing groups (sim.agents.behaviours.Groups.stats), crossings started and done, pushes started and ended."""
        s = self.state
        return {
            **self.groups.stats(),
            "crossings_started": s.cross_counts["started"],
            "crossings_done": s.cross_counts["done"],
            "crossing_now": int(s.crossing.sum()),
            "pushes": self.push.started,
            "pushes_done": self.push.finished,
        }

    # ------------------------------------------------------------------ scripted scenarios
    def place(self, i: int, xy: Sequence[float]) -> None:
        """Put agent i at rest on world point `xy` (after reset; the point must be walkable)."""
        g, orca, _ = self._parts("place")
        s = self.state
        p = np.asarray(xy, dtype=np.float64).reshape(2)
        if not bool(g.is_walkable(p[None])[0]):
            raise ValueError(f"agent {i} cannot stand at {p.tolist()}: not on the walkable area")
        s.pos[i], s.vel[i] = p, 0.0
        s.trail[:, i] = p
        orca.place(int(i), (float(p[0]), float(p[1])))

    def send(self, i: int, xy: Sequence[float], speed: float | None = None) -> None:
        """Give agent i a goal at the planning cell nearest `xy` (a goal site of its own), walking at `speed`."""
        g, _, rng = self._parts("send")
        s = self.state
        p = np.asarray(xy, dtype=np.float64).reshape(1, 2)
        site = g.add_site(int(g.nearest_node(p)[0]))
        if self.groups.of[i] >= 0:
            self.groups.dissolve(s, int(self.groups.of[i]))
        self._set_goal(
            i,
            int(g.nearest_node(s.pos[i : i + 1])[0]),
            site=site,
            goal_xy=p[0],
            speed=walking_speed(s, i, rng) if speed is None else float(speed),
        )

    def overdue(self) -> int:
        """Agents still travelling whose time budget has already run out (goals that will count as late)."""
        s = self.state
        moving = s.movement != IDLE
        return int(np.sum(moving & (s.time - s.goal_t0 > s.budget)))
