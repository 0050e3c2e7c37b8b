"""The record of one episode: what the machine has done so far, read by measures, rewards, renderers and the expert."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Episode:
    """Counters of one PointNav-style episode, updated once per step by `advance`."""

    horizon: int  # steps before truncation
    trajectory: list[tuple[float, float]]  # machine positions, the start first
    steps: int = 0
    progress: float = 0.0  # arc length of the machine's projection on the route
    max_progress: float = 0.0  # largest arc length reached
    lateral: float = 0.0  # signed offset from the route (left +)
    path_length: float = 0.0  # planar distance driven
    cost_total: int = 0  # steps that cost (sim.tasks.cost)
    charged: set[int] = field(default_factory=set)  # static bodies charged (cost_rule "metaurban": once each)
    collision_counts: dict[str, int] = field(default_factory=dict)  # steps in contact, per kind
    step_collisions: set[str] = field(default_factory=set)  # kinds touched on the last step
    succeeded: bool = False
    out_of_route: bool = False
    stuck: bool = False
    toppled: bool = False  # rolled or pitched past config.topple_angle
    cost_exceeded: bool = False  # the episode's cost passed config.max_episode_cost
    crashed: bool = False  # ran into a building (config.building_contact_ends)
    last_action: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.float64))

    def step_info(self, collided: bool, hits: set[str], route_length: float) -> dict[str, object]:
        """The per-step `info`: cost, route completion, kinds touched, and why the episode ended (if it did)."""
        reason = next(
            (
                name
                for name, hit in (
                    ("success", self.succeeded),
                    ("toppled", self.toppled),
                    ("out_of_route", self.out_of_route),
                    ("stuck", self.stuck),
                    ("cost_exceeded", self.cost_exceeded),
                    ("crashed", self.crashed),
                )
                if hit
            ),
            None,
        )
        return {
            "cost": float(collided),
            "route_completion": min(self.max_progress / route_length, 1.0),
            "collision_kinds": sorted(hits),
            "out_of_route": self.out_of_route,
            "stuck": self.stuck,
            "toppled": self.toppled,
            "cost_exceeded": self.cost_exceeded,
            "crashed": self.crashed,
            "end_reason": reason,
        }

    def advance(
        self,
        start: tuple[float, float],
        end: tuple[float, float],
        s: float,
        lateral: float,
        hits: set[str],
        collided: bool,
    ) -> tuple[float, float]:
        """Record a step from `start` to `end` (x, y), projected at arc length `s`; returns (progress, new progress)."""
        (x0, y0), (x, y) = start, end
        self.path_length += math.hypot(x - x0, y - y0)
        self.trajectory.append((x, y))
        progress, new_progress = s - self.progress, max(s - self.max_progress, 0.0)
        self.progress, self.lateral = s, lateral
        self.max_progress = max(self.max_progress, s)
        self.steps += 1
        self.step_collisions = hits
        for k in hits:
            self.collision_counts[k] = self.collision_counts.get(k, 0) + 1
        self.cost_total += int(collided)
        return progress, new_progress
