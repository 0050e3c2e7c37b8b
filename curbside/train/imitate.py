"""Imitation learning in plain torch: BC (supervised on expert actions) and GAIL (an adversarial reward from a
discriminator, an SB3 PPO generator on the train split)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np

from curbside.train.demos import Transitions
from curbside.train.policies import save_policy
from curbside.train.progress import progress_bar

DISC_NET_ARCH = (256, 256)  # the discriminator's MLP (the paper does not give one; the policy's size)


def train_bc(
    demos: Transitions,
    out: Path,
    *,
    steps: int,
    observation_space: Any,
    action_space: Any,
    seed: int = 0,
    hparams: Mapping[str, Any] | None = None,
    progress: bool = True,
) -> Path:
    """Behaviour cloning for `steps` minibatches: maximise the log-likelihood of the demonstrated actions under an SB3
    ActorCriticPolicy (loss - log p(a|s) - 1e-3 entropy, as the `imitation` library's BC), saved as `policy.zip`; a
    loss log beside. The loop runs on tensors built once: a minibatch is an index draw.
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
            dist = policy.get_distribution(obs[idx])  # the actor alone: BC never reads the value head
            log_prob, entropy = dist.log_prob(acts[idx]), dist.entropy()
            loss = -log_prob.mean() - 1e-3 * (entropy.mean() if entropy is not None else 0.0)
            policy.optimizer.zero_grad()
            loss.backward()
            policy.optimizer.step()
            if k % max(steps // 100, 1) == 0 or k == steps:
                rows.append(
                    {"minibatches": k, "loss": float(loss.detach()), "log_prob": float(log_prob.detach().mean())}
                )
                update(k)
    with open(out / "logs" / "progress.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return save_policy(policy, out / "policy.zip")


class Discriminator:
    """D(s, a): logits that (s, a) comes from the demonstrations; the generator's reward is -log(1 - D) =
    softplus(logit) (Ho and Ermon's GAIL, as the `imitation` library rewards it)."""

    def __init__(self, obs_dim: int, act_dim: int, net_arch: tuple[int, ...], lr: float, seed: int) -> None:
        import torch

        from curbside.train.offline import mlp

        torch.manual_seed(seed)
        self.net = mlp([obs_dim + act_dim, *net_arch, 1])
        self.opt = torch.optim.Adam(self.net.parameters(), lr=lr)

    def logits(self, obs: Any, act: Any) -> Any:
        import torch

        return self.net(torch.cat([obs, act], 1)).squeeze(1)

    def reward(self, obs: np.ndarray, act: np.ndarray) -> np.ndarray:
        """The generator's reward of a batch of (obs, action) pairs."""
        import torch
        import torch.nn.functional as F

        with torch.no_grad():
            return (
                F.softplus(
                    self.logits(torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(act, dtype=torch.float32))
                )
                .numpy()
                .astype(np.float32)
            )

    def train(
        self, expert: tuple[Any, Any], generated: tuple[Any, Any], updates: int, batch: int, gen: Any
    ) -> dict[str, float]:
        """`updates` minibatches of `batch` expert and `batch` generated pairs (binary cross-entropy)."""
        import torch
        import torch.nn.functional as F

        for _ in range(max(updates, 1)):
            i = torch.randint(len(expert[0]), (batch,), generator=gen)
            j = torch.randint(len(generated[0]), (batch,), generator=gen)
            le, lg = self.logits(expert[0][i], expert[1][i]), self.logits(generated[0][j], generated[1][j])
            loss = F.binary_cross_entropy_with_logits(le, torch.ones_like(le)) + F.binary_cross_entropy_with_logits(
                lg, torch.zeros_like(lg)
            )
            self.opt.zero_grad()
            loss.backward()
            self.opt.step()
        with torch.no_grad():  # the last minibatch's accuracies
            acc_expert, acc_gen = float((le > 0).float().mean()), float((lg < 0).float().mean())
        return {"disc_loss": float(loss.detach()), "disc_acc_expert": acc_expert, "disc_acc_generated": acc_gen}


GAIL_GENERATOR = "gail_generator.zip"  # out/checkpoints/: the latest round's generator (SB3 PPO, optimizer included)
GAIL_DISCRIMINATOR = "gail_discriminator.pt"  # and its discriminator: weights, optimizer, minibatch generator


def train_gail(
    demos: Transitions,
    out: Path,
    *,
    steps: int,
    venv: Any,
    hparams: Mapping[str, Any],
    seed: int = 0,
    resume: bool = False,
) -> Path:
    """GAIL for `steps` env steps: an SB3 PPO generator rewarded by the discriminator (the env's reward is kept
    in the logs only), the discriminator trained `disc_updates_per_round` minibatches after every rollout on
    `demo_batch_size` demonstrated and as many generated pairs. The generator goes to `policy.zip`, the
    discriminator's weights to `discriminator.pt`.

    After every round both are checkpointed to `out/checkpoints/` (the generator with its optimizer, the
    discriminator with its optimizer and minibatch generator): a round is 12,800 env steps under `paper`, minutes of
    work, and `resume` continues from the last one to `steps` in all."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnvWrapper

    from curbside.train.callbacks import RolloutThreads, training_logger
    from curbside.train.online import ppo_kwargs

    low, high = venv.action_space.low, venv.action_space.high
    disc = Discriminator(
        int(np.prod(venv.observation_space.shape)),
        int(np.prod(venv.action_space.shape)),
        DISC_NET_ARCH,
        float(hparams.get("disc_lr", 1e-3)),
        seed,
    )

    class DiscriminatorReward(VecEnvWrapper):
        """The venv with the discriminator's reward of (the observation acted on, the action taken)."""

        # The venv's observations are Box arrays (the discriminator's input); SB3's VecEnvObs also covers Dict and
        # Tuple spaces, hence the casts.
        def reset(self) -> np.ndarray:
            self.last_obs = cast(np.ndarray, self.venv.reset())
            return self.last_obs

        def step_async(self, actions: np.ndarray) -> None:
            self.actions = np.clip(actions, low, high)
            self.venv.step_async(actions)

        def step_wait(self) -> Any:
            obs, env_reward, dones, infos = self.venv.step_wait()
            reward = disc.reward(self.last_obs.reshape(len(obs), -1), self.actions.reshape(len(obs), -1))
            for info, r in zip(infos, env_reward):
                info["env_reward"] = float(r)
            self.last_obs = cast(np.ndarray, obs)
            return obs, reward, dones, infos

    expert = (
        torch.as_tensor(demos.obs, dtype=torch.float32),
        torch.as_tensor(np.clip(demos.actions, low, high), dtype=torch.float32),
    )
    updates = int(hparams.get("disc_updates_per_round", 4))
    batch = min(int(hparams.get("demo_batch_size", 512)), len(demos))
    gen = torch.Generator().manual_seed(seed)

    class TrainDiscriminator(BaseCallback):
        """After each rollout: the discriminator learns the new generated pairs against the demonstrations."""

        model: PPO  # given to the PPO learner below only

        def _on_rollout_end(self) -> None:
            buf = self.model.rollout_buffer
            generated = (
                torch.as_tensor(buf.observations.reshape(-1, expert[0].shape[1]), dtype=torch.float32),
                torch.as_tensor(np.clip(buf.actions.reshape(-1, expert[1].shape[1]), low, high), dtype=torch.float32),
            )
            for key, value in disc.train(expert, generated, updates, batch, gen).items():
                self.logger.record(f"gail/{key}", value)

        def _on_step(self) -> bool:
            return True

    ckpt = out / "checkpoints"
    resumed = resume and (ckpt / GAIL_GENERATOR).is_file() and (ckpt / GAIL_DISCRIMINATOR).is_file()
    if resumed:
        learner = PPO.load(ckpt / GAIL_GENERATOR, env=DiscriminatorReward(venv), device="cpu")
        state = torch.load(ckpt / GAIL_DISCRIMINATOR, weights_only=True)
        disc.net.load_state_dict(state["net"])
        disc.opt.load_state_dict(state["opt"])
        gen.set_state(state["generator"])
    else:
        learner = PPO("MlpPolicy", DiscriminatorReward(venv), seed=seed, device="cpu", **ppo_kwargs(hparams))
    learner.set_logger(training_logger(out / "logs", ("csv",), learner.num_timesteps if resumed else None))

    class Checkpoint(BaseCallback):
        """After each round (the discriminator's update runs first): generator and discriminator, each written
        beside its old copy and swapped in."""

        def _on_rollout_end(self) -> None:
            ckpt.mkdir(exist_ok=True)
            self.model.save(ckpt / f"tmp_{GAIL_GENERATOR}")
            (ckpt / f"tmp_{GAIL_GENERATOR}").replace(ckpt / GAIL_GENERATOR)
            state = {"net": disc.net.state_dict(), "opt": disc.opt.state_dict(), "generator": gen.get_state()}
            torch.save(state, ckpt / f"tmp_{GAIL_DISCRIMINATOR}")
            (ckpt / f"tmp_{GAIL_DISCRIMINATOR}").replace(ckpt / GAIL_DISCRIMINATOR)

        def _on_step(self) -> bool:
            return True

    learner.learn(
        total_timesteps=max(steps - learner.num_timesteps, 0) if resumed else steps,
        # RolloutThreads first: the discriminator trains at the rollout's end, on the update's threads.
        callback=[RolloutThreads(torch.get_num_threads()), TrainDiscriminator(), Checkpoint()],
        reset_num_timesteps=not resumed,
    )
    torch.save(disc.net.state_dict(), out / "discriminator.tmp.pt")
    (out / "discriminator.tmp.pt").replace(out / "discriminator.pt")
    return save_policy(learner, out / "policy.zip")
