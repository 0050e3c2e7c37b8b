"""Vector envs: env steps/s of one env in one process vs `gymnasium.make_vec(..., "async")` over N workers.

Usage: python benchmarks/vector_envs.py [--task PointNav|SocialNav] [--envs N] [--steps S] [--per-worker K]
Both sides run the bench scene (sim.bench.bench_scene) under the same fixed action cycle and count env steps per
wall-clock second (the vector env spends its time in N processes). Target (issue 14): with N = cores the vector
env reaches >= 1.8x one process on the 2-core dev machine. Also measured: N workers stepping K envs each
(curbside.train.sharded.ShardedVectorEnv, the harness default), which pays one pipe round trip per K env steps;
and the ceiling: N independent processes each stepping one env with no synchronisation at all, side by side (the
sum of their rates over one process's rate is the most any vector env of N workers could reach on this machine).
Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from functools import partial

import gymnasium as gym
import numpy as np

import sim  # noqa: F401  (registers the env ids)
from curbside.train.sharded import ShardedVectorEnv
from curbside.train.vec import single_thread_worker
from sim.bench import SOCIALNAV_BENCH, bench_scene

WARMUP = 200  # untimed steps (rounds) first: every process loads its numba kernels and settles on its first step
ACTIONS = np.array([[0.8, 0.0], [0.6, 0.3], [0.8, 0.0], [0.5, -0.3]], dtype=np.float32)


def _config(task: str, spec: dict) -> dict:
    return {"scene_spec": spec, **(SOCIALNAV_BENCH if task == "SocialNav" else {})}


def one_process(task: str, spec: dict, steps: int) -> float:
    """Env steps per wall second of one env stepped in this process (resets included, as a vector env has them)."""
    env = gym.make(f"curbside/{task}-v0", config=_config(task, spec))
    env.reset(seed=0)
    for k in range(-WARMUP, steps):
        if k == 0:
            t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(ACTIONS[k % len(ACTIONS)])
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


def _independent(args: tuple[str, dict, int]) -> float:
    """one_process in a worker of side_by_side (BLAS single-threaded, as vector env workers are)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    return one_process(*args)


def side_by_side(task: str, spec: dict, steps: int, n: int) -> float:
    """Summed env steps per wall second of `n` processes each stepping its own env, started together, never
    synchronised: the ceiling for a vector env of `n` workers."""
    import multiprocessing as mp

    with mp.get_context("forkserver").Pool(n) as pool:
        return float(sum(pool.map(_independent, [(task, spec, steps)] * n)))


def _rate(venv: gym.vector.VectorEnv, steps: int) -> float:
    """Env steps per wall second of `venv` under the fixed action cycle (steps counted over all its envs)."""
    n = venv.num_envs
    venv.reset(seed=0)
    rounds = max(steps // n, 1)
    for k in range(-WARMUP, rounds):
        if k == 0:
            t0 = time.perf_counter()
        venv.step(np.repeat(ACTIONS[k % len(ACTIONS)][None], n, axis=0))
    rate = rounds * n / (time.perf_counter() - t0)
    venv.close()
    return rate


def vector(task: str, spec: dict, steps: int, n: int) -> float:
    """Env steps per wall second of Gymnasium's async vector env of `n` workers (BLAS single-threaded)."""
    fn = single_thread_worker(partial(gym.make, f"curbside/{task}-v0", config=_config(task, spec)))
    return _rate(gym.vector.AsyncVectorEnv([fn] * n, context="forkserver",
                                           autoreset_mode=gym.vector.AutoresetMode.SAME_STEP), steps)


def sharded(task: str, spec: dict, steps: int, workers: int, per_worker: int) -> float:
    """Env steps per wall second of `workers` processes stepping `per_worker` envs each (ShardedVectorEnv, as the
    training harness builds it: curbside.train.envs.make_vec_env)."""
    fn = single_thread_worker(partial(gym.make, f"curbside/{task}-v0", config=_config(task, spec)))
    return _rate(ShardedVectorEnv([fn] * (workers * per_worker), workers=workers), steps)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=("PointNav", "SocialNav"), default="PointNav")
    ap.add_argument("--envs", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--per-worker", type=int, default=4, help="envs per worker of the sharded vector env")
    args = ap.parse_args()
    spec = bench_scene()
    single = one_process(args.task, spec, args.steps)
    vec = vector(args.task, spec, args.steps, args.envs)
    shard = sharded(args.task, spec, args.steps, args.envs, args.per_worker)
    ceiling = side_by_side(args.task, spec, args.steps, args.envs)
    result = {"task": args.task, "envs": args.envs, "steps": args.steps, "one_process_steps_per_s": round(single, 1),
              "vector_steps_per_s": round(vec, 1), "speedup": round(vec / single, 2),
              "sharded_envs_per_worker": args.per_worker, "sharded_steps_per_s": round(shard, 1),
              "sharded_speedup": round(shard / single, 2), "independent_steps_per_s": round(ceiling, 1),
              "ceiling_speedup": round(ceiling / single, 2), "cpu_count": os.cpu_count(),
              "loadavg_1min": round(os.getloadavg()[0], 2)}
    print(json.dumps(result, sort_keys=True))
