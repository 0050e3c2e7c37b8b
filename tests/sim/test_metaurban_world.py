"""MetaUrban's world on both backends: its ego (the `metaurban_*` machines: EgoVehicle's body on Bullet raycast
wheels), its cost rule (an object charged once, at its first contact) and its episode ends.

Each check runs the PyBullet env (the reference) and the batched env on the hand-built street (tests/street.py) and
could fail on either: a ride that does not climb, a cost counted per step, a horizon cut by route length.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from curbside.train.protocols import protocol
from kernel.config import ConfigError
from sim.batched import BatchedPointNav
from sim.envs.pointnav import PointNavEnv
from sim.machines import machine_spec, vehicle_drive
from tests.street import street

ROUTE = {"start": [3.0, 7.0], "goal": [40.0, 7.0]}  # left sidewalk; the trash bin stands on it at x = 15
FREE = {"stuck_steps": 0, "collision_steps": 0, "horizon": 10_000, "horizon_min_speed": None}


def _on_street(name: str, **over: object) -> dict:
    """Protocol `name`'s env config on the test street (its scenes and catalog left out; the street's clear path is
    narrower than a city's, so routes keep the realistic machines' margin)."""
    cfg = {k: v for k, v in protocol(name).env_config.items() if k not in ("preset", "catalog")}
    return {**cfg, "scene_spec": street(), "route_margin": 0.25, **over}


def test_the_raycast_vehicle_drive_is_metaurbans_for_numbers_and_arrays() -> None:
    """Engine force on four wheels (4 F / m), no engine past the top speed, brakes that stop but never reverse, the
    same doubles for one machine and for an array of them."""
    spec = machine_spec("metaurban_coco")
    v, _ = vehicle_drive(spec, 0.0, 0.0, 1.0, 450.0, 57.5, 0.02, 0.7)
    assert v == pytest.approx(4 * 450.0 / 1595.0 * 0.02)
    v = 0.0
    for _ in range(1500):  # 30 s of full throttle
        v, _ = vehicle_drive(spec, v, 0.0, 1.0, 450.0, 57.5, 0.02, 0.7)
    assert spec.v_max - 0.05 < v < spec.v_max + 0.05  # the engine cuts out at 30 km/h, the idle brake holds it there
    for _ in range(200):
        v, w = vehicle_drive(spec, v, 0.5, -1.0, 450.0, 57.5, 0.02, 0.7)
    assert v == 0.0 and w == 0.0  # braked to rest, not backwards
    speeds = np.array([0.0, 3.0, 8.0, 9.0])
    throttles = np.array([1.0, -0.5, 0.2, 0.0])
    steers = np.array([0.3, -1.0, 0.0, 1.0])
    v_arr, w_arr = vehicle_drive(spec, speeds, steers, throttles, 400.0, 50.0, 0.02, 0.7)
    for k in range(4):
        v_one, w_one = vehicle_drive(
            spec, float(speeds[k]), float(steers[k]), float(throttles[k]), 400.0, 50.0, 0.02, 0.7
        )
        assert (v_one, w_one) == (float(v_arr[k]), float(w_arr[k]))


def _drive_at_curb(machine: str, backend: str) -> tuple[float, float]:
    """(y, surface level) from the road (x = 10, y = 0.5) straight at the left curb at throttle 0.3, after 10 s or
    once past y = 6.2 (all four wheels over the sidewalk, the front ones short of the building at y = 9)."""
    cfg = {"scene_spec": street(), "machine": machine, **FREE, "out_of_route_distance": 100.0}
    cfg["terminate_off_walkable"] = False
    if backend == "pybullet":
        env = PointNavEnv(cfg)
        env.reset(seed=0, options=ROUTE)
        m = env.machine
        m.reset(10.0, 0.5, 0.0, math.pi / 2, np.random.default_rng(0))
        for _ in range(100):
            env.step([0.0, 0.3])
            if m.position[1] > 6.2:
                break
        y, z = m.position[1], m.position[2]
        env.close()
        return y, z
    env = BatchedPointNav(1, cfg)
    env.reset(seed=0, options=ROUTE)
    env.drive.x[:], env.drive.y[:], env.drive.yaw[:] = 10.0, 0.5, math.pi / 2
    env._locate_level()
    for _ in range(100):
        env.step(np.array([[0.0, 0.3]]))
        if env.drive.y[0] > 6.2:
            break
    y, level = float(env.drive.y[0]), int(env.level[0])
    env.close()
    return y, 0.15 if level == 0 else 0.0  # SIDEWALK_LEVEL stands on the curb


@pytest.mark.parametrize("backend", ["pybullet", "batched"])
def test_metaurbans_ego_mounts_a_curb_that_the_delivery_robot_cannot(backend: str) -> None:
    """The street's curb (0.15 m, at |y| = 4) is lower than the ego's axle: its raycast wheels drive up onto the
    sidewalk, all four on it. The delivery robot's 0.10 m wheels stop at the curb."""
    y, z = _drive_at_curb("metaurban_coco", backend)
    assert 6.2 < y < 7.0 and z == pytest.approx(0.15, abs=0.01)
    if backend == "pybullet":  # the batched env keeps a realistic machine on the walkable area by its levels
        y, z = _drive_at_curb("delivery_bot", backend)
        assert y < 4.5 and z < 0.14


@pytest.mark.parametrize("machine", ["metaurban_coco", "delivery_bot"])
def test_the_batched_body_grid_holds_a_curb_only_for_a_machine_that_cannot_climb_it(machine: str) -> None:
    from sim.raycast.grids import CURB, ROAD_LEVEL, build_grids
    from sim.scene.scene import Scene

    spec = machine_spec(machine)
    scene = Scene.parse(street(), source="test street")
    grids = build_grids(
        scene,
        resolution=0.05,
        lidar={"height": 0.4, "low_height": 0.1},
        body_height=spec.height,
        step_max=spec.wheel_radius,
        clearance=spec.clearance,
    )
    body = grids.tables[ROAD_LEVEL][2]
    raised = grids.kinds == CURB
    assert (body[raised] == 0).all() != spec.rides  # every raised cell blocks the delivery robot, none the ego


def _push(backend: str, cfg: dict) -> tuple[int, float]:
    """(steps in contact with the trash bin, episode cost) of the ego driven into it until 50 steps in contact."""
    contact, cost = 0, 0.0
    if backend == "pybullet":
        env = PointNavEnv(cfg)
        env.reset(seed=0, options=ROUTE)
        for _ in range(300):
            _, _, term, _, info = env.step([0.0, 0.5])
            assert not term
            contact += "object" in info["collision_kinds"]
            cost += info["cost"]
            if contact == 50:
                break
        env.close()
        return contact, cost
    env = BatchedPointNav(1, cfg)
    env.reset(seed=0, options=ROUTE)
    for _ in range(300):
        _, _, term, _, info = env.step(np.array([[0.0, 0.5]]))
        assert not term[0]
        contact += bool(info["collisions"][0] & 2)  # the object bit
        cost += float(info["cost"][0])
        if contact == 50:
            break
    env.close()
    return contact, cost


@pytest.mark.parametrize("backend", ["pybullet", "batched"])
def test_an_object_pushed_for_50_steps_costs_1_under_paper_and_50_under_curbside(backend: str) -> None:
    assert _push(backend, _on_street("paper")) == (50, 1.0)
    assert _push(backend, _on_street("curbside", machine="metaurban_coco", **FREE)) == (50, 50.0)
    base = {"scene_spec": street(), "machine": "metaurban_coco", "cost_kinds": ["object"], **FREE}
    assert _push(backend, {**base, "cost_rule": "metaurban"}) == (50, 1.0)
    assert _push(backend, {**base, "cost_rule": "contact_steps"}) == (50, 50.0)


@pytest.mark.parametrize("backend", ["pybullet", "batched"])
def test_an_episode_ends_at_1000_steps_under_paper(backend: str) -> None:
    """MetaUrban's ends: a machine standing still is neither stuck nor out of route; the horizon truncates it at
    step 1,000, whatever the route's length (the `curbside` protocol cuts it to route length / 0.5 m/s)."""
    cfg = _on_street("paper")
    steps = 0
    if backend == "pybullet":
        env = PointNavEnv(cfg)
        _, reset_info = env.reset(seed=0, options=ROUTE)
        term = trunc = False
        while not (term or trunc):
            _, _, term, trunc, _ = env.step([0.0, 0.0])
            steps += 1
        env.close()
    else:
        env = BatchedPointNav(1, cfg)
        _, reset_info = env.reset(seed=0, options=ROUTE)
        env.autoreset[0] = False  # the street holds no route of the protocol's lengths to draw next
        term = trunc = np.zeros(1, dtype=bool)
        while not (term[0] or trunc[0]):
            _, _, term, trunc, _ = env.step(np.zeros((1, 2)))
            steps += 1
        env.close()
    assert int(np.asarray(reset_info["horizon"]).reshape(-1)[0]) == 1000
    assert steps == 1000 and bool(np.asarray(trunc).reshape(-1)[0]) and not bool(np.asarray(term).reshape(-1)[0])
    env = PointNavEnv(_on_street("curbside"))
    _, reset_info = env.reset(seed=0, options=ROUTE)
    assert reset_info["horizon"] < 1000  # 37 m at 0.5 m/s
    env.close()


def test_metaurbans_rule_charges_no_building_and_leaving_the_route_costs() -> None:
    with pytest.raises(ConfigError, match="never charged by MetaUrban's cost function"):
        PointNavEnv({"scene_spec": street(), "cost_rule": "metaurban", "cost_kinds": ["object", "building"]})
    cfg = {"scene_spec": street(), "machine": "metaurban_coco", "cost_rule": "metaurban", "cost_kinds": ["object"]}
    env = BatchedPointNav(1, {**cfg, **FREE, "out_of_route_distance": 1.0, "terminate_off_walkable": False})
    env.reset(seed=0, options=ROUTE)
    for _ in range(100):  # steer off the route to the right until the episode ends out of route
        _, _, term, _, info = env.step(np.array([[-0.6, 0.4]]))
        if term[0]:
            break
    assert term[0] and info["final_info"]["out_of_route"][0] and info["final_info"]["cost"][0] == 1.0
    env.close()


def test_metaurbans_reward_replaces_the_step_on_a_crash_or_an_end_and_matches_its_batch() -> None:
    """The `metaurban` preset: 2 a metre of progress, the lateral and steering-range terms, 0.5 x speed / top speed,
    floored at 0; a charged crash makes the step -2, success +8, leaving the route -3. The scalar path (PyBullet env)
    and the batch path (batched env) give the same doubles."""
    from sim.tasks.pointnav import make_reward
    from sim.tasks.termination import StepContext, StepEnd

    reward = make_reward("metaurban", None)
    rng = np.random.default_rng(0)
    for _ in range(200):
        progress, lateral, speed = rng.uniform(-0.3, 0.8), rng.uniform(-6, 6), rng.uniform(-0.1, 8.0)
        steer, collided = rng.uniform(-1, 1), bool(rng.random() < 0.3)
        ends = [bool(rng.random() < 0.1), bool(rng.random() < 0.1)]
        end = StepEnd(succeeded=ends[0], out_of_route=ends[1] and not ends[0])
        step = StepContext(
            1,
            progress,
            max(progress, 0.0),
            1.0,
            100.0,
            lateral,
            0.1,
            speed,
            0.0,
            collided,
            collided,
            0.0,
            lambda: True,
            steer=steer,
            speed_fraction=abs(speed) / 8.33,
        )
        one = reward(step, end)
        many = reward.batch(
            np.array([progress]),
            np.array([max(progress, 0.0)]),
            np.array([lateral]),
            np.array([0.1]),
            np.array([speed]),
            np.array([collided]),
            np.array([end.succeeded]),
            np.array([end.out_of_route]),
            np.array([False]),
            np.array([steer]),
            np.array([abs(speed) / 8.33]),
        )
        assert one == float(many[0])
        if end.succeeded:
            assert one == 8.0
        elif end.out_of_route:
            assert one == -3.0
        elif collided:
            assert one == -2.0
        else:
            dense = 2.0 * progress - 0.4 * abs(lateral) + 0.5 * abs(speed) / 8.33
            dense += 2.0 * min(1.0 / max(speed, 1e-2) - abs(steer), 0.0)
            assert one == pytest.approx(max(dense, 0.0))


def test_the_expert_drives_metaurbans_ego_round_the_bin_without_touching_it() -> None:
    """`PurePursuitExpert.for_machine` steers the ego among free arcs: on the street it passes the trash bin on the
    sidewalk (the 1 m wide ego cannot turn on the spot, and cannot reverse) and reaches the goal at no cost."""
    from sim.expert import PurePursuitExpert

    env = PointNavEnv(_on_street("paper"))
    env.reset(seed=0, options=ROUTE)
    expert = PurePursuitExpert.for_machine(env.spec_machine)
    assert (
        expert.steering == "arcs" and PurePursuitExpert.for_machine(machine_spec("delivery_bot")).steering == "pursuit"
    )
    term = trunc = False
    while not (term or trunc):
        _, _, term, trunc, info = env.step(expert.act(env))
    assert info["success"] and info["episode_cost"] == 0.0
    env.close()


@pytest.mark.parametrize("backend", ["pybullet", "batched"])
def test_a_building_crash_ends_a_socialnav_episode_under_paper_but_not_a_pointnav_one(backend: str) -> None:
    """MetaUrban's dynamic env ends an episode when the ego runs into a building (its static env does not): the ego
    driven from the road over the curb into the building beyond ends its SocialNav episode as `crashed`."""
    from sim.batched.social import BatchedSocialNav
    from sim.envs.socialnav import SocialNavEnv

    free = {"out_of_route_distance": 100.0, "agents": {"dynamic_density": 0.0}, "traffic": False}
    for task, ends in (("SocialNav", True), ("PointNav", False)):
        cfg = {k: v for k, v in protocol("paper").env_for(task).items() if k not in ("preset", "catalog")}
        cfg = {**cfg, "scene_spec": street(), "route_margin": 0.25, **(free if task == "SocialNav" else {})}
        cfg["out_of_route_distance"] = 100.0
        crashed = False
        if backend == "pybullet":
            env = SocialNavEnv(cfg) if task == "SocialNav" else PointNavEnv(cfg)
            env.reset(seed=0, options=ROUTE)
            env.machine.reset(10.0, 0.5, 0.0, math.pi / 2, np.random.default_rng(0))
            for _ in range(150):
                _, _, term, _, info = env.step([0.0, 0.3])
                if term:
                    crashed = info["end_reason"] == "crashed"
                    break
        else:
            env = BatchedSocialNav(1, cfg) if task == "SocialNav" else BatchedPointNav(1, cfg)
            env.reset(seed=0, options=ROUTE)
            env.autoreset[0] = False
            env.drive.x[:], env.drive.y[:], env.drive.yaw[:] = 10.0, 0.5, math.pi / 2
            env._locate_level()
            for _ in range(150):
                _, _, term, _, info = env.step(np.array([[0.0, 0.3]]))
                if term[0]:
                    crashed = bool(info["final_info"]["crashed"][0])
                    break
        env.close()
        assert crashed == ends, task


@pytest.mark.parametrize("backend", ["pybullet", "batched"])
def test_the_ego_glances_off_an_objects_corner_and_stops_at_its_face(backend: str) -> None:
    """Bullet resolves the ego's chassis box against an object's box along the shallowest overlap: driven at the
    street's trash bin (0.6 m square) with 0.1 m of overlap it is pushed aside and passes; head on it stops. The
    batched env's `_deflect` does the same."""
    spec = street()
    bin_x, bin_y = next(o for o in spec["objects"] if o["category"] == "trash_bin")["position"][:2]
    cfg = {**_on_street("curbside", machine="metaurban_coco", **FREE), "out_of_route_distance": 100.0}
    ends = {}
    for offset in (0.7, 0.0):
        x0, y0 = bin_x - 5.0, bin_y + offset
        if backend == "pybullet":
            env = PointNavEnv(cfg)
            env.reset(seed=0, options=ROUTE)
            env.machine.reset(x0, y0, 0.15, 0.0, np.random.default_rng(0))
            for _ in range(60):
                env.step([0.0, float(np.clip((2.0 - env.machine.speed) * 2.0, -1.0, 1.0))])
            ends[offset] = (env.machine.position[0], env.machine.speed)
        else:
            env = BatchedPointNav(1, cfg)
            env.reset(seed=0, options=ROUTE)
            env.autoreset[0] = False
            env.drive.reset(0, x0, y0, 0.0, np.random.default_rng(0))
            env._locate_level()
            for _ in range(60):
                env.step(np.array([[0.0, float(np.clip((2.0 - env.drive.speed[0]) * 2.0, -1.0, 1.0))]]))
            ends[offset] = (float(env.drive.x[0]), float(env.drive.speed[0]))
        env.close()
    assert ends[0.7][0] > bin_x + 4.0 and ends[0.7][1] > 1.9  # passed the bin at speed
    assert ends[0.0][0] < bin_x - 0.9 and abs(ends[0.0][1]) < 0.05  # stopped at its face


def test_a_machine_that_leaves_the_scene_reads_its_lidar_safely_on_both_backends() -> None:
    """MetaUrban's ego may leave the sidewalks and, within 5 m of its route, the scene's grids: LiDAR origins off the
    grid (or rays that start past its ring) read the grid's edge, never memory outside it."""
    cfg = _on_street("paper")
    env = PointNavEnv(cfg)
    env.reset(seed=0, options=ROUTE)
    for x, y in ((-3.0, 7.0), (-40.0, -40.0), (200.0, 7.0)):
        env.machine.reset(x, y, 0.0, 0.3, np.random.default_rng(0))
        obs, *_ = env.step([0.0, 0.0])
        assert np.isfinite(obs).all()
    env.close()
    batched = BatchedPointNav(1, cfg)
    batched.reset(seed=0, options=ROUTE)
    batched.autoreset[0] = False
    for x, y in ((-3.0, 7.0), (-40.0, -40.0), (200.0, 7.0)):
        batched.drive.x[:], batched.drive.y[:] = x, y
        batched._locate_level()
        obs, *_ = batched.step(np.zeros((1, 2)))
        assert np.isfinite(obs).all()
    batched.close()
