"""Movements beyond idle, walk and run: standing groups and road crossings.

Standing groups (`group_prob`, `group_size`, `group_time`, `group_disperse_prob`): at reset about `group_prob`
of the agents whose kind can stand in a group (pedestrians and wheelchair users) are gathered into groups of
`group_size` = [min, max] members, standing in a ring on a sidewalk (neighbours' ORCA discs 5 cm apart, so a
group of four pedestrians spans 1.2 m) for a time drawn from `group_time`. When the time is up the group
either disperses (`group_disperse_prob`: every member takes its own goal) or walks on together: the members share
one goal site and the slowest member's walking speed, their goals form the same ring around one goal cell, and
once all of them have arrived they stand together again. A member that abandons its goal (stuck for
`regoal_steps`) dissolves its group. Standing members hold their spots: ORCA would otherwise let anyone walking
up behind a member herd it along (ORCA shares avoidance equally), so the crowd keeps them in place and, like
the ego, gives them `STAND_MARGIN` more ORCA radius; a member in the way of someone who cannot get past is
moved aside by the push (sim.agents.deadlock), which treats standing agents as the ones to yield.

Crossing (`cross_prob`): the chance that a new goal lies across a road. Roads are not walkable, so any path
across one already uses a crosswalk; a crossing goal makes it happen on purpose: the agent picks the crosswalk
whose near end is closest to it among those it stands on the near side of and walks to a goal site 2 m past
the far end (one site per crosswalk end, added to the navigation grid after the farthest-point sites).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.agents.crowd_goals import GoalSetter, walking_speed
from sim.agents.crowd_state import CrowdState
from sim.agents.kinds import IDLE, KIND_NAMES
from sim.agents.navgrid import NavGrid
from sim.scene.grid import RAMP, SIDEWALK
from sim.scene.scene import Scene

GROUP_KINDS = ("pedestrian", "wheelchair_user")
CROSS_BEYOND = 2.0  # metres past a crosswalk end (over the curb ramp) where a crossing goal lies
CROSS_SNAP = 1.5  # a crossing site must be a planning cell this close to that point
CENTRE_TRIES = 256  # candidate group centres checked at once, nearest first
STAND_MARGIN = 0.15  # m added to a standing member's ORCA radius: it does not reciprocate (as the ego's margin)


def ring_offsets(size: int, spacing: float, angle: float) -> np.ndarray:
    """Offsets [size, 2] of `size` points on a circle, neighbours `spacing` apart, the first at `angle`."""
    rho = spacing / 2.0 if size == 2 else spacing / (2.0 * np.sin(np.pi / size))
    angles = angle + 2.0 * np.pi * np.arange(size) / size
    return rho * np.stack([np.cos(angles), np.sin(angles)], 1)


def ring_spacing(radius: np.ndarray, safety_margin: float, members: np.ndarray) -> float:
    """Centre distance of neighbours in a group's ring: ORCA discs (radius + safety_margin) 5 cm apart."""
    return 2.0 * (float(radius[members].max()) + safety_margin) + 0.05


class Crossings:
    """Crosswalk ends as goal sites, and the choice of a crossing for an agent."""

    def __init__(self) -> None:
        self.near = np.zeros((0, 2))  # approach point on the side the agent starts from
        self.far = np.zeros((0, 2))  # goal point past the far end
        self.sites = np.zeros(0, dtype=np.int64)

    def setup(self, scene: Scene, grid: NavGrid) -> None:
        """Add one goal site 2 m past each end of every crosswalk of `scene` (skipped where no sidewalk is there)."""
        near, far, sites = [], [], []
        for cw in scene.crosswalks:
            ends = np.asarray(cw.get("ends") or [], dtype=np.float64)
            if ends.shape != (2, 2) or not np.isfinite(ends).all():
                continue
            for a, b in ((ends[0], ends[1]), (ends[1], ends[0])):
                length = float(np.hypot(*(b - a)))
                if length < 1e-6:
                    continue
                u = (b - a) / length
                target = b + u * CROSS_BEYOND
                node = int(grid.nearest_node(target[None])[0])
                xy = grid.node_xy(np.array([node]))[0]
                i, j = (int(v[0]) for v in grid.cell_of(xy[None]))
                if np.hypot(*(xy - target)) > CROSS_SNAP or grid.cells[i, j] not in (SIDEWALK, RAMP):
                    continue
                near.append(a - u * CROSS_BEYOND)
                far.append(xy)
                sites.append(grid.add_site(node))
        self.near = np.asarray(near, dtype=np.float64).reshape(-1, 2)
        self.far = np.asarray(far, dtype=np.float64).reshape(-1, 2)
        self.sites = np.asarray(sites, dtype=np.int64)

    def pick(self, xy: np.ndarray) -> int | None:
        """Goal site across the road from `xy` via the nearest crosswalk it is on the near side of; None if none."""
        if not len(self.sites):
            return None
        dn = np.hypot(*(self.near - xy).T)
        df = np.hypot(*(self.far - xy).T)
        ok = dn < df
        if not ok.any():
            return None
        return int(self.sites[int(np.argmin(np.where(ok, dn, np.inf)))])


class Groups:
    """Standing groups: formed at reset, standing for `group_time`, then dispersing or walking on together.

    The members' positions, movements and goals live in the crowd's state, passed to every method; new goals
    come from the GoalSetter the crowd passes.
    """

    def __init__(self) -> None:
        self.of = np.zeros(0, dtype=np.int64)  # group id of every agent, -1 for none
        self.spot = np.zeros((0, 2))  # where each standing member stands (NaN: not standing in a group)
        self.members: dict[int, np.ndarray] = {}
        self.walking: dict[int, bool] = {}
        self.formed = self.stands = self.dispersed = self.walks = 0

    def reset(
        self,
        state: CrowdState,
        grid: NavGrid,
        area: Any,
        config: Mapping[str, Any],
        rng: np.random.Generator,
        clear: list[tuple[float, float, float]],
    ) -> None:
        """Gather about group_prob of the eligible agents into standing rings (moves them; call before ORCA setup).

        Rings stand on sidewalk planning cells inside `area` (None: anywhere), outside the `clear` discs (x, y, r).
        """
        self.of = np.full(state.n, -1, dtype=np.int64)
        self.spot = np.full((state.n, 2), np.nan)
        self.members, self.walking = {}, {}
        self.formed = self.stands = self.dispersed = self.walks = 0
        if config["group_prob"] <= 0 or state.n < 2:
            return
        kinds = np.array([KIND_NAMES[k] for k in state.kind_idx])
        order = rng.permutation(np.flatnonzero(np.isin(kinds, GROUP_KINDS)))
        target = round(config["group_prob"] * state.n)
        lo, hi = (int(bound) for bound in config["group_size"])
        k = placed = 0
        while placed < target and len(order) - k >= lo:
            size = min(int(rng.integers(lo, hi + 1)), len(order) - k)
            members = order[k : k + size]
            k += size
            if self._place(state, grid, area, config, members, rng, clear):
                gid = len(self.members)
                self.members[gid], self.walking[gid] = members, False
                self.of[members] = gid
                state.movement[members] = IDLE
                state.idle_left[members] = rng.uniform(*config["group_time"])
                self.spot[members] = state.pos[members]
                placed += size
                self.formed += 1
                self.stands += 1

    def _place(
        self,
        state: CrowdState,
        grid: NavGrid,
        area: Any,
        config: Mapping[str, Any],
        members: np.ndarray,
        rng: np.random.Generator,
        clear: list[tuple[float, float, float]],
    ) -> bool:
        """Move `members` into a ring on a sidewalk near the first one's spawn point; False if none fits nearby."""
        spacing = ring_spacing(state.radius, config["safety_margin"], members)
        offsets = ring_offsets(len(members), spacing, float(rng.uniform(0.0, 2.0 * np.pi)))
        centres = grid.node_xy(np.arange(grid.n_nodes))
        dist = np.hypot(*(centres - state.pos[members[0]]).T)
        cand = np.flatnonzero(dist < 15.0)
        cand = cand[np.argsort(dist[cand], kind="stable")][:CENTRE_TRIES]
        if area is not None:
            import shapely

            cand = cand[shapely.contains_xy(area, centres[cand, 0], centres[cand, 1])]
        spread = float(np.hypot(*offsets.T).max())
        for x, y, radius in clear:
            cand = cand[np.hypot(centres[cand, 0] - x, centres[cand, 1] - y) > radius + spread]
        if not len(cand):
            return False
        slots = centres[cand][:, None, :] + offsets[None]  # [k, size, 2]
        flat = slots.reshape(-1, 2)
        i, j = grid.cell_of(flat)
        ok = (grid.is_free(flat) & (grid.cells[i, j] == SIDEWALK)).reshape(len(cand), -1).all(1)
        others = np.setdiff1d(np.arange(state.n), members)
        if len(others):
            # Other agents (groups placed earlier included) keep the spawn clearance from every slot.
            gap = np.linalg.norm(flat[:, None, :] - state.pos[others][None], axis=2)
            need = (
                np.tile(state.radius[members], len(cand))[:, None]
                + state.radius[others][None]
                + config["spawn_clearance"]
            )
            ok &= (gap >= need).reshape(len(cand), -1, len(others)).all((1, 2))
        hit = np.flatnonzero(ok)
        if not len(hit):
            return False
        state.pos[members] = slots[hit[0]]
        return True

    def stand_over(
        self,
        state: CrowdState,
        rng: np.random.Generator,
        config: Mapping[str, Any],
        i: int,
        nodes: np.ndarray,
        set_goal: GoalSetter,
    ) -> None:
        """Agent i's group has stood long enough: it disperses or walks on together to a shared goal."""
        gid = int(self.of[i])
        members = self.members[gid]
        self.spot[members] = np.nan
        if rng.random() < config["group_disperse_prob"]:
            self.dissolve(state, gid)
            self.dispersed += 1
            for k in members.tolist():
                set_goal(k, int(nodes[k]))
            return
        lead = int(members[0])
        set_goal(lead, int(nodes[lead]))
        crossing = bool(state.crossing[lead])
        speed = min(float(state.speed[lead]), *(walking_speed(state, int(k), rng) for k in members[1:]))
        spacing = ring_spacing(state.radius, config["safety_margin"], members)
        ring = state.goal[lead] + ring_offsets(len(members), spacing, float(rng.uniform(0.0, 2.0 * np.pi)))
        for k, xy in zip(members.tolist(), ring):
            set_goal(k, int(nodes[k]), site=int(state.site[lead]), goal_xy=xy, speed=speed)
        state.crossing[members] = crossing
        if crossing:
            state.cross_counts["started"] += len(members) - 1  # the lead's crossing was counted when it was drawn
        self.walking[gid] = True
        self.walks += 1

    def arrived(self, state: CrowdState, rng: np.random.Generator, config: Mapping[str, Any], i: int) -> None:
        """A walking member reached its goal: it waits; once all have, the group stands again."""
        gid = int(self.of[i])
        state.movement[i] = IDLE
        state.idle_left[i] = np.inf
        members = self.members[gid]
        if (state.movement[members] == IDLE).all():
            state.idle_left[members] = rng.uniform(*config["group_time"])
            self.spot[members] = state.pos[members]
            self.walking[gid] = False
            self.stands += 1

    def dissolve(self, state: CrowdState, gid: int) -> None:
        """End group `gid`: its members become single agents; those waiting for the others leave next step."""
        members = self.members.pop(gid)
        self.walking.pop(gid)
        self.of[members] = -1
        self.spot[members] = np.nan
        waiting = members[np.isinf(state.idle_left[members])]
        state.idle_left[waiting] = 0.0

    def standing(self, state: CrowdState) -> np.ndarray:
        """Bool mask of the members standing in their group now."""
        return ~np.isnan(self.spot[:, 0]) & (state.movement == IDLE)

    def stats(self) -> dict[str, int]:
        """Groups formed, standing now, walking now, stands so far, dispersals and walks together."""
        walking = sum(self.walking.values())
        return {
            "groups": len(self.members),
            "grouped_agents": int((self.of >= 0).sum()),
            "standing_groups": len(self.members) - walking,
            "walking_groups": walking,
            "formed": self.formed,
            "stands": self.stands,
            "dispersed": self.dispersed,
            "walks": self.walks,
        }
