"""PointNav env: Gymnasium conformance, determinism, bad input, reward and metrics (real PyBullet)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim  # noqa: F401  (registers the env ids)
from kernel.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.expert import PurePursuitExpert
from sim.machines import MACHINES
from sim.world import SceneError


@pytest.mark.parametrize("machine", list(MACHINES))
def test_check_env_passes_for_every_machine(spec, machine):
    env = gym.make("curbside/PointNav-v0", config={"scene_spec": spec, "machine": machine, "lidar": {"beams": 60}})
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_observation_layout_and_names(spec):
    env = PointNavEnv({"scene_spec": spec})
    obs, info = env.reset(seed=0)
    assert obs.shape == (329,) and len(env.observation_names) == 329
    assert env.observation_names[240] == "low_0" and env.observation_names[300] == "speed"
    assert env.observation_names[-1] == "goal_heading_cos"
    assert "steering" not in env.observation_names  # it duplicated last_steering
    assert env.observation_space.contains(obs)
    assert info["route_length"] >= 10.0
    # At the start the machine is on the route, facing along it, at rest.
    names = env.observation_names
    assert obs[names.index("speed")] == 0.0
    assert abs(obs[names.index("lateral_offset")]) < 0.05
    assert obs[names.index("wp0_x")] > 0.05  # the next waypoint lies ahead
    env.close()


def test_same_seed_same_episode_even_after_other_episodes(spec, random_trace):
    def run(env, seed):
        return random_trace(env, seed, 40)

    a = PointNavEnv({"scene_spec": spec})
    b = PointNavEnv({"scene_spec": spec})
    run(b, 11)  # b's world has history; a reset must not depend on it
    ta, tb = run(a, 3), run(b, 3)
    assert len(ta) == len(tb) and all(np.array_equal(x, y) for x, y in zip(ta, tb))
    start3 = a.route.start.copy()
    a.reset(seed=4)
    assert not np.allclose(a.route.start, start3)  # another seed, another route


def test_bad_input_is_rejected(spec):
    env = PointNavEnv({"scene_spec": spec})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step([math.nan, 0.0])
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step([0.0, math.inf])
    env.step([5.0, -7.0])  # clipped, not an error
    assert env.episode.last_action.tolist() == [1.0, -1.0]
    with pytest.raises(ConfigError, match="valid keys"):
        PointNavEnv({"scene_spec": spec, "lidar_beams": 10})
    with pytest.raises(ConfigError, match="delivery_bot"):
        PointNavEnv({"scene_spec": spec, "machine": "hoverboard"})
    with pytest.raises(SceneError, match="curbside.scene/1"):
        PointNavEnv({"scene_spec": dict(spec, version="curbside.scene/0")})
    with pytest.raises(ConfigError, match="route_length"):
        PointNavEnv({"scene_spec": spec, "route_length": [2.0, 10.0]})


def test_expert_succeeds_and_metrics_are_consistent(spec):
    env = gym.make("curbside/PointNav-v0", config={"scene_spec": spec})
    expert = PurePursuitExpert()
    results = []
    for seed in range(4):
        env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            _, r, term, trunc, info = env.step(expert.act(env))
            total += r
            done = term or trunc
        results.append(info)
        u = env.unwrapped
        assert info["metrics"]["route_completion"] == info["route_completion"]
        if info["success"]:
            assert info["route_completion"] >= 0.95
            assert 0.0 < info["spl"] <= 1.0
            assert total > 0.0  # progress plus the success bonus outweigh the lateral penalty
        assert info["path_length"] > 0 and info["time"] == pytest.approx(u.episode.steps * 0.1)
        # A step can hit several kinds at once, so the cost (collision steps) is at most the per-kind sum.
        assert (
            info["cost"] <= info["collisions"] == sum(info[f"collisions_{k}"] for k in ("object", "building", "curb"))
        )
    assert np.mean([i["success"] for i in results]) >= 0.75


def test_collision_costs_and_stops_the_machine(spec):
    # Full throttle straight east along the left clear path hits the trash bin at x = 15.
    env = PointNavEnv(
        {
            "scene_spec": spec,
            "out_of_route_distance": 50.0,
            "terminate_off_walkable": False,
            "reward": {"lateral": 0.0, "disp": 0.0},
        }
    )
    env.reset(seed=0, options={"start": [10.0, 7.0], "goal": [25.0, 7.0]})
    m = env.machine
    assert abs(m.position[0] - 10.0) < 0.3 and abs(m.position[1] - 7.0) < 0.3
    costs, rewards = [], []
    for _ in range(40):
        _, r, term, trunc, info = env.step([0.0, 1.0])
        costs.append(info["cost"])
        rewards.append(r)
        if term:
            break
    assert sum(costs) > 0 and "object" in info["collision_kinds"]
    assert m.position[0] < 14.8  # the bin (depth 0.6 at x = 15) was not driven through
    assert min(rewards) <= -env.reward_fn.crash  # R_crash


def test_curb_blocks_small_wheels(spec):
    # The delivery bot (wheel radius 0.10 m) cannot climb the 0.15 m curb from the road.
    env = PointNavEnv({"scene_spec": spec, "out_of_route_distance": 50.0, "terminate_off_walkable": False})
    env.reset(seed=0, options={"start": [12.0, 7.0], "goal": [25.0, 7.0]})
    m = env.machine
    m.reset(10.0, 2.0, 0.0, math.pi / 2, env.np_random)
    kinds = set()
    for _ in range(30):
        _, _, _, _, info = env.step([0.0, 0.6])
        kinds |= set(info["collision_kinds"])
    assert "curb" in kinds and m.position[1] < 4.0 and m.position[2] < 0.05


def test_async_vector_env(spec):
    envs = gym.make_vec(
        "curbside/PointNav-v0",
        num_envs=2,
        vectorization_mode="async",
        config={"scene_spec": spec, "lidar": {"beams": 30}},
    )
    obs, _ = envs.reset(seed=[1, 2])
    assert obs.shape == (2, 30 + 60 + 6 + 20 + 3)
    for _ in range(3):
        obs, r, term, trunc, info = envs.step(np.zeros((2, 2), dtype=np.float32))
    assert r.shape == (2,)
    envs.close()


def test_render_rgb_array(spec):
    env = gym.make(
        "curbside/PointNav-v0",
        config={"scene_spec": spec, "render": {"width": 64, "height": 48}},
        render_mode="rgb_array",
    )
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8 and img.std() > 5
    env.close()
