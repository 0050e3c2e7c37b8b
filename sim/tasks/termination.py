"""PointNav's episode end (sim.envs.pointnav steps it once a step; sim.batched.episodes restates it for arrays)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class StepContext:
    """One step as the episode rules (Termination, Reward) see it: the machine's motion along its route and what it
    touched. The env builds it once a step; the rules read nothing else."""

    steps: int  # steps of the episode so far, this one included
    progress: float  # change of the arc length along the route this step (negative going back)
    new_progress: float  # growth of the largest arc length reached
    max_progress: float  # largest arc length reached
    route_length: float
    lateral: float  # signed offset from the route (left +)
    d_steer: float  # steering change from the last action
    speed: float
    tilt: float  # max(|roll|, |pitch|) of the machine, rad
    collided: bool  # touched a cost kind this step
    in_contact: bool  # touched anything this step
    cost_total: float  # the episode's cost so far
    on_walkable: Callable[[], bool]  # whether the machine is on the walkable area (asked only when it decides)


@dataclass(frozen=True)
class StepEnd:
    """How a step ends its episode, if it does: at most one of succeeded, out_of_route, stuck, toppled and
    cost_exceeded holds (in that order of precedence, cost_exceeded only when nothing else ended it)."""

    succeeded: bool = False
    out_of_route: bool = False
    stuck: bool = False
    toppled: bool = False
    cost_exceeded: bool = False

    @property
    def terminated(self) -> bool:
        """The episode ends here."""
        return self.succeeded or self.out_of_route or self.stuck or self.toppled or self.cost_exceeded

    @property
    def failed_in_place(self) -> bool:
        """Ended without success or leaving the route (stuck, toppled, over its cost): the reward's `stuck` term."""
        return self.stuck or self.toppled or self.cost_exceeded


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

    def __call__(self, step: StepContext) -> StepEnd:
        """How `step` ends the episode; `step.on_walkable()` is asked only when it decides."""
        succeeded = step.max_progress >= self.success_completion * step.route_length
        out_of_route = (not succeeded) and (abs(step.lateral) > self.out_of_route_distance
                                            or (self.off_walkable_ends and not step.on_walkable()))
        self.contact_run = self.contact_run + 1 if step.in_contact else 0
        if step.max_progress >= self.mark[1] + self.stuck_distance:
            self.mark = (step.steps, step.max_progress)
        stuck = not (succeeded or out_of_route) and (
            (self.stuck_steps > 0 and step.steps - self.mark[0] >= self.stuck_steps)
            or (self.collision_steps > 0 and self.contact_run >= self.collision_steps))
        toppled = not succeeded and step.tilt > self.topple
        ended = succeeded or out_of_route or stuck or toppled
        return StepEnd(succeeded, out_of_route, stuck, toppled, not ended and step.cost_total > self.max_cost)
