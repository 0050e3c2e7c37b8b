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

This module holds AgentManager's reset, step and public API; its parts live beside it: configuration
(crowd_config), spawning (crowd_spawning), the ORCA simulator and the ego (crowd_orca) and goal following
(crowd_goals).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kernel.config import ConfigError, merge_strict
from sim.agents.behaviours import Crossings, Groups
from sim.agents.crowd_config import AGENT_DEFAULTS, check_behaviour_config
from sim.agents.crowd_goals import GoalFollowing
from sim.agents.crowd_kernels import nearest_nodes, on_mask
from sim.agents.crowd_orca import EgoState, OrcaCrowd, as_ego
from sim.agents.crowd_spawning import SPAWN_AREAS, AgentSpawning, sidewalk_length, spawn_region
from sim.agents.deadlock import PushResolver
from sim.agents.kinds import AGENT_KINDS, IDLE, KIND_NAMES, WALKING, agent_kind
from sim.agents.navgrid import NavGrid, build_navgrid
from sim.scene.scene import Scene, as_scene

# Names other modules import from here, though the crowd_* modules define them.
__all__ = ["AGENT_DEFAULTS", "AGENT_DTYPE", "SPAWN_AREAS", "AgentManager", "EgoState", "sidewalk_length"]

AGENT_DTYPE = np.dtype([("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("radius", "f8"), ("kind", "U16")])


class AgentManager(AgentSpawning, OrcaCrowd, GoalFollowing):
    """Spawns, plans and moves cohabitants on one scene; `reset` then `step` every simulator tick."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(AGENT_DEFAULTS, config, name="agents config")
        check_behaviour_config(self.config)
        if self.config["spawn_area"] not in SPAWN_AREAS:
            raise ConfigError(
                f"unknown agents spawn_area {self.config['spawn_area']!r}; valid: {', '.join(SPAWN_AREAS)}"
            )
        self._area: Any = None
        self._route_length = 0.0
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
        if self.config["lookahead_cells"] not in (1, 2, 4, 8):
            raise ConfigError(
                f"agents config lookahead_cells must be 1, 2, 4 or 8, got {self.config['lookahead_cells']}"
            )
        self.grid: NavGrid | None = None
        self._scene: Scene | None = None  # the scene the cached grid and ORCA obstacles belong to
        self.n = 0
        self.time = 0.0
        self.push = PushResolver(self.config["push_window"])
        self.groups = Groups()
        self.crossings = Crossings()

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
        fresh = scene is not self._scene
        if fresh:
            self.grid = build_navgrid(scene, plan_radius=c["plan_radius"], n_sites=c["n_goal_sites"])
            self._goal_cell_cache: dict = {}  # (site, spread) -> goal cells (GoalFollowing._goal_cells)
            self.crossings.setup(scene, self.grid)
        self._area = spawn_region(scene, c, route)
        if route is not None and len(route) >= 2:
            self._route_length = float(np.linalg.norm(np.diff(np.asarray(route)[:, :2], axis=0), axis=1).sum())
        kinds = self._draw_kinds(scene, rng)
        self.n = n = len(kinds)
        self.kind_idx = np.array([KIND_NAMES.index(k) for k in kinds], dtype=np.int16)
        self.radius = np.array([AGENT_KINDS[k].radius for k in kinds])
        self._template = np.zeros(n, dtype=AGENT_DTYPE)
        self._template["radius"], self._template["kind"] = self.radius, kinds
        ego = as_ego(ego)
        clear = list(keep_clear) + ([(ego.x, ego.y, ego.radius + 1.0)] if ego else [])
        self.pos = self._spawn_positions(rng, clear)
        self.vel = np.zeros((n, 2))
        self.movement = np.full(n, WALKING, dtype=np.int8)
        self.speed = np.zeros(n)
        self.site = np.zeros(n, dtype=np.int64)
        self.goal = np.zeros((n, 2))
        self.idle_left = np.zeros(n)
        self.best = np.full(n, np.inf)
        self.stall = np.zeros(n, dtype=np.int64)
        self.goal_t0 = np.zeros(n)
        self.budget = np.zeros(n)
        self.time = 0.0
        self.counts = {"in_time": 0, "late": 0, "abandoned": 0}
        self.crossing = np.zeros(n, dtype=bool)
        self.cross_counts = {"started": 0, "done": 0}
        self.push.window = float(c["push_window"])
        self.push.reset()
        self.groups.reset(self, rng, clear)
        self._build_orca(scene, fresh)
        self._orca_radius = self.radius + c["safety_margin"]
        self._orca_plain = True  # _orca_radius holds no standing margin
        self._ego_radius = float("nan")  # the ego's ORCA radius as last set (nan: set it on the next placement)
        self._scene = scene
        nodes = self.grid.nearest_node(self.pos)
        for i in range(n):
            if self.groups.of[i] >= 0:
                continue  # standing in its group already
            if rng.random() < c["idle_prob"]:
                self.movement[i] = IDLE
                self.idle_left[i] = rng.uniform(0.0, c["idle_time"][1])
            else:
                self._new_goal(i, int(nodes[i]))
        self.trail = np.repeat(self.pos[None], c["trail_length"], axis=0)
        self._set_ego(ego)
        return self.states()

    # ------------------------------------------------------------------ step
    def step(self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
        """Advance every agent by `dt` seconds around the ego (None: no ego) and return states()."""
        self.advance(dt, ego)
        return self.states()

    def advance(self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None = None) -> None:
        """step() without building its states (the env reads `pos` directly)."""
        if self.grid is None:
            raise RuntimeError("AgentManager.step called before reset(scene, rng)")
        g = self.grid
        self._set_ego(as_ego(ego))
        self.time += dt
        pref = np.zeros((self.n, 2))
        pinned = np.zeros(self.n, dtype=bool)
        ox, oy, res = float(g.origin[0]), float(g.origin[1]), float(g.res)
        if self.n:
            nodes = nearest_nodes(self.pos, ox, oy, res, g.nearest_rc, g.node_of)
            self.push.release(self, nodes)
            self._update_goals(dt, nodes)
            self.push.hold(self)
            self.push.detect(self, nodes)
            moving = self.movement != IDLE
            if moving.any():
                pref[moving] = self._preferred(nodes[moving], np.flatnonzero(moving))
            self.push.steer(self, pref)
            pinned = self.groups.standing(self) & ~self.push.busy(self.n)
            self._set_orca_radii(pinned)
        sim = self.sim
        sim.set_time_step(float(dt))
        set_pref = sim.set_agent_pref_velocity
        for i, v in enumerate(pref.tolist()):  # pyrvo has no batch setters; one list walk beats n numpy reads
            set_pref(i, v)
        sim.do_step()
        get_pos, get_vel = sim.get_agent_position, sim.get_agent_velocity
        state = np.array([get_pos(i).to_tuple() + get_vel(i).to_tuple() for i in range(self.n)]).reshape(self.n, 4)
        new_pos, new_vel = state[:, :2].copy(), state[:, 2:].copy()
        # ORCA's obstacle handling is not a hard guarantee at concave corners: an agent whose step would leave
        # the walkable area stays put instead; so do members standing in a group (see sim.agents.behaviours).
        bad = (~on_mask(new_pos, ox, oy, res, g.walkable) | pinned) if self.n else pinned
        for i in np.flatnonzero(bad):
            sim.set_agent_position(int(i), (float(self.pos[i, 0]), float(self.pos[i, 1])))
            sim.set_agent_velocity(int(i), (0.0, 0.0))
            new_pos[i], new_vel[i] = self.pos[i], 0.0
        self.pos, self.vel = new_pos, new_vel
        self.trail[:-1] = self.trail[1:]  # oldest first; in place, no new [trail, n, 2] array per step
        self.trail[-1] = self.pos

    # ------------------------------------------------------------------ outputs
    def states(self) -> np.ndarray:
        """Every agent's x, y, vx, vy, radius and kind as a structured array of AGENT_DTYPE."""
        out = self._template.copy()  # radius and kind never change within an episode
        if self.n:
            out["x"], out["y"] = self.pos[:, 0], self.pos[:, 1]
            out["vx"], out["vy"] = self.vel[:, 0], self.vel[:, 1]
        return out

    def goal_stats(self) -> dict[str, float]:
        """Goals reached within budget, late and abandoned so far, and the in-time fraction of finished goals."""
        done = sum(self.counts.values())
        return {**self.counts, "finished": done, "in_time_fraction": self.counts["in_time"] / done if done else 1.0}

    def behaviour_stats(self) -> dict[str, int]:
        """Standing groups (sim.agents.behaviours.Groups.stats), crossings started and done, pushes started and ended."""
        return {
            **self.groups.stats(),
            "crossings_started": self.cross_counts["started"],
            "crossings_done": self.cross_counts["done"],
            "crossing_now": int(self.crossing.sum()),
            "pushes": self.push.started,
            "pushes_done": self.push.finished,
        }

    # ------------------------------------------------------------------ scripted scenarios
    def place(self, i: int, xy: Sequence[float]) -> None:
        """Put agent i at rest on world point `xy` (after reset; the point must be walkable)."""
        p = np.asarray(xy, dtype=np.float64).reshape(2)
        if not bool(self.grid.is_walkable(p[None])[0]):
            raise ValueError(f"agent {i} cannot stand at {p.tolist()}: not on the walkable area")
        self.pos[i], self.vel[i] = p, 0.0
        self.trail[:, i] = p
        self.sim.set_agent_position(int(i), (float(p[0]), float(p[1])))
        self.sim.set_agent_velocity(int(i), (0.0, 0.0))

    def send(self, i: int, xy: Sequence[float], speed: float | None = None) -> None:
        """Give agent i a goal at the planning cell nearest `xy` (a goal site of its own), walking at `speed`."""
        g = self.grid
        p = np.asarray(xy, dtype=np.float64).reshape(1, 2)
        site = g.add_site(int(g.nearest_node(p)[0]))
        if self.groups.of[i] >= 0:
            self.groups.dissolve(self, int(self.groups.of[i]))
        self._new_goal(
            i,
            int(g.nearest_node(self.pos[i : i + 1])[0]),
            site=site,
            goal_xy=p[0],
            speed=self._walking_speed(i) if speed is None else float(speed),
        )

    def overdue(self) -> int:
        """Agents still travelling whose time budget has already run out (goals that will count as late)."""
        moving = self.movement != IDLE
        return int(np.sum(moving & (self.time - self.goal_t0 > self.budget)))
