"""Episode counters and PointNav's episode end for many envs at once (`sim.envs.episode.Episode.advance` and
`sim.tasks.pointnav.Termination` over arrays; the reward is `Reward.batch`, the PyBullet env's own code).

The scalar classes stay the PyBullet env's (they keep its episodes byte-identical); these arrays restate their
rules once for `n` envs: progress is paid for new ground, success at `success_completion` of the route, out of
route beyond `out_of_route_distance` or off the walkable area, stuck after `stuck_steps` without `stuck_distance`
of new progress or `collision_steps` steps in contact.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.raycast.grids import KIND_NAMES

KIND_BITS = {name: 1 << k for k, name in KIND_NAMES.items()}  # object 2, building 4, curb 8


class Episodes:
    """Per-env counters of the running episodes; `reset(mask)` starts new ones, `advance` records a step."""

    def __init__(self, n: int, cfg: Mapping[str, Any]) -> None:
        self.n = n
        self.success_completion = float(cfg["success_completion"])
        self.out_of_route_distance = float(cfg["out_of_route_distance"])
        self.stuck_distance = float(cfg["stuck_distance"])
        self.stuck_steps = int(cfg["stuck_steps"])
        self.collision_steps = int(cfg["collision_steps"])
        self.off_walkable_ends = bool(cfg["terminate_off_walkable"])
        self.max_cost = None if cfg["max_episode_cost"] is None else float(cfg["max_episode_cost"])
        self.cost_bits = sum(KIND_BITS[k] for k in cfg["cost_kinds"] if k in KIND_BITS)
        f = lambda: np.zeros(n)  # noqa: E731
        i = lambda: np.zeros(n, dtype=np.int64)  # noqa: E731
        self.progress, self.max_progress, self.lateral, self.path_length = f(), f(), f(), f()
        self.steps, self.horizon, self.cost_total, self.mark_step, self.contact_run = i(), i(), i(), i(), i()
        self.mark_progress = f()
        self.collision_counts = {k: i() for k in KIND_BITS}
        self.last_action = np.zeros((n, 2))

    def reset(self, k: int, horizon: int) -> None:
        """Env k starts an episode of `horizon` steps."""
        for a in (self.progress, self.max_progress, self.lateral, self.path_length, self.mark_progress):
            a[k] = 0.0
        for a in (self.steps, self.cost_total, self.mark_step, self.contact_run, *self.collision_counts.values()):
            a[k] = 0
        self.horizon[k] = horizon
        self.last_action[k] = 0.0

    def advance(self, dx: np.ndarray, dy: np.ndarray, s: np.ndarray, lateral: np.ndarray,
                hits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Record a step that moved every machine by (dx, dy) to arc length `s`, offset `lateral`, touching the
        kinds in bit mask `hits`; returns (progress, new progress, collided)."""
        self.path_length += np.hypot(dx, dy)
        progress, new_progress = s - self.progress, np.maximum(s - self.max_progress, 0.0)
        self.progress, self.lateral = s, lateral
        self.max_progress = np.maximum(self.max_progress, s)
        self.steps += 1
        for name, bit in KIND_BITS.items():
            self.collision_counts[name] += (hits & bit) > 0
        collided = (hits & self.cost_bits) > 0
        self.cost_total += collided
        return progress, new_progress, collided

    def end(self, length: np.ndarray, on_walkable: np.ndarray, in_contact: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(succeeded, out of route, stuck, cost exceeded) of every env after its step (`Termination.__call__` and
        `Termination.cost_exceeded`)."""
        succeeded = self.max_progress >= self.success_completion * length
        off = np.abs(self.lateral) > self.out_of_route_distance
        if self.off_walkable_ends:
            off |= ~on_walkable
        out = ~succeeded & off
        self.contact_run = np.where(in_contact, self.contact_run + 1, 0)
        moved_on = self.max_progress >= self.mark_progress + self.stuck_distance
        self.mark_step = np.where(moved_on, self.steps, self.mark_step)
        self.mark_progress = np.where(moved_on, self.max_progress, self.mark_progress)
        pinned = np.zeros(self.n, dtype=bool)
        if self.stuck_steps > 0:
            pinned |= self.steps - self.mark_step >= self.stuck_steps
        if self.collision_steps > 0:
            pinned |= self.contact_run >= self.collision_steps
        stuck = ~(succeeded | out) & pinned
        over = np.zeros(self.n, dtype=bool) if self.max_cost is None else self.cost_total > self.max_cost
        return succeeded, out, stuck, ~(succeeded | out | stuck) & over
