"""Imitation learning on the `imitation` library: BC (supervised on expert actions) and GAIL (adversarial
reward from a discriminator, PPO generator on the train split)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from curbside.train.demos import Transitions
from curbside.train.progress import progress_bar


def _transitions(tr: Transitions) -> Any:
    from imitation.data.types import Transitions as ImTransitions

    return ImTransitions(obs=tr.obs, acts=tr.actions, infos=np.array([{}] * len(tr)), next_obs=tr.next_obs,
                         dones=tr.terminals | tr.timeouts)


def train_bc(demos: Transitions, out: Path, *, steps: int, observation_space: Any, action_space: Any,
             seed: int = 0, hparams: Mapping[str, Any] | None = None, progress: bool = True) -> Path:
    """Behaviour cloning for `steps` minibatches: maximise the log-likelihood of the demonstrated actions under an SB3
    ActorCriticPolicy (imitation's BC loss: - log p(a|s) - 1e-3 entropy), saved as `policy.zip`; a loss log beside.

    The loop is plain torch on tensors built once (a minibatch is an index draw): imitation's BC rebuilt a data loader
    of dicts every epoch, ~120 ms a minibatch on this 2-core machine against ~2 ms here.
    """
    import csv

    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    h = {"learning_rate": 1e-3, "batch_size": 256, "net_arch": [256, 256], **(hparams or {})}
    # One thread: minibatches of 64-256 through a 256 x 256 MLP gain nothing from a second, and lose 3x when the
    # other core is busy (9 vs 27 ms measured with another job running).
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    lr, batch = float(h["learning_rate"]), int(h["batch_size"])
    policy = ActorCriticPolicy(observation_space, action_space, lr_schedule=lambda _: lr, net_arch=list(h["net_arch"]))
    obs = torch.as_tensor(demos.obs, dtype=torch.float32)
    acts = torch.as_tensor(np.clip(demos.actions, action_space.low, action_space.high), dtype=torch.float32)
    gen = torch.Generator().manual_seed(seed)
    out.mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    rows = []
    policy.set_training_mode(True)
    with progress_bar("bc minibatches", steps, progress) as update:
        for k in range(1, steps + 1):
            idx = torch.randint(len(obs), (min(batch, len(obs)),), generator=gen)
            _, log_prob, entropy = policy.evaluate_actions(obs[idx], acts[idx])
            loss = -log_prob.mean() - 1e-3 * (entropy.mean() if entropy is not None else 0.0)
            policy.optimizer.zero_grad()
            loss.backward()
            policy.optimizer.step()
            if k % max(steps // 100, 1) == 0 or k == steps:
                rows.append({"minibatches": k, "loss": float(loss.detach()), "log_prob": float(log_prob.detach().mean())})
                update(k)
    with open(out / "logs" / "progress.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    path = out / "policy.zip"
    policy.save(str(path))
    return path


def train_gail(demos: Transitions, out: Path, *, steps: int, venv: Any, hparams: Mapping[str, Any], seed: int = 0) -> Path:
    """GAIL for `steps` env steps with a PPO generator; the generator goes to `policy.zip`, the reward net beside it."""
    import torch
    from imitation.algorithms.adversarial.gail import GAIL
    from imitation.rewards.reward_nets import BasicRewardNet
    from imitation.util import logger as imit_logger
    from imitation.util.networks import RunningNorm
    from stable_baselines3 import PPO

    from curbside.train.online import ppo_kwargs

    torch.set_num_threads(1)
    log = imit_logger.configure(str(out / "logs"), format_strs=["csv"])
    learner = PPO("MlpPolicy", venv, seed=seed, device="cpu", **ppo_kwargs(hparams))
    reward_net = BasicRewardNet(venv.observation_space, venv.action_space, normalize_input_layer=RunningNorm)
    batch = min(int(hparams.get("demo_batch_size", 512)), len(demos))
    rollout = int(learner.n_steps) * venv.num_envs
    gail = GAIL(demonstrations=_transitions(demos), demo_batch_size=batch, gen_replay_buffer_capacity=max(rollout, batch),
                n_disc_updates_per_round=int(hparams.get("disc_updates_per_round", 4)), venv=venv, gen_algo=learner,
                reward_net=reward_net, disc_opt_kwargs={"lr": float(hparams.get("disc_lr", 1e-3))},
                allow_variable_horizon=True, custom_logger=log)
    gail.train(total_timesteps=steps)
    path = out / "policy.zip"
    learner.save(str(path))
    torch.save(reward_net, out / "reward_net.pt")
    return path
