"""PointNav's episode end (sim.envs.pointnav steps it once a step; sim.batched.episodes restates it for arrays)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Termination:
    """PointNav's episode end: success, out of route, or stuck (no new progress, or pinned in contact)."""

    success_completion: float
    out_of_route_distance: float
    stuck_distance: float
    stuck_steps: int
    collision_steps: int
    off_walkable_ends: bool  # leaving the walkable area ends the episode as out of route
    topple: float = float(np.radians(60.0))  # roll or pitch (rad) past which the machine has toppled
    max_cost: float = math.inf  # episode cost past which the episode ends (PPO-ET's rule; config None: never)
    mark: tuple[int, float] = (0, 0.0)  # (step, max progress) when progress last grew by stuck_distance
    contact_run: int = 0  # consecutive steps in contact

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> Termination:
        """A fresh detector for one episode of a task config."""
        return cls(float(cfg["success_completion"]), float(cfg["out_of_route_distance"]), float(cfg["stuck_distance"]),
                   int(cfg["stuck_steps"]), int(cfg["collision_steps"]), bool(cfg["terminate_off_walkable"]),
                   float(np.radians(cfg["topple_angle"])),
                   math.inf if cfg["max_episode_cost"] is None else float(cfg["max_episode_cost"]))

    def __call__(self, steps: int, max_progress: float, route_length: float, lateral: float,
                 on_walkable: Callable[[], bool], in_contact: bool) -> tuple[bool, bool, bool]:
        """(succeeded, out_of_route, stuck) after step `steps`; `on_walkable()` is asked only when it decides."""
        succeeded = max_progress >= self.success_completion * route_length
        out_of_route = (not succeeded) and (abs(lateral) > self.out_of_route_distance
                                            or (self.off_walkable_ends and not on_walkable()))
        self.contact_run = self.contact_run + 1 if in_contact else 0
        if max_progress >= self.mark[1] + self.stuck_distance:
            self.mark = (steps, max_progress)
        stuck = not (succeeded or out_of_route) and (
            (self.stuck_steps > 0 and steps - self.mark[0] >= self.stuck_steps)
            or (self.collision_steps > 0 and self.contact_run >= self.collision_steps))
        return succeeded, out_of_route, stuck
