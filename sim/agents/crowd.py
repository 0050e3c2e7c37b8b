"""AgentManager: cohabitants that plan over the walkable grid and avoid each other, objects, curbs and the ego with ORCA.

Each agent steers at a carrot a few cells ahead on its goal site's distance field (sim.agents.navgrid) and
ORCA (RVO2's solver in numba, sim.agents.orca_kernels) turns that preferred velocity into a collision-free one. The ego is one more ORCA agent whose
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
- ORCA: OrcaCrowd (crowd_orca), one per scene, owning its obstacle index and this episode's ORCA agents (the ego
  among them, radii as last set); `advance_crowds` steps many crowds' ORCA in one compiled call;
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
from sim.agents.crowd_orca import EgoState, OrcaCrowd, as_ego, step_crowds
from sim.agents.crowd_spawning import SPAWN_AREAS, draw_kinds, sidewalk_length, spawn_positions, spawn_region
from sim.agents.crowd_state import AGENT_DTYPE, CrowdState
from sim.agents.deadlock import PushResolver
from sim.agents.kinds import AGENT_KINDS, IDLE, agent_kind
from sim.agents.navgrid import NavGrid, build_navgrid
from sim.scene.scene import Scene, as_scene
from sim.schema import check_table

# Names other modules import from here, though the crowd_* modules define them.
__all__ = [
    "AGENT_DEFAULTS",
    "AGENT_DTYPE",
    "SPAWN_AREAS",
    "AgentManager",
    "EgoState",
    "advance_crowds",
    "sidewalk_length",
]


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
        cfg = self.config
        asked = sum(int(v) for v in cfg["counts"].values()) if cfg["counts"] else None
        if asked is not None and asked > cfg["max_agents"]:
            raise ConfigError(
                f"agents config counts ask for {asked} agents but max_agents is {cfg['max_agents']}; "
                "lower the counts or raise max_agents"
            )
        if asked is None and cfg["dynamic_density"] > 0 and cfg["max_agents"] < 1:
            raise ConfigError(
                f"agents config max_agents is 0 with dynamic_density {cfg['dynamic_density']:g}; set "
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
        cfg = self.config
        self.rng = rng
        scene = as_scene(scene, self._scene)
        grid, orca = self.grid, self.orca
        if grid is None or orca is None or scene is not self._scene:
            grid = build_navgrid(scene, plan_radius=cfg["plan_radius"], n_sites=cfg["n_goal_sites"])
            self.goal_cells.clear()
            self.crossings.setup(scene, grid)
            # Processing the scene's obstacles costs ~0.2 s, more than a short episode: each scene keeps its part.
            orca = OrcaCrowd(scene, grid, cfg)
            self.grid, self.orca, self._scene = grid, orca, scene
        area = spawn_region(scene, cfg, route)
        route_length = 0.0  # only spawn_area "route" reads it, and spawn_region has checked the route is there
        if route is not None and len(route) >= 2:
            route_length = float(np.linalg.norm(np.diff(np.asarray(route)[:, :2], axis=0), axis=1).sum())
        kinds = draw_kinds(scene, cfg, area, route_length, rng)
        radius = np.array([AGENT_KINDS[k].radius for k in kinds])
        ego = as_ego(ego)
        clear = list(keep_clear) + ([(ego.x, ego.y, ego.radius + 1.0)] if ego else [])
        pos = spawn_positions(grid, area, radius, cfg, rng, clear)
        self.state = state = CrowdState.start(kinds, radius, pos)
        self.push.window = float(cfg["push_window"])
        self.push.reset()
        self.groups.reset(state, grid, area, cfg, rng, clear)
        orca.start(state, cfg)
        nodes = grid.nearest_node(state.pos)
        for i in range(state.n):
            if self.groups.of[i] >= 0:
                continue  # standing in its group already
            if rng.random() < cfg["idle_prob"]:
                state.movement[i] = IDLE
                state.idle_left[i] = rng.uniform(0.0, cfg["idle_time"][1])
            else:
                self._set_goal(i, int(nodes[i]))
        state.trail = np.repeat(state.pos[None], cfg["trail_length"], axis=0)
        orca.set_ego(ego, cfg["ego_margin"])
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
        advance_crowds([self], dt, [ego])

    def plan_step(
        self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The first half of a step: goals, pushes and behaviours updated, the ego placed; returns the preferred
        velocities [n, 2] ORCA turns into safe ones and which agents stand pinned (`finish_step` takes both)."""
        grid, orca, rng = self._parts("step")
        cfg, state = self.config, self.state
        orca.set_ego(as_ego(ego), cfg["ego_margin"])
        state.time += dt
        pref = np.zeros((state.n, 2))
        pinned = np.zeros(state.n, dtype=bool)
        if state.n:
            ox, oy, res = float(grid.origin[0]), float(grid.origin[1]), float(grid.res)
            nodes = nearest_nodes(state.pos, ox, oy, res, grid.nearest_rc, grid.node_of)
            self.push.release(state, grid, cfg, nodes)
            update_goals(state, grid, rng, cfg, self.groups, self._set_goal, dt, nodes)
            self.push.hold(state)
            self.push.detect(state, grid, cfg, nodes)
            moving = state.movement != IDLE
            if moving.any():
                pref[moving] = preferred(state, grid, cfg, orca.visible, nodes[moving], np.flatnonzero(moving))
            self.push.steer(state, pref)
            pinned = self.groups.standing(state) & ~self.push.busy(state.n)
            orca.set_radii(state.radius, cfg["safety_margin"], pinned)
        return pref, pinned

    def finish_step(self, new_pos: np.ndarray, new_vel: np.ndarray, pinned: np.ndarray) -> None:
        """The second half of a step: ORCA's new positions and velocities [n, 2] taken, but for agents it would put
        off the walkable area and the `pinned` ones, which stay put."""
        grid, orca, _ = self._parts("step")
        state = self.state
        ox, oy, res = float(grid.origin[0]), float(grid.origin[1]), float(grid.res)
        # ORCA's obstacle handling is not a hard guarantee at concave corners: an agent whose step would leave
        # the walkable area stays put instead; so do members standing in a group (see sim.agents.behaviours).
        bad = (~on_mask(new_pos, ox, oy, res, grid.walkable) | pinned) if state.n else pinned
        for i in np.flatnonzero(bad):
            orca.place(int(i), (float(state.pos[i, 0]), float(state.pos[i, 1])))
            new_pos[i], new_vel[i] = state.pos[i], 0.0
        state.pos, state.vel = new_pos, new_vel
        state.trail[:-1] = state.trail[1:]  # oldest first; in place, no new [trail, n, 2] array per step
        state.trail[-1] = state.pos

    # ------------------------------------------------------------------ outputs
    def states(self) -> np.ndarray:
        """Every agent's x, y, vx, vy, radius and kind as a structured array of AGENT_DTYPE."""
        state = self.state
        out = state.template.copy()  # radius and kind never change within an episode
        if state.n:
            out["x"], out["y"] = state.pos[:, 0], state.pos[:, 1]
            out["vx"], out["vy"] = state.vel[:, 0], state.vel[:, 1]
        return out

    def goal_stats(self) -> dict[str, float]:
        """Goals reached within budget, late and abandoned so far, and the in-time fraction of finished goals."""
        counts = self.state.counts
        done = sum(counts.values())
        return {**counts, "finished": done, "in_time_fraction": counts["in_time"] / done if done else 1.0}

    def behaviour_stats(self) -> dict[str, int]:
        """Standing groups (sim.agents.behaviours.Groups.stats), crossings started and done, pushes started and ended."""
        state = self.state
        return {
            **self.groups.stats(),
            "crossings_started": state.cross_counts["started"],
            "crossings_done": state.cross_counts["done"],
            "crossing_now": int(state.crossing.sum()),
            "pushes": self.push.started,
            "pushes_done": self.push.finished,
        }

    # ------------------------------------------------------------------ scripted scenarios
    def place(self, i: int, xy: Sequence[float]) -> None:
        """Put agent i at rest on world point `xy` (after reset; the point must be walkable)."""
        grid, orca, _ = self._parts("place")
        state = self.state
        point = np.asarray(xy, dtype=np.float64).reshape(2)
        if not bool(grid.is_walkable(point[None])[0]):
            raise ValueError(f"agent {i} cannot stand at {point.tolist()}: not on the walkable area")
        state.pos[i], state.vel[i] = point, 0.0
        state.trail[:, i] = point
        orca.place(int(i), (float(point[0]), float(point[1])))

    def send(self, i: int, xy: Sequence[float], speed: float | None = None) -> None:
        """Give agent i a goal at the planning cell nearest `xy` (a goal site of its own), walking at `speed`."""
        grid, _, rng = self._parts("send")
        state = self.state
        point = np.asarray(xy, dtype=np.float64).reshape(1, 2)
        site = grid.add_site(int(grid.nearest_node(point)[0]))
        if self.groups.of[i] >= 0:
            self.groups.dissolve(state, int(self.groups.of[i]))
        self._set_goal(
            i,
            int(grid.nearest_node(state.pos[i : i + 1])[0]),
            site=site,
            goal_xy=point[0],
            speed=walking_speed(state, i, rng) if speed is None else float(speed),
        )

    def overdue(self) -> int:
        """Agents still travelling whose time budget has already run out (goals that will count as late)."""
        state = self.state
        moving = state.movement != IDLE
        return int(np.sum(moving & (state.time - state.goal_t0 > state.budget)))


def advance_crowds(
    managers: Sequence[AgentManager],
    dt: float,
    egos: Sequence[EgoState | Mapping[str, float] | Sequence[float] | None],
) -> None:
    """Advance every crowd by `dt` seconds around its ego, their ORCA steps in one compiled call
    (`crowd_orca.step_crowds`); each crowd moves as its own `advance` would move it (no draw depends on another)."""
    plans = [m.plan_step(dt, ego) for m, ego in zip(managers, egos)]
    moved = step_crowds([m._parts("step")[1] for m in managers], dt, [pref for pref, _ in plans])
    for m, (_, pinned), (new_pos, new_vel) in zip(managers, plans, moved):
        m.finish_step(new_pos, new_vel, pinned)
