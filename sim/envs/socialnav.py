"""SocialNav: PointNav among cohabitants (sim.agents) and road traffic, with the social metrics PSC, STL and SNS."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.agents.crowd import AgentManager
from sim.agents.vehicles import VehicleManager
from sim.envs.bodies import CohabitantBodies
from sim.envs.cohabitants import BodyAdapter, CrowdAdapter, TrafficAdapter
from sim.envs.pointnav import PointNavEnv
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
        cfg = self.config
        self.crowd_adapter = CrowdAdapter(cfg["agents"], float(cfg["personal_space"]))
        self.traffic_adapter = TrafficAdapter(cfg["vehicles"], bool(cfg["traffic"]), self.crowd_adapter)
        self.body_adapter = BodyAdapter(self.crowd_adapter, self.traffic_adapter)
        # Order matters: the traffic yields to where the crowd moved, the bodies go where both moved.
        self.managers = [self.crowd_adapter, self.traffic_adapter, self.body_adapter]
        self.collision_kinds_all = [*self.collision_kinds_all, "agent", "vehicle"]

    @property
    def crowd(self) -> AgentManager:
        """The current world's cohabitants (sim.agents.crowd.AgentManager)."""
        return self.crowd_adapter.crowd

    @property
    def traffic(self) -> VehicleManager:
        """The current world's road vehicles (sim.agents.vehicles.VehicleManager)."""
        return self.traffic_adapter.traffic

    @property
    def bodies(self) -> CohabitantBodies | None:
        """The current world's agent and vehicle bodies (None before the first reset builds a world)."""
        return self.body_adapter.bodies

    def agent_states(self) -> np.ndarray:
        """Every cohabitant's x, y, vx, vy, radius and kind (structured array; vehicles: vehicle_states())."""
        if self.route is None:
            raise RuntimeError("the env has no cohabitants yet: call reset() first")
        return self.crowd.states()

    def vehicle_states(self) -> np.ndarray:
        """Every vehicle's x, y, vx, vy, yaw, length and width (structured array)."""
        return self.traffic_adapter.states()
