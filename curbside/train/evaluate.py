"""Evaluate a policy on a split: SR, SPL, Cost (+ SNS, route completion) over episodes on held-out scenes."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from curbside.train.envs import env_id, split_config
from kernel.config import ConfigError

EVAL_SCENES = 50  # scenes of the split an evaluation draws its episodes from
EVAL_ACTIONS = ("mean", "sampled")  # how a policy acts in an evaluation: its mean action, or draws
SHARDS_PER_WORKER = 4  # an evaluation's episodes come in this many shards a worker (see `evaluate_run`)


def evaluate_policy(
    act: Callable[[np.ndarray], np.ndarray],
    task: str,
    env_config: Mapping[str, Any],
    *,
    split: str = "test",
    episodes: int = 50,
    seed: int = 0,
    num_scenes: int = EVAL_SCENES,
    progress: bool = True,
    seed_torch: bool = False,
) -> dict[str, Any]:
    """Mean metrics of `act(obs) -> action` over `episodes` episodes (seeds seed..seed+N-1) on `split`; `seed_torch`
    as in `episode_rows` (for an `act` that samples)."""
    from sim.eval import summarize

    summary = summarize(
        episode_rows(
            act,
            task,
            env_config,
            split=split,
            episodes=episodes,
            seed=seed,
            num_scenes=num_scenes,
            progress=progress,
            seed_torch=seed_torch,
        )
    )
    summary["split"] = split
    return summary


def episode_rows(
    act: Callable[[np.ndarray], np.ndarray],
    task: str,
    env_config: Mapping[str, Any],
    *,
    split: str,
    episodes: int,
    seed: int,
    num_scenes: int,
    progress: bool,
    seed_torch: bool = False,
) -> list[dict[str, float]]:
    """The metrics of each episode of `evaluate_policy`, in seed order; with `seed_torch`, torch's global generator
    is seeded with each episode's seed first and given back its state at the end (a training run that evaluates
    itself keeps its own draws)."""
    import gymnasium as gym

    import sim  # noqa: F401
    from sim.rollout import rollout

    cfg = split_config(env_config, split, num_scenes)
    cfg["scene_cache"] = 1  # evaluation visits each scene about once: no point keeping worlds
    cfg["scene_steps"] = 0  # every episode draws its scene from its seed, whatever the training envs reused
    env = gym.make(env_id(task), config=cfg)
    rows = []
    seeds: Iterable[int] = range(seed, seed + episodes)
    if progress:
        from rich.progress import track

        seeds = track(seeds, description=f"eval {task} {split}")
    if seed_torch:  # an `act` that samples draws the same actions for an episode wherever it runs
        import torch

        rng_state = torch.get_rng_state()
    try:
        policy = lambda e, obs: np.asarray(act(obs), dtype=np.float32).reshape(2)  # noqa: E731
        for s in seeds:
            if seed_torch:
                torch.manual_seed(s)
            rows.append(rollout(env, policy, s))
    finally:
        env.close()
        if seed_torch:
            torch.set_rng_state(rng_state)
    return rows


def _run_rows(
    run_dir: str,
    task: str,
    cfg: dict[str, Any],
    split: str,
    seed: int,
    episodes: int,
    num_scenes: int,
    actions: str,
    progress: bool = False,
    policy: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[dict[str, Any]]:
    """The episode rows of the policy saved in `run_dir` (or `policy`, loaded from it already) over seeds
    seed..seed+episodes-1, acting with `actions`."""
    from curbside.train.policies import load_policy

    act = policy if policy is not None else load_policy(run_dir, deterministic=actions == "mean")[0]
    return episode_rows(
        act,
        task,
        cfg,
        split=split,
        episodes=episodes,
        seed=seed,
        num_scenes=num_scenes,
        progress=progress,
        seed_torch=actions == "sampled",
    )


def _evaluate_shard(job: tuple[str, str, dict[str, Any], str, int, int, int, str]) -> list[dict[str, Any]]:
    """`_run_rows` of one shard of seeds, in a worker process of `evaluate_run` (which loads the policy once: the
    pool's workers end with their `evaluate_run`, so a policy saved again later is never served stale)."""
    import torch

    from curbside.train.policies import load_policy
    from kernel.executors import worker_state

    torch.set_num_threads(1)
    run_dir, actions = job[0], job[7]
    act = worker_state(
        "eval_policy", f"{run_dir}|{actions}", lambda: load_policy(run_dir, deterministic=actions == "mean")[0]
    )
    return _run_rows(*job, policy=act)


def evaluate_run(
    run_dir: Any,
    task: str,
    env_config: Mapping[str, Any],
    *,
    split: str = "test",
    episodes: int = 50,
    seed: int = 0,
    num_scenes: int = EVAL_SCENES,
    workers: int = 1,
    progress: bool = True,
    actions: str = "mean",
) -> dict[str, Any]:
    """`evaluate_policy` of the policy saved in `run_dir`, its episodes shared among `workers` processes: the same
    episodes in the same seed order, so the same figures whatever `workers` is. `actions` is "mean" (the policy's
    mean action) or "sampled" (drawn from its distribution, torch seeded with each episode's seed)."""
    from sim.eval import summarize

    if actions not in EVAL_ACTIONS:
        raise ConfigError(f"unknown actions {actions!r}; valid: {', '.join(EVAL_ACTIONS)}")
    workers = max(1, min(int(workers), episodes))
    if workers == 1:
        rows = _run_rows(str(run_dir), task, dict(env_config), split, seed, episodes, num_scenes, actions, progress)
    else:
        from concurrent.futures import ProcessPoolExecutor

        # Several shards a worker, handed out as workers free up: a failing policy's episodes run to the horizon,
        # several times longer than a success, and one worker would otherwise wait on a shard full of them.
        shards = min(episodes, workers * SHARDS_PER_WORKER)
        bounds = np.linspace(seed, seed + episodes, shards + 1).astype(int)
        jobs = [
            (str(run_dir), task, dict(env_config), split, int(a), int(b - a), num_scenes, actions)
            for a, b in zip(bounds[:-1], bounds[1:])
            if b > a
        ]
        import multiprocessing as mp

        # spawn, as kernel.executors: a worker forked from a parent that has loaded torch and pybullet can crash
        # (seen as BrokenProcessPool on paper-scale evaluations).
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
            rows = [row for part in pool.map(_evaluate_shard, jobs) for row in part]
    summary = summarize(rows)
    summary["split"] = split
    summary["actions"] = actions
    return summary


def evaluate_policy_batched(
    act_batch: Callable[[np.ndarray], np.ndarray],
    env_config: Mapping[str, Any],
    *,
    task: str = "PointNav",
    split: str = "test",
    episodes: int = 50,
    seed: int = 0,
    num_scenes: int = EVAL_SCENES,
    n_envs: int = 50,
) -> dict[str, Any]:
    """`task`'s metrics of `act_batch(obs [n, d]) -> actions [n, 2]` on the batched env (sim.batched), episode for
    episode the ones `evaluate_policy` runs on the PyBullet env: episode k uses seed `seed + k` (batched sub-env i
    reset with seed s draws the PyBullet env's reset(seed=s) scene and route, and SocialNav's crowd and traffic), in
    waves of `n_envs` episodes.

    Returns sr, spl, route_completion, cost (episode cost), SocialNav's sns, and episodes: the transfer gap is the
    PyBullet figure minus this.
    """
    from sim.batched import BatchedPointNav, BatchedSocialNav

    batched = {"PointNav": BatchedPointNav, "SocialNav": BatchedSocialNav}
    if task not in batched:
        raise ConfigError(f"no batched env for task {task!r}; valid: {', '.join(batched)}")
    cfg = split_config(env_config, split, num_scenes)
    cfg.update(scene_cache=max(1, min(num_scenes, n_envs)), route_pool=0, scene_steps=0)
    rows: list[dict[str, float]] = []
    env = batched[task](n_envs, config=cfg)
    try:
        for first in range(seed, seed + episodes, n_envs):
            n = min(n_envs, seed + episodes - first)
            obs, _ = env.reset(seed=[first + i for i in range(n_envs)])
            env.autoreset[n:] = False  # the last wave's spare envs, and each env once its episode is in
            finished: dict[int, dict[str, float]] = {}
            while len(finished) < n:
                obs, _, term, trunc, info = env.step(np.asarray(act_batch(obs), dtype=np.float32).reshape(n_envs, 2))
                for i in np.nonzero(term | trunc)[0].tolist():
                    if i < n and i not in finished:
                        fi = info["final_info"]
                        env.autoreset[i] = False
                        finished[i] = {
                            "success": float(fi["is_success"][i]),
                            "spl": float(fi["spl"][i]),
                            "cost": float(fi["episode_cost"][i]),
                            "route_completion": float(fi["route_completion"][i]),
                        }
                        if "sns" in fi:
                            finished[i]["sns"] = float(fi["sns"][i])
            rows.extend(finished[i] for i in range(n))
    finally:
        env.close()
    keys = ("success", "spl", "cost", "route_completion", "sns")
    means = {k: float(np.mean([r[k] for r in rows])) for k in keys if k in rows[0]}
    return {
        "sr": means.pop("success"),
        **means,
        "episodes": len(rows),
        "split": split,
        "env": "batched",
    }
