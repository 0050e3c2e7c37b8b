"""Every use of a closed, never-reset or failed-reset env is one clear error, and reset(options) is checked like a
config (PointNav, SocialNav and the batched env alike)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401
from sim.batched import BatchedPointNav

CFG = {"scene": {"blocks": 1}}
BAD_OPTIONS = [
    ({"Start": [1.0, 2.0]}, r"unknown reset option\(s\) \['Start'\]; valid: start, goal"),
    ({"start": [np.nan, np.nan], "goal": [1.0, 1.0]}, "finite"),
    ({"start": [1.0, 2.0, 3.0], "goal": [1.0, 2.0]}, r"must be \[x, y\]"),
    ({"start": "ab", "goal": [1.0, 2.0]}, r"must be \[x, y\]"),
    ({"start": [1.0, 2.0]}, "both 'start' and 'goal'"),
    (5, "must be a dict"),
    ("start", "must be a dict"),
    ([1.0, 2.0], "must be a dict"),
]


@pytest.mark.parametrize(("options", "match"), BAD_OPTIONS)
@pytest.mark.parametrize("task", ["PointNav", "SocialNav"])
def test_bad_reset_options_are_named(task, options, match) -> None:
    env = gym.make(f"curbside/{task}-v0", config=CFG)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options=options)
    env.close()


@pytest.mark.parametrize(("options", "match"), BAD_OPTIONS)
def test_bad_reset_options_of_the_batched_env_are_named(options, match) -> None:
    envs = BatchedPointNav(2, CFG)
    with pytest.raises(ValueError, match=match):
        envs.reset(seed=0, options=options)
    envs.close()


def test_a_closed_env_refuses_every_call() -> None:
    env = gym.make("curbside/PointNav-v0", config=CFG)
    env.reset(seed=0)
    env.close()
    for call in (
        lambda: env.step([0.0, 0.0]),
        lambda: env.reset(seed=0),
        lambda: env.unwrapped.render(),
        lambda: env.unwrapped.scene,
    ):
        with pytest.raises(RuntimeError, match="the env is closed"):
            call()
    env.close()  # closing twice is harmless


def test_an_env_before_reset_or_after_a_failed_reset_says_reset_first() -> None:
    env = gym.make("curbside/SocialNav-v0", config=CFG)
    with pytest.raises(RuntimeError, match="call reset"):
        _ = env.unwrapped.scene
    with pytest.raises(RuntimeError, match="call reset"):
        env.unwrapped.agent_states()
    env.reset(seed=0)
    env.step([0.0, 0.5])
    with pytest.raises(Exception):  # noqa: B017 (a route far off the map: the planner's own error)
        env.reset(seed=1, options={"start": [1e6, 1e6], "goal": [2e6, 2e6]})
    with pytest.raises(RuntimeError, match="the last one failed"):
        env.step([0.0, 0.5])  # not the old episode, silently continued
    env.close()


def test_nested_machine_values_are_checked_in_every_env() -> None:
    from kernel.config import ConfigError

    for machine in ({"base": {"wheel_radius": float("nan")}}, {"base": {"base": {"mass": float("inf")}}}):
        with pytest.raises(ConfigError, match=r"config\.machine\.base\."):
            gym.make("curbside/PointNav-v0", config={**CFG, "machine": machine})
        with pytest.raises(ConfigError, match=r"config\.machine\.base\."):
            BatchedPointNav(2, {**CFG, "machine": machine})
