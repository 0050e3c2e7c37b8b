"""PPO training throughput end to end (env steps, policy inference and the learner's updates) under a protocol.

Usage: python benchmarks/training_throughput.py [--protocol paper_realistic] [--iterations 2] [--only NAME ...]
       [--out benchmarks/results/training_throughput]

Each case builds the training VecEnv a `curbside train run` builds (curbside.train.envs.make_training_vec) and SB3's
PPO with the protocol's hyper-parameters, runs one PPO iteration (a train batch of env steps, then the update) to
warm up (scene builds, first touches), then times `--iterations` more: env steps per wall-clock second, with the
share of time in the update; and the milliseconds of one BC minibatch. Cases:
- ppo_pointnav_<protocol>_batched and ppo_socialnav_<protocol>_batched: the batched backend (sim.batched), the
  protocol's envs (paper_realistic: 64) in one batched env in the training process;
- ppo_pointnav_<protocol>_batched_sharded and ppo_socialnav_<protocol>_batched_sharded: the same envs as one batched
  env a core (curbside.train.batched_shards; training runs SocialNav's this way, PointNav's in one);
- ppo_pointnav_<protocol>_pybullet and ppo_socialnav_<protocol>_pybullet: the PyBullet envs sharded over the cores
  (8 envs; the paper's 128 processes do not fit two cores);
- bc_<protocol>_minibatch_ms: one behaviour-cloning minibatch of the protocol's batch size and network.
Writes summary.json (`<case>_env_steps_per_s` keys, the command, the load average) and a PNG beside it. Other
processes share the CPU: the 1-minute load average before each case is recorded; figures are lower bounds when it
was above 0.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

PYBULLET_ENVS = 8


def measure(task: str, backend: str, protocol: str, iterations: int, shards: int = 1) -> dict[str, Any]:
    """Env steps/s of PPO end to end for one (task, backend) under `protocol`; the batched envs in `shards` batched
    envs."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnvWrapper

    from curbside.train.callbacks import RolloutThreads
    from curbside.train.envs import make_training_vec
    from curbside.train.online import ppo_kwargs
    from curbside.train.protocols import protocol as get_protocol
    from curbside.train.run import resolve_run

    proto = get_protocol(protocol)
    n_envs = proto.n_envs if backend == "batched" else PYBULLET_ENVS
    run = resolve_run("ppo", task, protocol=protocol, n_envs=n_envs)
    extra = proto.backend_config(backend)
    torch.set_num_threads(2 if backend == "batched" else 1)
    t0 = time.perf_counter()
    vec = make_training_vec(
        task, {**run["env_config"], **extra}, n_envs, run["num_scenes"], backend=backend, shards=shards
    )
    shards = (len(getattr(vec.venv, "bounds", ())) or 1) if backend == "batched" else None  # batched env processes

    class EnvClock(VecEnvWrapper):
        """Seconds the training VecEnv spends stepping (the env alone, on the policy's own actions)."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.step_s = 0.0
            self.steps = 0

        def reset(self) -> Any:
            return self.venv.reset()

        def step_wait(self) -> Any:
            t = time.perf_counter()
            out = self.venv.step_wait()
            self.step_s += time.perf_counter() - t
            self.steps += self.num_envs
            return out

        def step_async(self, actions: Any) -> None:
            t = time.perf_counter()
            self.venv.step_async(actions)
            self.step_s += time.perf_counter() - t

    clock = EnvClock(vec)
    model = PPO("MlpPolicy", clock, seed=0, device="cpu", verbose=0, **ppo_kwargs(run["hparams"]))
    batch = model.n_steps * n_envs

    class UpdateTimer(BaseCallback):
        """Time spent outside rollouts (the update), from the rollout ends and starts SB3 reports."""

        def __init__(self) -> None:
            super().__init__()
            self.update_s = 0.0
            self.mark: float | None = None

        def _on_rollout_start(self) -> None:
            if self.mark is not None:
                self.update_s += time.perf_counter() - self.mark

        def _on_rollout_end(self) -> None:
            self.mark = time.perf_counter()

        def _on_step(self) -> bool:
            return True

    threads = RolloutThreads(torch.get_num_threads())  # as curbside.train.online trains
    try:
        model.learn(batch, callback=threads)  # warm-up: the first scenes are built here
        warm_s = time.perf_counter() - t0
        timer = UpdateTimer()
        clock.step_s, clock.steps = 0.0, 0
        w0 = time.perf_counter()
        model.learn(batch * iterations, reset_num_timesteps=False, callback=[timer, threads])
        wall = time.perf_counter() - w0
        if timer.mark is not None:
            timer.update_s += time.perf_counter() - timer.mark  # the last update
    finally:
        clock.close()
    env_alone = clock.steps / clock.step_s
    learner_s = timer.update_s / iterations
    end_to_end = batch * iterations / wall
    floor = batch / (batch / env_alone + learner_s)
    return {
        "task": task,
        "backend": backend,
        "batched_shards": shards,
        "protocol": protocol,
        "n_envs": n_envs,
        "train_batch": batch,
        "iterations": iterations,
        "env_steps": batch * iterations,
        "wall_s": round(wall, 2),
        "env_steps_per_s": round(end_to_end, 1),
        "update_share": round(timer.update_s / wall, 3),
        "env_alone_steps_per_s": round(env_alone, 1),
        "learner_s_per_batch": round(learner_s, 3),
        "floor_steps_per_s": round(floor, 1),
        "floor_ratio": round(end_to_end / floor, 3),
        "warmup_s": round(warm_s, 1),
        "net_arch": run["hparams"]["net_arch"],
        "n_epochs": run["hparams"]["n_epochs"],
        "load_avg_1min_before": None,
    }


def bc_minibatch_ms(protocol: str, steps: int = 2_000) -> float:
    """Milliseconds per BC minibatch (curbside.train.imitate.train_bc, the protocol's batch and network) on 30,000
    random PointNav-shaped transitions."""
    import tempfile

    import gymnasium as gym
    import numpy as np

    from curbside.train.demos import Transitions
    from curbside.train.imitate import train_bc
    from curbside.train.protocols import protocol as get_protocol

    rng = np.random.default_rng(0)
    n, d = 30_000, 329
    obs = rng.uniform(-1, 1, (n, d)).astype(np.float32)
    demos = Transitions(
        obs=obs,
        actions=rng.uniform(-1, 1, (n, 2)).astype(np.float32),
        rewards=np.zeros(n, np.float32),
        next_obs=obs,
        terminals=np.zeros(n, bool),
        timeouts=np.zeros(n, bool),
    )
    obs_space = gym.spaces.Box(-1.0, 1.0, (d,), np.float32)
    act_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    h = get_protocol(protocol).algo_hparams("bc")
    with tempfile.TemporaryDirectory() as tmp:
        train_bc(
            demos,
            Path(tmp) / "warm",
            steps=50,
            observation_space=obs_space,
            action_space=act_space,
            hparams=h,
            progress=False,
        )
        t0 = time.perf_counter()
        train_bc(
            demos,
            Path(tmp) / "bc",
            steps=steps,
            observation_space=obs_space,
            action_space=act_space,
            hparams=h,
            progress=False,
        )
    return 1000 * (time.perf_counter() - t0) / steps


def plot(summary: dict[str, Any], path: Path) -> None:
    """A bar per case: env steps/s end to end, the update's share, and a tick at the env alone."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = summary["cases"]
    names = list(cases)
    rates = [cases[n]["env_steps_per_s"] for n in names]
    upd = [cases[n]["env_steps_per_s"] * cases[n]["update_share"] for n in names]
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.barh(names, rates, color="#4c72b0", label="env steps/s (end to end)")
    ax.barh(names, upd, color="#dd8452", alpha=0.6, label="share of wall time in the update")
    alone = [cases[n].get("env_alone_steps_per_s", float("nan")) for n in names]
    ax.scatter(alone, names, marker="|", s=200, color="k", label="env alone (the same run)", zorder=3)
    ax.axvline(2800, color="k", ls="--", lw=1, label="target 2,800 (paper, PointNav)")
    ax.axvline(1400, color="k", ls=":", lw=1, label="target 1,400 (paper, SocialNav)")
    ax.set_xlabel("PPO env steps per wall-clock second, 2-core machine")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    from curbside.train.sharded import usable_cores

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--protocol", default="paper_realistic")
    ap.add_argument("--iterations", type=int, default=2, help="timed PPO iterations per case (after one warm-up)")
    ap.add_argument("--only", nargs="*", default=None, help="case names to run (default: all)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "training_throughput")
    args = ap.parse_args()
    cases = [
        ("PointNav", "batched"),
        ("SocialNav", "batched"),
        ("PointNav", "batched_sharded"),
        ("SocialNav", "batched_sharded"),
        ("PointNav", "pybullet"),
        ("SocialNav", "pybullet"),
        ("bc", "minibatch"),
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "summary.json"
    summary: dict[str, Any] = json.loads(path.read_text()) if path.is_file() else {"cases": {}}
    command = "python benchmarks/" + " ".join(shlex.quote(a) for a in [Path(__file__).name, *sys.argv[1:]])
    if args.only:  # a partial re-measure: its command goes with the cases it measured, the full run's stays
        summary.setdefault("case_commands", {}).update({name: command for name in args.only})
    else:
        summary["command"] = command
        summary.pop("case_commands", None)
    summary["machine"] = f"{os.cpu_count()} CPUs"
    for task, backend in cases:
        name = f"ppo_{task.lower()}_{args.protocol}_{backend}" if task != "bc" else f"bc_{args.protocol}_minibatch_ms"
        if args.only and name not in args.only:
            continue
        if task == "bc":
            summary[name] = round(bc_minibatch_ms(args.protocol), 2)
            print(f"{name}: {summary[name]} ms a BC minibatch", flush=True)
            path.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
            continue
        load = os.getloadavg()[0]
        sharded = backend == "batched_sharded"
        result = measure(
            task,
            "batched" if sharded else backend,
            args.protocol,
            args.iterations,
            shards=usable_cores() if sharded else 1,
        )
        result["load_avg_1min_before"] = round(load, 2)
        summary["cases"][name] = result
        summary[f"{name}_env_steps_per_s"] = result["env_steps_per_s"]
        summary[f"{name}_env_alone_steps_per_s"] = result["env_alone_steps_per_s"]
        summary[f"{name}_learner_s_per_batch"] = result["learner_s_per_batch"]
        summary[f"{name}_floor_ratio"] = result["floor_ratio"]
        print(
            f"{name}: {result['env_steps_per_s']:,.0f} env steps/s ({result['n_envs']} envs, batch "
            f"{result['train_batch']:,}, update {100 * result['update_share']:.0f} % of the time; warm-up "
            f"{result['warmup_s']} s; load before {load:.2f}); env alone {result['env_alone_steps_per_s']:,.0f} "
            f"env steps/s, learner {result['learner_s_per_batch']:.2f} s a batch: floor "
            f"{result['floor_steps_per_s']:,.0f}, end to end / floor {result['floor_ratio']:.2f}",
            flush=True,
        )
        path.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    plot(summary, args.out / "summary.png")


if __name__ == "__main__":
    main()
