"""The crowd's configuration (SocialNav's `agents`): one Key per setting, AGENT_DEFAULTS and AGENTS_TABLE."""

from __future__ import annotations

from typing import Any

from sim.agents.crowd_spawning import SPAWN_AREAS
from sim.agents.kinds import DEFAULT_MIX
from sim.schema import Choice, Float, Int, Key, Pair, Pos, Rule, Table, defaults_of, table_of

AGENT_KEYS: dict[str, Key] = {
    "dynamic_density": Key(
        2.0,
        Float(0.0, 100.0, hint="agents per 100 m of sidewalk"),
        "agents per 100 m of sidewalk (MetaUrban's rho_d); ignored when `counts` is given",
    ),
    "counts": Key(
        {},
        Rule("mapping", item=Int(0, 10_000), hint="{kind: count}"),
        "explicit {kind: count}; non-empty overrides dynamic_density",
    ),
    "mix": Key(
        dict(DEFAULT_MIX),
        Rule("mapping", item=Float(0.0, 1e6), hint="{kind: share}"),
        "kind shares when spawning by density",
    ),
    "max_agents": Key(1000, Int(0, 10_000), "the most agents an episode holds"),
    "plan_radius": Key(
        0.5, Float(0.0, 5.0), "objects and edges are grown by this much for planning (the widest ORCA radius)"
    ),
    "n_goal_sites": Key(
        32, Int(1, 1024), "distance fields shared by all agents; more sites = more varied goals, slower reset"
    ),
    "goal_spread": Key(2.5, Float(0.0, 100.0), "each agent's goal is a free cell within this distance of its site"),
    "lookahead_cells": Key(8, Choice(1, 2, 4, 8), "cells ahead on the distance field an agent steers at: 1, 2, 4 or 8"),
    "keep_right": Key(0.5, Float(-5.0, 5.0), "metres the carrot is shifted to the right of the path (lane formation)"),
    "arrive_radius": Key(0.5, Pos(100.0), "metres from its goal at which an agent has arrived"),
    "crowded_arrive_radius": Key(
        2.0, Float(0.0, 100.0), "a stalled agent this close to its goal has arrived (someone stands on it)"
    ),
    "idle_prob": Key(0.25, Float(0.0, 1.0), "chance to stand still on arrival"),
    "idle_time": Key([2.0, 8.0], Pair(Float(0.0, 3600.0), hint="seconds"), "[min, max] seconds an idle agent stands"),
    "run_prob": Key(0.1, Float(0.0, 1.0), "chance that a kind able to run runs to its next goal"),
    "neighbor_dist": Key(5.0, Pos(100.0), "ORCA: metres within which other agents are considered"),
    "max_neighbors": Key(10, Int(0, 100), "ORCA: the most neighbours considered"),
    "time_horizon": Key(2.0, Pos(100.0), "ORCA: seconds ahead that velocities stay collision-free from agents"),
    "time_horizon_obst": Key(1.0, Pos(100.0), "ORCA: seconds ahead that velocities stay collision-free from obstacles"),
    "safety_margin": Key(0.1, Float(0.0, 5.0), "added to every ORCA radius so sampling error never lets bodies touch"),
    "ego_margin": Key(0.25, Float(0.0, 5.0), "the ego does not reciprocate, so agents keep extra room from it"),
    "stuck_steps": Key(
        30,
        Int(0, 1_000_000),
        "steps without progress before the side-step (rotate); push after this or twice this",
    ),
    "regoal_steps": Key(150, Int(1, 1_000_000), "steps without progress before an agent picks a new goal"),
    "push_window": Key(
        12.0,
        Float(0.0, 100.0, hint="metres; 0 turns the push half of push-and-rotate off"),
        "metres searched for a passing place when pushed aside (push half); 0 turns push off",
    ),
    "group_prob": Key(
        0.15,
        Float(0.0, 1.0, hint="share of agents that start in standing groups"),
        "share of agents (pedestrians, wheelchair users) that start in standing groups",
    ),
    "group_size": Key([2, 4], Pair(Int(2, 8), hint="[min, max] members"), "members per group, [min, max]"),
    "group_time": Key(
        [10.0, 40.0],
        Pair(Float(0.0, 3600.0), hint="[min, max] seconds a group stands"),
        "seconds a group stands before dispersing or walking on together",
    ),
    "group_disperse_prob": Key(
        0.5,
        Float(0.0, 1.0, hint="chance that a group disperses"),
        "chance that a group disperses (else it walks on together and stands again)",
    ),
    "cross_prob": Key(
        0.15,
        Float(0.0, 1.0, hint="chance that a new goal lies across a road"),
        "chance that a new goal lies across a road, reached over the nearest crosswalk",
    ),
    "stuck_progress": Key(0.25, Float(0.0, 100.0), "metres of field distance that count as progress"),
    "budget_factor": Key(2.0, Pos(100.0), "goal time budget = factor * path length / speed + slack"),
    "budget_slack": Key(10.0, Float(0.0, 10_000.0), "seconds added to every goal's time budget"),
    "spawn_clearance": Key(0.3, Float(0.0, 10.0), "metres kept free around a spawned agent"),
    "spawn_area": Key(
        "sidewalks",
        Choice(*SPAWN_AREAS),
        "sidewalks | intersections (within intersection_margin of X/T/O blocks) | route",
    ),
    "intersection_margin": Key(
        10.0, Float(0.0, 1000.0), "metres around an intersection/junction/roundabout road polygon"
    ),
    "route_band": Key(
        5.0, Pos(1000.0), 'metres either side of the ego\'s route ("route": dynamic_density per 100 m of route)'
    ),
    "trail_length": Key(15, Int(0, 10_000), "past positions kept per agent (drawn as its trail)"),
}
AGENT_DEFAULTS: dict[str, Any] = defaults_of(AGENT_KEYS)
AGENTS_TABLE: dict[str, Rule | Table] = table_of(AGENT_KEYS)
