"""Environments for training and evaluation: task names, split configs, and vector envs whose workers each own
a shard of the training scenes (so every worker's scene cache holds all of its scenes after warm-up)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym

from kernel.config import ConfigError

TASKS = {"PointNav": "curbside/PointNav-v0", "SocialNav": "curbside/SocialNav-v0"}
SPLITS = ("train", "test", "unseen", "finetune")
# Batched training envs cut into one batched env a core. SocialNav's crowds step one env at a time in Python, and one
# batched env leaves the second core idle while it rolls out: PPO under `paper_realistic` trains at 361 env steps/s in
# two shards against 276 in one. PointNav's step is mostly the LiDAR march, which already runs on every core, and the
# hand-over costs more than the second shard brings: 584 against 688 (benchmarks/training_throughput.py).
BATCHED_SHARDED_TASKS = ("SocialNav",)
MAX_WORKER_SCENES = 16  # built worlds a training worker keeps (a paper-scale world holds ~100 MB)


def env_id(task: str) -> str:
    """The Gymnasium id of a task name (PointNav, SocialNav); unknown names raise listing the valid ones."""
    if task not in TASKS:
        raise ConfigError(f"unknown task {task!r}; valid: {', '.join(TASKS)}")
    return TASKS[task]


def split_config(base: Mapping[str, Any] | None, split: str, num_scenes: int, scene_seed: int = 0) -> dict[str, Any]:
    """An env config drawing episodes from `num_scenes` scenes of `split` starting at `scene_seed`."""
    if split not in SPLITS:
        raise ConfigError(f"unknown split {split!r}; valid: {', '.join(SPLITS)}")
    cfg = dict(base or {})
    cfg.update(split=split, scene_seed=scene_seed, num_scenes=num_scenes)
    # Every env curbside trains, evaluates or records demonstrations in is configured here: a protocol's catalog
    # (the paper's 1,023 assets) is built the first time one is needed.
    from curbside.train.protocols import ensure_catalog

    ensure_catalog(cfg)
    return cfg


def env_fns(
    task: str,
    config: Mapping[str, Any],
    n_envs: int,
    num_scenes: int,
    split: str = "train",
    wrappers: tuple[Callable[[gym.Env], gym.Env], ...] = (),
) -> list[Callable[[], gym.Env]]:
    """`n_envs` env constructors; worker k gets scenes [k n / N, (k + 1) n / N) of the split (n = num_scenes,
    N = n_envs; with fewer scenes than workers, worker k gets scene k mod n), up to MAX_WORKER_SCENES of them held
    in its scene cache."""
    eid = env_id(task)

    def make(k: int) -> Callable[[], gym.Env]:
        lo, hi = k * num_scenes // n_envs, (k + 1) * num_scenes // n_envs
        if hi <= lo:
            lo, hi = k % num_scenes, k % num_scenes + 1

        def thunk() -> gym.Env:
            from stable_baselines3.common.monitor import Monitor

            import sim  # noqa: F401  (registers the env ids, in this process or a spawned worker)

            cfg = split_config(config, split, hi - lo, scene_seed=lo)
            cfg.setdefault("scene_cache", min(hi - lo, MAX_WORKER_SCENES))
            env: gym.Env = gym.make(eid, config=cfg)
            for w in wrappers:
                env = w(env)
            return Monitor(env, info_keywords=("is_success", "episode_cost", "route_completion"))

        return thunk

    return [make(k) for k in range(n_envs)]


def make_vec_env(
    task: str,
    config: Mapping[str, Any],
    n_envs: int,
    num_scenes: int,
    *,
    split: str = "train",
    subprocess: bool = True,
    seed: int = 0,
    workers: int | None = None,
    wrappers: tuple[Callable[[gym.Env], gym.Env], ...] = (),
) -> Any:
    """An SB3 VecEnv over `n_envs` sharded envs: `workers` shards (default: one per core, at most n_envs), shard 0
    in this process and the others in worker processes, that each step n_envs / workers envs with BLAS
    single-threaded (curbside.train.sharded), reset in the same step as SB3 expects; SB3's DummyVecEnv in this
    process when `subprocess` is False."""
    import os

    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

    from curbside.train.sharded import ShardedVectorEnv
    from curbside.train.vec import VectorEnvAdapter, single_thread_worker

    fns = env_fns(task, config, n_envs, num_scenes, split, wrappers)
    workers = min(n_envs, workers or os.cpu_count() or 1)
    vec: VecEnv
    if subprocess and n_envs > 1 and workers > 1:
        vec = VectorEnvAdapter(ShardedVectorEnv([single_thread_worker(f) for f in fns], workers), wrappers=(Monitor,))
    else:
        vec = DummyVecEnv(fns)
    vec.seed(seed)
    return vec


def make_training_vec(
    task: str,
    config: Mapping[str, Any],
    n_envs: int,
    num_scenes: int,
    *,
    backend: str = "pybullet",
    split: str = "train",
    seed: int = 0,
    subprocess: bool = True,
    shards: int | None = None,
) -> Any:
    """The SB3 VecEnv online training steps: `make_vec_env`'s sharded PyBullet envs, or (backend "batched")
    sim.batched envs (BatchedPointNav, BatchedSocialNav) drawing from `num_scenes` scenes of `split`, cut into
    `shards` batched envs that step side by side (curbside.train.batched_shards). `shards` None: one a core for
    SocialNav, one batched env in this process for PointNav (BATCHED_SHARDED_TASKS); `subprocess` False: one."""
    if backend == "pybullet":
        return make_vec_env(task, config, n_envs, num_scenes, split=split, subprocess=subprocess, seed=seed)
    env_id(task)  # an unknown task fails here, naming the valid ones

    from stable_baselines3.common.vec_env import VecEnv, VecMonitor

    from curbside.train.batched_shards import BatchedShards
    from curbside.train.sharded import usable_cores

    cfg = split_config(config, split, num_scenes)
    if shards is None:
        shards = usable_cores() if task in BATCHED_SHARDED_TASKS else 1
    shards = max(1, min(shards, n_envs)) if subprocess else 1
    # Each shard keeps the scenes its own envs use: two per env, as one batched env of all of them would.
    cfg.setdefault("scene_cache", min(num_scenes, max(2 * -(-n_envs // shards), 8)))
    make = BatchedShard(task, cfg)
    inner: VecEnv = make(n_envs) if shards == 1 else BatchedShards(make, n_envs, shards)
    vec = VecMonitor(inner, info_keywords=("is_success", "episode_cost", "route_completion"))
    vec.seed(seed)
    return vec


@dataclass(frozen=True)
class BatchedShard:
    """Builds one shard of a batched training env: `task`'s sim.batched env of n envs under `config`, as an SB3 VecEnv
    (picklable: worker processes build their shards with it)."""

    task: str
    config: Mapping[str, Any]

    def __call__(self, n_envs: int) -> Any:
        from curbside.train.vec import VectorEnvAdapter
        from sim.batched import BatchedPointNav, BatchedSocialNav

        batched = BatchedSocialNav if self.task == "SocialNav" else BatchedPointNav
        return VectorEnvAdapter(batched(n_envs, config=dict(self.config)))
