"""The PyBullet envs' grid LiDAR (sim.sensors.GridLidar over sim.raycast) against Bullet's ray test, its reference.

At the same poses in the same world, the grid scan (static scene from distance grids, SocialNav's agents and vehicles
intersected exactly) and a Bullet `Lidar` on the env's client must agree within TOL (docs/raycast.md), on the sidewalk
and on a crosswalk (the road level, where the low scan sees the curbs), and the agents must be seen by both.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from kernel.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.envs.socialnav import SocialNavEnv
from sim.expert import PurePursuitExpert
from sim.sensors import GridLidar, Lidar
from tests.street import street

TOL = {"far_frac": 0.05, "median": 0.03}  # beams more than 0.1 m off (fraction), median error (m)


def _bullet_twin(env: PointNavEnv, lidar: GridLidar) -> Lidar:
    """A Bullet LiDAR of the same beams, range and height on the env's world."""
    return Lidar(env.client, lidar.beams, lidar.range_m, lidar.height, lidar.start_radius)


def _errors(env: PointNavEnv) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, |grid - bullet| in m, grid hit ids) of both scans at the machine's current pose."""
    m = env.machine
    out = []
    for name, lid in (("high", env.lidar), ("low", env.low_lidar)):
        twin = _bullet_twin(env, lid)
        grid = lid.scan(*m.position, m.yaw).astype(np.float64) * lid.range_m
        bullet = twin.scan(*m.position, m.yaw).astype(np.float64) * twin.range_m
        out.append((name, np.abs(grid - bullet), lid.hit_ids.copy(), twin.hit_ids.copy()))
    return out


def _check(env: PointNavEnv, where: str) -> None:
    for name, err, _, _ in _errors(env):
        assert (err > 0.1).mean() <= TOL["far_frac"], (where, name, np.nonzero(err > 0.1)[0], err.max())
        assert np.median(err) <= TOL["median"], (where, name, np.median(err))


def test_grid_scans_match_bullet_along_an_expert_run_and_on_the_road() -> None:
    env = PointNavEnv({"scene_spec": street()})
    env.reset(seed=0, options={"start": [3.0, 7.0], "goal": [40.0, 7.0]})
    assert isinstance(env.lidar, GridLidar) and isinstance(env.low_lidar, GridLidar)
    expert = PurePursuitExpert()
    for k in range(60):
        env.step(expert.act(env))
        if k % 10 == 0:
            _check(env, f"step {k}")
    # On the crosswalk (x = 29.5): the machine is on the road, the low scan sees the curbs as walls.
    env.reset(seed=0, options={"start": [29.5, -3.0], "goal": [29.5, 6.0]})
    for _ in range(8):
        env.step([0.0, 0.4])
    assert env.machine.position[2] < 0.5 * env.scene.curb_height, "the machine should be down on the crosswalk"
    _check(env, "crosswalk")
    ((_, _, low_ids, _),) = [e for e in _errors(env) if e[0] == "low"]
    assert (low_ids == GridLidar.STATIC_HIT).any(), "the low scan must see the curbs from the road"
    env.close()


def test_a_perturbed_pose_leaves_the_tolerance() -> None:
    """The check can fail: the grid scan taken 0.3 m beside the machine disagrees with Bullet's."""
    env = PointNavEnv({"scene_spec": street()})
    env.reset(seed=0, options={"start": [10.0, 7.0], "goal": [40.0, 7.0]})
    m = env.machine
    x, y, z = m.position
    grid = env.lidar.scan(x, y + 0.3, z, m.yaw) * env.lidar.range_m
    bullet = _bullet_twin(env, env.lidar).scan(x, y, z, m.yaw) * env.lidar.range_m
    err = np.abs(grid.astype(np.float64) - bullet)
    assert (err > 0.1).mean() > TOL["far_frac"] or np.median(err) > TOL["median"]
    env.close()


def test_socialnav_grid_scans_see_agents_and_vehicles_as_bullet_does() -> None:
    cfg = {
        "scene": {"blocks": 1},
        "route_length": [15.0, 30.0],
        "agents": {"counts": {"pedestrian": 12, "cyclist": 2, "wheelchair_user": 2}},
        "traffic": True,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = SocialNavEnv(cfg)
    seen_agents = seen_vehicles = 0
    for seed in range(3):
        env.reset(seed=seed)
        m = env.machine
        # An agent just ahead, so that some beams certainly meet one.
        env.crowd.pos[0] = (m.position[0] + 1.5 * np.cos(m.yaw), m.position[1] + 1.5 * np.sin(m.yaw))
        env.body_adapter.sync()
        for k in range(20):
            env.step([0.0, 0.3])
            if k % 5 == 0:
                _check(env, f"seed {seed} step {k}")
                moving = np.array(env.bodies.agents + env.bodies.vehicles)
                for name, _, grid_ids, bullet_ids in _errors(env):
                    # Beam by beam, the same moving body (or none of them) is met first, but for a few beams
                    # that graze a body's edge or pass a static object's corner.
                    g = np.where(np.isin(grid_ids, moving), grid_ids, -1)
                    b = np.where(np.isin(bullet_ids, moving), bullet_ids, -1)
                    assert (g != b).mean() <= TOL["far_frac"], (seed, k, name, g[g != b], b[g != b])
                    seen_agents += int(np.isin(g, env.bodies.agents).sum())
                    seen_vehicles += int(np.isin(g, env.bodies.vehicles).sum())
    assert seen_agents > 0, "the agent put ahead of the machine must be seen"
    assert seen_vehicles > 0, "the traffic on the road must be seen from the sidewalk"
    env.close()


def test_backend_choice() -> None:
    bullet = PointNavEnv({"scene_spec": street(), "lidar": {"static": "bullet"}})
    bullet.reset(seed=0)
    assert type(bullet.lidar) is Lidar
    bullet.close()
    with pytest.raises(ConfigError, match="lidar.static 'bullet'"):
        PointNavEnv({"scene_spec": street(), "collision": "convex", "lidar": {"static": "grid"}})
    with pytest.raises(ConfigError, match="valid: auto, grid, bullet"):
        PointNavEnv({"scene_spec": street(), "lidar": {"static": "fast"}})


def test_march_never_steps_over_a_thin_pole_beside_a_grazed_wall() -> None:
    """A beam running 0.1-1 m beside a long wall meets a one-cell pole 15-30 m ahead, exactly where it is."""
    from sim.raycast.grids import RING, _distance
    from sim.raycast.march import trace

    res, rows, cols = 0.05, 200, 1400  # 10 x 70 m
    frame = {
        "x0": np.array([-RING * res]),
        "y0": np.array([-RING * res]),
        "cols": np.array([cols + 2 * RING]),
        "offset": np.zeros(1, dtype=np.int64),
    }
    for gap in (0.1, 0.25, 0.5, 1.0):
        for pole_x in (15.0, 22.5, 30.0):
            occ = np.zeros((rows, cols), dtype=bool)
            occ[100, 100:1300] = True  # the wall: y in [5.0, 5.05), x from 5 to 65 m
            y = 5.0 - gap + 0.5 * res  # the beam runs along the middle of a row of cells
            occ[int(y / res), int(pole_x / res)] = True
            d = trace(_distance(occ).ravel(), frame, np.array([2.0]), np.array([y]), np.zeros((1, 1)), 0.3, 50.0, res)[
                0, 0
            ]
            assert abs(d - (pole_x - 2.0)) < 1e-6, (gap, pole_x, d)
            occ[int(y / res), int(pole_x / res)] = False
            d = trace(_distance(occ).ravel(), frame, np.array([2.0]), np.array([y]), np.zeros((1, 1)), 0.3, 50.0, res)[
                0, 0
            ]
            assert d == 50.0, (gap, pole_x, d)  # no pole: nothing in range, the range exactly


def test_rays_against_circles_and_boxes() -> None:
    from sim.raycast.shapes import box_hits, circle_hits

    cos, sin = np.array([1.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])  # +x, +y, -x
    dist, which = np.full(3, np.inf), -np.ones(3, dtype=np.int64)
    circle_hits(
        0.0, 0.0, cos, sin, np.array([5.0, 0.0]), np.array([0.0, 0.2]), np.array([1.0, 0.5]), 0.5, 50.0, dist, which
    )
    assert dist[0] == pytest.approx(4.0) and which[0] == 0  # the circle ahead, entered at 4 m
    assert dist[1] == 0.5 and which[1] == 1  # starts inside the second circle: met at the start radius
    assert np.isinf(dist[2]) and which[2] == -1  # behind (-x) the ray leaves that circle before its start
    dist, which = np.full(3, np.inf), -np.ones(3, dtype=np.int64)
    circle_hits(0.0, 0.0, cos, sin, np.array([60.0]), np.array([0.0]), np.array([1.0]), 0.5, 50.0, dist, which)
    assert np.isinf(dist).all() and (which == -1).all()  # beyond the range
    dist, which = np.full(3, np.inf), -np.ones(3, dtype=np.int64)
    # A 4 x 2 m box 10 m ahead turned by 90 degrees: its 2 m side faces the ray; the ray along +y runs beside it.
    box_hits(
        0.0, 0.0, cos, sin, np.array([10.0]), np.array([0.0]), np.array([np.pi / 2]), 2.0, 1.0, 0.5, 50.0, dist, which
    )
    assert dist[0] == pytest.approx(9.0) and which[0] == 0
    assert np.isinf(dist[1:]).all()


def test_parked_or_absent_bodies_are_not_seen() -> None:
    cfg = {"scene_spec": street(), "agents": {"counts": {"pedestrian": 3}}, "traffic": False}
    env = SocialNavEnv(cfg)
    env.reset(seed=0)
    cos, sin = np.cos(env.lidar.angles), np.sin(env.lidar.angles)
    m = env.machine
    env.crowd.pos[0] = (m.position[0] + 1.0, m.position[1])
    env.body_adapter.sync()
    d, ids = env.bodies.ray_hits(m.position[0], m.position[1], 0.5, cos, sin, 0.4, 50.0)
    assert (ids == env.bodies.agents[0]).any()
    env.bodies.park()
    d, ids = env.bodies.ray_hits(m.position[0], m.position[1], 0.5, cos, sin, 0.4, 50.0)
    assert np.isinf(d).all() and (ids == -1).all()
    env.close()
    empty = SocialNavEnv({"scene_spec": street(), "agents": {"counts": {"pedestrian": 0}}, "traffic": False})
    empty.reset(seed=0)
    assert len(empty.crowd.pos) == 0
    d, ids = empty.bodies.ray_hits(0.0, 0.0, 0.5, cos, sin, 0.4, 50.0)
    assert np.isinf(d).all() and (ids == -1).all()
    empty.close()


def test_auto_picks_bullet_for_mesh_collision() -> None:
    from sim.tasks.pointnav import DEFAULT_CONFIG, static_lidar

    assert static_lidar(DEFAULT_CONFIG) == "grid"
    assert static_lidar({**DEFAULT_CONFIG, "collision": "convex"}) == "bullet"
    assert static_lidar({**DEFAULT_CONFIG, "lidar": {**DEFAULT_CONFIG["lidar"], "static": "bullet"}}) == "bullet"
