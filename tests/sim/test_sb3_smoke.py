"""Stable-Baselines3 PPO trains on PointNav unchanged (a few hundred steps; torch only in tests)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401


def test_ppo_smoke(spec):
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("curbside/PointNav-v0", config={"scene_spec": spec, "lidar": {"beams": 32}, "horizon": 64})
    model = sb3.PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu", verbose=0)
    model.learn(total_timesteps=256)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (2,) and np.isfinite(action).all()
    env.close()
