"""World builder, machines, route planner, LiDAR and metrics registry, each on real PyBullet."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from kernel.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.machines import MACHINES, WHEELED, Machine, machine_spec
from sim.metrics import MEASURES, Measure, make_measures, register_measure
from sim.route import RoutePlanner
from sim.scene.grid import decode_walkable
from sim.sensors import Lidar
from sim.world import World


def test_world_surfaces_and_heights(spec):
    w = World(spec)
    kinds = set(w.kinds.values())
    assert {"ground", "sidewalk", "ramp", "building", "object"} <= kinds
    assert len(w.object_ids) == len(spec["objects"])
    assert w.surface_height(10.0, 7.0) == pytest.approx(0.15, abs=1e-3)  # raised sidewalk
    assert w.surface_height(10.0, 0.0) == pytest.approx(0.0, abs=1e-3)  # road
    h = w.surface_height(29.5, 4.6)  # on the ramp: between road and sidewalk
    assert 0.01 < h < 0.14
    w.close()


def test_machines_table_and_custom():
    realistic = {"delivery_bot", "delivery_bot_mod1", "delivery_bot_mod2", "wheelchair", "mobility_scooter"}
    metaurban = {f"metaurban_{n}" for n in ("coco", "coco_mod1", "coco_mod2", "wheelchair", "scooter")}
    assert set(WHEELED) == realistic | metaurban
    assert all(MACHINES[n].drive == "force" for n in realistic) and all(MACHINES[n].rides for n in metaurban)
    assert {(MACHINES[n].v_max_kmh, MACHINES[n].steer_max_deg, MACHINES[n].engine_force) for n in metaurban} == {
        (MACHINES[n].v_max_kmh, MACHINES[n].steer_max_deg, MACHINES[n].engine_force) for n in realistic
    }  # the paper's Table 2 limits on both bodies
    assert MACHINES["mobility_scooter"].v_max == pytest.approx(12.5)
    custom = machine_spec({"base": "wheelchair", "v_max_kmh": 8, "engine_force": [120, 130]})
    assert custom.v_max_kmh == 8 and custom.engine_force == (120.0, 130.0) and custom.wheelbase == 0.5
    with pytest.raises(ConfigError, match="valid machines"):
        machine_spec("segway")
    with pytest.raises(ConfigError, match="unknown machine parameter"):
        machine_spec({"turbo": True})


def test_top_speed_and_forces_drawn_in_range(spec):
    w = World(spec)
    rng = np.random.default_rng(0)
    m = Machine(w.client, machine_spec("delivery_bot_mod1"))  # 10 km/h
    m.reset(2.0, 7.0, 0.15, 0.0, rng)
    assert 350 <= m.engine_force <= 550 and 35 <= m.brake_force <= 80
    for _ in range(150):  # 3 s of full throttle on the open clear path
        m.command(0.0, 1.0, 0.02)
        p.stepSimulation(physicsClientId=w.client)
        m.sync()
    assert 0.8 * m.spec.v_max < m.speed <= m.spec.v_max + 1e-6
    for _ in range(100):  # braking stops it and does not drive it backwards
        m.command(0.0, -1.0, 0.02)
        p.stepSimulation(physicsClientId=w.client)
        m.sync()
    assert abs(m.speed) < 0.05
    w.close()


def test_route_planner_keeps_clear_of_obstacles(spec):
    planner = RoutePlanner(spec, half_width=0.25)
    rng = np.random.default_rng(1)
    grid = decode_walkable(spec)
    for _ in range(5):
        route = planner.sample(rng, 10.0, 40.0)
        assert 10.0 <= route.length <= 40.0
        assert all(grid.label_at(x, y) > 0 for x, y in route.points)
    route = planner.plan([10.0, 7.0], [20.0, 7.0])
    # The trash bin at (15, 7) sits on the straight line: the route bends around it.
    s, lat = route.locate(15.0, 7.0)
    assert abs(lat) > 0.6
    s0, lat0 = route.locate(*route.point_at(5.0))
    assert s0 == pytest.approx(5.0, abs=0.05) and abs(lat0) < 1e-6


def test_lidar_sees_the_bin(spec):
    w = World(spec)
    lid = Lidar(w.client, beams=8, range_m=20.0, start_radius=0.5)
    d = lid.scan(13.0, 7.0, 0.15, 0.0)
    assert d.shape == (8,) and d.min() >= 0 and d.max() <= 1
    assert d[0] * 20.0 == pytest.approx(15.0 - 0.3 - 13.0, abs=0.15)  # beam 0 ahead hits the bin's face
    assert lid.hit_ids[0] in w.object_ids
    w.close()


def test_measure_registry():
    assert {"success", "spl", "cost", "route_completion"} <= set(MEASURES)

    @register_measure("test_constant")
    class Constant(Measure):
        def value(self, view, metrics):
            return {"k": 2.0 * metrics.get("x", 1.0)}

    ms = make_measures(["test_constant"])
    assert ms[0].value(None, {"x": 3.0}) == {"k": 6.0}
    with pytest.raises(ConfigError, match="registered measures"):
        make_measures(["nope"])
    MEASURES.pop("test_constant")


def test_measures_declare_what_they_need(spec):
    # SNS reads STL and PSC: listed after them it is built, before them the env refuses at construction.
    assert [m.name for m in make_measures(["stl", "psc", "sns"])] == ["stl", "psc", "sns"]
    with pytest.raises(ConfigError, match="'sns' needs 'stl', 'psc' listed before it"):
        make_measures(["sns", "stl", "psc"])
    # PSC reads the cohabitants: a PointNav env refuses it at construction instead of failing at a step.
    with pytest.raises(ConfigError, match="'psc' needs cohabitants"):
        PointNavEnv({"scene_spec": spec, "measures": ["success", "psc"]})
