"""SocialNav's managers: the crowd (`AgentManager`), the traffic (`VehicleManager`) and their PyBullet bodies.

Listed in this order in `env.managers`: the traffic yields to the crowd's new positions, and the bodies are placed
where both moved to. Crowd and traffic keep planners built for one scene (navigation grid, lanes), and the bodies
live in one Bullet client, so each cached world has its own of all three.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.agents.crowd import AgentManager, EgoState, advance_crowds
from sim.agents.crowd_kernels import box_gaps, cell_values
from sim.agents.vehicles import VehicleManager
from sim.envs.bodies import CohabitantBodies
from sim.envs.managers import EgoPose, Manager, ResetContext, SceneContext, TickContext
from sim.sensors import GridLidar

_NO_POSES = (np.zeros(0), np.zeros(0), np.zeros(0))


def crowd_ego(ego: EgoPose) -> EgoState:
    """The ego as the crowd avoids it: position, velocity and the radius of its footprint's circumcircle."""
    return EgoState(
        ego.x,
        ego.y,
        ego.speed * math.cos(ego.yaw),
        ego.speed * math.sin(ego.yaw),
        0.5 * math.hypot(ego.length, ego.width),
    )


class CrowdAdapter(Manager[AgentManager]):
    """The cohabitants (ORCA): spawned at reset away from the route's ends, moved every step around the ego."""

    def __init__(self, config: Mapping[str, Any], personal_space: float) -> None:
        self.config = config
        self.personal_space = personal_space  # PSC's gap between body surfaces, metres
        self.crowd = AgentManager(config)  # checks the agents config when the env is built
        self.min_distance = math.inf  # the ego footprint's gap to the nearest agent body, this step

    def on_scene(self, ctx: SceneContext) -> None:
        self.crowd = AgentManager(self.config)

    def leave_scene(self) -> AgentManager:
        return self.crowd

    def enter_scene(self, state: AgentManager | None) -> None:
        assert state is not None  # every cached world got its crowd from on_scene
        self.crowd = state

    def reset(self, ctx: ResetContext) -> None:
        start, goal = ctx.route.start, ctx.route.goal
        self.crowd.reset(
            ctx.scene,
            ctx.rng,
            ego=crowd_ego(ctx.ego),
            keep_clear=[(float(goal[0]), float(goal[1]), 1.0), (float(start[0]), float(start[1]), 2.0)],
            route=ctx.route.points,
        )
        self.min_distance = self._nearest(ctx.ego)

    def after_step(self, ctx: TickContext) -> None:
        CrowdAdapter.after_steps([self], [ctx])

    @staticmethod
    def after_steps(adapters: Sequence[CrowdAdapter], ticks: Sequence[TickContext]) -> None:
        """`after_step` of many crowds (a batched env's), their ORCA steps in one compiled call."""
        advance_crowds([a.crowd for a in adapters], ticks[0].dt, [crowd_ego(t.ego) for t in ticks])
        for a, tick in zip(adapters, ticks):
            a.min_distance = a._nearest(tick.ego)

    def view_fields(self) -> dict[str, Any]:
        return {"min_agent_distance": lambda: self.min_distance, "personal_space": self.personal_space}

    def _nearest(self, ego: EgoPose) -> float:
        """Smallest gap (m) between the ego's footprint rectangle and any agent's body circle."""
        pos = self.crowd.pos
        if not len(pos):
            return math.inf
        cos_yaw, sin_yaw = math.cos(ego.yaw), math.sin(ego.yaw)
        # Agent centres in the ego frame, then the distance to the footprint box (0 inside it).
        ex, ey = box_gaps(pos, ego.x, ego.y, cos_yaw, sin_yaw, 0.5 * ego.length, 0.5 * ego.width)
        return float(np.min(np.hypot(ex, ey) - self.crowd.radius))


class TrafficAdapter(Manager[VehicleManager]):
    """Road vehicles (IDM) that yield to the crowd and the ego; `enabled` False: no vehicles at all."""

    def __init__(self, config: Mapping[str, Any], enabled: bool, crowd: CrowdAdapter) -> None:
        self.config = config
        self.enabled = enabled
        self.people = crowd  # the crowd whose positions the vehicles yield to
        self.traffic = VehicleManager(config)  # checks the vehicles config when the env is built

    def on_scene(self, ctx: SceneContext) -> None:
        self.traffic = VehicleManager(self.config)

    def leave_scene(self) -> VehicleManager:
        return self.traffic

    def enter_scene(self, state: VehicleManager | None) -> None:
        assert state is not None  # every cached world got its traffic from on_scene
        self.traffic = state

    def reset(self, ctx: ResetContext) -> None:
        if self.enabled:
            self.traffic.reset(ctx.scene, ctx.rng)
        else:
            self.traffic.clear()

    def after_step(self, ctx: TickContext) -> None:
        if self.enabled:
            people = np.concatenate([self.people.crowd.pos, [[ctx.ego.x, ctx.ego.y]]])
            self.traffic.advance(ctx.dt, people)

    def poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, y and yaw of every vehicle on the road (none without traffic)."""
        return self.traffic.poses() if self.enabled else _NO_POSES

    def states(self) -> np.ndarray:
        """Every vehicle's x, y, vx, vy, yaw, length and width (structured array)."""
        return self.traffic.states() if self.enabled else np.zeros(0, dtype=self.traffic.states().dtype)


@dataclass
class WorldBodies:
    """The cohabitants' bodies of one world, and that world's curb height (agents on sidewalks stand on it)."""

    bodies: CohabitantBodies
    curb_height: float


class BodyAdapter(Manager[WorldBodies]):
    """The crowd's and the traffic's PyBullet bodies, placed at their states after every reset and step."""

    def __init__(self, crowd: CrowdAdapter, traffic: TrafficAdapter) -> None:
        self.crowd = crowd
        self.traffic = traffic
        self.world: WorldBodies | None = None  # the current world's bodies, made with it (on_scene)

    @property
    def bodies(self) -> CohabitantBodies | None:
        """The current world's bodies (None before the first world is built)."""
        return None if self.world is None else self.world.bodies

    def on_scene(self, ctx: SceneContext) -> None:
        # A new world in its client: no agent body or shape exists there yet.
        vehicle = self.traffic.traffic.config
        bodies = CohabitantBodies(ctx.client, ctx.collision_kinds, (vehicle["length"], vehicle["width"]))
        self.world = WorldBodies(bodies, float(ctx.scene.curb_height))
        for lidar in ctx.lidars:
            if isinstance(lidar, GridLidar):  # the grids hold the static scene only: the bodies trace themselves
                lidar.moving = bodies.ray_hits

    def leave_scene(self) -> WorldBodies | None:
        # The bodies stay in the world being left: parked, they are out of the way when it returns.
        self.park()
        return self.world

    def enter_scene(self, state: WorldBodies | None) -> None:
        assert state is not None  # every cached world got its bodies from on_scene
        self.world = state

    def park(self) -> None:
        # Last episode's agents and vehicles must not stand where the next start's surface height is probed.
        if self.world is not None:
            self.world.bodies.park()

    def reset(self, ctx: ResetContext) -> None:
        self.sync()

    def after_step(self, ctx: TickContext) -> None:
        self.sync()

    def sync(self) -> None:
        """Place every agent and vehicle body at its state (after the crowd or the traffic moved)."""
        world = self.world
        assert world is not None  # made with the world (on_scene)
        crowd = self.crowd.crowd
        world.bodies.sync(crowd.kind_idx, crowd.pos, agent_base_heights(crowd, world.curb_height), self.traffic.poses())


def agent_base_heights(crowd: AgentManager, curb: float) -> np.ndarray:
    """The ground height under every agent of `crowd` (m): the curb's on sidewalks, the road's on crosswalks."""
    xy = crowd.pos
    if not len(xy):
        return np.zeros(0)
    grid = crowd.grid
    assert grid is not None  # the crowd's reset built its grid; only then are there agents
    codes = cell_values(xy, float(grid.origin[0]), float(grid.origin[1]), float(grid.res), grid.cells)
    # Legend: sidewalk on the curb, crosswalk on the road, ramps half way.
    return np.array([curb, curb, 0.0, curb / 2])[np.minimum(codes, 3)]
