"""Evaluate a policy on a split: SR, SPL, Cost (+ SNS, route completion) over episodes on held-out scenes."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from curbside.train.envs import env_id, split_config

EVAL_SCENES = 50  # scenes of the split an evaluation draws its episodes from


def evaluate_policy(act: Callable[[np.ndarray], np.ndarray], task: str, env_config: Mapping[str, Any], *,
                    split: str = "test", episodes: int = 50, seed: int = 0, num_scenes: int = EVAL_SCENES,
                    progress: bool = True) -> dict[str, Any]:
    """Mean metrics of `act(obs) -> action` over `episodes` episodes (seeds seed..seed+N-1) on `split`."""
    import gymnasium as gym

    import sim  # noqa: F401
    from sim.eval import summarize
    from sim.rollout import rollout

    cfg = split_config(env_config, split, num_scenes)
    cfg["scene_cache"] = 1  # evaluation visits each scene about once: no point keeping worlds
    env = gym.make(env_id(task), config=cfg)
    rows = []
    seeds = range(seed, seed + episodes)
    if progress:
        from rich.progress import track
        seeds = track(seeds, description=f"eval {task} {split}")
    try:
        policy = lambda e, obs: np.asarray(act(obs), dtype=np.float32).reshape(2)  # noqa: E731
        for s in seeds:
            rows.append(rollout(env, policy, s))
    finally:
        env.close()
    summary = summarize(rows)
    summary["split"] = split
    return summary
