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
             seed: int = 0, batch_size: int = 256, net_arch: tuple[int, ...] = (256, 256), progress: bool = True) -> Path:
    """Behaviour cloning for `steps` minibatches; the policy (an SB3 ActorCriticPolicy) goes to `policy.zip`."""
    import torch
    from imitation.algorithms import bc
    from imitation.util import logger as imit_logger
    from stable_baselines3.common.policies import ActorCriticPolicy

    torch.set_num_threads(2)
    torch.manual_seed(seed)
    log = imit_logger.configure(str(out / "logs"), format_strs=["csv"])
    policy = ActorCriticPolicy(observation_space, action_space, lr_schedule=lambda _: 1e-3, net_arch=list(net_arch))
    trainer = bc.BC(observation_space=observation_space, action_space=action_space, demonstrations=_transitions(demos),
                    policy=policy, rng=np.random.default_rng(seed), batch_size=batch_size, device="cpu",
                    custom_logger=log)
    with warnings.catch_warnings():
        # imitation logs a loss tensor through float(): harmless, and not the user's to fix.
        warnings.filterwarnings("ignore", message="Converting a tensor with requires_grad")
        # imitation's own bars are nested tqdm lines per epoch: one rich bar over the minibatches instead.
        with progress_bar("bc minibatches", steps, progress) as update:
            done = [0]

            def tick() -> None:
                done[0] += 1
                update(done[0])

            trainer.train(n_batches=steps, log_interval=max(steps // 10, 1), progress_bar=False, on_batch_end=tick)
    path = out / "policy.zip"
    trainer.policy.save(str(path))
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
    batch = min(512, len(demos))
    gail = GAIL(demonstrations=_transitions(demos), demo_batch_size=batch, gen_replay_buffer_capacity=max(4096, batch),
                n_disc_updates_per_round=4, venv=venv, gen_algo=learner, reward_net=reward_net,
                allow_variable_horizon=True, custom_logger=log)
    gail.train(total_timesteps=steps)
    path = out / "policy.zip"
    learner.save(str(path))
    torch.save(reward_net, out / "reward_net.pt")
    return path
