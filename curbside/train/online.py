"""Online RL on Stable-Baselines3: PPO, PPO-Lag (Lagrangian cost penalty) and PPO-ET (episode ends on a cost).

PPO-Lag and PPO-ET are PPO with a small, explicit change each (Ray et al. 2019's Lagrangian safe RL; Sun et al.
2021's early termination as used by MetaUrban's Table 1):
- PPO-Lag trains on r - lambda * c, and after every rollout raises lambda by `lag_lr` * (mean episode cost -
  `cost_limit`) (never below 0), so the policy trades progress against the cost budget.
- PPO-ET ends an episode once its cost exceeds `cost_limit` (the env's `max_episode_cost`; MetaUrban's rule), with
  the reward's `stuck` penalty.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from curbside.train.policies import save_policy
from kernel.config import ConfigError

ONLINE_ALGOS = ("ppo", "ppo_lag", "ppo_et")
SAFE_KEYS = ("cost_limit", "lag_lr", "lag_init")  # PPO-Lag / PPO-ET settings, not SB3 PPO arguments
GAIL_KEYS = ("demo_batch_size", "disc_updates_per_round", "disc_lr")
CHECKPOINT_EVERY = 25_000  # env steps between checkpoints: a killed run loses minutes, not hours


def early_termination_config(env_config: Mapping[str, Any], cost_limit: float) -> dict[str, Any]:
    """PPO-ET's training env config: the episode ends, failed, once its cost exceeds `cost_limit` (the env's
    `max_episode_cost`, with the reward's `stuck` term as its penalty)."""
    return {**env_config, "max_episode_cost": float(cost_limit)}


def _lagrange_callback(lag_lr: float, cost_limit: float, lam0: float, state: Path) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class LagrangeCallback(BaseCallback):
        """PPO-Lag: subtract lambda * cost from every reward; update lambda from the rollout's episode costs.

        lambda is not part of SB3's checkpoint: it is kept in `state` (lagrange.json) so a resumed run goes on
        with the multiplier it had.
        """

        def __init__(self) -> None:
            super().__init__()
            self.lam = float(json.loads(state.read_text())["lambda"]) if state.is_file() else lam0
            self.episode_costs: list[float] = []

        def _on_step(self) -> bool:
            # SB3 passes the rollout's rewards array by reference: the penalty enters GAE and the value targets.
            infos, rewards = self.locals["infos"], self.locals["rewards"]
            for k, info in enumerate(infos):
                rewards[k] -= self.lam * float(info.get("cost", 0.0))
                if "episode_cost" in info:
                    self.episode_costs.append(float(info["episode_cost"]))
            return True

        def _on_rollout_end(self) -> None:
            if self.episode_costs:
                jc = float(np.mean(self.episode_costs))
                self.lam = max(0.0, self.lam + lag_lr * (jc - cost_limit))
                self.logger.record("lagrange/episode_cost", jc)
                self.episode_costs = []
            self.logger.record("lagrange/lambda", self.lam)
            state.write_text(json.dumps({"lambda": self.lam, "steps": self.num_timesteps}))

    return LagrangeCallback()


def ppo_kwargs(hparams: Mapping[str, Any]) -> dict[str, Any]:
    """The SB3 PPO keyword arguments of our hyperparameters (net_arch and log_std_init go to policy_kwargs)."""
    h = {k: v for k, v in hparams.items() if k not in SAFE_KEYS + GAIL_KEYS + ("train_batch",)}
    policy_kwargs = {"net_arch": list(h.pop("net_arch")), "log_std_init": float(h.pop("log_std_init"))}
    return dict(h, policy_kwargs=policy_kwargs)


def train_online(
    algo: str,
    task: str,
    out: Path,
    *,
    steps: int,
    env_config: Mapping[str, Any],
    n_envs: int,
    num_scenes: int,
    hparams: Mapping[str, Any],
    seed: int = 0,
    resume: bool = False,
    eval_every: int = 0,
    eval_episodes: int = 20,
    eval_split: str = "test",
    eval_actions: str = "mean",
    progress: bool = True,
    subprocess: bool = True,
    split: str = "train",
    backend: str = "pybullet",
    backend_config: Mapping[str, Any] | None = None,
    init_from: Path | None = None,
    meta: Mapping[str, Any] | None = None,
) -> Path:
    """Train `algo` on `split` for `steps` env steps; checkpoints, CSV/TensorBoard logs and the final policy
    (`policy.zip`) go to `out`; returns the policy path. `resume` continues from `out/checkpoints`; `init_from`
    starts from another run's policy (its evaluation is the curve's first row when `eval_every` > 0); the curve's
    policy acts as `eval_actions` says (curbside.train.evaluate.EVAL_ACTIONS).
    `backend_config` holds env keys of the training backend alone (scene_steps; sim.batched's route_pool): the
    evaluations and run.json's env_config leave them out, and `env_config` wins where it sets one (ablation (b)'s
    runs change scenes more often, so that a run visits the scenes it counts)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList

    from curbside.train.callbacks import CheckpointEvery, RolloutThreads, SplitEvalCallback, training_logger
    from curbside.train.envs import make_training_vec

    out.mkdir(parents=True, exist_ok=True)
    ckpt_dir = out / "checkpoints"
    latest = latest_checkpoint(ckpt_dir) if resume else None
    source = (
        check_init_from(init_from, algo, task, env_config, hparams["net_arch"])
        if init_from is not None and latest is None
        else None
    )
    train_config = early_termination_config(env_config, hparams["cost_limit"]) if algo == "ppo_et" else dict(env_config)
    # The batched envs' shards rest while the policy updates (one shard steps in this process): the update may use
    # every core.
    torch.set_num_threads(2 if backend == "batched" else 1)
    vec = make_training_vec(
        task,
        {**(backend_config or {}), **train_config},
        n_envs,
        num_scenes,
        backend=backend,
        split=split,
        seed=seed,
        subprocess=subprocess,
    )
    kwargs = ppo_kwargs(hparams)
    if latest is not None:
        model = PPO.load(latest, env=vec, device="cpu")
    elif source is not None:
        policy_kwargs = kwargs.pop("policy_kwargs")
        model = PPO("MlpPolicy", vec, seed=seed, device="cpu", verbose=0, policy_kwargs=policy_kwargs, **kwargs)
        model.policy.load_state_dict(PPO.load(source, device="cpu").policy.state_dict())
    else:
        model = PPO("MlpPolicy", vec, seed=seed, device="cpu", verbose=0, **kwargs)
    model.set_logger(
        training_logger(out / "logs", ("csv", "tensorboard"), model.num_timesteps if latest is not None else None)
    )
    callbacks: list = [CheckpointEvery(ckpt_dir, CHECKPOINT_EVERY), RolloutThreads(torch.get_num_threads())]
    if algo == "ppo_lag":
        state = out / "lagrange.json"
        if latest is None and state.exists():
            state.unlink()  # a fresh run starts from lag_init
        callbacks.append(
            _lagrange_callback(
                float(hparams["lag_lr"]), float(hparams["cost_limit"]), float(hparams["lag_init"]), state
            )
        )
    if eval_every > 0:
        curve = out / "eval_curve.csv"
        if latest is None and curve.exists():
            curve.unlink()  # a fresh run writes a fresh curve
        callbacks.append(
            SplitEvalCallback(
                task,
                env_config,
                eval_every,
                eval_episodes,
                eval_split,
                curve,
                at_start=latest is None,
                actions=eval_actions,
            )
        )
    (out / "run.json").write_text(
        json.dumps(
            {
                "algo": algo,
                "task": task,
                "steps": steps,
                "n_envs": n_envs,
                "num_scenes": num_scenes,
                "seed": seed,
                "hparams": dict(hparams),
                "env_config": dict(env_config),
                "eval_every": eval_every,
                "eval_episodes": eval_episodes,
                **dict(meta or {}),
            },
            indent=2,
            default=str,
        )
    )
    remaining = max(steps - model.num_timesteps, 0)
    try:
        model.learn(
            remaining, callback=CallbackList(callbacks), progress_bar=progress, reset_num_timesteps=latest is None
        )
    finally:
        vec.close()
    return save_policy(model, out / "policy.zip")


def check_init_from(
    run_dir: Path, algo: str, task: str, env_config: Mapping[str, Any], net_arch: list[int] | None = None
) -> Path:
    """The policy file of the run `run_dir` that a PPO-family run of `task` (with network `net_arch`, when given) can
    start from; a ConfigError when it is not one (another task, algorithm family, observation space or network)."""
    from curbside.train.policies import read_run

    run = read_run(Path(run_dir))
    if run["algo"] not in ONLINE_ALGOS + ("gail",) or run.get("engine") == "rllib":
        raise ConfigError(
            f"--init-from {run_dir} is a {run['algo']} run; {algo} starts from a PPO, PPO-Lag, PPO-ET "
            "or GAIL run trained with --executor local"
        )
    if run["task"] != task:
        raise ConfigError(f"--init-from {run_dir} was trained on {run['task']}, not {task}; start from a {task} run")
    mine, theirs = observation_shape(task, env_config), observation_shape(run["task"], run.get("env_config", {}))
    if mine != theirs:
        raise ConfigError(
            f"--init-from {run_dir} observes {theirs}, this run {mine}: train with the source run's "
            "lidar and observation settings"
        )
    theirs_arch = list(run.get("hparams", {}).get("net_arch", []))
    if net_arch is not None and theirs_arch and theirs_arch != list(net_arch):
        raise ConfigError(
            f"--init-from {run_dir} has a {theirs_arch} network, this run {list(net_arch)}: train with "
            "the source run's net_arch"
        )
    path = Path(run_dir) / "policy.zip"
    if not path.is_file():
        raise ConfigError(
            f"{path} is missing; the source run did not finish: resume it with `curbside train run "
            f"--resume --out {run_dir}`"
        )
    return path


def observation_shape(task: str, env_config: Mapping[str, Any]) -> tuple[int, ...]:
    """The observation shape of `task`'s env under `env_config` (the table's layout, no scene built)."""
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import env_id, split_config

    env = gym.make(env_id(task), config=split_config(env_config, "train", 1))
    try:
        return tuple(env.observation_space.shape or ())
    finally:
        env.close()


def latest_checkpoint(ckpt_dir: Path) -> Path | None:
    """The newest whole checkpoint in `ckpt_dir`: one that is not a readable SB3 zip (a run killed while an older
    trainer wrote it in place) is skipped with a warning, so the run resumes from the one before."""
    import zipfile

    files = sorted(ckpt_dir.glob("policy_*_steps.zip"), key=lambda f: int(f.stem.split("_")[-2]))
    for path in reversed(files):
        try:
            with zipfile.ZipFile(path) as zf:
                if "data" in zf.namelist() and zf.testzip() is None:
                    return path
        except (zipfile.BadZipFile, OSError):
            pass
        warnings.warn(f"checkpoint {path} is not a whole SB3 zip; resuming from the one before it", stacklevel=2)
    return None
