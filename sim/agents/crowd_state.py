"""CrowdState: the per-episode state of the crowd, one array entry per agent, that every crowd part reads and writes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.agents.kinds import KIND_NAMES, WALKING

AGENT_DTYPE = np.dtype([("x", "f8"), ("y", "f8"), ("vx", "f8"), ("vy", "f8"), ("radius", "f8"), ("kind", "U16")])


@dataclass
class CrowdState:
    """Agents' kinds, bodies, motion and goals in one episode; AgentManager.reset makes it, every part updates it."""

    n: int  # number of agents this episode
    kind_idx: np.ndarray  # [n] int16 index into sim.agents.kinds.KIND_NAMES
    radius: np.ndarray  # [n] body radius of each agent's kind, m
    pos: np.ndarray  # [n, 2] world positions, m
    vel: np.ndarray  # [n, 2] velocities ORCA gave them last step, m/s
    movement: np.ndarray  # [n] int8 movement code (IDLE, WALKING, RUNNING of sim.agents.kinds)
    speed: np.ndarray  # [n] preferred speed toward the current goal, m/s
    site: np.ndarray  # [n] int64 goal site (index into the navigation grid's sites) each agent heads for
    goal: np.ndarray  # [n, 2] goal point near that site, m
    idle_left: np.ndarray  # [n] seconds an idle agent keeps standing (inf: a group member waiting for the others)
    best: np.ndarray  # [n] field distance to the goal site at the last progress, m (inf: none since the goal was set)
    stall: np.ndarray  # [n] int64 steps since the last progress of `stuck_progress` metres
    goal_t0: np.ndarray  # [n] episode time the current goal was given, s
    budget: np.ndarray  # [n] seconds the current goal may take and still count as in time
    crossing: np.ndarray  # [n] bool: the current goal lies across a road
    trail: np.ndarray  # [trail_length, n, 2] recent positions, oldest first
    template: np.ndarray  # [n] AGENT_DTYPE rows with radius and kind filled: they never change within an episode
    time: float = 0.0  # seconds since reset
    counts: dict[str, int] = field(default_factory=lambda: {"in_time": 0, "late": 0, "abandoned": 0})  # goals ended
    cross_counts: dict[str, int] = field(default_factory=lambda: {"started": 0, "done": 0})  # road crossings

    @classmethod
    def start(cls, kinds: list[str], radius: np.ndarray, pos: np.ndarray) -> CrowdState:
        """A fresh episode's state: agents of `kinds` and `radius` at rest at `pos`, walking, with no goal yet.

        The trail is empty until reset fills it from the positions the agents start at (groups move some first).
        """
        n = len(kinds)
        template = np.zeros(n, dtype=AGENT_DTYPE)
        template["radius"], template["kind"] = radius, kinds
        return cls(
            n=n,
            kind_idx=np.array([KIND_NAMES.index(k) for k in kinds], dtype=np.int16),
            radius=radius,
            pos=pos,
            vel=np.zeros((n, 2)),
            movement=np.full(n, WALKING, dtype=np.int8),
            speed=np.zeros(n),
            site=np.zeros(n, dtype=np.int64),
            goal=np.zeros((n, 2)),
            idle_left=np.zeros(n),
            best=np.full(n, np.inf),
            stall=np.zeros(n, dtype=np.int64),
            goal_t0=np.zeros(n),
            budget=np.zeros(n),
            crossing=np.zeros(n, dtype=bool),
            trail=np.zeros((0, n, 2)),
            template=template,
        )

    @classmethod
    def empty(cls) -> CrowdState:
        """The state of a manager before its first reset: no agents."""
        return cls.start([], np.zeros(0), np.zeros((0, 2)))
