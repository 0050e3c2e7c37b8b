"""SocialNav's config: defaults, presets and the table of PointNav's keys plus cohabitants, traffic and social metrics.

The agent and vehicle defaults live with their simulators (sim.agents.crowd.AGENT_DEFAULTS,
sim.agents.vehicles.VEHICLE_DEFAULTS); their value ranges are listed here so SocialNav rejects a bad number at
construction. A key those modules add later is still checked against its default's type (sim.schema.infer).
"""

from __future__ import annotations

from typing import Any

from sim.agents.crowd import AGENT_DEFAULTS, SPAWN_AREAS
from sim.agents.vehicles import VEHICLE_DEFAULTS
from sim.metrics import SOCIALNAV_MEASURES
from sim.schema import Bool, Choice, Float, Int, Pair, Pos, Rule
from sim.tasks.pointnav import CONFIG_TABLE as POINTNAV_TABLE
from sim.tasks.pointnav import DEFAULT_CONFIG as POINTNAV_CONFIG
from sim.tasks.pointnav import TASK_PRESETS
from sim.tasks.sensors import RENDER_TABLE

AGENTS_TABLE: dict[str, Rule] = {
    "dynamic_density": Float(0.0, 100.0, hint="agents per 100 m of sidewalk"),
    "counts": Rule("mapping", item=Int(0, 10_000), hint="{kind: count}"),
    "mix": Rule("mapping", item=Float(0.0, 1e6), hint="{kind: share}"),
    "max_agents": Int(0, 10_000),
    "plan_radius": Float(0.0, 5.0),
    "n_goal_sites": Int(1, 1024),
    "goal_spread": Float(0.0, 100.0),
    "lookahead_cells": Choice(1, 2, 4, 8),
    "keep_right": Float(-5.0, 5.0),
    "arrive_radius": Pos(100.0),
    "crowded_arrive_radius": Float(0.0, 100.0),
    "idle_prob": Float(0.0, 1.0),
    "idle_time": Pair(Float(0.0, 3600.0), hint="seconds"),
    "run_prob": Float(0.0, 1.0),
    "neighbor_dist": Pos(100.0),
    "max_neighbors": Int(0, 100),
    "time_horizon": Pos(100.0),
    "time_horizon_obst": Pos(100.0),
    "safety_margin": Float(0.0, 5.0),
    "ego_margin": Float(0.0, 5.0),
    "stuck_steps": Int(0, 1_000_000),
    "regoal_steps": Int(1, 1_000_000),
    "stuck_progress": Float(0.0, 100.0),
    "budget_factor": Pos(100.0),
    "budget_slack": Float(0.0, 10_000.0),
    "spawn_clearance": Float(0.0, 10.0),
    "spawn_area": Choice(*SPAWN_AREAS),
    "intersection_margin": Float(0.0, 1000.0),
    "route_band": Pos(1000.0),
    "trail_length": Int(0, 10_000),
}
VEHICLES_TABLE: dict[str, Rule] = {
    "traffic_density": Float(0.0, 100.0, hint="vehicles per 100 m of lane"),
    "desired_speed": Pair(Float(0.0, 50.0), hint="m/s"),
    "time_headway": Pos(100.0),
    "min_gap": Float(0.0, 100.0),
    "max_accel": Pos(100.0),
    "comfort_decel": Pos(100.0),
    "max_decel": Pos(100.0),
    "delta": Pos(100.0),
    "length": Pos(50.0),
    "width": Pos(20.0),
    "crosswalk_margin": Float(0.0, 100.0),
    "stop_gap": Float(0.0, 100.0),
    "max_hold": Pos(3600.0),
    "junction_stop": Float(0.0, 100.0),
    "turning": Bool(),
}
CONFIG_TABLE: dict[str, Any] = {
    **POINTNAV_TABLE,
    "agents": AGENTS_TABLE,
    "vehicles": VEHICLES_TABLE,
    "traffic": Bool(),
    "personal_space": Float(0.0, 10.0, hint="metres between body surfaces"),
    "render": {**RENDER_TABLE, "camera": Choice("dashboard", "map", "top_down", "chase")},
}

DEFAULT_CONFIG: dict[str, Any] = {
    **POINTNAV_CONFIG,
    "agents": dict(AGENT_DEFAULTS),
    "vehicles": dict(VEHICLE_DEFAULTS),
    "traffic": True,  # vehicles on the roads
    "personal_space": 0.45,  # m between body surfaces (ego footprint to agent body): Hall's intimate distance
    "cost_kinds": ["object", "building", "agent", "vehicle"],
    "measures": list(SOCIALNAV_MEASURES),
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
    split: {
        "run_prob": 0.3,
        "idle_prob": 0.1,
        "keep_right": 0.0,
        "time_horizon": 1.0,
        "mix": {
            "pedestrian": 0.40,
            "wheelchair_user": 0.08,
            "cyclist": 0.14,
            "skateboarder": 0.10,
            "scooter_rider": 0.14,
            "delivery_robot": 0.09,
            "robot_dog": 0.05,
        },
    }
    for split in ("unseen", "finetune")
}
