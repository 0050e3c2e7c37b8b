"""SocialNav-v0: Gymnasium conformance, agents as collidable bodies seen by the LiDAR, social metrics."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim  # noqa: F401 - registers the envs
from sim.agents import AGENT_DTYPE
from sim.expert import PurePursuitExpert

CFG = {
    "agents": {"counts": {"pedestrian": 8, "cyclist": 1, "wheelchair_user": 1, "robot_dog": 1, "delivery_robot": 1}},
    "route_length": [15.0, 30.0],
    "horizon": 400,
}


@pytest.fixture(scope="module")
def env():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = gym.make("curbside/SocialNav-v0", config=CFG, render_mode="rgb_array")
    yield e
    e.close()


def test_check_env() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = gym.make("curbside/SocialNav-v0", config=CFG).unwrapped
        check_env(e, skip_render_check=True)
        e.close()


def test_agent_states_and_bodies(env) -> None:
    env.reset(seed=0)
    u = env.unwrapped
    st = u.agent_states()
    assert st.dtype == AGENT_DTYPE and len(st) == 12
    assert set(st["kind"]) >= {"pedestrian", "cyclist", "robot_dog"}
    before = st.copy()
    for _ in range(20):
        env.step(np.zeros(2, dtype=np.float32))
    after = u.agent_states()
    assert np.hypot(after["x"] - before["x"], after["y"] - before["y"]).max() > 0.5, "agents should move"
    # Every agent is a PyBullet body at its state's position.
    import pybullet as p

    for body, a in zip(u.bodies.agents, after):
        pos, _ = p.getBasePositionAndOrientation(body, physicsClientId=u.client)
        assert abs(pos[0] - a["x"]) < 1e-6 and abs(pos[1] - a["y"]) < 1e-6


def test_agent_collision_costs_and_lidar_sees_agents(env) -> None:
    env.reset(seed=1)
    u = env.unwrapped
    x, y, _ = u.machine.position
    ahead = (x + 1.2 * np.cos(u.machine.yaw), y + 1.2 * np.sin(u.machine.yaw))
    u.crowd.pos[0] = ahead
    u.body_adapter.sync()
    u.lidar.scan(*u.machine.position, u.machine.yaw)
    assert u.bodies.agents[0] in set(u.lidar.hit_ids.tolist()), "the LiDAR must see an agent in front"
    u.crowd.pos[0] = (x, y)
    u.body_adapter.sync()
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["cost"] == 1.0 and "agent" in info["collision_kinds"]


def test_expert_episode_metrics(env) -> None:
    env.reset(seed=2)
    expert = PurePursuitExpert()
    info: dict = {}
    for _ in range(400):
        _, _, term, trunc, info = env.step(expert.act(env))
        if term or trunc:
            break
    m = info["metrics"]
    for k in ("success", "spl", "cost", "psc", "stl", "sns", "collisions_agent", "collisions_vehicle"):
        assert k in m
    assert 0.0 <= m["psc"] <= 1.0 and 0.0 <= m["stl"] <= 1.0
    assert m["sns"] == pytest.approx(0.5 * (m["psc"] + m["stl"]))
    assert m["stl"] <= m["success"]


def test_deterministic_and_renders(env) -> None:
    env.reset(seed=5)
    for _ in range(10):
        env.step(np.array([0.0, 0.5], dtype=np.float32))
    s1 = env.unwrapped.agent_states()
    env.reset(seed=5)
    for _ in range(10):
        env.step(np.array([0.0, 0.5], dtype=np.float32))
    assert np.array_equal(s1, env.unwrapped.agent_states())
    u = env.unwrapped
    x, y, _ = u.machine.position
    u.crowd.pos[0] = (x + 3.0, y + 3.0)
    frame = env.render()
    assert frame.shape == (384, 768, 3) and frame.dtype == np.uint8  # the dashboard: chase view and map
    from sim.agents.kinds import AGENT_KINDS

    colour = np.array([int(255 * c) for c in AGENT_KINDS[str(u.agent_states()["kind"][0])].color])
    assert (frame.reshape(-1, 3) == colour).all(1).sum() > 10, "the agent next to the ego is drawn in its kind colour"
