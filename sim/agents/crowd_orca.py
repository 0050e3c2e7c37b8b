"""The crowd's ORCA side: the ego as ORCA sees it, the pyrvo simulators of a scene and their obstacles."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyrvo

from sim.agents.behaviours import STAND_MARGIN
from sim.agents.kinds import AGENT_KINDS, KIND_NAMES
from sim.agents.navgrid import boundary_segments
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
    """AgentManager's ORCA part: builds and reuses pyrvo simulators, parks unused slots, places the ego."""

    def _build_orca(self, scene: Scene, fresh: bool) -> None:
        c = self.config
        if fresh:
            self._obstacles = self._orca_obstacles(scene)
            self._sims: dict[int, Any] = {}
        # Processing the scene's obstacles (object footprints, walkable boundary) costs ~0.2 s, more than a short
        # episode: each scene keeps one simulator per agent capacity (a power of two) and reuses it. RVO2's
        # clearAgents is never called (it left the agent k-d tree pointing at deleted agents): every slot is
        # rewritten each episode (position, velocity, preference, radius, speed) and unused slots are parked far
        # apart, so an episode's state does not depend on the episodes before it.
        cap = 1 << max(self.n - 1, 0).bit_length()
        sim = self._sims.get(cap)
        if sim is None:
            sim = pyrvo.RVOSimulator(
                0.1, c["neighbor_dist"], c["max_neighbors"], c["time_horizon"], c["time_horizon_obst"], 0.3, 2.0
            )
            for i in range(cap):
                sim.add_agent(
                    self._parked(i),
                    c["neighbor_dist"],
                    c["max_neighbors"],
                    c["time_horizon"],
                    c["time_horizon_obst"],
                    0.1,
                    0.0,
                )
            # The ego is the last ORCA agent; it starts parked far away so it influences nobody until placed.
            # Its max speed is 0: agents see its position, velocity and radius only, and its own ORCA velocity is
            # never used (_set_ego overwrites both before every step), but RVO2 would gather every obstacle within
            # time_horizon_obst * max speed of it each step (about half of do_step at 50 m/s).
            sim.add_agent(
                self._parked(cap),
                c["neighbor_dist"],
                c["max_neighbors"],
                c["time_horizon"],
                c["time_horizon_obst"],
                0.1,
                0.0,
            )
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
                pos, radius, top = self._parked(i), 0.1, 0.0
            sim.set_agent_position(i, pos)
            sim.set_agent_velocity(i, (0.0, 0.0))
            sim.set_agent_pref_velocity(i, (0.0, 0.0))
            sim.set_agent_radius(i, radius)
            sim.set_agent_max_speed(i, top)

    def _orca_obstacles(self, scene: Scene) -> list[list[tuple[float, float]]]:
        """ORCA obstacles of a scene: object footprints (counter-clockwise) and walkable-boundary segments."""
        out = []
        for o in scene.objects:
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

    def _set_ego(self, ego: EgoState | None) -> None:
        if ego is None:
            self.sim.set_agent_position(self.ego_id, self._parked(self.ego_id))
            self.sim.set_agent_velocity(self.ego_id, (0.0, 0.0))
            self.sim.set_agent_pref_velocity(self.ego_id, (0.0, 0.0))
            return
        radius = float(ego.radius + self.config["ego_margin"])
        if radius != self._ego_radius:  # the ego's footprint does not change within an episode
            self.sim.set_agent_radius(self.ego_id, radius)
            self._ego_radius = radius
        self.sim.set_agent_position(self.ego_id, (ego.x, ego.y))
        self.sim.set_agent_velocity(self.ego_id, (ego.vx, ego.vy))
        self.sim.set_agent_pref_velocity(self.ego_id, (ego.vx, ego.vy))

    def _set_orca_radii(self, pinned: np.ndarray) -> None:
        """ORCA radii: radius + safety_margin, plus STAND_MARGIN for agents that hold their spot (no reciprocity)."""
        if not pinned.any() and self._orca_plain:
            return  # nobody holds a spot, nor did last step: the radii are radius + safety_margin already
        want = self.radius + self.config["safety_margin"] + STAND_MARGIN * pinned
        for i in np.flatnonzero(want != self._orca_radius).tolist():
            self.sim.set_agent_radius(i, float(want[i]))
        self._orca_radius = want
        self._orca_plain = not pinned.any()
