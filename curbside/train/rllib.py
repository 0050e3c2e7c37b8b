"""PPO at cluster scale on Ray RLlib (new API stack): the curbside envs registered with RLlib, its env runners
spread over the workers of a Ray cluster, writing the layout `curbside train run` writes.

Layout of `out` (as SB3's runs): run.json (with "engine": "rllib"), logs/progress.csv and TensorBoard events
(SB3's logger, SB3's key names), checkpoints/policy_<steps>_steps/ (RLlib checkpoints, one every ~100k env steps),
policy/ (the final checkpoint, which `curbside train eval` loads), eval_curve.csv with --eval-every.

The hyperparameters are the SB3 baselines' (curbside.train.protocols) mapped onto RLlib's names; a rollout
of n_steps per env feeds each update as in SB3. What RLlib does differently: the policy's log-std is an output of
the network rather than a free parameter (log_std_init is unused), and advantages are computed by RLlib's GAE.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import ConfigError

RLLIB_ALGOS = ("ppo", "ppo_et")  # PPO-Lag's multiplier update lives in an SB3 callback: --executor local
CHECKPOINT_EVERY = 100_000  # env steps between RLlib checkpoints (each is a folder of several files)


def rllib_env_name(task: str) -> str:
    """The name a task's env is registered under with RLlib (`ray.tune.registry`)."""
    return f"curbside-rllib/{task}"


def make_rllib_env(ctx: Mapping[str, Any]) -> Any:
    """RLlib's env creator: env runner k of N (worker_index 1..N; 0 is the driver's) owns scenes
    [(k-1) n / N, k n / N) of the train split, all in its scene cache, as a local worker does (envs.env_fns)."""
    import gymnasium as gym

    import sim  # noqa: F401  (registers the env ids in the env runner's process)
    from curbside.train.envs import env_id, split_config
    from curbside.train.online import early_termination_config

    n, runners = int(ctx["num_scenes"]), max(int(getattr(ctx, "num_workers", 0) or 0), 1)
    k = max(int(getattr(ctx, "worker_index", 0) or 0) - 1, 0)
    lo, hi = k * n // runners, (k + 1) * n // runners
    if hi <= lo:
        lo, hi = k % n, k % n + 1
    base = ctx["env_config"]
    if ctx["algo"] == "ppo_et":
        base = early_termination_config(base, float(ctx["cost_limit"]))
    cfg = split_config(base, "train", hi - lo, scene_seed=lo)
    cfg.setdefault("scene_cache", min(hi - lo, 16))
    return gym.make(env_id(ctx["task"]), config=cfg)


def ppo_config(
    algo: str,
    task: str,
    env_config: Mapping[str, Any],
    hparams: Mapping[str, Any],
    *,
    num_env_runners: int,
    envs_per_runner: int,
    num_scenes: int,
    seed: int,
) -> Any:
    """The RLlib PPOConfig of our PPO hyperparameters (SB3 names mapped onto RLlib's)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    if algo not in RLLIB_ALGOS:
        raise ConfigError(f"the ray executor trains {', '.join(RLLIB_ALGOS)}; train {algo} with --executor local")
    register_env(rllib_env_name(task), make_rllib_env)
    h = dict(hparams)
    if "target_kl" in h:
        raise ConfigError(
            "the ray executor has no target_kl (RLlib's KL term is a loss penalty, not SB3's early stop of a batch's "
            "epochs); train with --executor local, or drop target_kl from --hparams"
        )
    n_envs = num_env_runners * envs_per_runner
    ctx = {
        "task": task,
        "env_config": dict(env_config),
        "num_scenes": num_scenes,
        "algo": algo,
        "cost_limit": float(h["cost_limit"]),
    }
    return (
        PPOConfig()
        .environment(rllib_env_name(task), env_config=ctx)
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=envs_per_runner,
            num_cpus_per_env_runner=1,
            rollout_fragment_length=int(h["n_steps"]),
        )
        .learners(num_learners=0)  # the learner runs in the driver; env runners are the scaled-out part
        .training(
            lr=float(h["learning_rate"]),
            gamma=float(h["gamma"]),
            lambda_=float(h["gae_lambda"]),
            clip_param=float(h["clip_range"]),
            entropy_coeff=float(h["ent_coef"]),
            vf_loss_coeff=float(h["vf_coef"]),
            grad_clip=float(h["max_grad_norm"]),
            num_epochs=int(h["n_epochs"]),
            minibatch_size=int(h["batch_size"]),
            train_batch_size_per_learner=int(h["n_steps"]) * n_envs,
            use_kl_loss=False,
            vf_clip_param=float("inf"),
        )  # SB3's PPO: no KL term, no value clipping
        .rl_module(
            model_config=DefaultModelConfig(
                fcnet_hiddens=list(h["net_arch"]), fcnet_activation="tanh", vf_share_layers=False
            )
        )
        .debugging(seed=seed, log_level="ERROR")
    )


def _latest_checkpoint(ckpt_dir: Path) -> Path | None:
    dirs = sorted((d for d in ckpt_dir.glob("policy_*_steps") if d.is_dir()), key=lambda d: int(d.name.split("_")[-2]))
    return dirs[-1] if dirs else None


def train_rllib(
    algo: str,
    task: str,
    out: Path,
    *,
    steps: int,
    env_config: Mapping[str, Any],
    n_envs: int,
    num_env_runners: int,
    num_scenes: int,
    hparams: Mapping[str, Any],
    seed: int = 0,
    resume: bool = False,
    eval_every: int = 0,
    eval_episodes: int = 20,
    eval_split: str = "test",
    address: str | None = None,
    progress: bool = True,
    meta: Mapping[str, Any] | None = None,
) -> Path:
    """Train PPO on RLlib for `steps` env steps with `num_env_runners` env runners (each stepping
    ceil(n_envs / runners) envs) on the Ray cluster at `address` (or one started here); returns the policy folder."""
    import logging

    import ray
    from stable_baselines3.common.logger import configure

    from curbside.train.callbacks import append_eval_row
    from curbside.train.evaluate import evaluate_policy
    from kernel.executors import connect_ray

    if not 1 <= num_env_runners <= 1024:
        raise ConfigError(f"num_env_runners must be in [1, 1024], got {num_env_runners}")
    envs_per_runner = max(1, math.ceil(n_envs / num_env_runners))
    logging.getLogger("ray.rllib").setLevel(logging.ERROR)  # RLlib's notices about its API stacks, on every run
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = connect_ray(num_env_runners + 1, address)  # one CPU for the driver's learner
    algo_obj = None
    try:
        config = ppo_config(
            algo,
            task,
            env_config,
            hparams,
            num_env_runners=num_env_runners,
            envs_per_runner=envs_per_runner,
            num_scenes=num_scenes,
            seed=seed,
        )
        algo_obj = config.build_algo()
        ckpt_dir = out / "checkpoints"
        latest = _latest_checkpoint(ckpt_dir) if resume else None
        done = 0
        if latest is not None:
            algo_obj.restore_from_path(str(latest.resolve()))
            done = int(latest.name.split("_")[-2])
        (out / "run.json").write_text(
            json.dumps(
                {
                    "algo": algo,
                    "task": task,
                    "steps": steps,
                    "n_envs": num_env_runners * envs_per_runner,
                    "num_scenes": num_scenes,
                    "seed": seed,
                    "hparams": dict(hparams),
                    "env_config": dict(env_config),
                    "engine": "rllib",
                    "num_env_runners": num_env_runners,
                    "envs_per_runner": envs_per_runner,
                    **dict(meta or {}),
                },
                indent=2,
                default=str,
            )
        )
        logger = configure(str(out / "logs"), ["csv", "tensorboard"])
        next_ckpt = (done // CHECKPOINT_EVERY + 1) * CHECKPOINT_EVERY
        next_eval = (done // eval_every + 1) * eval_every if eval_every > 0 else None
        t0, start_steps, iteration = time.perf_counter(), done, 0
        with _bar(f"rllib {algo} {task}", steps, progress) as update:
            update(done)
            while done < steps:
                result = algo_obj.train()
                iteration += 1
                done += int(result["env_runners"]["num_env_steps_sampled"])  # this iteration's env steps
                _log(logger, result, done, iteration, time.perf_counter() - t0, done - start_steps)
                update(done)
                if done >= next_ckpt:
                    algo_obj.save_to_path(str((ckpt_dir / f"policy_{done}_steps").resolve()))
                    next_ckpt = (done // CHECKPOINT_EVERY + 1) * CHECKPOINT_EVERY
                if next_eval is not None and done >= next_eval:
                    next_eval = (done // eval_every + 1) * eval_every
                    summary = evaluate_policy(
                        module_policy(algo_obj.get_module()),
                        task,
                        env_config,
                        split=eval_split,
                        episodes=eval_episodes,
                        progress=False,
                    )
                    append_eval_row(out / "eval_curve.csv", done, summary, logger, eval_split)
                    logger.dump(done)
        path = out / "policy"
        algo_obj.save_to_path(str(path.resolve()))
        return path
    finally:
        if algo_obj is not None:
            algo_obj.stop()
        if started:
            ray.shutdown()


def _log(
    logger: Any, result: Mapping[str, Any], steps: int, iteration: int, elapsed: float, session_steps: int
) -> None:
    """One row of logs/progress.csv under SB3's key names."""
    runners = result.get("env_runners", {})
    learner = result.get("learners", {}).get("default_policy", {})
    logger.record("time/iterations", iteration)
    logger.record("time/total_timesteps", steps)
    logger.record("time/time_elapsed", int(elapsed))
    logger.record("time/fps", int(session_steps / max(elapsed, 1e-9)))
    for key, name in (("episode_return_mean", "rollout/ep_rew_mean"), ("episode_len_mean", "rollout/ep_len_mean")):
        if key in runners and np.isfinite(float(runners[key])):
            logger.record(name, float(runners[key]))
    for key, name in (
        ("policy_loss", "train/policy_gradient_loss"),
        ("vf_loss", "train/value_loss"),
        ("entropy", "train/entropy"),
        ("default_optimizer_learning_rate", "train/learning_rate"),
    ):
        if key in learner:
            logger.record(name, float(learner[key]))
    logger.dump(steps)


def module_policy(module: Any) -> Any:
    """act(obs) -> the deterministic action (the Gaussian's mean, clipped to [-1, 1]) of an RLlib PPO module."""
    import torch

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            batch = torch.as_tensor(np.asarray(obs, dtype=np.float32)[None])
            logits = module.forward_inference({"obs": batch})["action_dist_inputs"][0].numpy()
        mean = logits[: logits.shape[-1] // 2]  # DiagGaussian inputs: means, then log-stds
        return np.clip(mean, -1.0, 1.0).astype(np.float32)

    return act


def load_rllib_policy(policy_dir: Path) -> Any:
    """act(obs) of the final checkpoint `policy_dir` that train_rllib wrote (its RL module alone, no cluster)."""
    import logging

    from ray.rllib.core.rl_module.rl_module import RLModule

    logging.getLogger("ray.rllib").setLevel(logging.ERROR)  # RLlib's own deprecation notice about its checkpoints
    module_dir = Path(policy_dir) / "learner_group" / "learner" / "rl_module" / "default_policy"
    if not module_dir.is_dir():
        raise ConfigError(
            f"{policy_dir} is not an RLlib PPO checkpoint (no {module_dir.relative_to(policy_dir)}); "
            "train again with `curbside train run --executor ray`"
        )
    return module_policy(RLModule.from_checkpoint(str(module_dir.resolve())))


def _bar(description: str, total: int, enabled: bool) -> Any:
    """The training progress bar over env steps (curbside.train.progress)."""
    from curbside.train.progress import progress_bar

    return progress_bar(description, total, enabled)
