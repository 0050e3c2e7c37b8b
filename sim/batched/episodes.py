"""Episode counters for many envs at once (`sim.envs.episode.Episode.advance` over arrays). The episode end is the
PyBullet env's own rules (`sim.tasks.termination.end_of_step`), the reward its `Reward.batch`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.raycast.grids import KIND_NAMES
from sim.tasks.cost import MOVING_KINDS, CostRule
from sim.tasks.termination import EndMarks, EndRules, end_of_step

KIND_BITS = {name: 1 << k for k, name in KIND_NAMES.items()}  # object 2, building 4, curb 8
# SocialNav's moving bodies (sim.batched.social), beside the grids' kinds.
SOCIAL_KIND_BITS = {**KIND_BITS, "agent": 1 << 4, "vehicle": 1 << 5}


class Episodes:
    """Per-env counters of the running episodes; `reset(mask)` starts new ones, `advance` records a step.

    `kind_bits`: the collision kinds counted (`collisions_<kind>`) and their bits in `advance`'s hit masks."""

    def __init__(self, n: int, cfg: Mapping[str, Any], kind_bits: Mapping[str, int] = KIND_BITS) -> None:
        self.n = n
        self.kind_bits = dict(kind_bits)
        self.rules = EndRules.from_config(cfg)
        self.marks = EndMarks.zeros(n)
        self.cost_bits = sum(kind_bits[k] for k in cfg["cost_kinds"] if k in kind_bits)
        self.moving_cost_bits = sum(kind_bits[k] for k in cfg["cost_kinds"] if k in kind_bits and k in MOVING_KINDS)
        self.cost_rule = CostRule.from_config(cfg)
        self.charged: list[set[int]] = [set() for _ in range(n)]  # objects charged (cost_rule "metaurban": once each)
        f = lambda: np.zeros(n)  # noqa: E731
        i = lambda: np.zeros(n, dtype=np.int64)  # noqa: E731
        self.progress, self.max_progress, self.lateral, self.path_length = f(), f(), f(), f()
        self.steps, self.horizon, self.cost_total = i(), i(), i()
        self.collision_counts = {k: i() for k in kind_bits}
        self.last_action = np.zeros((n, 2))

    def reset(self, k: int, horizon: int) -> None:
        """Env k starts an episode of `horizon` steps."""
        for a in (self.progress, self.max_progress, self.lateral, self.path_length):
            a[k] = 0.0
        for counts in (self.steps, self.cost_total, *self.collision_counts.values()):
            counts[k] = 0
        self.marks.reset(k)
        self.charged[k] = set()
        self.horizon[k] = horizon
        self.last_action[k] = 0.0

    def advance(
        self,
        dx: np.ndarray,
        dy: np.ndarray,
        s: np.ndarray,
        lateral: np.ndarray,
        hits: np.ndarray,
        new_static: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Record a step that moved every machine by (dx, dy) to arc length `s`, offset `lateral`, touching the
        kinds in bit mask `hits` (and, where `new_static`, an object not touched before in the episode); returns
        (progress, new progress, collided: the step's cost, sim.tasks.cost)."""
        self.path_length += np.hypot(dx, dy)
        progress, new_progress = s - self.progress, np.maximum(s - self.max_progress, 0.0)
        self.progress, self.lateral = s, lateral
        self.max_progress = np.maximum(self.max_progress, s)
        self.steps += 1
        for name, bit in self.kind_bits.items():
            self.collision_counts[name] += (hits & bit) > 0
        fresh = np.zeros(self.n, dtype=bool) if new_static is None else new_static
        collided = np.asarray(
            self.cost_rule((hits & self.cost_bits) > 0, fresh, (hits & self.moving_cost_bits) > 0, lateral), dtype=bool
        )
        self.cost_total += collided
        return progress, new_progress, collided

    def end(
        self, length: np.ndarray, on_walkable: np.ndarray, in_contact: np.ndarray, building: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(succeeded, out of route, stuck, cost exceeded, crashed into a building) of every env after its step
        (`end_of_step`; a wheeled machine on the distance grids never topples)."""
        succeeded, out, stuck, _, over, crashed = end_of_step(
            self.rules,
            self.marks,
            self.steps,
            self.max_progress,
            length,
            self.lateral,
            on_walkable,
            in_contact,
            np.zeros(self.n),
            self.cost_total,
            building,
        )
        return succeeded, out, stuck, over, np.asarray(crashed) & np.ones(self.n, dtype=bool)
