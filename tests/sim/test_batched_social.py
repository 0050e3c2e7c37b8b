"""The batched SocialNav env (sim.batched.social) against the PyBullet SocialNav env, its reference.

On the hand-built street (tests/street.py) with a dense crowd along the route, the same seed, route and expert
actions give the same agents and vehicles at reset (the same draws in the same order), then machine poses, agent
positions, LiDAR scans (agents included), rewards and the social metrics within the bounds of docs/batched.md.
Contacts: a machine driven into a standing agent stops at it in both envs and the contact costs; an agent walking
into a machine pushes it out.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  (registers the env ids)
from kernel.config import ConfigError
from sim.agents.kinds import IDLE
from sim.batched import BatchedSocialNav
from sim.batched.episodes import SOCIAL_KIND_BITS
from sim.envs.socialnav import SocialNavEnv
from sim.expert import PurePursuitExpert
from tests.street import street

ROUTE = {"start": [3.0, 7.0], "goal": [40.0, 7.0]}  # left sidewalk, around the trash bin at x = 15
CROWD = {"dynamic_density": 40.0, "spawn_area": "route"}  # 15 agents along the route's 37 m
B = 240  # high beams
TOL = {
    "position": 0.02,  # m, the machine over the replay (as BatchedPointNav's)
    "lidar_median": 0.01,  # m, median beam error of the high scan over the replay
    "agent_beams": 0.05,  # m, median error of the beams that end on an agent in the PyBullet scan
    "reward": 0.002,  # per step
    "min_distance": 0.02,  # m, the machine's gap to the nearest agent body (PSC's input)
}


def _config() -> dict:
    return {"scene_spec": street(), "agents": dict(CROWD)}


def _decode(obs: np.ndarray) -> np.ndarray:
    """High-scan distances (m) of an observation (log-encoded, 50 m range)."""
    return np.expm1(obs[:B].astype(np.float64) * math.log1p(50.0))


@pytest.fixture(scope="module")
def replay():
    """The expert drives the PyBullet env to the goal; the batched env replays its actions step for step."""
    ref = SocialNavEnv(_config())
    env = BatchedSocialNav(1, _config())
    ref.reset(seed=0, options=ROUTE)
    env.reset(seed=0, options=ROUTE)
    out = {
        "agents_at_reset": (ref.crowd.pos.copy(), env.crowds[0].crowd.pos.copy()),
        "vehicles_at_reset": (np.stack(ref.traffic_adapter.poses(), 1), env._vehicles[0].copy()),
        "pos": [],
        "lidar": [],
        "agent_beams": [],
        "reward": [],
        "min_distance": [],
    }
    expert = PurePursuitExpert()
    for _ in range(400):
        a = np.asarray(expert.act(ref), dtype=np.float64)
        obs_ref, r_ref, term_ref, trunc_ref, info_ref = ref.step(a)
        obs, r, term, trunc, info = env.step(a[None])
        if term_ref or trunc_ref or term[0] or trunc[0]:  # the batched env has reset itself: compare the ends
            out["end"] = (info_ref, info["final_info"], bool(term_ref), bool(term[0]))
            break
        m = ref.machine
        out["pos"].append(math.hypot(m.position[0] - env.drive.x[0], m.position[1] - env.drive.y[0]))
        out["reward"].append(abs(r_ref - r[0]))
        out["min_distance"].append(abs(ref.crowd_adapter.min_distance - env.crowds[0].min_distance))
        err = np.abs(_decode(obs_ref) - _decode(obs[0]))
        out["lidar"].append(float(np.median(err)))
        on_agent = np.isin(ref.lidar.hit_ids, ref.bodies.agents)
        out["agent_beams"].extend(err[on_agent].tolist())
    ref.close()
    env.close()
    return out


def test_reset_draws_the_pybullet_envs_agents_and_vehicles(replay) -> None:
    ref_agents, agents = replay["agents_at_reset"]
    assert len(agents) == 15
    np.testing.assert_array_equal(agents, ref_agents)
    ref_cars, cars = replay["vehicles_at_reset"]
    assert len(cars) >= 1
    np.testing.assert_array_equal(cars, ref_cars)


def test_replay_matches_pybullet_within_tolerances(replay) -> None:
    assert len(replay["pos"]) > 100  # the expert's drive to the goal
    assert max(replay["pos"]) < TOL["position"]
    assert max(replay["lidar"]) < TOL["lidar_median"]
    assert max(replay["reward"]) < TOL["reward"]
    assert max(replay["min_distance"]) < TOL["min_distance"]
    # The scans saw agents (capsules traced by both envs), and agree there.
    assert len(replay["agent_beams"]) > 50
    assert float(np.median(replay["agent_beams"])) < TOL["agent_beams"]


def test_episode_end_and_social_metrics_match_pybullet(replay) -> None:
    info_ref, final, term_ref, term = replay["end"]
    assert term_ref and term and info_ref["is_success"] and final["is_success"][0]
    steps = info_ref["metrics"]["steps"]
    assert final["steps"][0] == pytest.approx(steps, abs=1)
    for key in ("spl", "stl", "psc"):
        assert final[key][0] == pytest.approx(info_ref[key], abs=2.0 / steps), key
    assert final["sns"][0] == pytest.approx(0.5 * (final["stl"][0] + final["psc"][0]))
    assert final["psc"][0] < 1.0  # the crowd came within the personal space: PSC was measured, not defaulted


def test_crowd_and_traffic_match_pybullet_exactly_given_the_same_ego() -> None:
    # The cohabitants react to the machine, whose pose differs between the backends by up to `position`: an agent
    # deciding on that difference (its carrot in sight or not) can part by centimetres for a few steps. Given the
    # PyBullet env's machine pose at every step, the batched env's crowd and traffic are the PyBullet env's, bit for bit.
    ref, env = SocialNavEnv(_config()), BatchedSocialNav(1, _config())
    ref.reset(seed=0, options=ROUTE)
    env.reset(seed=0, options=ROUTE)
    egos = []
    step_crowd = ref.crowd_adapter.after_step

    def record(ctx):  # the PyBullet env's tick: its machine as the cohabitants see it
        egos.append(ctx.ego)
        step_crowd(ctx)

    ref.crowd_adapter.after_step = record
    env._ego = lambda k: egos[-1]
    expert = PurePursuitExpert()
    for _ in range(140):
        a = np.asarray(expert.act(ref), dtype=np.float64)
        _, _, term_ref, trunc_ref, _ = ref.step(a)
        _, _, term, trunc, _ = env.step(a[None])
        if term_ref or trunc_ref or term[0] or trunc[0]:
            break
        np.testing.assert_array_equal(env.crowds[0].crowd.pos, ref.crowd.pos)
        np.testing.assert_array_equal(env.crowds[0].crowd.vel, ref.crowd.vel)
        np.testing.assert_array_equal(env._vehicles[0], np.stack(ref.traffic_adapter.poses(), 1))
    assert len(egos) > 100
    ref.close()
    env.close()


def _standing_agent_ahead(env_ref: SocialNavEnv, env: BatchedSocialNav, xy: tuple[float, float]) -> None:
    for crowd in (env_ref.crowd, env.crowds[0].crowd):
        crowd.place(0, xy)
        crowd.state.movement[0] = IDLE
        crowd.state.idle_left[0] = 1e9
    env_ref.body_adapter.sync()
    env.sync_shapes()


def test_a_standing_agent_ahead_stops_the_machine_in_both_envs_and_costs() -> None:
    cfg = _config()
    ref, env = SocialNavEnv(cfg), BatchedSocialNav(1, cfg)
    ref.reset(seed=0, options=ROUTE)
    env.reset(seed=0, options=ROUTE)
    _standing_agent_ahead(ref, env, (8.0, 7.0))
    radius = float(env.crowds[0].crowd.radius[0])
    half_l = 0.5 * env.spec_machine.length
    hits_ref = hits = 0
    for _ in range(25):
        _, _, term_ref, _, info_ref = ref.step(np.array([0.0, 0.6]))
        _, _, term, _, info = env.step(np.array([[0.0, 0.6]]))
        hits_ref += "agent" in info_ref["collision_kinds"]
        hits += bool(info["collisions"][0] & SOCIAL_KIND_BITS["agent"])
        # The batched machine never drives into the agent's body (bisection: a few mm at most).
        _, _, _, depth = env._contacts(np.array([0]), env.drive.x, env.drive.y, env.drive.yaw)
        assert depth[0] < 0.01
        assert env.drive.x[0] < 8.0 - radius - half_l + 0.01
        assert ref.machine.position[0] < 8.0
        if term_ref or term[0]:
            break
    assert hits_ref >= 1 and hits >= 1
    assert info["cost"][0] == 1.0  # agents cost by default (SocialNav's cost_kinds)


def test_an_agent_walking_into_the_machine_pushes_it_out() -> None:
    env = BatchedSocialNav(1, _config())
    env.reset(seed=0, options=ROUTE)
    x0, y0 = float(env.drive.x[0]), float(env.drive.y[0])
    radius = float(env.crowds[0].crowd.radius[0])
    half_l = 0.5 * env.spec_machine.length
    crowd = env.crowds[0].crowd
    crowd.place(0, (x0 + half_l + radius - 0.1, y0))  # 0.1 m into the machine's front
    crowd.state.movement[0] = IDLE
    crowd.state.idle_left[0] = 1e9
    env.sync_shapes()
    _, _, _, _, info = env.step(np.array([[0.0, 0.0]]))
    assert info["collisions"][0] & SOCIAL_KIND_BITS["agent"]
    assert env.drive.x[0] == pytest.approx(x0 - 0.11, abs=0.005)  # pushed back by the overlap (+1 cm)
    _, _, _, depth = env._contacts(np.array([0]), env.drive.x, env.drive.y, env.drive.yaw)
    assert depth[0] == 0.0


def test_config_is_socialnavs_with_route_pool_and_unknown_keys_fail() -> None:
    env = BatchedSocialNav(2, {"split": "unseen", "route_pool": 4, "scene_spec": street()})
    assert env.config["agents"]["run_prob"] == 0.3  # the unseen split's agent behaviour, as SocialNavEnv's
    assert env.config["cost_kinds"] == ["object", "building", "agent", "vehicle"]
    env.close()
    with pytest.raises(ConfigError, match="personal_spac.*valid"):
        BatchedSocialNav(1, {"personal_spac": 1.0})
    envs = gym.make_vec("curbside/BatchedSocialNav-v0", num_envs=2, config={"scene_spec": street()})
    obs, _ = envs.reset(seed=3)
    assert obs.shape == (2, SocialNavEnv({"scene_spec": street()}).observation_space.shape[0])
    envs.close()


def test_same_seed_same_episodes_byte_for_byte_and_autoreset_keys() -> None:
    runs = []
    for _ in range(2):
        env = BatchedSocialNav(3, {"scene_spec": street(), "agents": dict(CROWD), "route_length": [5.0, 15.0]})
        obs, _ = env.reset(seed=7)
        rng = np.random.default_rng(0)
        trace, finals = [obs], []
        for _ in range(60):
            obs, reward, term, trunc, info = env.step(rng.uniform(-1.0, 1.0, (3, 2)))
            trace += [obs, reward, np.stack([env.crowds[k].crowd.pos.sum(axis=0) for k in range(3)])]
            if "final_info" in info:
                done = info["_final_info"]
                assert done.any() and all(info["final_obs"][k] is not None for k in np.nonzero(done)[0])
                finals.append({key: info["final_info"][key][done] for key in ("psc", "stl", "sns", "success")})
        env.close()
        runs.append((trace, finals))
    (a, fa), (b, fb) = runs
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert fa and len(fa) == len(fb)  # episodes ended (short routes), with the social metrics in final_info
    for x, y in zip(fa, fb):
        assert all(np.array_equal(x[k], y[k]) for k in x)
        assert np.all((x["psc"] >= 0.0) & (x["psc"] <= 1.0))
        np.testing.assert_allclose(x["sns"], 0.5 * (x["psc"] + x["stl"]))
