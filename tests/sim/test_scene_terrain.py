"""Terrain inside scenes (docs/terrain.md): placement rules and determinism, physics and friction under a machine,
the top-down drawing, Bullet's and the grid's LiDAR over a stair, the route planner, and bad configs and records."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pybullet as p
import pytest
from shapely.geometry import LineString, Polygon

from kernel.config import ConfigError
from sim.machines import Machine, machine_spec
from sim.palette import EDGE, rgb255, terrain_colour
from sim.raycast.grids import CURB as CURB_KIND
from sim.raycast.grids import SIDEWALK_LEVEL, build_grids
from sim.route import RoutePlanner
from sim.scene import dumps, generate_scene
from sim.scene.scene import Scene, SceneError
from sim.scene.terrain import patch_record
from sim.sensors import GridLidar, Lidar
from sim.terrain.patches import LIFT, riser_lines
from sim.topdown import Canvas, draw_scene
from sim.world import World
from tests.street import CURB, street

Y_CLEAR = 7.0  # the left sidewalk's clear path in tests.street.street (clear zone 5.6-8.4 m, frontage 8.4-9.0 m)


def _scene(cfg: dict[str, Any], seed: int) -> dict[str, Any]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no catalog: fallback boxes
        return generate_scene(cfg, seed)


def _street(*patches: dict[str, Any]) -> dict[str, Any]:
    """The test street without furniture, with `patches` as its terrain."""
    spec = street(furniture="scattered", n_objects=0)
    spec["terrain"] = list(patches)
    return spec


def _rough(x: float, length: float = 3.0) -> dict[str, Any]:
    """Uneven pavers (3 cm bumps) across the left clear path from x to x + length."""
    return patch_record(
        "t0",
        "rough",
        "pavers",
        "r0-s1",
        "clear",
        x + length / 2,
        Y_CLEAR,
        CURB,
        math.pi / 2,
        (2.4, length, 0.03),
        seed=7,
    )


def _slick(x: float) -> dict[str, Any]:
    return patch_record("t1", "slick", "wet", "r0-s1", "clear", x + 1.5, Y_CLEAR, CURB, math.pi / 2, (2.4, 3.0, 0.0))


def _stair(x: float, n: int = 1) -> dict[str, Any]:
    """A stair of `n` 0.15 m steps in the left frontage zone, rising to the building line at y = 9 m."""
    depth = n * 0.3 + 0.2
    return patch_record(
        "t2",
        "steps",
        "concrete",
        "r0-s1",
        "frontage",
        x,
        9.0 - 0.01 - depth / 2,
        CURB,
        math.pi / 2,
        (depth, 2.0, n * 0.15),
        steps=n,
        tread=0.3,
    )


def test_same_seed_same_patches_density_zero_none_and_objects_untouched() -> None:
    cfg = {"blocks": 2}
    a, b = _scene(cfg, 5), _scene(cfg, 5)
    assert dumps(a) == dumps(b) and a["terrain"]
    none = _scene({**cfg, "terrain": {"density": 0.0}}, 5)
    assert none["terrain"] == [] and set(none["stats"]["terrain"].values()) == {0}
    assert none["objects"] == a["objects"]  # terrain draws from its own streams, after every object
    assert sum(a["stats"]["terrain"].values()) == len(a["terrain"])
    only = _scene({**cfg, "terrain": {"kinds": ["steps"]}}, 5)
    assert {t["kind"] for t in only["terrain"]} == {"steps"}
    assert [t["footprint"] for t in only["terrain"]] == [t["footprint"] for t in a["terrain"] if t["kind"] == "steps"]


def test_higher_density_places_more_patches() -> None:
    counts = [
        sum(len(_scene({"blocks": 2, "terrain": {"density": rho}}, s)["terrain"]) for s in range(3))
        for rho in (0.3, 1.0, 3.0)
    ]
    assert counts[0] < counts[1] < counts[2], counts


def test_patches_keep_the_placement_rules() -> None:
    kinds = set()
    for seed in range(4):
        spec = _scene({"blocks": 3, "terrain": {"density": 3.0}}, seed)
        walks = {sw["id"]: sw for sw in spec["sidewalks"]}
        objects = [Polygon(o["footprint"]) for o in spec["objects"]]
        ramps = [Polygon(r["polygon"]) for c in spec["crosswalks"] for r in c["ramps"]]
        corridors = [
            LineString(sw["clear_path"]).buffer(0.5 * spec["config"]["min_clear_width"], cap_style="flat")
            for sw in spec["sidewalks"]
        ]
        placed: list[Polygon] = []
        for t in spec["terrain"]:
            kinds.add(t["kind"])
            poly, sw = Polygon(t["footprint"]), walks[t["sidewalk_id"]]
            assert Polygon(sw["polygon"]).buffer(1e-3).contains(poly), t["id"]
            assert not any(poly.intersects(o) for o in objects), t["id"]
            assert not any(poly.intersects(r) for r in ramps), t["id"]
            assert not any(poly.intersects(q) for q in placed), t["id"]
            placed.append(poly)
            if t["kind"] == "steps":
                zones = {z["kind"]: Polygon(z["polygon"]) for z in sw["zones"]}
                assert t["zone"] == "frontage" and zones["frontage"].buffer(1e-3).contains(poly), t["id"]
                assert poly.distance(zones["building"]) < 0.05, "a stair leads up to the building line"
                assert not any(poly.intersects(c) for c in corridors), "steps never enter the clear-path corridor"
                assert 1 <= t["steps"] <= 3 and 0.13 * t["steps"] - 1e-6 <= t["size"][2] <= 0.17 * t["steps"] + 1e-6
            else:
                assert t["size"][2] <= 0.04 + 1e-6
    assert kinds == {"roots", "rough", "steps", "slick"}


def test_bad_terrain_config_and_records_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"terrain\.density must be a finite number in \[0, 10\]"):
        generate_scene({"terrain": {"density": -1.0}}, 0)
    with pytest.raises(ConfigError, match="terrain.kinds must be a list of roots, rough, steps, slick"):
        generate_scene({"terrain": {"kinds": ["cliff"]}}, 0)
    with pytest.raises(ConfigError, match="valid keys: density, kinds"):
        generate_scene({"terrain": {"amount": 1.0}}, 0)
    bad = _street({**_stair(20.0), "steps": 0})
    with pytest.raises(SceneError, match=r"terrain\[0\] a stair needs steps"):
        Scene.parse(bad)
    with pytest.raises(SceneError, match=r"terrain\[0\] surface must be one of asphalt"):
        Scene.parse(_street({**_slick(10.0), "surface": "ice"}))
    for seed in ("abc", -5, 1.5):  # World() raised ValueError from numpy for these
        with pytest.raises(SceneError, match=r"terrain\[0\] seed \(of the bumps\) must be an integer >= 0"):
            Scene.parse(_street({**_rough(8.0), "seed": seed}))
    with pytest.raises(SceneError, match=r"terrain\[0\] size must be at most 50 m deep and wide, got 2.4 x 3000"):
        Scene.parse(_street(_rough(8.0, length=3000.0)))  # a 0.1 m grid of 30 million samples
    with pytest.raises(SceneError, match=r"terrain\[0\] a stair needs steps \(an integer 1 to 50\)"):
        Scene.parse(_street({**_stair(20.0), "steps": 1000, "tread": 0.0001}))


def _drive(spec: dict[str, Any], x1: float = 20.0) -> dict[str, np.ndarray]:
    """A wheelchair driven at full throttle along the clear path from x = 4 m to `x1`: x, z, pitch, friction."""
    world = World(Scene.parse(spec))
    try:
        m = Machine(world.client, machine_spec("wheelchair"))
        m.ground = world.friction_at
        m.reset(4.0, Y_CLEAR, world.surface_height(4.0, Y_CLEAR), 0.0, np.random.default_rng(0))
        rows = []
        for _ in range(1500):
            m.command(0.0, 1.0, 0.02)
            p.stepSimulation(physicsClientId=world.client)
            m.sync()
            rows.append((m.position[0], m.position[2], m.pitch, m.surface_friction))
            if m.position[0] > x1:
                break
        return dict(zip(("x", "z", "pitch", "mu"), np.array(rows).T))
    finally:
        world.close()


def test_a_machine_rides_the_bumps_and_reads_the_patch_friction() -> None:
    flat = _drive(_street())
    rough = _drive(_street(_rough(8.0), _slick(14.0)))
    assert flat["x"][-1] > 20.0 and rough["x"][-1] > 20.0, "rough and slick ground is drivable"
    on = (rough["x"] > 8.5) & (rough["x"] < 10.5)
    settled = flat["x"] > 6.0
    assert np.ptp(flat["z"][settled]) < 0.003 and np.abs(flat["pitch"][settled]).max() < math.radians(0.3)
    assert np.ptp(rough["z"][on]) > 0.01, "the body rises and falls over the bumps"
    assert np.abs(rough["pitch"][on]).max() > math.radians(1.0), "and pitches"
    assert set(rough["mu"][(rough["x"] > 9.0) & (rough["x"] < 10.5)]) == {0.65}  # pavers
    assert set(rough["mu"][(rough["x"] > 15.0) & (rough["x"] < 16.5)]) == {0.45}  # wet
    assert set(rough["mu"][rough["x"] < 7.0]) == {math.inf} == set(flat["mu"])  # off patches the tyres decide


def test_reset_reads_the_friction_under_the_new_position() -> None:
    world = World(Scene.parse(_street(_slick(8.0))))
    try:
        m = Machine(world.client, machine_spec("wheelchair"))
        m.ground = world.friction_at
        for x, mu in ((9.5, 0.45), (4.0, math.inf), (9.5, 0.45)):  # on the wet patch, off it, on it again
            m.reset(x, Y_CLEAR, world.surface_height(x, Y_CLEAR), 0.0, np.random.default_rng(0))
            assert m.surface_friction == mu  # not the last episode's, before the first sync
    finally:
        world.close()


def test_lidar_sees_a_step_and_the_grid_agrees_with_bullet() -> None:
    x, yaw = 20.0, math.pi / 2
    ranges = {}
    for name, spec in (("none", _street()), ("stair", _street(_stair(x)))):
        scene = Scene.parse(spec)
        world = World(scene)
        z = world.surface_height(x, Y_CLEAR)
        bullet = Lidar(world.client, beams=8, range_m=5.0, height=0.08, start_radius=0.3)
        grids = build_grids(scene, resolution=0.05, lidar={"height": 0.4, "low_height": 0.08}, body_height=None)
        grid = GridLidar(grids, "low", beams=8, range_m=5.0, height=0.08, start_radius=0.3)
        ranges[name] = (bullet.scan(x, Y_CLEAR, z, yaw)[0] * 5.0, grid.scan(x, Y_CLEAR, z, yaw)[0] * 5.0)
        world.close()
    (b0, g0), (b1, g1) = ranges["none"], ranges["stair"]
    assert b0 == pytest.approx(2.0, abs=0.02)  # the building wall at y = 9 m
    assert b1 == pytest.approx(9.0 - 0.01 - 0.5 + 0.15 - Y_CLEAR, abs=0.02)  # the riser, in front of the wall
    assert abs(g0 - b0) < 0.1 and abs(g1 - b1) < 0.1


def test_stairs_are_walls_to_bodies_and_routes_rough_ground_is_not() -> None:
    scene = Scene.parse(_street(_rough(8.0), _stair(20.0)))
    grids = build_grids(scene, resolution=0.1, lidar={"height": 0.4, "low_height": 0.08}, body_height=1.0)
    body = grids.tables[SIDEWALK_LEVEL][2]

    def cell(x: float, y: float) -> tuple[int, int]:
        c, r = (int((v - o) / grids.resolution) for v, o in zip((x, y), grids.origin))
        return r, c

    assert body[cell(20.0, 8.75)] == 0 and grids.kinds[cell(20.0, 8.75)] == CURB_KIND
    assert body[cell(9.5, Y_CLEAR)] > 0
    for spec, free in ((_street(), True), (_street(_rough(19.0)), True), (scene, False)):
        planner = RoutePlanner(spec, half_width=0.1, margin=0.0)
        ((r, c),) = planner.grid.world_to_cell(np.array([[20.0, 8.625]]))  # a cell centre on the stair
        assert bool(planner.free[r, c]) is free
    world = World(scene)
    assert world.surface_height(20.0, 8.9) == pytest.approx(CURB + LIFT + 0.15, abs=1e-3)
    assert set(world.kinds[b] for b in world.patch_index) == {"sidewalk"}
    world.close()


def test_top_down_draws_patches_and_risers() -> None:
    spec = _street(_slick(10.0), _stair(20.0))
    images = []
    for s in (_street(), spec):
        c = Canvas((0.0, 0.0, 30.0, 10.0), 20.0)
        draw_scene(c, s)
        images.append(c.image())

    def px(img: np.ndarray, x: float, y: float) -> tuple[int, ...]:
        return tuple(int(v) for v in img[int((10.0 - y) * 20.0), int(x * 20.0)])

    assert px(images[1], 11.5, Y_CLEAR) == rgb255(terrain_colour("slick", "wet"))
    assert px(images[0], 11.5, Y_CLEAR) != px(images[1], 11.5, Y_CLEAR)
    ((a, b),) = riser_lines(_stair(20.0))
    mid = (a + b) / 2
    assert px(images[1], 20.3, float(mid[1])) == rgb255(EDGE)


def test_generated_patches_are_built_into_the_world() -> None:
    scene = Scene.parse(_scene({"blocks": 2}, 1))
    assert scene.terrain
    world = World(scene)
    assert len(world.patch_index) == len(scene.terrain)
    stair = next(t for t in scene.terrain if t["kind"] == "steps")
    x, y, base = stair["position"]
    far = 0.45 * stair["size"][0]  # on the landing, near the building line
    px, py = x + far * math.cos(stair["yaw"]), y + far * math.sin(stair["yaw"])
    assert world.surface_height(px, py) == pytest.approx(base + LIFT + stair["size"][2], abs=1e-3)
    assert world.friction_at(px, py) == 0.75  # concrete
    road = scene.roads[0]["centerlines"][0][0]
    assert world.friction_at(*road) == math.inf
    world.close()
