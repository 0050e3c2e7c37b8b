"""The crowd's configuration: AGENT_DEFAULTS and the value ranges of its deadlock and behaviour keys."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from kernel.config import ConfigError
from sim.agents.kinds import DEFAULT_MIX

AGENT_DEFAULTS: dict[str, Any] = {
    "dynamic_density": 2.0,  # agents per 100 m of sidewalk (MetaUrban's rho_d); ignored when `counts` is given
    "counts": {},  # explicit {kind: count}; non-empty overrides dynamic_density
    "mix": dict(DEFAULT_MIX),  # kind shares when spawning by density
    "max_agents": 1000,
    "plan_radius": 0.5,  # objects and edges are grown by this much for planning (the widest ORCA radius)
    "n_goal_sites": 32,  # distance fields shared by all agents; more sites = more varied goals, slower reset
    "goal_spread": 2.5,  # each agent's goal is a free cell within this distance of its site
    "lookahead_cells": 8,  # 1, 2, 4 or 8
    "keep_right": 0.5,  # metres the carrot is shifted to the right of the path (lane formation)
    "arrive_radius": 0.5,
    "crowded_arrive_radius": 2.0,  # a stalled agent this close to its goal has arrived (someone stands on it)
    "idle_prob": 0.25,  # chance to stand still on arrival
    "idle_time": [2.0, 8.0],
    "run_prob": 0.1,  # chance that a kind able to run runs to its next goal
    "neighbor_dist": 5.0,
    "max_neighbors": 10,
    "time_horizon": 2.0,
    "time_horizon_obst": 1.0,
    "safety_margin": 0.1,  # added to every ORCA radius so sampling error never lets bodies touch
    "ego_margin": 0.25,  # the ego does not reciprocate, so agents keep extra room from it
    "stuck_steps": 30,  # steps without progress before the side-step (rotate); push after this or twice this
    "regoal_steps": 150,
    "push_window": 12.0,  # metres searched for a passing place when pushed aside (push half); 0 turns push off
    "group_prob": 0.15,  # share of agents (pedestrians, wheelchair users) that start in standing groups
    "group_size": [2, 4],  # members per group, [min, max]
    "group_time": [10.0, 40.0],  # seconds a group stands before dispersing or walking on together
    "group_disperse_prob": 0.5,  # chance that a group disperses (else it walks on together and stands again)
    "cross_prob": 0.15,  # chance that a new goal lies across a road, reached over the nearest crosswalk
    "stuck_progress": 0.25,  # metres of field distance that count as progress
    "budget_factor": 2.0,  # goal time budget = factor * path length / speed + slack
    "budget_slack": 10.0,
    "spawn_clearance": 0.3,
    "spawn_area": "sidewalks",  # sidewalks | intersections (within intersection_margin of X/T/O blocks) | route
    "intersection_margin": 10.0,  # metres around an intersection/junction/roundabout road polygon
    "route_band": 5.0,  # metres either side of the ego's route ("route": dynamic_density per 100 m of route)
    "trail_length": 15,
}
# Value ranges of the deadlock and behaviour keys: (low, high, integers only, a [min, max] pair, what it means).
BEHAVIOUR_RANGES: dict[str, tuple[float, float, bool, bool, str]] = {
    "stuck_steps": (0, 1_000_000, True, False, "steps"),
    "regoal_steps": (1, 1_000_000, True, False, "steps"),
    "push_window": (0.0, 100.0, False, False, "metres; 0 turns the push half of push-and-rotate off"),
    "group_prob": (0.0, 1.0, False, False, "share of agents that start in standing groups"),
    "group_size": (2, 8, True, True, "[min, max] members"),
    "group_time": (0.0, 3600.0, False, True, "[min, max] seconds a group stands"),
    "group_disperse_prob": (0.0, 1.0, False, False, "chance that a group disperses"),
    "cross_prob": (0.0, 1.0, False, False, "chance that a new goal lies across a road"),
}


def check_behaviour_config(config: Mapping[str, Any]) -> None:
    """Raise ConfigError naming the key and its valid range for a bad deadlock or behaviour value."""
    for key, (lo, hi, integer, pair, hint) in BEHAVIOUR_RANGES.items():
        value = config[key]
        items = list(value) if pair and isinstance(value, (list, tuple)) else [value]
        number = "an integer" if integer else "a finite number"
        ok = (
            len(items) == (2 if pair else 1)
            and all(
                isinstance(v, (int, float))
                and not isinstance(v, bool)
                and (isinstance(v, int) or not integer)
                and math.isfinite(v)
                and lo <= v <= hi
                for v in items
            )
            and (not pair or items[0] <= items[1])
        )
        if not ok:
            span = f"{number} in [{lo:g}, {hi:g}]"
            what = f"a [min, max] pair (min <= max), each {span}" if pair else span
            raise ConfigError(f"agents config.{key} must be {what}, got {value!r} ({hint})")
