"""A tiny env the ShardedVectorEnv fault tests drive: each action value asks it for one behaviour (module-level, so
forkserver workers and a child interpreter import it by name)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

RAISE, EXIT, BIG, SLOW = 99.0, -99.0, 50.0, 7.0  # actions: raise ValueError, os._exit(3), a 400 KB info, sleep 1 s


class Counter(gym.Env):
    """Observation [its index, steps since reset]; info {"n": steps since reset} (and "big" on a BIG action)."""

    def __init__(self, index: int) -> None:
        self.index, self.n = index, 0
        self.observation_space = gym.spaces.Box(-1e9, 1e9, (2,), np.float64)
        self.action_space = gym.spaces.Box(-1e9, 1e9, (1,), np.float64)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Back to 0 steps."""
        super().reset(seed=seed)
        self.n = 0
        return np.array([self.index, 0.0]), {"n": 0}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Count a step, or do what the action asks."""
        a = float(action[0])
        if a == RAISE:
            raise ValueError(f"env {self.index} was asked to fail")
        if a == EXIT:
            os._exit(3)
        if a == SLOW:
            time.sleep(1.0)
        self.n += 1
        info: dict[str, Any] = {"n": self.n}
        if a == BIG:
            info["big"] = np.full(50_000, float(self.index))  # 400 KB: more than a socket's buffer holds
        return np.array([self.index, float(self.n)]), 0.0, False, False, info

    def frame(self) -> np.ndarray:
        """A 400 KB array (what call("render") returns for a camera frame)."""
        return np.full(50_000, float(self.index))


def counters(n: int) -> list[Callable[[], gym.Env]]:
    """Factories of Counter 0..n-1."""
    return [lambda i=i: Counter(i) for i in range(n)]


class Chooser(gym.Env):
    """Discrete actions (they cannot share memory, so they travel through the pipe): reward = the action chosen,
    terminated on action 2."""

    def __init__(self, index: int) -> None:
        self.index = index
        self.observation_space = gym.spaces.Box(-1e9, 1e9, (1,), np.float64)
        self.action_space = gym.spaces.Discrete(3)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Observation: the env's index."""
        super().reset(seed=seed)
        return np.array([float(self.index)]), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Reward the action; end the episode on 2."""
        return np.array([float(self.index)]), float(action), int(action) == 2, False, {"a": int(action)}
