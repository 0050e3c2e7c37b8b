"""Vector envs: env steps/s of one env in one process vs vector envs of N workers, in paired rounds.

Usage: python benchmarks/vector_envs.py [--task PointNav|SocialNav] [--workers N] [--per-worker K] [--steps S]
                                        [--rounds R] [--out results.json]
Every side runs the bench scene (sim.bench.bench_scene) under the same fixed action cycle and counts env steps per
wall-clock second. Target: with N = cores workers the vector env reaches >= 1.8x one process on the
2-core dev machine. Measured, one after another in each of R rounds (this VM's speed drifts by 20 % over minutes,
so each ratio divides two rates taken seconds apart, and the summary is the median round):
  one       one env stepped in a process of its own (resets included, as a vector env has them);
  sharded   curbside.train.sharded.ShardedVectorEnv, N workers of K envs (the training harness's vector env);
  async     Gymnasium's AsyncVectorEnv (`gymnasium.make_vec(..., vectorization_mode="async")`), N workers of 1 env;
  barrier   N processes each stepping its own env, held in lock-step by a semaphore barrier and passing no data:
            what any synchronous vector env of N workers could reach at best (it waits for the slower step);
  ceiling   the same N processes never synchronised: what the cores give.
Every env and process is built once and kept between rounds; each timed run starts after WARMUP untimed steps.
Every process stepping envs has BLAS limited to one thread, as the training harness's workers have.
Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import time
from functools import partial
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import sim  # noqa: F401  (registers the env ids)
from curbside.train.handover import wait_for
from curbside.train.sharded import ShardedVectorEnv
from curbside.train.vec import single_thread_worker
from sim.bench import SOCIALNAV_BENCH, bench_scene

WARMUP = 100  # untimed steps (rounds) before each timed run: caches refill after the other sides ran
ACTIONS = np.array([[0.8, 0.0], [0.6, 0.3], [0.8, 0.0], [0.5, -0.3]], dtype=np.float32)
PARTS = ("one", "sharded", "async", "barrier", "ceiling")


def make_env(task: str, spec: dict) -> gym.Env:
    """The bench env of `task` on scene `spec` (SocialNav with 20 agents and traffic)."""
    extra = SOCIALNAV_BENCH if task == "SocialNav" else {}
    return gym.make(f"curbside/{task}-v0", config={"scene_spec": spec, **extra})


def run_vector(venv: gym.vector.VectorEnv, steps: int) -> float:
    """Env steps per wall second of `venv` (steps counted over all its envs), after WARMUP rounds."""
    n = venv.num_envs
    rounds = max(steps // n, 1)
    for k in range(-WARMUP, rounds):
        if k == 0:
            t0 = time.perf_counter()
        venv.step(np.repeat(ACTIONS[k % len(ACTIONS)][None], n, axis=0))
    return rounds * n / (time.perf_counter() - t0)


def _stepper(task: str, spec: dict, index: int, pipe: Any, sems: list[list[Any]]) -> None:
    """A process of the barrier and ceiling runs: on ("run", steps, sync) step its env and send back its rate;
    with `sync`, wait before each step until every process has finished its previous one (sems[i][j]: j's posts
    to i, one semaphore per pair so that a post for the next step is never taken for this one)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)  # as vector env workers are
    env = make_env(task, spec)
    env.reset(seed=index)
    n = len(sems)
    pipe.send("ready")
    while (msg := pipe.recv())[0] == "run":
        _, steps, sync = msg
        for k in range(-WARMUP, steps):
            if k == 0:
                t0 = time.perf_counter()
            if sync:  # a barrier: post to every other process, take one post from each (spinning, as the
                # sharded env's hand-over does)
                for j in range(n):
                    if j != index:
                        sems[j][index].release()
                for j in range(n):
                    if j != index:
                        wait_for(sems[index][j], 3600.0, lambda: True)
            _, _, term, trunc, _ = env.step(ACTIONS[k % len(ACTIONS)])
            if term or trunc:
                env.reset()
        pipe.send(steps / (time.perf_counter() - t0))
    env.close()


class Steppers:
    """N processes, each with its own bench env, kept between runs (the barrier and ceiling sides)."""

    def __init__(self, task: str, spec: dict, n: int) -> None:
        ctx = mp.get_context("forkserver")
        sems = [[ctx.Semaphore(0) for _ in range(n)] for _ in range(n)]
        self.pipes, self.procs = [], []
        for i in range(n):
            a, b = ctx.Pipe()
            proc = ctx.Process(target=_stepper, args=(task, spec, i, b, sems), daemon=True)
            proc.start()
            self.pipes.append(a)
            self.procs.append(proc)
        for pipe in self.pipes:
            pipe.recv()

    def rate(self, steps: int, sync: bool) -> float:
        """Summed env steps per wall second of the N processes stepping `steps` // N steps each at once."""
        for pipe in self.pipes:
            pipe.send(("run", steps // len(self.pipes), sync))
        return float(sum(pipe.recv() for pipe in self.pipes))

    def close(self) -> None:
        """Stop the processes."""
        for pipe, proc in zip(self.pipes, self.procs):
            pipe.send(("stop",))
            proc.join(timeout=10)


def main() -> None:
    """Parse the command line, run the rounds, print one JSON line per round and the summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=("PointNav", "SocialNav"), default="PointNav")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2, help="N: worker processes (default: cores)")
    ap.add_argument("--per-worker", type=int, default=1, help="K: envs per worker of the sharded vector env")
    ap.add_argument("--steps", type=int, default=4000, help="env steps per timed run")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated subset of {','.join(PARTS)}")
    ap.add_argument("--out", type=Path, help="also write the rounds and the summary here (JSON)")
    args = ap.parse_args()
    parts = args.parts.split(",")
    if "one" not in parts or not set(parts) <= set(PARTS):
        ap.error(f"--parts must include 'one' and name only {', '.join(PARTS)}")
    spec = bench_scene()
    fn = single_thread_worker(partial(make_env, args.task, spec))
    one = Steppers(args.task, spec, 1)  # a process of its own: this one holds the sharded env's local shard
    sides: dict[str, Any] = {}
    if "sharded" in parts:
        sides["sharded"] = ShardedVectorEnv([fn] * (args.workers * args.per_worker), workers=args.workers)
    if "async" in parts:
        sides["async"] = gym.vector.AsyncVectorEnv(
            [fn] * args.workers, context="forkserver", autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
        )
    steppers = Steppers(args.task, spec, args.workers) if {"barrier", "ceiling"} & set(parts) else None
    for venv in sides.values():
        venv.reset(seed=0)
    rounds = []
    for r in range(args.rounds):
        rates = {"one": one.rate(args.steps, False)}
        for name, venv in sides.items():
            rates[name] = run_vector(venv, args.steps)
        for name, sync in (("barrier", True), ("ceiling", False)):
            if name in parts:
                rates[name] = steppers.rate(args.steps, sync)
        row = {
            "round": r,
            **{f"{k}_steps_per_s": round(v, 1) for k, v in rates.items()},
            **{f"{k}_speedup": round(v / rates["one"], 3) for k, v in rates.items() if k != "one"},
        }
        rounds.append(row)
        print(json.dumps(row), flush=True)
    for venv in sides.values():
        venv.close()
    for procs in (one, steppers):
        if procs is not None:
            procs.close()
    summary = {
        "task": args.task,
        "workers": args.workers,
        "sharded_envs_per_worker": args.per_worker,
        "steps": args.steps,
        "rounds": args.rounds,
        "cpu_count": os.cpu_count(),
        "loadavg_1min": round(os.getloadavg()[0], 2),
        **{
            f"median_{k}": round(statistics.median(row[k] for row in rounds), 2)
            for k in rounds[0]
            if k.endswith("_speedup") or k == "one_steps_per_s"
        },
    }
    print(json.dumps(summary, sort_keys=True))
    if args.out:
        args.out.write_text(json.dumps({"summary": summary, "rounds": rounds}, indent=1) + "\n")


if __name__ == "__main__":
    main()
