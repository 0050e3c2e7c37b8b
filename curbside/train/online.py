"""Online RL on Stable-Baselines3: PPO, PPO-Lag (Lagrangian cost penalty) and PPO-ET (episode ends on a cost).

PPO-Lag and PPO-ET are PPO with a small, explicit change each (Ray et al. 2019's Lagrangian safe RL; Sun et al.
2021's early termination as used by MetaUrban's Table 1):
- PPO-Lag trains on r - lambda * c, and after every rollout raises lambda by `lag_lr` * (mean episode cost -
  `cost_limit`) (never below 0), so the policy trades progress against the cost budget.
- PPO-ET ends an episode at its first cost step with `et_penalty`: the simplest hard constraint.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

ONLINE_ALGOS = ("ppo", "ppo_lag", "ppo_et")
PPO_DEFAULTS: dict[str, Any] = {
    "learning_rate": 3e-4, "n_steps": 512, "batch_size": 256, "n_epochs": 10, "gamma": 0.99, "gae_lambda": 0.95,
    "clip_range": 0.2, "ent_coef": 0.0, "vf_coef": 0.5, "max_grad_norm": 0.5, "net_arch": [256, 256],
    "log_std_init": -0.5, "cost_limit": 1.0, "lag_lr": 0.05, "lag_init": 0.1, "et_penalty": -5.0,
}


class EarlyTermination(gym.Wrapper):
    """PPO-ET: the first step whose info["cost"] is 1 ends the episode, with `penalty` added to its reward."""

    def __init__(self, env: gym.Env, penalty: float = -5.0) -> None:
        super().__init__(env)
        self.penalty = float(penalty)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        """Step; end the episode on a cost step (metrics are still reported by the env's own end)."""
        obs, r, term, trunc, info = self.env.step(action)
        if info.get("cost", 0.0) > 0 and not (term or trunc):
            r += self.penalty
            term = True
            u = self.env.unwrapped
            metrics = u._episode_metrics()
            info.update(metrics, metrics=metrics, episode_cost=metrics.get("cost", 1.0), cost=1.0,
                        is_success=False, early_terminated=True)
        return obs, r, term, trunc, info


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
    h = dict(hparams)
    extra = {k: h.pop(k) for k in ("cost_limit", "lag_lr", "lag_init", "et_penalty")}
    del extra
    policy_kwargs = {"net_arch": list(h.pop("net_arch")), "log_std_init": float(h.pop("log_std_init"))}
    return dict(h, policy_kwargs=policy_kwargs)


def train_online(algo: str, task: str, out: Path, *, steps: int, env_config: Mapping[str, Any], n_envs: int,
                 num_scenes: int, hparams: Mapping[str, Any], seed: int = 0, resume: bool = False,
                 eval_every: int = 0, eval_episodes: int = 20, eval_split: str = "test",
                 progress: bool = True, subprocess: bool = True) -> Path:
    """Train `algo` on the train split for `steps` env steps; checkpoints, CSV/TensorBoard logs and the final
    policy (`policy.zip`) go to `out`; returns the policy path. `resume` continues from `out/checkpoints`."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback
    from stable_baselines3.common.logger import configure

    from curbside.train.callbacks import SplitEvalCallback
    from curbside.train.envs import make_vec_env

    torch.set_num_threads(1)  # the env workers need the cores; a 256x256 MLP does not
    out.mkdir(parents=True, exist_ok=True)
    wrappers: tuple = ()
    if algo == "ppo_et":
        pen = float(hparams["et_penalty"])
        wrappers = (lambda e: EarlyTermination(e, pen),)
    vec = make_vec_env(task, env_config, n_envs, num_scenes, subprocess=subprocess, seed=seed, wrappers=wrappers)
    ckpt_dir = out / "checkpoints"
    latest = _latest_checkpoint(ckpt_dir) if resume else None
    if latest is not None:
        model = PPO.load(latest, env=vec, device="cpu")
    else:
        model = PPO("MlpPolicy", vec, seed=seed, device="cpu", verbose=0, **ppo_kwargs(hparams))
    model.set_logger(configure(str(out / "logs"), ["csv", "tensorboard"]))
    callbacks: list = [CheckpointCallback(max(100_000 // n_envs, 1), str(ckpt_dir), name_prefix="policy")]
    if algo == "ppo_lag":
        state = out / "lagrange.json"
        if latest is None and state.exists():
            state.unlink()  # a fresh run starts from lag_init
        callbacks.append(_lagrange_callback(float(hparams["lag_lr"]), float(hparams["cost_limit"]),
                                            float(hparams["lag_init"]), state))
    if eval_every > 0:
        callbacks.append(SplitEvalCallback(task, env_config, eval_every, eval_episodes, eval_split, out / "eval_curve.csv"))
    (out / "run.json").write_text(json.dumps({"algo": algo, "task": task, "steps": steps, "n_envs": n_envs,
                                              "num_scenes": num_scenes, "seed": seed, "hparams": dict(hparams),
                                              "env_config": dict(env_config)}, indent=2, default=str))
    remaining = max(steps - model.num_timesteps, 0)
    try:
        model.learn(remaining, callback=CallbackList(callbacks), progress_bar=progress,
                    reset_num_timesteps=latest is None)
    finally:
        vec.close()
    path = out / "policy.zip"
    model.save(path)
    return path


def _latest_checkpoint(ckpt_dir: Path) -> Path | None:
    files = sorted(ckpt_dir.glob("policy_*_steps.zip"), key=lambda f: int(f.stem.split("_")[-2]))
    return files[-1] if files else None
