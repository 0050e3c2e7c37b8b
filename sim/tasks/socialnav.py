"""SocialNav's config: PointNav's keys plus cohabitants, traffic and social metrics, declared once, and its presets.

The agents' and the vehicles' keys are declared with their simulators (sim.agents.crowd_config.AGENT_KEYS,
sim.agents.vehicle_config.VEHICLE_KEYS); SocialNav's table holds their rules, so a bad number fails at
construction.
"""

from __future__ import annotations

from typing import Any

from sim.agents.crowd_config import AGENT_KEYS, AGENTS_TABLE
from sim.agents.vehicle_config import VEHICLE_KEYS, VEHICLES_TABLE
from sim.metrics import SOCIALNAV_MEASURES
from sim.schema import Bool, Choice, Float, Key, Rule, Table, defaults_of, redeclare, table_of
from sim.tasks.pointnav import CONFIG_KEYS as POINTNAV_KEYS
from sim.tasks.pointnav import TASK_PRESETS
from sim.tasks.sensors import RENDER_KEYS

# AGENTS_TABLE and VEHICLES_TABLE: the agents' and vehicles' rules, importable from the task as well.
__all__ = [
    "AGENTS_TABLE",
    "CONFIG_KEYS",
    "CONFIG_TABLE",
    "DEFAULT_CONFIG",
    "PRESETS",
    "SPLIT_AGENT_BEHAVIOUR",
    "VEHICLES_TABLE",
]

CONFIG_KEYS: dict[str, Key | dict[str, Key]] = {
    **POINTNAV_KEYS,
    "cost_kinds": redeclare(
        POINTNAV_KEYS["cost_kinds"],
        default=["object", "building", "agent", "vehicle"],
        doc="contacts that cost: PointNav's plus agents and vehicles",
    ),
    "measures": redeclare(POINTNAV_KEYS["measures"], default=list(SOCIALNAV_MEASURES)),
    "render": {
        **RENDER_KEYS,
        "camera": redeclare(
            RENDER_KEYS["camera"],
            rule=Choice("dashboard", "map", "top_down", "chase"),
            doc='the view render() draws ("map": the map alone)',
        ),
    },
    "agents": AGENT_KEYS,
    "vehicles": VEHICLE_KEYS,
    "traffic": Key(True, Bool(), "vehicles on the roads"),
    "personal_space": Key(
        0.45,
        Float(0.0, 10.0, hint="metres between body surfaces"),
        "m between body surfaces (ego footprint to agent body): Hall's intimate distance",
    ),
}
DEFAULT_CONFIG: dict[str, Any] = defaults_of(CONFIG_KEYS)
CONFIG_TABLE: dict[str, Rule | Table] = table_of(CONFIG_KEYS)
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
