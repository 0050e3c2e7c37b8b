"""The crowd's ORCA side: the ego as ORCA sees it, the pyrvo simulators of a scene and their obstacles (OrcaCrowd)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyrvo

from sim.agents.behaviours import STAND_MARGIN
from sim.agents.crowd_state import CrowdState
from sim.agents.kinds import AGENT_KINDS, KIND_NAMES
from sim.agents.navgrid import NavGrid, boundary_segments
from sim.scene.scene import Scene


@dataclass(frozen=True)
class EgoState:
    """The ego as ORCA sees it: centre, velocity and radius in the world frame."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    radius: float = 0.5


def as_ego(ego: EgoState | Mapping[str, float] | Sequence[float] | None) -> EgoState | None:
    """The ego as an EgoState, from one, a mapping of its fields or a sequence of them (None stays None)."""
    if ego is None or isinstance(ego, EgoState):
        return ego
    if isinstance(ego, Mapping):
        return EgoState(**{k: float(v) for k, v in ego.items()})
    return EgoState(*(float(v) for v in ego))


class OrcaCrowd:
    """The crowd's ORCA side on one scene: its obstacles, one pyrvo simulator per agent capacity, the ego's slot.

    AgentManager makes one per scene (processing the obstacles costs ~0.2 s, more than a short episode) and calls
    `start` at every reset; the agents' state reaches it only through the arguments of its methods.
    """

    def __init__(self, scene: Scene, grid: NavGrid) -> None:
        self.obstacles = orca_obstacles(scene, grid)  # object footprints and walkable-boundary segments
        self.origin = (float(grid.origin[0]), float(grid.origin[1]))  # the grid corner unused slots park beyond
        self.sims: dict[int, Any] = {}  # agent capacity (a power of two) -> its pyrvo.RVOSimulator
        self.sim: Any = None  # this episode's simulator (start picks it)
        self.ego_id = 0  # the ego's ORCA slot: the one after the agents' capacity
        self.radius = np.zeros(0)  # [n] each agent's ORCA radius as last set
        self.plain = True  # `radius` holds no standing margin (radius + safety_margin for every agent)
        self.ego_radius = float("nan")  # the ego's ORCA radius as last set (nan: set it on the next placement)

    def start(self, state: CrowdState, config: Mapping[str, Any]) -> None:
        """Ready the simulator of `state.n` agents for an episode: every slot rewritten, the ego's parked."""
        c = config
        # Each scene keeps one simulator per agent capacity and reuses it. RVO2's clearAgents is never called (it
        # left the agent k-d tree pointing at deleted agents): every slot is rewritten each episode (position,
        # velocity, preference, radius, speed) and unused slots are parked far apart, so an episode's state does
        # not depend on the episodes before it.
        cap = 1 << max(state.n - 1, 0).bit_length()
        sim = self.sims.get(cap)
        if sim is None:
            sim = self._simulator(cap, c)
            self.sims[cap] = sim
        self.sim, self.ego_id = sim, cap
        for i in range(cap + 1):
            if i < state.n:
                kind = AGENT_KINDS[KIND_NAMES[state.kind_idx[i]]]
                top = (kind.run_speed or kind.pref_speed) + 3.0 * kind.speed_std
                pos = (float(state.pos[i, 0]), float(state.pos[i, 1]))
                radius = float(state.radius[i] + c["safety_margin"])
            else:
                pos, radius, top = self.parked(i), 0.1, 0.0
            sim.set_agent_position(i, pos)
            sim.set_agent_velocity(i, (0.0, 0.0))
            sim.set_agent_pref_velocity(i, (0.0, 0.0))
            sim.set_agent_radius(i, radius)
            sim.set_agent_max_speed(i, top)
        self.radius = state.radius + c["safety_margin"]
        self.plain = True
        self.ego_radius = float("nan")

    def _simulator(self, cap: int, config: Mapping[str, Any]) -> Any:
        """A new simulator with `cap` parked agent slots, the ego's slot after them, and the scene's obstacles."""
        c = config
        sim = pyrvo.RVOSimulator(
            0.1, c["neighbor_dist"], c["max_neighbors"], c["time_horizon"], c["time_horizon_obst"], 0.3, 2.0
        )
        for i in range(cap):
            sim.add_agent(
                self.parked(i),
                c["neighbor_dist"],
                c["max_neighbors"],
                c["time_horizon"],
                c["time_horizon_obst"],
                0.1,
                0.0,
            )
        # The ego is the last ORCA agent; it starts parked far away so it influences nobody until placed. Its max
        # speed is 0: agents see its position, velocity and radius only, and its own ORCA velocity is never used
        # (set_ego overwrites both before every step), but RVO2 would gather every obstacle within
        # time_horizon_obst * max speed of it each step (about half of do_step at 50 m/s).
        sim.add_agent(
            self.parked(cap),
            c["neighbor_dist"],
            c["max_neighbors"],
            c["time_horizon"],
            c["time_horizon_obst"],
            0.1,
            0.0,
        )
        for vertices in self.obstacles:
            sim.add_obstacle(vertices)
        sim.process_obstacles()
        return sim

    def parked(self, slot: int = 0) -> tuple[float, float]:
        """A far-away spot for an unused ORCA slot: 20 m apart, beyond any neighbour distance."""
        return (self.origin[0] - 1e4 - 20.0 * slot, self.origin[1] - 1e4)

    def set_ego(self, ego: EgoState | None, margin: float) -> None:
        """Put the ego (radius + `margin`: it does not reciprocate) into its slot, or park it when there is none."""
        sim = self.sim
        if ego is None:
            sim.set_agent_position(self.ego_id, self.parked(self.ego_id))
            sim.set_agent_velocity(self.ego_id, (0.0, 0.0))
            sim.set_agent_pref_velocity(self.ego_id, (0.0, 0.0))
            return
        radius = float(ego.radius + margin)
        if radius != self.ego_radius:  # the ego's footprint does not change within an episode
            sim.set_agent_radius(self.ego_id, radius)
            self.ego_radius = radius
        sim.set_agent_position(self.ego_id, (ego.x, ego.y))
        sim.set_agent_velocity(self.ego_id, (ego.vx, ego.vy))
        sim.set_agent_pref_velocity(self.ego_id, (ego.vx, ego.vy))

    def set_radii(self, radius: np.ndarray, safety_margin: float, pinned: np.ndarray) -> None:
        """ORCA radii: `radius` + safety_margin, plus STAND_MARGIN for the `pinned` agents (they do not reciprocate)."""
        if not pinned.any() and self.plain:
            return  # nobody holds a spot, nor did last step: the radii are radius + safety_margin already
        want = radius + safety_margin + STAND_MARGIN * pinned
        for i in np.flatnonzero(want != self.radius).tolist():
            self.sim.set_agent_radius(i, float(want[i]))
        self.radius = want
        self.plain = not pinned.any()

    def step(self, dt: float, pref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One ORCA step of `dt` seconds toward the preferred velocities `pref` [n, 2]: new positions and velocities."""
        n = len(pref)
        sim = self.sim
        sim.set_time_step(float(dt))
        set_pref = sim.set_agent_pref_velocity
        for i, v in enumerate(pref.tolist()):  # pyrvo has no batch setters; one list walk beats n numpy reads
            set_pref(i, v)
        sim.do_step()
        get_pos, get_vel = sim.get_agent_position, sim.get_agent_velocity
        out = np.array([get_pos(i).to_tuple() + get_vel(i).to_tuple() for i in range(n)]).reshape(n, 4)
        return out[:, :2].copy(), out[:, 2:].copy()

    def place(self, i: int, xy: tuple[float, float]) -> None:
        """Put agent i at rest on `xy`."""
        self.sim.set_agent_position(i, xy)
        self.sim.set_agent_velocity(i, (0.0, 0.0))


def orca_obstacles(scene: Scene, grid: NavGrid) -> list[list[tuple[float, float]]]:
    """ORCA obstacles of a scene: object footprints (counter-clockwise) and walkable-boundary segments."""
    out = []
    for o in scene.objects:
        pts = np.asarray(o.get("footprint") or [], dtype=np.float64)
        if len(pts) >= 3:
            area2 = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
            out.append([tuple(p) for p in (pts if area2 > 0 else pts[::-1]).tolist()])  # RVO2 wants CCW
    out += [[a, b] for a, b in boundary_segments(grid.cells > 0, grid.origin, grid.res)]
    return out
