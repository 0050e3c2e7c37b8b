"""The batched numpy env (sim.batched) against the PyBullet PointNav env, its reference, and its VectorEnv API.

The match: on the hand-built street (tests/street.py), the same start, goal and action sequence (the expert's actions
driving the PyBullet env, 100 steps along the left sidewalk and around the trash bin on it) give observations and
rewards within TOL (docs/batched.md says why each bound is what it is); the same check fails for a perturbed action
sequence.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sim  # noqa: F401  (registers the env ids)
from kernel.config import ConfigError
from sim.batched import BatchedPointNav
from sim.envs.pointnav import PointNavEnv
from sim.expert import PurePursuitExpert
from tests.street import street

ROUTE = {"start": [3.0, 7.0], "goal": [40.0, 7.0]}  # left sidewalk, swerving around the trash bin at x = 15
STEPS = 100
B, L = 240, 60  # high and low beams (PointNav defaults)
# Tolerances (docs/batched.md): LiDAR in metres at PyBullet's own poses; the rest over the replay of 100 steps.
TOL = {
    "lidar_far_frac": 0.05,  # at most this fraction of beams more than 2 cells (0.1 m) off at the same pose
    "lidar_median": 0.03,  # median beam error (m) at the same pose
    "position": 0.02,  # m (measured 3 mm: Bullet's contact solver keeps the wheels a hair above the slab)
    "yaw": 0.005,  # rad
    "state": 0.005,  # speed, yaw rate, heading error, lateral offset (normalised observation values)
    "nav": 0.005,  # waypoints and goal (normalised observation values)
    "reward": 0.002,  # per step
    "replay_lidar_median": 0.01,  # median beam error (m) in the replay (its poses are up to `position` off)
}


def _decode(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """LiDAR distances (m) of an observation: the log-encoded 50 m scan and the linear 5 m low scan."""
    high = np.expm1(obs[:B].astype(np.float64) * math.log1p(50.0))
    return high, obs[B : B + L].astype(np.float64) * 5.0


@pytest.fixture(scope="module")
def reference():
    """The PyBullet run: actions, observations, rewards, end flags, poses and raw scans at every step."""
    env = PointNavEnv({"scene_spec": street(), "lidar": {"static": "bullet"}})  # Bullet's rays: the reference
    expert = PurePursuitExpert()
    env.reset(seed=0, options=ROUTE)
    out = {"actions": [], "obs": [], "rewards": [], "ends": [], "poses": [], "scans": []}
    for _ in range(STEPS):
        a = np.asarray(expert.act(env), dtype=np.float64)
        obs, r, term, trunc, _ = env.step(a)
        m = env.machine
        out["actions"].append(a)
        out["obs"].append(obs)
        out["rewards"].append(r)
        out["ends"].append((term, trunc))
        out["poses"].append((m.position[0], m.position[1], m.yaw))
        env.lidar.scan(*m.position, m.yaw)
        out["scans"].append(
            (
                env.lidar.distances.astype(np.float64) * env.lidar.range_m,
                env.low_lidar.scan(*m.position, m.yaw).astype(np.float64) * env.low_lidar.range_m,
            )
        )
        assert not (term or trunc), "the reference run must last STEPS steps"
    env.close()
    return out


def _replay(actions: list[np.ndarray]) -> dict[str, list]:
    env = BatchedPointNav(1, {"scene_spec": street()})
    env.reset(seed=0, options=ROUTE)
    out = {"obs": [], "rewards": [], "ends": [], "poses": []}
    for a in actions:
        obs, r, term, trunc, info = env.step(np.asarray(a)[None])
        out["obs"].append(info["final_obs"][0] if term[0] or trunc[0] else obs[0])
        out["rewards"].append(float(r[0]))
        out["ends"].append((bool(term[0]), bool(trunc[0])))
        out["poses"].append((env.drive.x[0], env.drive.y[0], env.drive.yaw[0]))
    return out


def mismatches(ref: dict[str, list], run: dict[str, list]) -> list[str]:
    """Where a batched run leaves TOL of the PyBullet run (empty: it matches)."""
    bad = []
    for k, (o_ref, o, r_ref, r, e_ref, e, p_ref, p) in enumerate(
        zip(
            ref["obs"], run["obs"], ref["rewards"], run["rewards"], ref["ends"], run["ends"], ref["poses"], run["poses"]
        )
    ):
        checks = {
            "position": math.hypot(p[0] - p_ref[0], p[1] - p_ref[1]),
            "yaw": abs((p[2] - p_ref[2] + math.pi) % (2 * math.pi) - math.pi),
            "state": float(np.abs(o[B + L : B + L + 4] - o_ref[B + L : B + L + 4]).max()),
            "nav": float(np.abs(o[B + L + 4 :] - o_ref[B + L + 4 :]).max()),
            "reward": abs(r - r_ref),
            "replay_lidar_median": float(np.median(np.abs(_decode(o)[0] - _decode(o_ref)[0]))),
        }
        bad += [f"step {k}: {name} off by {v:.4f} > {TOL[name]}" for name, v in checks.items() if v > TOL[name]]
        if e != e_ref:
            bad.append(f"step {k}: (terminated, truncated) {e} != PyBullet's {e_ref}")
    return bad


def test_lidar_matches_pybullet_at_the_same_poses(reference):
    env = BatchedPointNav(1, {"scene_spec": street()})
    env.reset(seed=0, options=ROUTE)
    for k, ((x, y, yaw), (high_ref, low_ref)) in enumerate(zip(reference["poses"], reference["scans"])):
        env.drive.x[0], env.drive.y[0], env.drive.yaw[0] = x, y, yaw
        env._locate_level()
        high, low = _decode(env._observe()[0])
        for name, err in (("high", np.abs(high - high_ref)), ("low", np.abs(low - low_ref))):
            assert (err > 0.1).mean() <= TOL["lidar_far_frac"], (k, name, np.nonzero(err > 0.1)[0])
            assert np.median(err) <= TOL["lidar_median"], (k, name, np.median(err))


def test_replay_matches_pybullet_and_a_perturbed_one_does_not(reference):
    assert mismatches(reference, _replay(reference["actions"])) == []
    steer_off = [a + np.array([0.1, 0.0]) for a in reference["actions"]]
    assert any("position" in m for m in mismatches(reference, _replay(steer_off)))
    slower = [a - np.array([0.0, 0.05]) for a in reference["actions"]]
    assert mismatches(reference, _replay(slower)) != []


def test_running_into_an_object_stops_and_costs_as_in_pybullet():
    cfg = {"scene_spec": street(), "collision_steps": 0, "stuck_steps": 0}
    route = {"start": [8.0, 7.0], "goal": [30.0, 7.0]}  # straight at the trash bin
    ref, env = PointNavEnv({**cfg, "lidar": {"static": "bullet"}}), BatchedPointNav(1, cfg)
    ref.reset(seed=0, options=route)
    env.reset(seed=0, options=route)
    for _ in range(40):
        _, r_ref, *_, info_ref = ref.step([0.0, 0.5])
        _, r, *_, info = env.step(np.array([[0.0, 0.5]]))
    assert info_ref["collision_kinds"] == ["object"] and info["collisions"][0] == 2  # KIND_BITS["object"]
    assert info["cost"][0] == info_ref["cost"] == 1.0
    assert abs(r[0] - r_ref) < TOL["reward"]
    assert env.drive.speed[0] == 0.0
    assert abs(env.drive.x[0] - ref.machine.position[0]) < 0.1  # stops where its footprint meets the bin
    ref.close()


def test_running_into_a_wall_at_an_angle_slides_along_it_as_in_pybullet():
    cfg = {"scene_spec": street(), "collision_steps": 0, "stuck_steps": 0}
    route = {"start": [6.0, 7.0], "goal": [30.0, 7.0]}
    ref, env = PointNavEnv({**cfg, "lidar": {"static": "bullet"}}), BatchedPointNav(1, cfg)
    ref.reset(seed=0, options=route)
    env.reset(seed=0, options=route)
    hits = 0
    for k in range(60):  # left into the building wall (y = 9 m) at ~48 degrees, then straight on at 0.6 throttle
        action = [0.25 if k < 12 else 0.0, 0.6]
        ref.step(action)
        _, _, _, _, info = env.step(np.array([action]))
        hits += int(info["collisions"][0] != 0)
    assert hits > 10  # it pressed on the wall, turning parallel to it
    m, drive = ref.machine, env.drive
    assert abs(math.degrees(m.yaw)) < 1.0 and abs(math.degrees(drive.yaw[0])) < 1.0
    assert drive.speed[0] > 0.8 * m.speed > 3.0  # sliding on, nearly as fast as Bullet's machine
    assert abs(drive.x[0] - m.position[0]) < 2.5 and abs(drive.y[0] - m.position[1]) < 0.1
    ref.close()


def test_meeting_a_wall_steeply_turns_the_machine_to_face_it_and_stops_it_as_in_pybullet():
    """Past the critical angle the push on the front corner turns Bullet's machine to face the wall, where it stands
    under full throttle; below it, it slides on. Both envs, from the same pose at 45 and 70 degrees to the building
    wall (y = 9 m), 2 m/s held by the same speed controller."""
    import pybullet as p

    cfg = {"scene_spec": street(), "collision_steps": 0, "stuck_steps": 0}
    route = {"start": [6.0, 7.0], "goal": [30.0, 7.0]}
    ref, env = PointNavEnv({**cfg, "lidar": {"static": "bullet"}}), BatchedPointNav(1, cfg)
    for degrees, slides in ((45.0, True), (70.0, False)):
        ref.reset(seed=0, options=route)
        env.reset(seed=0, options=route)
        th = math.radians(degrees)
        x, y = 12.0 - 3.0 * math.cos(th), 9.0 - 3.0 * math.sin(th)
        p.resetBasePositionAndOrientation(ref.machine.body, [0, 0, -50], [0, 0, 0, 1], physicsClientId=ref.client)
        ref.machine.reset(x, y, 0.15, th, np.random.default_rng(0))
        env.drive.x[0], env.drive.y[0], env.drive.yaw[0] = x, y, th
        for _ in range(60):
            ref.step([0.0, float(np.clip((2.0 - ref.machine.speed) * 2.0, -1.0, 1.0))])
            env.step(np.array([[0.0, float(np.clip((2.0 - env.drive.speed[0]) * 2.0, -1.0, 1.0))]]))
        m, drive = ref.machine, env.drive
        if slides:  # along the wall, parallel to it, ~1 m apart after 10 m
            assert abs(math.degrees(m.yaw)) < 2.0 and abs(math.degrees(drive.yaw[0])) < 2.0
            assert m.speed > 1.9 and drive.speed[0] > 1.9
            assert m.position[0] > x + 8.0 and abs(drive.x[0] - m.position[0]) < 1.5
        else:  # facing the wall, standing where they met it
            assert abs(math.degrees(m.yaw) - 90.0) < 2.0 and abs(math.degrees(drive.yaw[0]) - 90.0) < 2.0
            assert abs(m.speed) < 0.05 and abs(drive.speed[0]) < 0.05
            assert abs(drive.x[0] - m.position[0]) < 0.3
        assert abs(drive.y[0] - m.position[1]) < 0.2
    ref.close()


def test_the_low_part_of_a_curb_ramp_puts_the_body_at_the_road_level():
    """Where a ramp's surface lies more than the wheel radius below the sidewalk top (the first third of the test
    street's 1.2 m ramps: under 5 cm for the delivery robot's 10 cm wheels), the sidewalk beside it is a curb to
    climb: the batched body collides at the road level there, and at the sidewalk level higher up the ramp; a machine
    that comes down onto the low part with its body still over the sidewalk keeps the sidewalk level."""
    from sim.raycast.grids import LOW_RAMP, build_grids
    from sim.scene.scene import Scene

    scene = Scene.parse(street(), source="test street")
    lidar = {"height": 0.4, "low_height": 0.1}
    grids = build_grids(scene, resolution=0.05, lidar=lidar, body_height=0.55, step_max=0.10)
    rows, cols = np.nonzero(grids.kinds == LOW_RAMP)
    y = grids.origin[1] + (rows + 0.5) * grids.resolution
    x = grids.origin[0] + (cols + 0.5) * grids.resolution
    # the ramps span x 28-31 m; Bullet's wedges flare ~0.4 m to the sides
    assert rows.size > 0 and np.all((np.abs(y) > 3.95) & (np.abs(y) < 4.45) & (x > 27.5) & (x < 31.5))
    assert not (build_grids(scene, resolution=0.05, lidar=lidar, body_height=0.55).kinds == LOW_RAMP).any()

    env = BatchedPointNav(3, {"scene_spec": street(), "horizon": 10_000, "horizon_min_speed": None})
    env.reset(seed=0, options={"start": [6.0, 7.0], "goal": [50.0, 7.0]})
    # low on the ramp; high on it; low on its flare, its body's front over the sidewalk beside the ramp
    env.drive.x[:], env.drive.y[:], env.drive.yaw[:] = [29.5, 29.5, 31.3], [4.2, 4.9, 4.2], [0.0, 0.0, 0.0]
    env.body_level[:] = 0
    env._locate_level()
    assert env.body_level.tolist() == [1, 0, 0] and env.level.tolist() == [0, 0, 0]  # ROAD_LEVEL is 1
    env.close()


def test_vector_env_api_and_same_step_autoreset():
    env = BatchedPointNav(3, {"scene_spec": street(), "horizon": 6, "horizon_min_speed": None})
    assert env.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    assert env.single_observation_space.shape == (329,) and env.observation_space.shape == (3, 329)
    assert env.action_space.shape == (3, 2)
    obs, info = env.reset(seed=1)
    assert obs.dtype == np.float32 and obs in env.observation_space
    assert info["_route_length"].all() and (info["route_length"] > 0).all()
    rng = np.random.default_rng(0)
    for _ in range(6):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, (3, 2)))
        assert obs.shape == (3, 329) and obs.dtype == np.float32 and obs in env.observation_space
        assert reward.shape == (3,) and reward.dtype == np.float64 and term.dtype == trunc.dtype == bool
    assert (term | trunc).all() and info["_final_obs"].all()  # the horizon ends every episode at step 6
    final = np.stack(info["final_obs"])
    assert final.shape == (3, 329) and not np.array_equal(final, obs)
    assert info["final_info"]["_steps"].all() and (info["final_info"]["steps"] == 6).all()
    assert info["_route_length"].all()  # the new episodes' reset info
    obs, *_ = env.step(np.zeros((3, 2)))  # the reset envs run on
    assert obs in env.observation_space


def test_an_env_with_autoreset_off_is_not_reset_until_the_next_reset_call():
    env = BatchedPointNav(3, {"scene_spec": street(), "horizon": 6, "horizon_min_speed": None})
    env.reset(seed=1)
    env.autoreset[1] = False
    for _ in range(6):
        obs, _, term, trunc, info = env.step(np.zeros((3, 2)))
    assert (term | trunc).all() and info["_final_info"].all()  # every episode's end is reported
    assert info["_route_length"].tolist() == [True, False, True]  # env 1 was not reset
    assert np.array_equal(obs[1], info["final_obs"][1]) and not np.array_equal(obs[0], info["final_obs"][0])
    env.reset(seed=1)
    assert env.autoreset.all()
    env.close()


def test_same_seed_same_arrays_and_pointnav_draws():
    def run(seed: int) -> list[np.ndarray]:
        env = BatchedPointNav(2, {"scene_spec": street(), "num_waypoints": 4})
        out = [env.reset(seed=seed)[0]]
        rng = np.random.default_rng(seed)
        for _ in range(30):
            obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, (2, 2)))
            out += [obs, r, term, trunc]
        return out

    a, b, c = run(3), run(3), run(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))
    # Sub-env i reset with seed s draws the route and forces PointNavEnv.reset(seed=s + i) draws.
    env = BatchedPointNav(2, {"scene_spec": street()})
    env.reset(seed=7)
    ref = PointNavEnv({"scene_spec": street()})
    for i in range(2):
        ref.reset(seed=7 + i)
        assert np.array_equal(env.routes.routes[i].points, ref.route.points)
        assert env.drive.engine_force[i] == ref.machine.engine_force
    ref.close()


def test_bad_input_fails_clearly():
    env = BatchedPointNav(2, {"scene_spec": street()})
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((2, 2)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"env\(s\) \[1\] hold NaN"):
        env.step(np.array([[0.0, 0.5], [np.nan, 0.5]]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2))
    with pytest.raises(ConfigError, match="valid keys: .*route_pool"):
        BatchedPointNav(2, {"scene_spec": street(), "route_pol": 8})
    with pytest.raises(ConfigError, match="lidar.resolution"):
        BatchedPointNav(2, {"lidar": {"resolution": float("nan")}})
    with pytest.raises(ConfigError, match="lidar.static must be 'grid'"):
        BatchedPointNav(2, {"scene_spec": street(), "lidar": {"static": "bullet"}})
    with pytest.raises(ConfigError, match="gui"):
        BatchedPointNav(2, {"gui": True})
    with pytest.raises(ConfigError, match="num_envs"):
        BatchedPointNav(0)


def test_make_vec_gives_the_batched_env_by_its_name_and_pybullet_envs_by_default():
    envs = gym.make_vec("curbside/BatchedPointNav-v0", num_envs=3, config={"scene_spec": street()})
    assert isinstance(envs.unwrapped, BatchedPointNav) and envs.num_envs == 3
    for task in ("PointNav", "SocialNav"):
        pybullet = gym.make_vec(f"curbside/{task}-v0", num_envs=2, config={"scene_spec": street()})
        assert isinstance(pybullet, gym.vector.SyncVectorEnv) and pybullet.num_envs == 2
        assert pybullet.reset(seed=0)[0].shape[0] == 2
        pybullet.close()
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (3, 329)
    envs.close()


def test_final_info_has_the_spl_of_the_pybullet_env():
    cfg = {"scene_spec": street()}
    route = {"start": [8.0, 5.6], "goal": [22.0, 5.6]}  # along the sidewalk, clear of the bin
    ref, env = PointNavEnv(cfg), BatchedPointNav(1, cfg)
    ref.reset(seed=0, options=route)
    env.reset(seed=0, options=route)
    reference = env.reference[0]  # (the autoreset at the episode's end draws a new route)
    expert, actions = PurePursuitExpert(), []
    for _ in range(400):  # the expert on the PyBullet env, its actions replayed on the batched env
        actions.append(expert.act(ref))
        _, _, term, trunc, info_ref = ref.step(actions[-1])
        if term or trunc:
            break
    for a in actions:
        _, _, term_b, trunc_b, info = env.step(np.asarray(a, dtype=np.float64)[None])
        if term_b[0] or trunc_b[0]:
            break
    assert info_ref["is_success"] and info["final_info"]["is_success"][0]
    spl, spl_ref = info["final_info"]["spl"][0], info_ref["spl"]
    assert 0.8 < spl <= 1.0 and 0.8 < spl_ref <= 1.0
    assert spl == pytest.approx(reference / max(info["final_info"]["path_length"][0], reference))
    assert reference == pytest.approx(ref.reference_length())  # the same geodesic as the PyBullet env's
    assert set(info_ref["metrics"]) <= set(info["final_info"])  # every measure of the PyBullet env
    for key in ("success", "steps", "route_completion"):
        assert info["final_info"][key][0] == pytest.approx(info_ref["metrics"][key], abs=0.05), key
    ref.close()
