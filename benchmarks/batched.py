"""Batched envs: env steps/s of `sim.batched.BatchedPointNav` (or BatchedSocialNav) with N envs, against one PyBullet env.

Usage: python benchmarks/batched.py [--task PointNav|SocialNav] [--envs 1 8 64 256] [--seconds S] [--route-pool K]
       [--out FILE]
Every run drives the bench scene (sim.bench.bench_scene, ~150-200 objects, 240 + 60 LiDAR beams) under the fixed
action cycle of benchmarks/vector_envs.py, resets included (SAME_STEP autoreset; with route_pool 0 every reset
plans a new route, as the PyBullet env does). Steps are counted over all envs per wall-clock second and per CPU
second of this process; the scene's one-off build (distance grids, route planner) is not timed. Target:
>= 5,000 env steps/s with 64 envs on the 2-core dev machine. Other processes share the CPU: the 1-minute load
average is printed beside each figure, and the figures are lower bounds when it is above 0.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from sim.batched import BatchedPointNav, BatchedSocialNav
from sim.bench import bench_scene
from sim.envs.pointnav import PointNavEnv
from sim.envs.socialnav import SocialNavEnv

# Per task: the batched env and the PyBullet env it is measured against (SocialNav: the task's default crowd).
ENVS = {"PointNav": (BatchedPointNav, PointNavEnv), "SocialNav": (BatchedSocialNav, SocialNavEnv)}

ACTIONS = np.array([[0.8, 0.0], [0.6, 0.3], [0.8, 0.0], [0.5, -0.3]], dtype=np.float32)  # benchmarks/vector_envs.py


def batched_rate(spec: dict, n: int, seconds: float, route_pool: int, task: str = "PointNav") -> dict:
    """Env steps per wall and per CPU second of `task`'s batched env with n envs under the action cycle, with
    episode counts."""
    env = ENVS[task][0](n, {"scene_spec": spec, "route_pool": route_pool})
    env.reset(seed=0)
    env.step(np.repeat(ACTIONS[:1], n, axis=0))  # warm (first-touch of the grids)
    rounds = episodes = 0
    w0, c0 = time.perf_counter(), time.process_time()
    while time.perf_counter() - w0 < seconds:
        _, _, term, trunc, _ = env.step(np.repeat(ACTIONS[rounds % len(ACTIONS)][None], n, axis=0))
        episodes += int((term | trunc).sum())
        rounds += 1
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    env.close()
    return {
        "envs": n,
        "route_pool": route_pool,
        "steps": rounds * n,
        "episodes": episodes,
        "steps_per_s": round(rounds * n / wall, 1),
        "steps_per_cpu_s": round(rounds * n / cpu, 1),
        "ms_per_batch_step": round(1000 * wall / rounds, 2),
        "loadavg_1min": round(os.getloadavg()[0], 2),
    }


def pybullet_rate(spec: dict, seconds: float, task: str = "PointNav") -> dict:
    """Env steps per wall and CPU second of one PyBullet env of `task` under the same action cycle."""
    env = ENVS[task][1]({"scene_spec": spec})
    env.reset(seed=0)
    steps = 0
    w0, c0 = time.perf_counter(), time.process_time()
    while time.perf_counter() - w0 < seconds:
        _, _, term, trunc, _ = env.step(ACTIONS[steps % len(ACTIONS)])
        if term or trunc:
            env.reset()
        steps += 1
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    env.close()
    return {
        "env": f"PyBullet {task}Env",
        "envs": 1,
        "steps": steps,
        "steps_per_s": round(steps / wall, 1),
        "steps_per_cpu_s": round(steps / cpu, 1),
        "loadavg_1min": round(os.getloadavg()[0], 2),
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=sorted(ENVS), default="PointNav")
    ap.add_argument("--envs", type=int, nargs="+", default=[1, 8, 64, 256])
    ap.add_argument("--seconds", type=float, default=10.0, help="timed seconds per configuration")
    ap.add_argument("--route-pool", type=int, nargs="+", default=[0, 64], help="route_pool values to run")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="append the command and results to this file "
        f"(e.g. benchmarks/results/sim_speed/batched_{date.today()}.txt)",
    )
    args = ap.parse_args()
    spec = bench_scene()
    lines = [json.dumps(pybullet_rate(spec, args.seconds, args.task), sort_keys=True)]
    print(lines[-1], flush=True)
    for pool in args.route_pool:
        for n in args.envs:
            lines.append(
                json.dumps(
                    {"env": f"Batched{args.task}", **batched_rate(spec, n, args.seconds, pool, args.task)},
                    sort_keys=True,
                )
            )
            print(lines[-1], flush=True)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with args.out.open("a", encoding="utf-8") as f:
            f.write("$ python " + " ".join(shlex.quote(a) for a in sys.argv) + "\n" + "\n".join(lines) + "\n")
