"""Where a ShardedVectorEnv step's time goes: timestamps in the parent and its worker, per round.

Usage: python benchmarks/handover_timeline.py [--task PointNav|SocialNav] [--steps 6000]
Two envs of the bench scene, one in this process (shard 0) and one in a worker; both processes stamp the phases of
every step with time.perf_counter (one clock across processes) through wrappers around the module's functions, so
the timed code is the real hand-over. Prints per phase mean / p10 / p50 / p90 (us) over the rounds after the first
1,000: the parent's work before its env steps (step_async), each env's step, the parent batching its env's infos,
the worker's reply, the parent's work after both are done, and the imbalance |parent done - worker done|, which
lock-step costs on every round whatever the hand-over.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from curbside.train import handover, sharded
from sim.bench import bench_scene

OUT = Path("/tmp/curbside_timeline")


def _install(tag: str, stamps: dict[str, list[float]], dump_after: int = 0) -> None:
    """Wrap run_command, wait_for and reply (where the worker's `serve` and the parent's ShardedVectorEnv look them
    up) to stamp `tag`_<phase> (the worker dumps its stamps after `dump_after` step replies: a worker process is
    never joined with its atexit hooks run)."""
    run, wait, reply = handover.run_command, handover.wait_for, handover.reply

    def stamp(name: str) -> None:
        stamps.setdefault(f"{tag}_{name}", []).append(time.perf_counter())

    def run_command(envs: Any, arrays: Any, lo: int, command: str, data: Any) -> Any:
        stamp("run0") if command == "step" else None
        out = run(envs, arrays, lo, command, data)
        stamp("run1") if command == "step" else None
        return out

    def wait_for(sem: Any, spin: float, alive: Any, poll: float = 1.0) -> None:
        wait(sem, spin, alive, poll)
        stamp("woke")

    def reply_(pipe: Any, sem: Any, arrays: Any, w: int, status: str, payload: Any) -> None:
        reply(pipe, sem, arrays, w, status, payload)
        if status == "step":
            stamp("replied")
            if len(stamps[f"{tag}_replied"]) == dump_after:
                np.savez(OUT / f"{tag}.npz", **{k: np.array(v) for k, v in stamps.items()})

    handover.run_command, handover.wait_for, handover.reply = run_command, wait_for, reply_
    sharded.run_command, sharded.wait_for = run_command, wait_for


def _make(task: str, spec: dict, steps: int) -> object:
    """The bench env; in the worker process, also the stamping wrappers."""
    from threadpoolctl import threadpool_limits
    from vector_envs import make_env

    if mp.parent_process() is not None and not getattr(sharded, "_stamping", False):
        sharded._stamping = True  # a diagnostic flag on the module
        _install("w", {}, dump_after=steps)
    threadpool_limits(1)
    return make_env(task, spec)


def main() -> None:
    """Run the rounds and print the phases."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=("PointNav", "SocialNav"), default="PointNav")
    ap.add_argument("--steps", type=int, default=6000)
    args = ap.parse_args()
    from vector_envs import ACTIONS

    OUT.mkdir(exist_ok=True)
    (OUT / "w.npz").unlink(missing_ok=True)
    fn = partial(_make, args.task, bench_scene(), args.steps)
    venv = sharded.ShardedVectorEnv([fn, fn], workers=2)
    venv.reset(seed=0)
    stamps: dict[str, list[float]] = {}
    sharded._stamping = True
    _install("p", stamps)
    for k in range(args.steps):
        stamps.setdefault("p_loop", []).append(time.perf_counter())
        venv.step(np.repeat(ACTIONS[k % len(ACTIONS)][None], 2, axis=0))
    venv.close()
    w = dict(np.load(OUT / "w.npz"))
    p = {k: np.array(v) for k, v in stamps.items()}
    n = args.steps - 1
    loop, pr0, pr1, pwoke = p["p_loop"], p["p_run0"], p["p_run1"], p["p_woke"]
    wr0, wr1, wrep = w["w_run0"], w["w_run1"], w["w_replied"]
    # The parent's own env's infos are batched between its step's end and its wait; the wait ends at `pwoke`.
    phases = {
        "round": loop[1 : n + 1] - loop[:n],
        "parent: step_async, its env starts": pr0[:n] - loop[:n],
        "worker: woken, its env starts": wr0[:n] - loop[:n],
        "parent env step": pr1[:n] - pr0[:n],
        "worker env step": wr1[:n] - wr0[:n],
        "worker: reply": wrep[:n] - wr1[:n],
        "parent: after both, to its next step": loop[1 : n + 1] - np.maximum(pr1[:n], wrep[:n]),
        "parent: waiting": pwoke[:n] - pr1[:n],
        "imbalance |parent env done - worker replied|": np.abs(pr1[:n] - wrep[:n]),
    }
    for name, x in phases.items():
        x = x[1000:] * 1e6
        print(
            f"{name:48s} mean {x.mean():7.1f}  p10 {np.percentile(x, 10):7.1f}  p50 {np.percentile(x, 50):7.1f}  "
            f"p90 {np.percentile(x, 90):7.1f}"
        )


if __name__ == "__main__":
    main()
