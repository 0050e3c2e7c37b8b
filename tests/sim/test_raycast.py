"""The PyBullet envs' grid LiDAR (sim.sensors.GridLidar over sim.raycast) against Bullet's ray test, its reference.

At the same poses in the same world, the grid scan (static scene from distance grids, SocialNav's agents and vehicles
intersected exactly) and a Bullet `Lidar` on the env's client must agree within TOL (docs/raycast.md), on the sidewalk
and on a crosswalk (the road level, where the low scan sees the curbs), and the agents must be seen by both.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from curbside.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.envs.socialnav import SocialNavEnv
from sim.expert import PurePursuitExpert
from sim.sensors import GridLidar, Lidar
from tests.scenes import street

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
    (_, _, low_ids, _), = [e for e in _errors(env) if e[0] == "low"]
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
    cfg = {"scene": {"blocks": 1}, "route_length": [15.0, 30.0],
           "agents": {"counts": {"pedestrian": 12, "cyclist": 2, "wheelchair_user": 2}}, "traffic": True}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = SocialNavEnv(cfg)
    seen_agents = seen_vehicles = 0
    for seed in range(3):
        env.reset(seed=seed)
        m = env.machine
        # An agent just ahead, so that some beams certainly meet one.
        env.crowd.pos[0] = (m.position[0] + 1.5 * np.cos(m.yaw), m.position[1] + 1.5 * np.sin(m.yaw))
        env._sync_bodies()
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
