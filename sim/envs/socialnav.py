"""SocialNav: PointNav among cohabitants (sim.agents) and road traffic, with the social metrics PSC, STL and SNS."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from sim.agents.crowd import AgentManager, EgoState
from sim.agents.crowd_kernels import box_gaps, cell_values
from sim.agents.vehicles import VehicleManager
from sim.envs.bodies import CohabitantBodies
from sim.envs.pointnav import PointNavEnv
from sim.metrics import EpisodeView
from sim.scene.scene import Scene
from sim.sensors import GridLidar
from sim.tasks.socialnav import CONFIG_TABLE, DEFAULT_CONFIG, PRESETS, SPLIT_AGENT_BEHAVIOUR


class SocialNavEnv(PointNavEnv):
    """PointNav plus pedestrians, vulnerable road users, robots (ORCA) and vehicles (IDM) that react to the ego.

    Spaces, reward and episode end are PointNav's (see its docstring). Additions:

    | what | where |
    |---|---|
    | agents and vehicles | kinematic PyBullet bodies (capsules per kind colour and height, boxes), seen by the LiDAR |
    | cost | +1 per step in collision, agents (`collisions_agent`) and vehicles (`collisions_vehicle`) included |
    | metrics | `psc`, `stl`, `sns` (docs/metrics.md) beside PointNav's |
    | `agent_states()` | structured array x, y, vx, vy, radius, kind (sim.agents.AGENT_DTYPE) |
    | `vehicle_states()` | structured array x, y, vx, vy, yaw, length, width |
    | config | `agents` (sim.agents.AGENT_DEFAULTS), `vehicles`, `traffic`, `personal_space` |

    `render()` draws PointNav's dashboard (default; its map shows agents by kind with short trails), or camera
    "map" (the map alone), "top_down" or "chase" (sim/viewer.py).
    """

    default_config: dict[str, Any] = DEFAULT_CONFIG
    presets: dict[str, dict[str, Any]] = PRESETS
    config_table: dict[str, Any] = CONFIG_TABLE  # sim.tasks.socialnav: type and range of every key
    has_agents = True

    def __init__(self, config: Mapping[str, Any] | None = None, render_mode: str | None = None) -> None:
        split = (config or {}).get("split", DEFAULT_CONFIG["split"]) if isinstance(config, Mapping) else None
        if split in SPLIT_AGENT_BEHAVIOUR:
            agents = (config or {}).get("agents") or {}
            config = {**(config or {}), "agents": {**SPLIT_AGENT_BEHAVIOUR[split], **agents}}
        super().__init__(config, render_mode)
        self.crowd = AgentManager(self.config["agents"])
        self.traffic = VehicleManager(self.config["vehicles"])
        self.collision_kinds_all = [*self.collision_kinds_all, "agent", "vehicle"]
        self.bodies: CohabitantBodies | None = None  # per world, made with it (_on_scene)

    # -- hooks -------------------------------------------------------------------------------------
    _WORLD_STATE = ("crowd", "traffic", "bodies")  # the world's collision kinds are its bodies' dict

    def _on_scene(self, scene: Scene) -> None:
        # A new world in its client: no agent body or shape exists there yet. Crowd and traffic keep planners
        # built for one scene (navigation grid, lanes), so each cached world has its own.
        self.crowd = AgentManager(self.config["agents"])
        self.traffic = VehicleManager(self.config["vehicles"])
        self._collision_kinds = {}
        size = (self.traffic.config["length"], self.traffic.config["width"])
        self.bodies = CohabitantBodies(self.client, self._collision_kinds, size)
        for lidar in (self.lidar, self.low_lidar):
            if isinstance(lidar, GridLidar):  # the grids hold the static scene only: the bodies trace themselves
                lidar.moving = self.bodies.ray_hits

    def _park_bodies(self) -> None:
        # Last episode's agents and vehicles must not stand where the next start's surface height is probed.
        if self.bodies is not None:
            self.bodies.park()

    def _scene_state(self) -> dict[str, Any]:
        # The agent bodies live in the world being left: park them so they are out of the way when it returns.
        self._park_bodies()
        return {k: getattr(self, k, None) for k in self._WORLD_STATE}

    def _load_scene_state(self, state: dict[str, Any]) -> None:
        for k in self._WORLD_STATE:
            setattr(self, k, state.get(k))
        bodies = self.bodies
        assert bodies is not None  # every cached world got its bodies from _on_scene
        self._collision_kinds = bodies.collision_kinds

    def _on_reset(self, rng: np.random.Generator) -> None:
        scene, route = self.scene, self.route
        assert route is not None  # reset calls this hook once the machine stands on the route
        start = route.start
        goal = route.goal
        self.crowd.reset(
            scene,
            rng,
            ego=self._ego_state(),
            keep_clear=[(float(goal[0]), float(goal[1]), 1.0), (float(start[0]), float(start[1]), 2.0)],
            route=route.points,
        )
        if self.config["traffic"]:
            self.traffic.reset(scene, rng)
        else:
            self.traffic.clear()
        self._sync_bodies()
        self._min_agent_distance = self._nearest_agent()

    def _measure_view(self) -> EpisodeView:
        return replace(
            super()._measure_view(),
            min_agent_distance=lambda: self._min_agent_distance,
            personal_space=float(self.config["personal_space"]),
        )

    def _on_step(self) -> None:
        ego = self._ego_state()
        self.crowd.advance(self.dt, ego)
        if self.config["traffic"]:
            people = np.concatenate([self.crowd.pos, [[ego.x, ego.y]]])
            self.traffic.advance(self.dt, people)
        self._sync_bodies()
        self._min_agent_distance = self._nearest_agent()

    # -- bodies ------------------------------------------------------------------------------------
    def _sync_bodies(self) -> None:
        vehicles = self.traffic.poses() if self.config["traffic"] else (np.zeros(0), np.zeros(0), np.zeros(0))
        crowd, bodies = self.crowd, self.bodies
        assert bodies is not None  # made with the world (_on_scene)
        bodies.sync(crowd.kind_idx, crowd.pos, self._agent_base_heights(crowd.pos), vehicles)

    def _agent_base_heights(self, xy: np.ndarray) -> np.ndarray:
        g = self.crowd.grid
        if not len(xy):
            return np.zeros(0)
        assert g is not None  # the crowd's reset built its grid; only then are there agents
        codes = cell_values(xy, float(g.origin[0]), float(g.origin[1]), float(g.res), g.cells)
        curb = self.scene.curb_height
        # Legend: sidewalk on the curb, crosswalk on the road, ramps half way.
        return np.array([curb, curb, 0.0, curb / 2])[np.minimum(codes, 3)]

    # -- state -------------------------------------------------------------------------------------
    def _ego_state(self) -> EgoState:
        m = self.machine
        assert m is not None  # called from reset's hook and from steps, once the machine is placed
        x, y, _ = m.position
        s = m.spec
        return EgoState(
            float(x),
            float(y),
            m.speed * math.cos(m.yaw),
            m.speed * math.sin(m.yaw),
            0.5 * math.hypot(s.length, s.width),
        )

    def _nearest_agent(self) -> float:
        """Smallest gap (m) between the ego's footprint rectangle and any agent's body circle."""
        pos = self.crowd.pos
        if not len(pos):
            return math.inf
        m = self.machine
        assert m is not None  # as in _ego_state
        x, y, _ = m.position
        c, s = math.cos(m.yaw), math.sin(m.yaw)
        # Agent centres in the ego frame, then the distance to the footprint box (0 inside it).
        ex, ey = box_gaps(pos, float(x), float(y), c, s, 0.5 * m.spec.length, 0.5 * m.spec.width)
        return float(np.min(np.hypot(ex, ey) - self.crowd.radius))

    def agent_states(self) -> np.ndarray:
        """Every cohabitant's x, y, vx, vy, radius and kind (structured array; vehicles: vehicle_states())."""
        if self.route is None:
            raise RuntimeError("the env has no cohabitants yet: call reset() first")
        return self.crowd.states()

    def vehicle_states(self) -> np.ndarray:
        """Every vehicle's x, y, vx, vy, yaw, length and width (structured array)."""
        return self.traffic.states() if self.config["traffic"] else np.zeros(0, dtype=self.traffic.states().dtype)
