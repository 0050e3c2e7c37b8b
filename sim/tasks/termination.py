"""PointNav's episode end, written once over arrays: `end_of_step` decides it for any number of envs (the batched env
passes its n envs, `Termination` the PyBullet env's one)."""

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
    building_contact: bool = False  # touched a building this step
    steer: float = 0.0  # this step's steering command in [-1, 1]
    speed_fraction: float = 0.0  # speed / the machine's top speed


@dataclass(frozen=True)
class StepEnd:
    """How a step ends its episode, if it does (`end_of_step`'s flags for one env)."""

    succeeded: bool = False
    out_of_route: bool = False
    stuck: bool = False
    toppled: bool = False
    cost_exceeded: bool = False
    crashed: bool = False  # ran into a building (`building_contact_ends`)

    @property
    def terminated(self) -> bool:
        """The episode ends here."""
        return self.succeeded or self.out_of_route or self.stuck or self.toppled or self.cost_exceeded or self.crashed

    @property
    def failed_in_place(self) -> bool:
        """Ended without success or leaving the route (stuck, toppled, over its cost, crashed into a building): the
        reward's `stuck` term."""
        return self.stuck or self.toppled or self.cost_exceeded or self.crashed


@dataclass(frozen=True)
class EndRules:
    """PointNav's episode-end rules, from a task config."""

    success_completion: float
    out_of_route_distance: float
    stuck_distance: float
    stuck_steps: int
    collision_steps: int
    off_walkable_ends: bool  # leaving the walkable area ends the episode as out of route
    topple: float  # roll or pitch (rad) past which the machine has toppled
    max_cost: float  # episode cost past which the episode ends (PPO-ET's rule; config None: never)
    out_of_route_ends: bool = True  # False: leaving the route is allowed, the machine may come back to it
    building_contact_ends: bool = False  # a step in contact with a building ends the episode (MetaUrban's SocialNav)

    @property
    def reads_walkable(self) -> bool:
        """Whether the end of a step depends on the machine being on the walkable area (a lookup a step)."""
        return self.off_walkable_ends and self.out_of_route_ends

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> EndRules:
        """The rules of a task config."""
        return cls(
            float(cfg["success_completion"]),
            float(cfg["out_of_route_distance"]),
            float(cfg["stuck_distance"]),
            int(cfg["stuck_steps"]),
            int(cfg["collision_steps"]),
            bool(cfg["terminate_off_walkable"]),
            float(np.radians(cfg["topple_angle"])),
            math.inf if cfg["max_episode_cost"] is None else float(cfg["max_episode_cost"]),
            bool(cfg["out_of_route_ends"]),
            bool(cfg["building_contact_ends"]),
        )


@dataclass
class EndMarks:
    """What the stuck rule remembers of an episode (numbers) or of n episodes (arrays of n): the step and largest arc
    length when progress last grew by `stuck_distance`, and the run of consecutive steps in contact."""

    step: Any = 0
    progress: Any = 0.0
    contact_run: Any = 0

    @classmethod
    def zeros(cls, n: int) -> EndMarks:
        """Marks of n episodes."""
        return cls(np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n, dtype=np.int64))

    def reset(self, k: Any) -> None:
        """Episode(s) `k` of arrays start afresh."""
        self.step[k], self.progress[k], self.contact_run[k] = 0, 0.0, 0


def end_of_step(
    rules: EndRules,
    marks: EndMarks,
    steps: Any,
    max_progress: Any,
    route_length: Any,
    lateral: Any,
    on_walkable: Any,
    in_contact: Any,
    tilt: Any,
    cost_total: Any,
    building_contact: Any = False,
) -> tuple[Any, ...]:
    """(succeeded, out_of_route, stuck, toppled, cost_exceeded, crashed) after a step, `marks` advanced: for one
    episode (numbers, bools) or n (arrays of n). Success excludes the rest; toppled may hold beside out of route or
    stuck; crashed (a building touched, with `building_contact_ends`) beside any but success; cost_exceeded only when
    nothing else ended the episode.

    Written with operators that mean the same on numbers and on arrays (`x ^ True` for not; a choice between two
    values is a sum of products, exact since one factor is 0): the PyBullet env's step pays no numpy call per rule.
    """
    succeeded = max_progress >= rules.success_completion * route_length
    off = False
    if rules.out_of_route_ends:
        off = abs(lateral) > rules.out_of_route_distance
        if rules.off_walkable_ends:
            off = off | (on_walkable ^ True)
    out = (succeeded ^ True) & off
    marks.contact_run = (marks.contact_run + 1) * in_contact
    moved_on = max_progress >= marks.progress + rules.stuck_distance
    stay = moved_on ^ True
    marks.step = steps * moved_on + marks.step * stay
    marks.progress = max_progress * moved_on + marks.progress * stay
    pinned = False
    if rules.stuck_steps > 0:
        pinned = pinned | (steps - marks.step >= rules.stuck_steps)
    if rules.collision_steps > 0:
        pinned = pinned | (marks.contact_run >= rules.collision_steps)
    stuck = ((succeeded | out) ^ True) & pinned
    toppled = (succeeded ^ True) & (tilt > rules.topple)  # beside out of route or stuck, it names the end (step_info)
    # `succeeded & False`: False of succeeded's shape (an array of n, or a bool)
    crashed = (succeeded ^ True) & building_contact if rules.building_contact_ends else succeeded & False
    over = ((succeeded | out | stuck | toppled | crashed) ^ True) & (cost_total > rules.max_cost)
    return succeeded, out, stuck, toppled, over, crashed


class Termination:
    """The PyBullet env's episode end: `end_of_step` for one env, fed one `StepContext` a step."""

    def __init__(self, rules: EndRules) -> None:
        self.rules = rules
        self.marks = EndMarks()

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> Termination:
        """A fresh detector for one episode of a task config."""
        return cls(EndRules.from_config(cfg))

    def __call__(self, step: StepContext) -> StepEnd:
        """How `step` ends the episode; `step.on_walkable()` is asked only when the rules read it."""
        on_walkable = bool(step.on_walkable()) if self.rules.reads_walkable else True
        ends = end_of_step(
            self.rules,
            self.marks,
            step.steps,
            step.max_progress,
            step.route_length,
            step.lateral,
            on_walkable,
            bool(step.in_contact),
            step.tilt,
            step.cost_total,
            bool(step.building_contact),
        )
        return StepEnd(*(bool(end) for end in ends))
