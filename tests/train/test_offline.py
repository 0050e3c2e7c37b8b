"""The torch learners of offline RL and GAIL on problems whose answer is known: IQL and TD3+BC recover the
demonstrated policy, the discriminator tells demonstrations from other actions, and GAIL's generator is rewarded
by it (real torch and SB3, no env mocks)."""

from __future__ import annotations

import numpy as np
import pytest

from curbside.train.demos import Transitions
from curbside.train.offline import OfflineHparams, load_actor, train_offline
from kernel.config import ConfigError


def linear_demos(n: int = 2_000, obs_dim: int = 6, seed: int = 0) -> tuple[Transitions, np.ndarray]:
    """Transitions whose action is tanh(W obs) and whose reward is 1 a step (every action is the expert's)."""
    rng = np.random.default_rng(seed)
    w = rng.normal(0.0, 0.8, (2, obs_dim))
    obs = rng.uniform(-1.0, 1.0, (n, obs_dim)).astype(np.float32)
    acts = np.tanh(obs @ w.T).astype(np.float32)
    ends = np.zeros(n, dtype=bool)
    ends[49::50] = True
    tr = Transitions(
        obs=obs,
        actions=acts,
        rewards=np.ones(n, dtype=np.float32),
        next_obs=np.roll(obs, -1, 0),
        terminals=ends,
        timeouts=np.zeros(n, dtype=bool),
    )
    return tr, w


@pytest.mark.parametrize("algo", ["iql", "td3bc"])
def test_offline_learners_recover_the_demonstrated_policy(algo, tmp_path) -> None:
    import torch

    tr, w = linear_demos()
    path = train_offline(
        algo, tr, tmp_path, steps=1_500, hparams={"learning_rate": 1e-3, "net_arch": [64, 64]}, progress=False
    )
    actor = load_actor(path)
    test = np.random.default_rng(1).uniform(-1.0, 1.0, (200, tr.obs.shape[1])).astype(np.float32)
    with torch.no_grad():
        pred = actor(torch.as_tensor(test)).numpy()
    err = np.abs(pred - np.tanh(test @ w.T)).mean()
    untrained = np.abs(np.tanh(test @ w.T)).mean()  # a policy that always outputs 0
    assert err < 0.25 * untrained, (err, untrained)


def test_offline_training_is_deterministic_for_a_seed(tmp_path) -> None:
    import torch

    tr, _ = linear_demos(300)
    a = torch.load(train_offline("iql", tr, tmp_path / "a", steps=20, progress=False), weights_only=True)
    b = torch.load(train_offline("iql", tr, tmp_path / "b", steps=20, progress=False), weights_only=True)
    assert all(torch.equal(a["actor"][k], b["actor"][k]) for k in a["actor"])


def test_unknown_offline_hyper_parameter_names_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match=r"unknown offline hyper-parameter\(s\) \['lr'\]; valid: .*learning_rate"):
        OfflineHparams.of({"lr": 1e-3})


def test_discriminator_tells_demonstrations_from_other_actions() -> None:
    import torch

    from curbside.train.imitate import Discriminator

    tr, _ = linear_demos(1_000)
    expert = (torch.as_tensor(tr.obs), torch.as_tensor(tr.actions))
    other = (expert[0], -expert[1])  # the opposite action in the same states
    disc = Discriminator(tr.obs.shape[1], 2, (64, 64), 1e-3, seed=0)
    before = disc.reward(tr.obs[:200], tr.actions[:200]).mean() - disc.reward(tr.obs[:200], -tr.actions[:200]).mean()
    stats = disc.train(expert, other, updates=300, batch=64, gen=torch.Generator().manual_seed(0))
    after = disc.reward(tr.obs[:200], tr.actions[:200]).mean() - disc.reward(tr.obs[:200], -tr.actions[:200]).mean()
    assert stats["disc_acc_expert"] > 0.9 and stats["disc_acc_generated"] > 0.9
    assert after > before + 1.0  # demonstrated actions now earn the generator more reward than others
