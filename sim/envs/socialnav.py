"""SocialNav: PointNav among cohabitants (sim.agents) and road traffic, with the social metrics PSC, STL and SNS."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pybullet as p

from sim.agents.crowd import AGENT_DEFAULTS, AgentManager, EgoState
from sim.agents.kinds import AGENT_KINDS, KIND_NAMES
from sim.agents.render import draw_top_down
from sim.agents.vehicles import VEHICLE_DEFAULTS, VehicleManager
from sim.envs.pointnav import PointNavEnv
from sim.metrics import SOCIALNAV_MEASURES
from sim.tasks.pointnav import DEFAULT_CONFIG as POINTNAV_CONFIG
from sim.tasks.pointnav import TASK_PRESETS
from sim.tasks.socialnav import CONFIG_TABLE

DEFAULT_CONFIG: dict[str, Any] = {
    **POINTNAV_CONFIG,
    "agents": dict(AGENT_DEFAULTS),
    "vehicles": dict(VEHICLE_DEFAULTS),
    "traffic": True,  # vehicles on the roads
    "personal_space": 0.45,  # m between body surfaces (ego footprint to agent body): Hall's intimate distance
    "stl_cruise_speed": 2.5,  # m/s; t_ref = geodesic / min(this, v_max); the expert's cruise speed
    "cost_kinds": ["object", "building", "agent", "vehicle"],
    "measures": list(SOCIALNAV_MEASURES),
    "render": {**POINTNAV_CONFIG["render"], "camera": "map", "width": 256, "height": 256},
}
# SocialNav's presets: PointNav's plus the paper's 10 dynamic agents per block (7.2 per 100 m of sidewalk on the
# metaurban12k scenes, which have ~139 m of sidewalk per block).
PRESETS: dict[str, dict[str, Any]] = {
    name: {**preset, "agents": {"dynamic_density": 7.2}} for name, preset in TASK_PRESETS.items()
}
# Unseen agent behaviour (the paper's "unseen" split has unseen agent behaviour too): in unseen and finetune,
# more people run and fewer stand, lanes do not form (no keep-right offset), wheeled VRUs are twice as common,
# and agents react later to each other. Keys the caller sets in `agents` still win.
SPLIT_AGENT_BEHAVIOUR: dict[str, dict[str, Any]] = {
    split: {"run_prob": 0.3, "idle_prob": 0.1, "keep_right": 0.0, "time_horizon": 1.0,
            "mix": {"pedestrian": 0.40, "wheelchair_user": 0.08, "cyclist": 0.14, "skateboarder": 0.10,
                    "scooter_rider": 0.14, "delivery_robot": 0.09, "robot_dog": 0.05}}
    for split in ("unseen", "finetune")
}
VEHICLE_HEIGHT = 1.5


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
    | config | `agents` (sim.agents.AGENT_DEFAULTS), `vehicles`, `traffic`, `personal_space`, `stl_cruise_speed` |

    `render()` with camera "map" (default) draws a top-down map with agents by kind and short trails;
    "top_down" and "chase" are PointNav's TinyRenderer cameras.
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
        self._agent_bodies: list[int] = []
        self._vehicle_bodies: list[int] = []
        self._shapes: dict[Any, tuple[int, int]] = {}
        self._body_kind_idx = self._body_kind_src = np.zeros(0, dtype=np.int16)
        self._vehicles_shown = -1
        self._vehicle_states: np.ndarray | None = None  # the traffic's states of this tick, shared by sync and obs

    # -- hooks -------------------------------------------------------------------------------------
    _WORLD_STATE = ("crowd", "traffic", "_agent_bodies", "_vehicle_bodies", "_shapes", "_vehicles_shown", "_collision_kinds",
                    "_body_kind_idx", "_body_kind_src", "_body_kinds", "_half_heights", "_body_xyz")

    def _on_scene(self, spec: Mapping[str, Any]) -> None:
        # A new world in its client: no agent body or shape exists there yet. Crowd and traffic keep planners
        # built for one scene (navigation grid, lanes), so each cached world has its own.
        self.crowd = AgentManager(self.config["agents"])
        self.traffic = VehicleManager(self.config["vehicles"])
        self._agent_bodies, self._vehicle_bodies, self._shapes = [], [], {}
        self._vehicles_shown = -1
        self._collision_kinds = {}
        self._body_kind_idx = self._body_kind_src = np.zeros(0, dtype=np.int16)

    def _park_bodies(self) -> None:
        # Last episode's agents and vehicles must not stand where the next start's surface height is probed.
        for body in self._agent_bodies + self._vehicle_bodies:
            p.resetBasePositionAndOrientation(body, [0, 0, -20], [0, 0, 0, 1], physicsClientId=self.client)
        self._vehicles_shown = -1
        if getattr(self, "_body_xyz", None) is not None:
            self._body_xyz = np.full_like(self._body_xyz, np.nan)

    def _scene_state(self) -> dict[str, Any]:
        # The agent bodies live in the world being left: park them so they are out of the way when it returns.
        self._park_bodies()
        return {k: getattr(self, k, None) for k in self._WORLD_STATE}

    def _load_scene_state(self, state: dict[str, Any]) -> None:
        for k in self._WORLD_STATE:
            setattr(self, k, state.get(k))

    def _on_reset(self, rng: np.random.Generator) -> None:
        spec = self.scene_spec
        start = self.route.start
        goal = self.route.goal
        self.crowd.reset(spec, rng, ego=self._ego_state(), keep_clear=[(float(goal[0]), float(goal[1]), 1.0),
                                                                   (float(start[0]), float(start[1]), 2.0)],
                        route=self.route.points)
        if self.config["traffic"]:
            self.traffic.reset(spec, rng)
        else:
            self.traffic.n = 0
        self._sync_bodies()
        self._min_agent_distance = self._nearest_agent()

    def _on_step(self) -> None:
        ego = self._ego_state()
        self.crowd.step(self.dt, ego)
        if self.config["traffic"]:
            people = np.concatenate([self.crowd.pos, [[ego.x, ego.y]]])
            self._vehicle_states = self.traffic.step(self.dt, people)
        self._sync_bodies()
        self._min_agent_distance = self._nearest_agent()

    # -- bodies ------------------------------------------------------------------------------------
    def _shape(self, key: Any, make: Any) -> tuple[int, int]:
        if key not in self._shapes:
            self._shapes[key] = make()
        return self._shapes[key]

    def _sync_bodies(self) -> None:
        c = self.client
        crowd = self.crowd
        vehicles = self._vehicle_states if self._vehicle_states is not None else self.vehicle_states()
        self._vehicle_states = None
        self._ensure_bodies(vehicles)
        if crowd.n:
            xyz = np.empty((crowd.n, 3))
            xyz[:, :2] = crowd.pos
            xyz[:, 2] = self._agent_base_heights(crowd.pos) + self._half_heights
            # Standing agents keep their body where it is: a Bullet reset per body is the cost worth saving.
            moved = np.flatnonzero(np.any(xyz != self._body_xyz, axis=1))
            for k, pos in zip(moved.tolist(), xyz[moved].tolist()):
                p.resetBasePositionAndOrientation(self._agent_bodies[k], pos, (0, 0, 0, 1), physicsClientId=c)
            self._body_xyz = xyz
        if len(vehicles):
            half_yaw = (0.5 * vehicles["yaw"]).tolist()
            for body, x, y, h in zip(self._vehicle_bodies, vehicles["x"].tolist(), vehicles["y"].tolist(), half_yaw):
                p.resetBasePositionAndOrientation(body, [x, y, VEHICLE_HEIGHT / 2], [0, 0, math.sin(h), math.cos(h)],
                                                  physicsClientId=c)

    def _bodies_match(self) -> bool:
        """Whether the agent bodies still match the crowd's agents (a reset may change their number or kinds)."""
        idx = self.crowd.kind_idx
        if len(self._agent_bodies) != self.crowd.n:
            return False
        if self._body_kind_src is not idx:  # a new episode: compare by value once, then by identity
            if not np.array_equal(self._body_kind_idx, idx):
                return False
            self._body_kind_src = idx
        return True

    def _ensure_bodies(self, vehicles: np.ndarray) -> None:
        c = self.client
        if not self._bodies_match():
            kinds = [KIND_NAMES[k] for k in self.crowd.kind_idx]
            for b in self._agent_bodies:
                p.removeBody(b, physicsClientId=c)
                self._collision_kinds.pop(b, None)
            self._agent_bodies = []
            for k in kinds:
                kind = AGENT_KINDS[k]
                # Capsules, not cylinders: Bullet ray-tests a cylinder about four times slower than a capsule, and
                # the LiDAR's rays made cylinders the costliest part of a SocialNav step.
                shaft = max(kind.height - 2.0 * kind.radius, 0.0)
                col, vis = self._shape(k, lambda kind=kind, shaft=shaft: (
                    p.createCollisionShape(p.GEOM_CAPSULE, radius=kind.radius, height=shaft, physicsClientId=c),
                    p.createVisualShape(p.GEOM_CAPSULE, radius=kind.radius, length=shaft,
                                        rgbaColor=[*kind.color, 1.0], physicsClientId=c)))
                body = p.createMultiBody(0.0, col, vis, [0, 0, -20], physicsClientId=c)
                self._agent_bodies.append(body)
                self._collision_kinds[body] = "agent"
            self._body_kinds = kinds
            self._body_kind_idx = self._body_kind_src = self.crowd.kind_idx
            self._half_heights = np.array([max(AGENT_KINDS[k].height, 2.0 * AGENT_KINDS[k].radius) / 2 for k in kinds])
            self._body_xyz = np.full((len(kinds), 3), np.nan)  # nan != anything: every body moves on the first sync
        while len(self._vehicle_bodies) < len(vehicles):
            cfg = self.traffic.config
            half = [cfg["length"] / 2, cfg["width"] / 2, VEHICLE_HEIGHT / 2]
            col, vis = self._shape("vehicle", lambda half=half: (
                p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=c),
                p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=[0.25, 0.25, 0.65, 1.0], physicsClientId=c)))
            body = p.createMultiBody(0.0, col, vis, [0, 0, -20], physicsClientId=c)
            self._vehicle_bodies.append(body)
            self._collision_kinds[body] = "vehicle"
        if len(vehicles) != self._vehicles_shown:  # park unused bodies once, not every step
            for body in self._vehicle_bodies[len(vehicles):]:
                p.resetBasePositionAndOrientation(body, [0, 0, -20], [0, 0, 0, 1], physicsClientId=c)
            self._vehicles_shown = len(vehicles)

    def _agent_base_heights(self, xy: np.ndarray) -> np.ndarray:
        g = self.crowd.grid
        if not len(xy):
            return np.zeros(0)
        i, j = g.cell_of(xy)
        curb = float(self.scene_spec.get("curb_height", 0.15))
        # Legend: sidewalk on the curb, crosswalk on the road, ramps half way.
        return np.choose(np.minimum(g.cells[i, j], 3), [curb, curb, 0.0, curb / 2])

    # -- state -------------------------------------------------------------------------------------
    def _ego_state(self) -> EgoState:
        m = self.machine
        x, y, _ = m.position
        s = m.spec
        return EgoState(float(x), float(y), m.speed * math.cos(m.yaw), m.speed * math.sin(m.yaw),
                        0.5 * math.hypot(s.length, s.width))

    def _nearest_agent(self) -> float:
        """Smallest gap (m) between the ego's footprint rectangle and any agent's body circle."""
        pos = self.crowd.pos
        if not len(pos):
            return math.inf
        m = self.machine
        x, y, _ = m.position
        c, s = math.cos(m.yaw), math.sin(m.yaw)
        dx, dy = pos[:, 0] - x, pos[:, 1] - y
        # Agent centres in the ego frame, then the distance to the footprint box (0 inside it).
        ex = np.maximum(np.abs(c * dx + s * dy) - 0.5 * m.spec.length, 0.0)
        ey = np.maximum(np.abs(-s * dx + c * dy) - 0.5 * m.spec.width, 0.0)
        return float(np.min(np.hypot(ex, ey) - self.crowd.radius))

    def agent_states(self) -> np.ndarray:
        """Every cohabitant's x, y, vx, vy, radius and kind (structured array; vehicles: vehicle_states())."""
        return self.crowd.states()

    def vehicle_states(self) -> np.ndarray:
        """Every vehicle's x, y, vx, vy, yaw, length and width (structured array)."""
        return self.traffic.states() if self.config["traffic"] else np.zeros(0, dtype=self.traffic.states().dtype)

    def render(self) -> np.ndarray | None:
        """RGB frame: the top-down agent map (camera 'map') or PointNav's TinyRenderer cameras."""
        if self.render_mode != "rgb_array":
            return None
        r = self.config["render"]
        if r["camera"] != "map":
            return super().render()
        m = self.machine
        x, y, _ = m.position
        return draw_top_down(self.scene_spec, (x, y), agents=self.crowd.states(), trails=self.crowd.trail,
                             vehicles=self.vehicle_states(), ego=(x, y, m.yaw, m.spec.length, m.spec.width),
                             route=self.route.point_at(np.linspace(0.0, self.route.length, 100)),
                             size=int(r["width"]), view=float(r["top_down_height"]) * 1.6)
