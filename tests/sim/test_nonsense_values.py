"""Values that look like config but mean nothing are refused at construction, naming the key (env and batched)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401
from kernel.config import ConfigError
from sim.batched import BatchedPointNav


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ({"scene": {"blocks": 1, "templates": "h"}}, "sidewalk template"),
        ({"scene": {"blocks": 1, "templates": 5}}, "templates must be a string"),
        ({"scene": {"blocks": 1, "templates": ""}}, "sidewalk template"),
        ({"scene": {"blocks": 1}, "camera": {"near": 10.0, "far": 1.0}}, r"camera.near \(10.0\) must be below"),
        ({"scene": {"blocks": 1}, "machine": {"color": "red"}}, r"machine.color must be \[r, g, b, a\]"),
        ({"scene": {"blocks": 1}, "machine": {"base": {"color": [2, 0, 0, 1]}}}, r"machine.base.color"),
        ({"scene": {"blocks": 1, "lanes": [1.5, 2]}}, r"lanes must be .* each an integer in \[1, 4\]"),
        ({"scene": {"blocks": 1}, "lidar": {"range": 1e-9}}, r"lidar.range 1e-09 m ends inside this machine's"),
    ],
)
def test_nonsense_values_are_refused_at_construction(config, match) -> None:
    with pytest.raises(ConfigError, match=match):
        gym.make("curbside/PointNav-v0", config=config)
    if "camera" not in config:
        with pytest.raises(ConfigError, match=match):
            BatchedPointNav(2, config)


def test_complex_actions_are_refused_not_truncated() -> None:
    env = gym.make("curbside/PointNav-v0", config={"scene": {"blocks": 1}})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="complex"):
        env.step(np.array([0.1 + 1j, 0.5]))
    env.close()
    envs = BatchedPointNav(2, {"scene": {"blocks": 1}})
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="complex"):
        envs.step(np.array([[0.1 + 1j, 0.5], [0.0, 0.0]]))


def test_a_scene_spec_without_sidewalks_is_refused_at_construction() -> None:
    from tests.street import street

    spec = {**street(), "sidewalks": []}
    with pytest.raises(ConfigError, match="scene_spec has no sidewalk"):
        gym.make("curbside/PointNav-v0", config={"scene_spec": spec})
    with pytest.raises(ConfigError, match="scene_spec has no sidewalk"):
        BatchedPointNav(2, {"scene_spec": spec})


@pytest.mark.parametrize(
    ("agents", "match"),
    [
        ({"max_agents": 0}, "max_agents is 0 with dynamic_density"),
        ({"counts": {"pedestrian": 5}, "max_agents": 3}, "counts ask for 5 agents but max_agents is 3"),
    ],
)
def test_agent_limits_that_no_scene_can_meet_are_refused_at_construction(agents, match) -> None:
    with pytest.raises(ConfigError, match=match):
        gym.make("curbside/SocialNav-v0", config={"scene": {"blocks": 1}, "agents": agents})
    env = gym.make(
        "curbside/SocialNav-v0", config={"scene": {"blocks": 1}, "agents": {"max_agents": 0, "dynamic_density": 0.0}}
    )
    env.reset(seed=0)
    assert env.unwrapped.crowd.n == 0
    env.close()
