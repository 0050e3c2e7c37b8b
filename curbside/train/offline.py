"""Offline RL from a Minari demonstration set, in plain torch: IQL and TD3+BC, counted in gradient steps.

- IQL (Kostrikov, Nair and Levine, 2022): V regresses an `expectile` of the target twin-Q; Q regresses
  r + gamma V(s'); the actor maximises the advantage-weighted log-likelihood of the demonstrated actions,
  weights exp(beta A) capped at 100. The actor is a Gaussian whose mean is squashed by tanh; it acts with the mean.
- TD3+BC (Fujimoto and Gu, 2021): TD3 (twin critics, target smoothing noise 0.2 clipped at 0.5, the actor updated
  every `actor_delay` steps) with the actor's loss -lambda Q(s, pi(s)) + (pi(s) - a)^2, lambda = alpha / mean|Q|.

Observations are already in [-1, 1] (sim.envs.observation), so neither normalises them. Every network is an MLP of
`net_arch` (ReLU). The learner writes `policy.pt` (the actor's weights and shape; `load_actor` rebuilds it) and
`train_log.json`. The hyper-parameters are those of `curbside.train.protocols` (`OfflineHparams` rejects others).
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from curbside.train.demos import Transitions
from curbside.train.progress import progress_bar
from kernel.config import ConfigError

ALGOS = ("iql", "td3bc")
MAX_WEIGHT = 100.0  # IQL's cap on exp(beta A)
LOG_STD = (-5.0, 2.0)  # IQL actor's log-std bounds
POLICY_NOISE, NOISE_CLIP = 0.2, 0.5  # TD3's target smoothing


@dataclass(frozen=True)
class OfflineHparams:
    """One offline learner's hyper-parameters (protocol `hparams` of iql or td3bc)."""

    learning_rate: float = 3e-4  # actor and critics
    batch_size: int = 256
    gamma: float = 0.99
    tau: float = 5e-3  # Polyak step of the target networks
    net_arch: tuple[int, ...] = (256, 256)
    expectile: float = 0.7  # IQL
    beta: float = 3.0  # IQL: inverse temperature of the advantage weights
    alpha: float = 2.5  # TD3+BC: weight of the Q term against the BC term
    actor_delay: int = 2  # TD3+BC: critic steps per actor step

    @classmethod
    def of(cls, hparams: Mapping[str, Any]) -> OfflineHparams:
        """From a protocol's hparams dict; unknown keys are a ConfigError naming the valid ones."""
        valid = {f.name for f in fields(cls)}
        unknown = sorted(set(hparams) - valid)
        if unknown:
            raise ConfigError(f"unknown offline hyper-parameter(s) {unknown}; valid: {', '.join(sorted(valid))}")
        h = dict(hparams)
        if "net_arch" in h:
            h["net_arch"] = tuple(int(u) for u in h["net_arch"])
        return cls(**h)


def mlp(sizes: list[int], out_act: Any = None) -> Any:
    """Linear layers of `sizes` with ReLU between them (and `out_act` after the last, if given)."""
    from torch import nn

    layers: list[Any] = []
    for k in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[k], sizes[k + 1]))
        if k < len(sizes) - 2:
            layers.append(nn.ReLU())
    if out_act is not None:
        layers.append(out_act)
    return nn.Sequential(*layers)


def make_actor(obs_dim: int, act_dim: int, net_arch: tuple[int, ...]) -> Any:
    """The deterministic part of both actors: obs -> tanh(mean action)."""
    from torch import nn

    return mlp([obs_dim, *net_arch, act_dim], nn.Tanh())


class TwinQ:
    """Two Q networks (obs, action) -> value and their Polyak-averaged targets."""

    def __init__(self, obs_dim: int, act_dim: int, net_arch: tuple[int, ...], lr: float) -> None:
        import torch

        self.nets = [mlp([obs_dim + act_dim, *net_arch, 1]) for _ in range(2)]
        self.targets = [copy.deepcopy(q).requires_grad_(False) for q in self.nets]
        self.opt = torch.optim.Adam([p for q in self.nets for p in q.parameters()], lr=lr)

    @staticmethod
    def _q(nets: list[Any], obs: Any, act: Any) -> tuple[Any, Any]:
        import torch

        x = torch.cat([obs, act], 1)
        return nets[0](x).squeeze(1), nets[1](x).squeeze(1)

    def __call__(self, obs: Any, act: Any) -> tuple[Any, Any]:
        return self._q(self.nets, obs, act)

    def target(self, obs: Any, act: Any) -> Any:
        """min of the two target networks."""
        import torch

        return torch.minimum(*self._q(self.targets, obs, act))

    def step(self, loss: Any, tau: float) -> None:
        """One Adam step on `loss`, then the targets move `tau` toward the networks."""
        import torch

        self.opt.zero_grad()
        loss.backward()
        self.opt.step()
        with torch.no_grad():
            for q, t in zip(self.nets, self.targets):
                for p, tp in zip(q.parameters(), t.parameters()):
                    tp.lerp_(p, tau)


class IQL:
    """Implicit Q-learning: `update(batch)` is one gradient step of V, the twin Q and the actor."""

    def __init__(self, obs_dim: int, act_dim: int, h: OfflineHparams) -> None:
        import torch

        self.h = h
        self.q = TwinQ(obs_dim, act_dim, h.net_arch, h.learning_rate)
        self.v = mlp([obs_dim, *h.net_arch, 1])
        self.v_opt = torch.optim.Adam(self.v.parameters(), lr=h.learning_rate)
        self.actor = make_actor(obs_dim, act_dim, h.net_arch)
        self.log_std = torch.nn.Parameter(torch.zeros(act_dim))
        self.actor_opt = torch.optim.Adam([*self.actor.parameters(), self.log_std], lr=h.learning_rate)

    def update(self, obs: Any, act: Any, rew: Any, next_obs: Any, done: Any, step: int) -> dict[str, Any]:
        import torch

        h = self.h
        with torch.no_grad():
            q_target = self.q.target(obs, act)
            next_v = self.v(next_obs).squeeze(1)
        v = self.v(obs).squeeze(1)
        u = q_target - v
        v_loss = (torch.abs(h.expectile - (u < 0).float()) * u.pow(2)).mean()
        self.v_opt.zero_grad()
        v_loss.backward()
        self.v_opt.step()
        q1, q2 = self.q(obs, act)
        backup = rew + h.gamma * (1.0 - done) * next_v
        q_loss = (q1 - backup).pow(2).mean() + (q2 - backup).pow(2).mean()
        self.q.step(q_loss, h.tau)
        weight = torch.exp(h.beta * u.detach()).clamp(max=MAX_WEIGHT)
        dist = torch.distributions.Normal(self.actor(obs), self.log_std.clamp(*LOG_STD).exp())
        actor_loss = -(weight * dist.log_prob(act).sum(1)).mean()
        self.actor_opt.zero_grad()
        actor_loss.backward()
        self.actor_opt.step()
        return {"v_loss": v_loss.detach(), "q_loss": q_loss.detach(), "actor_loss": actor_loss.detach()}


class TD3BC:
    """TD3+BC: `update(batch)` is one critic step and, every `actor_delay` steps, one actor step."""

    def __init__(self, obs_dim: int, act_dim: int, h: OfflineHparams) -> None:
        import torch

        self.h = h
        self.q = TwinQ(obs_dim, act_dim, h.net_arch, h.learning_rate)
        self.actor = make_actor(obs_dim, act_dim, h.net_arch)
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=h.learning_rate)
        self.last_actor_loss: Any = float("nan")

    def update(self, obs: Any, act: Any, rew: Any, next_obs: Any, done: Any, step: int) -> dict[str, Any]:
        import torch

        h = self.h
        with torch.no_grad():
            noise = (torch.randn_like(act) * POLICY_NOISE).clamp(-NOISE_CLIP, NOISE_CLIP)
            next_act = (self.actor_target(next_obs) + noise).clamp(-1.0, 1.0)
            backup = rew + h.gamma * (1.0 - done) * self.q.target(next_obs, next_act)
        q1, q2 = self.q(obs, act)
        q_loss = (q1 - backup).pow(2).mean() + (q2 - backup).pow(2).mean()
        self.q.step(q_loss, h.tau)
        if step % h.actor_delay == 0:
            pi = self.actor(obs)
            q_pi = self.q.nets[0](torch.cat([obs, pi], 1))
            lam = h.alpha / q_pi.abs().mean().detach().clamp(min=1e-6)
            actor_loss = -lam * q_pi.mean() + (pi - act).pow(2).mean()
            self.actor_opt.zero_grad()
            actor_loss.backward()
            self.actor_opt.step()
            with torch.no_grad():
                for p, tp in zip(self.actor.parameters(), self.actor_target.parameters()):
                    tp.lerp_(p, h.tau)
            self.last_actor_loss = actor_loss.detach()
        return {"q_loss": q_loss.detach(), "actor_loss": self.last_actor_loss}


LEARNERS: dict[str, type[IQL] | type[TD3BC]] = {"iql": IQL, "td3bc": TD3BC}


def train_offline(
    algo: str,
    demos: Transitions,
    out: Path,
    *,
    steps: int,
    seed: int = 0,
    hparams: Mapping[str, Any] | None = None,
    progress: bool = True,
) -> Path:
    """Train IQL or TD3+BC for `steps` gradient steps; write `policy.pt` and `train_log.json` under `out`."""
    import torch

    if algo not in LEARNERS:
        raise ConfigError(f"unknown offline algorithm {algo!r}; valid: {', '.join(ALGOS)}")
    h = OfflineHparams.of(hparams or {})
    # One thread: minibatches of 256 through 256 x 256 MLPs gain little from a second and lose 3x when it is busy.
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    obs = torch.as_tensor(demos.obs, dtype=torch.float32)
    act = torch.as_tensor(np.clip(demos.actions, -1.0, 1.0), dtype=torch.float32)
    rew = torch.as_tensor(demos.rewards, dtype=torch.float32)
    next_obs = torch.as_tensor(demos.next_obs, dtype=torch.float32)
    done = torch.as_tensor(demos.terminals, dtype=torch.float32)  # a timeout bootstraps: only terminals end values
    learner = LEARNERS[algo](obs.shape[1], act.shape[1], h)
    gen = torch.Generator().manual_seed(seed)
    log: list[dict[str, float]] = []
    every = max(steps // 100, 1)
    with progress_bar(f"{algo} gradient steps", steps, progress) as update:
        for k in range(1, steps + 1):
            idx = torch.randint(len(obs), (min(h.batch_size, len(obs)),), generator=gen)
            metrics = learner.update(obs[idx], act[idx], rew[idx], next_obs[idx], done[idx], k)
            if k % every == 0 or k == steps:
                log.append({"gradient_steps": k, **{name: float(v) for name, v in metrics.items()}})
                update(k)
    out.mkdir(parents=True, exist_ok=True)
    (out / "train_log.json").write_text(json.dumps(log, indent=1))
    path = out / "policy.pt"
    tmp = path.with_suffix(".pt.tmp")
    torch.save(
        {
            "algo": algo,
            "obs_dim": int(obs.shape[1]),
            "act_dim": int(act.shape[1]),
            "net_arch": list(h.net_arch),
            "actor": learner.actor.state_dict(),
        },
        tmp,
    )
    tmp.replace(path)
    return path


def load_actor(path: Path) -> Any:
    """The deterministic actor of a `policy.pt`: a torch module obs [n, obs_dim] -> action [n, act_dim] in [-1, 1]."""
    import torch

    saved = torch.load(path, map_location="cpu", weights_only=True)
    actor = make_actor(int(saved["obs_dim"]), int(saved["act_dim"]), tuple(saved["net_arch"]))
    actor.load_state_dict(saved["actor"])
    return actor.eval()
