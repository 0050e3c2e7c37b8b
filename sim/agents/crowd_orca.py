"""The crowd's ORCA side: the ego as ORCA sees it, a scene's obstacles and this episode's ORCA agents (OrcaCrowd)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import typed

from sim.agents.behaviours import STAND_MARGIN
from sim.agents.crowd_state import CrowdState
from sim.agents.kinds import AGENT_KINDS, KIND_NAMES
from sim.agents.navgrid import NavGrid, boundary_segments
from sim.agents.orca_kernels import ObstacleIndex, orca_crowds, visible_many
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
    """The crowd's ORCA side on one scene: its obstacle index, this episode's ORCA agents and the ego among them.

    AgentManager makes one per scene (indexing the obstacles costs more than a short episode) and calls `start` at
    every reset; the agents' state reaches it only through the arguments of its methods. The solver is
    `sim.agents.orca_kernels` (RVO2's algorithm in numba); `step_crowds` steps many crowds in one call.
    """

    def __init__(self, scene: Scene, grid: NavGrid, config: Mapping[str, Any]) -> None:
        self.index = ObstacleIndex.build(orca_obstacles(scene, grid), obstacle_reach(config))
        self.config = config
        # This episode's ORCA agents, the ego last (it moves none of its own: the env places it every step).
        self.pos = np.zeros((1, 2))
        self.vel = np.zeros((1, 2))
        self.radius = np.full(1, 0.1)  # [n + 1] ORCA radii as last set
        self.max_speed = np.zeros(1)
        self.moves = np.zeros(1, dtype=np.bool_)
        self.plain = True  # the agents' radii hold no standing margin (radius + safety_margin for every agent)

    @property
    def n(self) -> int:
        """Agents this episode (the ego not counted)."""
        return len(self.pos) - 1

    def start(self, state: CrowdState, config: Mapping[str, Any]) -> None:
        """Ready the ORCA agents of an episode: `state`'s at rest with their kinds' top speeds, the ego parked."""
        n = state.n
        self.config = config
        self.pos = np.zeros((n + 1, 2))
        self.pos[:n] = state.pos
        self.pos[n] = self.parked()
        self.vel = np.zeros((n + 1, 2))
        self.radius = np.append(state.radius + config["safety_margin"], 0.1)
        self.max_speed = np.zeros(n + 1)
        for i in range(n):
            kind = AGENT_KINDS[KIND_NAMES[state.kind_idx[i]]]
            self.max_speed[i] = (kind.run_speed or kind.pref_speed) + 3.0 * kind.speed_std
        self.moves = np.ones(n + 1, dtype=np.bool_)
        self.moves[n] = False
        self.plain = True

    def parked(self) -> tuple[float, float]:
        """A far-away spot for the ego when there is none: beyond any neighbour distance of the scene."""
        return (float(self.index.origin[0]) - 1e4, float(self.index.origin[1]) - 1e4)

    def set_ego(self, ego: EgoState | None, margin: float) -> None:
        """Put the ego (radius + `margin`: it does not reciprocate) in its slot, or park it when there is none."""
        n = self.n
        if ego is None:
            self.pos[n] = self.parked()
            self.vel[n] = 0.0
            return
        self.radius[n] = float(ego.radius + margin)
        self.pos[n] = (ego.x, ego.y)
        self.vel[n] = (ego.vx, ego.vy)

    def set_radii(self, radius: np.ndarray, safety_margin: float, pinned: np.ndarray) -> None:
        """ORCA radii: `radius` + safety_margin, plus STAND_MARGIN for the `pinned` agents (they do not reciprocate)."""
        if not pinned.any() and self.plain:
            return
        self.radius[: self.n] = radius + safety_margin + STAND_MARGIN * pinned
        self.plain = not pinned.any()

    def place(self, i: int, xy: tuple[float, float]) -> None:
        """Put agent i at rest on `xy`."""
        self.pos[i] = xy
        self.vel[i] = 0.0

    def visible(self, p: np.ndarray, q: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Whether discs of `radius` [k] see points q [k, 2] from p [k, 2] past the obstacles (RVO2's
        queryVisibility: an edge blocks a disc crossing it from outside)."""
        ix = self.index
        return visible_many(
            np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(q, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(radius, dtype=np.float64).reshape(-1),
            ix.point,
            ix.nxt,
            float(ix.origin[0]),
            float(ix.origin[1]),
            ix.shape[0],
            ix.shape[1],
            ix.start,
            ix.items,
        )


_LISTS: list[tuple[tuple[ObstacleIndex, ...], tuple[Any, ...]]] = []  # recent calls' indices and their lists
_KEEP_LISTS = 8  # calls remembered: a process's envs (a vector of PyBullet envs, a batched env) each find theirs


def index_lists(indices: Sequence[ObstacleIndex]) -> tuple[Any, ...]:
    """The indices' arrays as `orca_crowds` takes them: numba typed lists (one compiled kernel whatever the number of
    scenes; a tuple would compile one a length), origins and shapes as arrays. Scenes change seldom: the lists of
    the last few sets of indices are reused."""
    for k, (kept, lists) in enumerate(_LISTS):
        if len(kept) == len(indices) and all(a is b for a, b in zip(kept, indices)):
            _LISTS.append(_LISTS.pop(k))  # most recently used last
            return lists
    lists = (
        *(typed.List([getattr(ix, name) for ix in indices]) for name in ("point", "nxt", "prv", "direction", "convex")),
        np.array([ix.origin for ix in indices], dtype=np.float64).reshape(-1, 2),
        np.array([ix.shape for ix in indices], dtype=np.int64).reshape(-1, 2),
        typed.List([ix.start for ix in indices]),
        typed.List([ix.items for ix in indices]),
        typed.List([ix.item_d for ix in indices]),
    )
    _LISTS.append((tuple(indices), lists))
    del _LISTS[:-_KEEP_LISTS]
    return lists


def obstacle_reach(config: Mapping[str, Any]) -> float:
    """Metres within which an ORCA agent looks for obstacle edges, at most: RVO2's range (time_horizon_obst x max
    speed + radius) of the fastest and widest kind, with the safety and standing margins."""
    top = max((k.run_speed or k.pref_speed) + 3.0 * k.speed_std for k in AGENT_KINDS.values())
    widest = max(k.radius for k in AGENT_KINDS.values())
    return float(config["time_horizon_obst"]) * top + widest + float(config["safety_margin"]) + STAND_MARGIN + 0.01


def step_crowds(
    crowds: Sequence[OrcaCrowd], dt: float, prefs: Sequence[np.ndarray]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """One ORCA step of every crowd in one compiled call (`orca_kernels.orca_crowds`, the crowds shared among numba's
    threads); crowd c's agents head for `prefs[c]` [n_c, 2]. The crowds keep their new positions and velocities and
    each gets (positions, velocities) [n_c, 2] back. Every crowd's ORCA keys must be equal (one env config)."""
    if not crowds:
        return []
    c0 = crowds[0].config
    keys = ("neighbor_dist", "max_neighbors", "time_horizon", "time_horizon_obst")
    for crowd in crowds[1:]:
        if any(crowd.config[k] != c0[k] for k in keys):
            raise ValueError(f"crowds stepped together need equal ORCA keys {keys}")
    sizes = np.array([len(c.pos) for c in crowds], dtype=np.int64)
    start = np.zeros(len(crowds) + 1, dtype=np.int64)
    np.cumsum(sizes, out=start[1:])
    pref = np.zeros((int(start[-1]), 2))
    for k, (crowd, p) in enumerate(zip(crowds, prefs)):
        pref[start[k] : start[k] + crowd.n] = p
    # One obstacle index per distinct scene (envs may share one).
    scenes: dict[int, int] = {}
    order: list[ObstacleIndex] = []
    scene_of = np.empty(len(crowds), dtype=np.int64)
    for k, crowd in enumerate(crowds):
        key = id(crowd.index)
        if key not in scenes:
            scenes[key] = len(order)
            order.append(crowd.index)
        scene_of[k] = scenes[key]
    new_pos, new_vel = orca_crowds(
        start,
        scene_of,
        np.concatenate([c.pos for c in crowds]),
        np.concatenate([c.vel for c in crowds]),
        pref,
        np.concatenate([c.radius for c in crowds]),
        np.concatenate([c.max_speed for c in crowds]),
        np.concatenate([c.moves for c in crowds]),
        float(dt),
        float(c0["neighbor_dist"]),
        int(c0["max_neighbors"]),
        float(c0["time_horizon"]),
        float(c0["time_horizon_obst"]),
        *index_lists(order),
    )
    out = []
    for k, crowd in enumerate(crowds):
        lo, hi = int(start[k]), int(start[k + 1])
        crowd.pos, crowd.vel = new_pos[lo:hi].copy(), new_vel[lo:hi].copy()
        out.append((crowd.pos[: crowd.n].copy(), crowd.vel[: crowd.n].copy()))
    return out


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
