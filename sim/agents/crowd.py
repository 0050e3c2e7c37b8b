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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyrvo

from curbside.config import ConfigError, merge_strict
from sim.agents.behaviours import STAND_MARGIN, Crossings, Groups
from sim.agents.deadlock import PushResolver
from sim.agents.kinds import AGENT_KINDS, DEFAULT_MIX, KIND_NAMES, agent_kind
from sim.agents.navgrid import JUMPS, NavGrid, boundary_segments, build_navgrid

AGENT_DTYPE = np.dtype([("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("radius", "f8"), ("kind", "U16")])
IDLE, WALKING, RUNNING = 0, 1, 2

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
        ok = (len(items) == (2 if pair else 1)
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) and (isinstance(v, int) or not integer)
                      and math.isfinite(v) and lo <= v <= hi for v in items)
              and (not pair or items[0] <= items[1]))
        if not ok:
            span = f"{number} in [{lo:g}, {hi:g}]"
            what = f"a [min, max] pair (min <= max), each {span}" if pair else span
            raise ConfigError(f"agents config.{key} must be {what}, got {value!r} ({hint})")




@dataclass(frozen=True)
class EgoState:
    """The ego as ORCA sees it: centre, velocity and radius in the world frame."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    radius: float = 0.5


def _as_ego(ego: EgoState | Mapping[str, float] | Sequence[float] | None) -> EgoState | None:
    if ego is None or isinstance(ego, EgoState):
        return ego
    if isinstance(ego, Mapping):
        return EgoState(**{k: float(v) for k, v in ego.items()})
    return EgoState(*(float(v) for v in ego))


SPAWN_AREAS = ("sidewalks", "intersections", "route")


def spawn_region(spec: dict[str, Any], config: Mapping[str, Any], route: np.ndarray | None) -> Any:
    """The polygon agents spawn in (None: every sidewalk): around intersections, or along the ego's route."""
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union

    area = config["spawn_area"]
    if area == "sidewalks":
        return None
    if area == "intersections":
        roads = [Polygon(r["polygon"]) for r in spec.get("roads", []) if r.get("block") in ("X", "T", "O")]
        return unary_union(roads).buffer(float(config["intersection_margin"])) if roads else Polygon()
    if route is None or len(route) < 2:
        raise ConfigError("agents spawn_area 'route' needs the ego's route (SocialNav passes it at reset)")
    return LineString(np.asarray(route)[:, :2]).buffer(float(config["route_band"]))


def sidewalk_length(spec: dict[str, Any]) -> float:
    """Total sidewalk length in metres (clear-path polylines, else curb edges) used by dynamic_density."""
    total = 0.0
    for sw in spec.get("sidewalks", []):
        line = np.asarray(sw.get("clear_path") or sw.get("edge") or [], dtype=np.float64)
        if len(line) >= 2:
            total += float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())
    return total


class AgentManager:
    """Spawns, plans and moves cohabitants on one scene; `reset` then `step` every simulator tick."""

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = merge_strict(AGENT_DEFAULTS, config, name="agents config")
        check_behaviour_config(self.config)
        if self.config["spawn_area"] not in SPAWN_AREAS:
            raise ConfigError(f"unknown agents spawn_area {self.config['spawn_area']!r}; valid: {', '.join(SPAWN_AREAS)}")
        self._area: Any = None
        self._route_length = 0.0
        for kind in self.config["counts"]:
            agent_kind(kind)
        if any(v < 0 for v in self.config["mix"].values()) or sum(self.config["mix"].values()) <= 0:
            raise ConfigError("agents config mix needs non-negative shares with a positive sum")
        if self.config["lookahead_cells"] not in (1, 2, 4, 8):
            raise ConfigError(f"agents config lookahead_cells must be 1, 2, 4 or 8, got {self.config['lookahead_cells']}")
        self.grid: NavGrid | None = None
        self._scene: Any = None  # the spec the cached grid and ORCA obstacles belong to
        self.n = 0
        self.time = 0.0
        self.push = PushResolver(self.config["push_window"])
        self.groups = Groups()
        self.crossings = Crossings()

    # ------------------------------------------------------------------ reset
    def reset(self, spec: dict[str, Any], rng: np.random.Generator, ego: EgoState | None = None,
              keep_clear: Sequence[tuple[float, float, float]] = (), route: np.ndarray | None = None) -> np.ndarray:
        """Build the planner for `spec`, spawn agents away from `keep_clear` discs (x, y, r) and return states().

        `route` (N, 2): the ego's route, for `spawn_area: "route"` (agents per 100 m of route, along it).
        """
        c = self.config
        self.rng = rng
        fresh = spec is not self._scene
        if fresh:
            self.grid = build_navgrid(spec, plan_radius=c["plan_radius"], n_sites=c["n_goal_sites"])
            self.crossings.setup(spec, self.grid)
        self._area = spawn_region(spec, c, route)
        if route is not None and len(route) >= 2:
            self._route_length = float(np.linalg.norm(np.diff(np.asarray(route)[:, :2], axis=0), axis=1).sum())
        kinds = self._draw_kinds(spec, rng)
        self.n = n = len(kinds)
        self.kind_idx = np.array([KIND_NAMES.index(k) for k in kinds], dtype=np.int16)
        self.radius = np.array([AGENT_KINDS[k].radius for k in kinds])
        self._template = np.zeros(n, dtype=AGENT_DTYPE)
        self._template["radius"], self._template["kind"] = self.radius, kinds
        ego = _as_ego(ego)
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
        self._build_orca(spec, fresh)
        self._orca_radius = self.radius + c["safety_margin"]
        self._scene = spec
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

    def _draw_kinds(self, spec: dict[str, Any], rng: np.random.Generator) -> list[str]:
        c = self.config
        if c["counts"]:
            kinds = [k for k in KIND_NAMES for _ in range(int(c["counts"].get(k, 0)))]
        else:
            n = int(round(c["dynamic_density"] * self._area_length(spec) / 100.0))
            names = list(c["mix"])
            p = np.array([c["mix"][k] for k in names], dtype=np.float64)
            kinds = list(rng.choice(names, size=n, p=p / p.sum())) if n else []
        if len(kinds) > c["max_agents"]:
            raise ConfigError(f"{len(kinds)} agents requested but max_agents is {c['max_agents']}; "
                              "lower dynamic_density/counts or raise max_agents")
        return [str(k) for k in kinds]

    def _area_length(self, spec: dict[str, Any]) -> float:
        """Metres of sidewalk (or route) the spawn count scales with: dynamic_density agents per 100 m of it."""
        if self._area is None:
            return sidewalk_length(spec)
        if self.config["spawn_area"] == "route":
            return float(self._route_length)
        from shapely.geometry import LineString

        total = 0.0
        for sw in spec.get("sidewalks", []):
            line = sw.get("clear_path") or sw.get("edge") or []
            if len(line) >= 2:
                total += LineString(line).intersection(self._area).length
        return total

    def _spawn_positions(self, rng: np.random.Generator, clear: list[tuple[float, float, float]]) -> np.ndarray:
        g = self.grid
        cand = g.node_xy(rng.permutation(g.n_nodes))
        if self._area is not None:
            import shapely

            cand = cand[shapely.contains_xy(self._area, cand[:, 0], cand[:, 1])]
        for x, y, r in clear:
            cand = cand[np.hypot(cand[:, 0] - x, cand[:, 1] - y) > r]
        cand = cand + rng.uniform(-0.3, 0.3, cand.shape) * g.res  # off the cell centres, still in the cell
        pos = np.zeros((self.n, 2))
        placed, k = 0, 0
        while placed < self.n and k < len(cand):
            p = cand[k]
            k += 1
            if placed:
                d = np.linalg.norm(pos[:placed] - p, axis=1)
                if np.any(d < self.radius[:placed] + self.radius[placed] + self.config["spawn_clearance"]):
                    continue
            pos[placed] = p
            placed += 1
        if placed < self.n:
            raise ValueError(f"only {placed} of {self.n} agents fit on this scene's walkable area; "
                             "lower dynamic_density or the explicit counts")
        return pos

    def _build_orca(self, spec: dict[str, Any], fresh: bool) -> None:
        c = self.config
        if fresh:
            self._obstacles = self._orca_obstacles(spec)
            self._sims: dict[int, Any] = {}
        # Processing the scene's obstacles (object footprints, walkable boundary) costs ~0.2 s, more than a short
        # episode: each scene keeps one simulator per agent capacity (a power of two) and reuses it. RVO2's
        # clearAgents is never called (it left the agent k-d tree pointing at deleted agents): every slot is
        # rewritten each episode (position, velocity, preference, radius, speed) and unused slots are parked far
        # apart, so an episode's state does not depend on the episodes before it.
        cap = 1 << max(self.n - 1, 0).bit_length()
        sim = self._sims.get(cap)
        if sim is None:
            sim = pyrvo.RVOSimulator(0.1, c["neighbor_dist"], c["max_neighbors"], c["time_horizon"],
                                     c["time_horizon_obst"], 0.3, 2.0)
            for i in range(cap):
                sim.add_agent(self._parked(i), c["neighbor_dist"], c["max_neighbors"], c["time_horizon"],
                              c["time_horizon_obst"], 0.1, 0.0)
            # The ego is the last ORCA agent; it starts parked far away so it influences nobody until placed.
            sim.add_agent(self._parked(cap), c["neighbor_dist"], c["max_neighbors"], c["time_horizon"],
                          c["time_horizon_obst"], 0.1, 50.0)
            for vertices in self._obstacles:
                sim.add_obstacle(vertices)
            sim.process_obstacles()
            self._sims[cap] = sim
        self.sim, self.ego_id = sim, cap
        for i in range(cap + 1):
            if i < self.n:
                kind = AGENT_KINDS[KIND_NAMES[self.kind_idx[i]]]
                top = (kind.run_speed or kind.pref_speed) + 3.0 * kind.speed_std
                pos, radius = (float(self.pos[i, 0]), float(self.pos[i, 1])), float(self.radius[i] + c["safety_margin"])
            else:
                pos, radius, top = self._parked(i), 0.1, 0.0 if i < cap else 50.0
            sim.set_agent_position(i, pos)
            sim.set_agent_velocity(i, (0.0, 0.0))
            sim.set_agent_pref_velocity(i, (0.0, 0.0))
            sim.set_agent_radius(i, radius)
            sim.set_agent_max_speed(i, top)

    def _orca_obstacles(self, spec: dict[str, Any]) -> list[list[tuple[float, float]]]:
        """ORCA obstacles of a scene: object footprints (counter-clockwise) and walkable-boundary segments."""
        out = []
        for o in spec.get("objects", []):
            pts = np.asarray(o.get("footprint") or [], dtype=np.float64)
            if len(pts) >= 3:
                area2 = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
                out.append([tuple(p) for p in (pts if area2 > 0 else pts[::-1]).tolist()])  # RVO2 wants CCW
        g = self.grid
        out += [[a, b] for a, b in boundary_segments(g.cells > 0, g.origin, g.res)]
        return out

    def _parked(self, slot: int = 0) -> tuple[float, float]:
        """A far-away spot for an unused ORCA slot: 20 m apart, beyond any neighbour distance."""
        g = self.grid
        return (float(g.origin[0]) - 1e4 - 20.0 * slot, float(g.origin[1]) - 1e4)

    # ------------------------------------------------------------------ goals
    def _new_goal(self, i: int, node: int, abandon: bool = False, site: int | None = None,
                  goal_xy: np.ndarray | None = None, speed: float | None = None) -> None:
        """Send agent i (at `node`) to a random goal, or to `site` (its cell nearest `goal_xy`) walking at `speed`."""
        c, g, rng = self.config, self.grid, self.rng
        spread = c["goal_spread"]
        self.crossing[i] = False
        # cross_prob 0 draws nothing, so runs without crossings keep their random stream.
        if site is None and c["cross_prob"] > 0 and rng.random() < c["cross_prob"]:
            site = self.crossings.pick(self.pos[i])
            if site is not None:
                self.crossing[i] = True
                self.cross_counts["started"] += 1
                spread = min(spread, 1.0)  # stay by the crosswalk's far end, not 2.5 m around it
        if site is None:
            spread_sites = g.sites[:g.n_spread]  # crossing sites are goals of crossings only
            here = int(np.argmin(np.linalg.norm(g.node_xy(spread_sites) - self.pos[i], axis=1)))
            choices = np.delete(np.arange(len(spread_sites)), here) if len(spread_sites) > 1 else np.arange(1)
            site = int(rng.choice(choices))
        if abandon:
            self.counts["abandoned"] += 1
        if speed is None:
            kind = AGENT_KINDS[KIND_NAMES[self.kind_idx[i]]]
            run = kind.run_speed is not None and rng.random() < c["run_prob"]
            self.movement[i] = RUNNING if run else WALKING
            self.speed[i] = kind.sample_speed(rng, "running" if run else "walking")
        else:
            self.movement[i], self.speed[i] = WALKING, speed
        dist = g.field(site)
        if goal_xy is None:
            centre = g.node_xy(np.array([g.sites[site]]))[0]
            near = np.flatnonzero(np.linalg.norm(g.node_xy(np.flatnonzero(dist < spread * 1.5)) - centre, axis=1)
                                  < spread)
            near_nodes = np.flatnonzero(dist < spread * 1.5)[near]
            goal_node = int(rng.choice(near_nodes)) if len(near_nodes) else int(g.sites[site])
        else:
            goal_node = int(g.nearest_node(np.asarray(goal_xy, dtype=np.float64)[None])[0])
        self.site[i] = site
        self.goal[i] = g.node_xy(np.array([goal_node]))[0]
        length = float(dist[node]) + c["goal_spread"]
        self.goal_t0[i] = self.time
        self.budget[i] = c["budget_factor"] * length / max(self.speed[i], 0.1) + c["budget_slack"]
        self.best[i] = np.inf
        self.stall[i] = 0

    def _walking_speed(self, i: int) -> float:
        """A fresh walking speed for agent i's kind."""
        return AGENT_KINDS[KIND_NAMES[self.kind_idx[i]]].sample_speed(self.rng, "walking")

    # ------------------------------------------------------------------ step
    def _set_ego(self, ego: EgoState | None) -> None:
        if ego is None:
            self.sim.set_agent_position(self.ego_id, self._parked(self.ego_id))
            self.sim.set_agent_velocity(self.ego_id, (0.0, 0.0))
            self.sim.set_agent_pref_velocity(self.ego_id, (0.0, 0.0))
            return
        self.sim.set_agent_radius(self.ego_id, float(ego.radius + self.config["ego_margin"]))
        self.sim.set_agent_position(self.ego_id, (ego.x, ego.y))
        self.sim.set_agent_velocity(self.ego_id, (ego.vx, ego.vy))
        self.sim.set_agent_pref_velocity(self.ego_id, (ego.vx, ego.vy))

    def step(self, dt: float, ego: EgoState | Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
        """Advance every agent by `dt` seconds around the ego (None: no ego) and return states()."""
        if self.grid is None:
            raise RuntimeError("AgentManager.step called before reset(spec, rng)")
        g = self.grid
        self._set_ego(_as_ego(ego))
        self.time += dt
        pref = np.zeros((self.n, 2))
        pinned = np.zeros(self.n, dtype=bool)
        if self.n:
            nodes = g.nearest_node(self.pos)
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
        new_pos = np.array([get_pos(i).to_tuple() for i in range(self.n)]).reshape(self.n, 2)
        new_vel = np.array([get_vel(i).to_tuple() for i in range(self.n)]).reshape(self.n, 2)
        # ORCA's obstacle handling is not a hard guarantee at concave corners: an agent whose step would leave
        # the walkable area stays put instead; so do members standing in a group (see sim.agents.behaviours).
        bad = (~g.is_walkable(new_pos) | pinned) if self.n else pinned
        for i in np.flatnonzero(bad):
            sim.set_agent_position(int(i), (float(self.pos[i, 0]), float(self.pos[i, 1])))
            sim.set_agent_velocity(int(i), (0.0, 0.0))
            new_pos[i], new_vel[i] = self.pos[i], 0.0
        self.pos, self.vel = new_pos, new_vel
        self.trail[:-1] = self.trail[1:]  # oldest first; in place, no new [trail, n, 2] array per step
        self.trail[-1] = self.pos
        return self.states()

    def _set_orca_radii(self, pinned: np.ndarray) -> None:
        """ORCA radii: radius + safety_margin, plus STAND_MARGIN for agents that hold their spot (no reciprocity)."""
        want = self.radius + self.config["safety_margin"] + STAND_MARGIN * pinned
        for i in np.flatnonzero(want != self._orca_radius).tolist():
            self.sim.set_agent_radius(i, float(want[i]))
        self._orca_radius = want

    def _update_goals(self, dt: float, nodes: np.ndarray) -> None:
        c, g = self.config, self.grid
        idle = self.movement == IDLE
        if idle.any():
            self.idle_left[idle] -= dt
            for i in np.flatnonzero(idle & (self.idle_left <= 0)).tolist():
                if self.movement[i] != IDLE:
                    continue  # its group's decision already sent it off
                if self.groups.of[i] >= 0:
                    self.groups.stand_over(self, i, nodes)
                else:
                    self._new_goal(i, int(nodes[i]))
            idle = self.movement == IDLE
        moving = np.flatnonzero(~idle)
        if not len(moving):
            return
        d = self.pos[moving] - self.goal[moving]
        to_goal = np.sqrt((d * d).sum(1))  # == np.linalg.norm(axis=1), without its dispatch cost
        stall = self.stall[moving]
        arrived = (to_goal < c["arrive_radius"]) | ((to_goal < c["crowded_arrive_radius"]) & (stall >= c["stuck_steps"] // 2))
        dist = g.distance(nodes[moving], self.site[moving], planned=True)  # _new_goal planned every goal's field
        progressed = dist < self.best[moving] - c["stuck_progress"]
        go = ~arrived & progressed
        held = ~arrived & ~progressed
        stall = np.where(go, 0, stall + held)
        best = np.where(go, dist, self.best[moving])
        # Progress during the side-step counts from where it began, not from before being pushed back.
        restart = held & (stall == c["stuck_steps"])
        best[restart] = dist[restart]
        self.stall[moving], self.best[moving] = stall, best
        if arrived.any():
            for i in moving[arrived].tolist():
                late = self.time - self.goal_t0[i] > self.budget[i]
                self.counts["late" if late else "in_time"] += 1
                self.cross_counts["done"] += int(self.crossing[i])
                self.crossing[i] = False
                if self.groups.of[i] >= 0:
                    self.groups.arrived(self, i)
                elif self.rng.random() < c["idle_prob"]:
                    self.movement[i] = IDLE
                    self.idle_left[i] = self.rng.uniform(*c["idle_time"])
                else:
                    self._new_goal(i, int(nodes[i]))
        for i in moving[held & (stall >= c["regoal_steps"])].tolist():
            if self.groups.of[i] >= 0:
                self.groups.dissolve(self, int(self.groups.of[i]))
            self._new_goal(i, int(nodes[i]), abandon=True)

    def _preferred(self, nodes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        g, c = self.grid, self.config
        sites = self.site[idx]
        pos = self.pos[idx]
        steps = c["lookahead_cells"]
        carrot = g.node_xy(g.lookahead(nodes, sites, steps, planned=True))
        # Keep right: shortest paths hug the same inner edges in both directions, so opposing flows would meet
        # head-on in one lane (ORCA then herds the weaker side backwards); a right offset forms two lanes.
        d = carrot - pos
        norm = np.maximum(np.sqrt((d * d).sum(1))[:, None], 1e-6)
        shifted = carrot + np.stack([d[:, 1], -d[:, 0]], 1) / norm * c["keep_right"]
        ok = g.is_free(shifted)
        carrot[ok] = shifted[ok]
        # A carrot behind a concave corner (a crosswalk mouth) would press the agent into the curb: fall back
        # to nearer points of the path (steps, steps/2, ..., 1 cells; the last without a check) until one is in
        # sight. The rungs are looked up at once for the few agents that need them.
        visible = self.sim.query_visibility
        pos_l, rad_l = pos.tolist(), self.radius[idx].tolist()
        blocked = [k for k, (p, q, r) in enumerate(zip(pos_l, carrot.tolist(), rad_l)) if not visible(p, q, r)]
        if blocked:
            b = np.asarray(blocked)
            rungs = [g.node_xy(g.lookahead(nodes[b], sites[b], s, planned=True)).tolist()
                     for s in JUMPS[::-1] if s <= steps]
            for m, k in enumerate(blocked):
                for rung in rungs[:-1]:
                    if visible(pos_l[k], rung[m], rad_l[k]):
                        carrot[k] = rung[m]
                        break
                else:
                    carrot[k] = rungs[-1][m]
        # Close to the site the field's single target cell would pull everyone to one point: aim at the own goal.
        goal = self.goal[idx]
        near = g.distance(nodes, sites, planned=True) < 1.5 * c["goal_spread"]
        carrot[near] = goal[near]
        d = carrot - pos
        norm = np.sqrt((d * d).sum(1))[:, None]
        direction = np.where(norm > 1e-6, d / np.maximum(norm, 1e-6), 0.0)
        dg = goal - pos
        speed = np.minimum(self.speed[idx], np.maximum(np.sqrt((dg * dg).sum(1)), 0.3))
        stall = self.stall[idx]
        stuck = stall >= c["stuck_steps"]
        if stuck.any():
            # Side-step (the rotate half of push-and-rotate): to the right when there is room, else to the left,
            # switching sides every `stuck_steps` so an agent pinned against a curb or a wall gets out.
            dx, dy = direction[stuck, 0].copy(), direction[stuck, 1].copy()
            right = np.stack([dy, -dx], 1)
            probe = pos[stuck] + right * 1.0
            sign = np.where(g.is_free(probe), 1.0, -1.0)
            phase = (stall[stuck] - c["stuck_steps"]) // c["stuck_steps"]
            sign = np.where(phase % 2 == 1, -sign, sign)
            ang = -1.2 * sign
            cs, sn = np.cos(ang), np.sin(ang)
            direction[stuck, 0], direction[stuck, 1] = cs * dx - sn * dy, sn * dx + cs * dy
        return direction * speed[:, None]

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
        return {**self.groups.stats(), "crossings_started": self.cross_counts["started"],
                "crossings_done": self.cross_counts["done"], "crossing_now": int(self.crossing.sum()),
                "pushes": self.push.started, "pushes_done": self.push.finished}

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
        self._new_goal(i, int(g.nearest_node(self.pos[i:i + 1])[0]), site=site, goal_xy=p[0],
                       speed=self._walking_speed(i) if speed is None else float(speed))

    def overdue(self) -> int:
        """Agents still travelling whose time budget has already run out (goals that will count as late)."""
        moving = self.movement != IDLE
        return int(np.sum(moving & (self.time - self.goal_t0 > self.budget)))
