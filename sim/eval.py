"""Policy evaluation over episodes: SR, SPL, Cost and the mean of every other numeric metric the env reports."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.rollout import make_policy, rollout


def evaluate(env_id: str, policy: str, episodes: int, config: Mapping[str, Any] | None = None, *,
             seed: int = 0, progress: bool = False) -> dict[str, Any]:
    """Mean metrics over `episodes` episodes with seeds seed..seed+N-1: keys sr, spl, cost, episodes, ..."""
    import gymnasium as gym

    from sim.envs import register_envs

    register_envs()

    env = gym.make(env_id, config=dict(config or {}))
    act = make_policy(policy, env)
    rows = []
    try:
        if progress:
            from rich.progress import track
            seeds = track(range(seed, seed + episodes), description=f"{env_id} {policy}")
        else:
            seeds = range(seed, seed + episodes)
        for s in seeds:
            rows.append(rollout(env, act, s))
    finally:
        env.close()
    summary = summarize(rows)
    summary["per_episode"] = rows
    return summary


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean of every numeric metric over episodes; `success` becomes `sr`; `episodes` is the count."""
    keys = sorted({k for r in rows for k, v in r.items() if isinstance(v, (int, float))})
    summary: dict[str, Any] = {k: float(np.mean([r.get(k, 0.0) for r in rows])) for k in keys}
    summary["sr"] = summary.pop("success")
    summary["episodes"] = len(rows)
    return summary
