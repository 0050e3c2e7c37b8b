"""Terrain: Wave Function Collapse properties, seamless tile heights, runways, and what wheels and slopes do."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kernel.config import ConfigError
from sim.envs import register_envs
from sim.machines import Machine, machine_spec
from sim.terrain.heights import TileGeometry, tile_surface
from sim.terrain.runway import PAPER_SPEED, RUNWAYS, build_runway, drive_forward
from sim.terrain.wfc import SURFACES, allowed_east, allowed_north, collapse, tile_set

TILES = tile_set(4)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(1, 5), cols=st.integers(1, 12))
def test_every_neighbouring_pair_is_allowed_and_the_seed_decides(seed: int, rows: int, cols: int) -> None:
    grid = collapse(rows, cols, np.random.default_rng(seed), TILES, start_flat=True)
    assert len(grid) == rows and all(len(r) == cols for r in grid)
    for r in range(rows):
        assert grid[r][0].west == 0 and grid[r][0].shape == "flat"
        for c in range(cols):
            t = grid[r][c]
            assert 0 <= t.west < 4 and 0 <= t.east < 4
            if c + 1 < cols:
                assert allowed_east(t, grid[r][c + 1])
            if r + 1 < rows:
                assert allowed_north(t, grid[r + 1][c])
    assert collapse(rows, cols, np.random.default_rng(seed), TILES, start_flat=True) == grid


def test_the_rules_refuse_what_would_leave_a_seam() -> None:
    from sim.terrain.wfc import Tile

    step = Tile("step_up", 0, "asphalt")
    assert allowed_east(step, Tile("flat", 1, "grass")) and not allowed_east(step, Tile("flat", 0, "grass"))
    # Side by side along y, a step and a slope between the same levels do not match along their shared edge.
    assert not allowed_north(step, Tile("slope_up", 0, "asphalt"))
    assert allowed_north(Tile("rough", 2, "gravel"), Tile("flat", 2, "wet"))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tile_heights_meet_at_every_border(seed: int) -> None:
    geo = TileGeometry()
    rng = np.random.default_rng(seed)
    grid = collapse(3, 10, rng, TILES, weights={"rough": 3.0})
    surf = [[tile_surface(t, geo, np.random.default_rng(k)) for k, t in enumerate(row)] for row in grid]
    for r in range(3):
        for c in range(10):
            u, v, z = surf[r][c]
            if c + 1 < 10:
                u2, v2, z2 = surf[r][c + 1]
                np.testing.assert_allclose(z[:, -1], z2[:, 0], atol=1e-9)  # east edge = the next tile's west edge
            if r + 1 < 3:
                u2, v2, z2 = surf[r + 1][c]
                np.testing.assert_allclose(np.interp(u2, u, z[-1]), z2[0], atol=1e-9)  # north edge = south edge


def test_impossible_terrains_say_so() -> None:
    with pytest.raises(ConfigError, match="unknown terrain shapes"):
        tile_set(3, shapes=("cliff",))
    with pytest.raises(ConfigError, match="weights"):
        collapse(2, 2, np.random.default_rng(0), tile_set(1, shapes=("slope_up",)))


def test_runways_are_deterministic_and_carry_their_surfaces_friction() -> None:
    for name in RUNWAYS:
        grids = []
        for _ in range(2):
            c = p.connect(p.DIRECT)
            rw = build_runway(c, name, seed=3, cols=8)
            grids.append(rw.tiles)
            tile, body = rw.tiles[0][1], rw.bodies[1 + 1]  # bodies: the ground, then the tiles row by row
            assert p.getDynamicsInfo(body, -1, physicsClientId=c)[1] == pytest.approx(SURFACES[tile.surface])
            p.disconnect(c)
        assert grids[0] == grids[1]


def _max_step(machine: dict) -> float:
    """The highest step (of 0.01 .. 0.2 m) the machine drives up from a standing start at full throttle."""
    best = 0.0
    for h in np.arange(0.01, 0.21, 0.01):
        c = p.connect(p.DIRECT)
        p.setGravity(0, 0, -9.81, physicsClientId=c)
        p.setTimeStep(0.02, physicsClientId=c)
        ground = p.createCollisionShape(p.GEOM_BOX, halfExtents=[60, 5, 0.5], physicsClientId=c)
        p.createMultiBody(0, ground, -1, [0, 0, -0.5], physicsClientId=c)
        step = p.createCollisionShape(p.GEOM_BOX, halfExtents=[50, 5, h / 2], physicsClientId=c)
        p.createMultiBody(0, step, -1, [53, 0, h / 2], physicsClientId=c)
        m = Machine(c, machine_spec(machine))
        m.reset(0, 0, 0, 0, np.random.default_rng(0))
        for _ in range(250):
            m.command(0.0, 1.0, 0.02)
            p.stepSimulation(physicsClientId=c)
            m.sync()
        up = m.position[0] > 3.5 and m.position[2] > h - 0.02
        p.disconnect(c)
        if not up:
            break
        best = float(h)
    return best


def test_a_larger_wheel_climbs_a_higher_step() -> None:
    base = {"base": "delivery_bot", "v_max_kmh": 6.0}
    small, large = _max_step({**base, "wheel_radius": 0.08}), _max_step({**base, "wheel_radius": 0.16})
    assert 0.0 < small < large, (small, large)


@pytest.mark.parametrize("grade", [0.05, 0.1])
def test_a_slope_slows_a_machine_by_its_grade_once(grade: float) -> None:
    # Steady speed uphill where the drive (falling to zero at v_max) meets gravity's pull along the slope and rolling
    # resistance: counting the grade twice (count_grade, on in the envs) stalls the wheelchair on a 10 % ramp.
    spec = machine_spec("wheelchair")
    c = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81, physicsClientId=c)
    p.setTimeStep(0.02, physicsClientId=c)
    th = math.atan(grade)
    slab = p.createCollisionShape(p.GEOM_BOX, halfExtents=[100, 5, 0.5], physicsClientId=c)
    p.createMultiBody(0, slab, -1, [0, 0, -0.5], p.getQuaternionFromEuler([0, -th, 0]), physicsClientId=c)
    m = Machine(c, spec)
    m.count_grade = False  # as on the runways: the grade comes from Bullet's gravity once
    m.reset(-20 * math.cos(th), 0, -20 * math.sin(th) + 0.01, 0, np.random.default_rng(0))
    m.engine_force = float(max(spec.engine_force))
    speeds = []
    for _ in range(1500):
        m.command(0.0, 1.0, 0.02)
        p.stepSimulation(physicsClientId=c)
        m.sync()
        speeds.append(m.speed)
    p.disconnect(c)
    g = 9.81
    drag = 0.5 * 1.2 * spec.drag_area * np.mean(speeds[-200:]) ** 2
    expected = spec.v_max * (
        1 - (spec.mass * g * math.sin(th) + spec.rolling_resistance * spec.mass * g + drag) / m.engine_force
    )
    assert np.mean(speeds[-200:]) == pytest.approx(expected, rel=0.03)


def test_a_toppled_machine_ends_the_episode_with_its_reason() -> None:
    register_envs()
    env = gym.make("curbside/PointNav-v0")
    env.reset(seed=0)
    u = env.unwrapped
    x, y, z = u.machine.position
    # Knocked onto its side (as a fall from a step would leave it).
    p.resetBasePositionAndOrientation(
        u.machine.body, [x, y, z + 0.3], p.getQuaternionFromEuler([math.radians(85), 0, 0]), physicsClientId=u.client
    )
    _, reward, terminated, truncated, info = env.step(np.array([0.0, 0.0], dtype=np.float32))
    assert terminated and info["toppled"] and info["end_reason"] == "toppled" and not info["is_success"]
    env.close()


def test_the_table4_trial_reports_distance_time_and_why_it_ended() -> None:
    out = drive_forward("mobility_scooter", "roughs", seed=0, max_time=3.0)
    assert out["reason"] in ("toppled", "stuck", "slow", "end", "time") and 0.0 < out["time"] <= 3.0 + 1e-9
    assert out["x_displacement"] > 1.0  # it drove forward


@pytest.mark.parametrize("name", ["delivery_bot", "wheelchair", "mobility_scooter"])
def test_wheeled_machines_drive_straight_at_their_top_speed_on_flat_ground(name: str) -> None:
    from sim.terrain.wheels import WheeledMachine

    c = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81, physicsClientId=c)
    p.setTimeStep(0.02, physicsClientId=c)
    ground = p.createCollisionShape(p.GEOM_BOX, halfExtents=[200, 5, 0.5], physicsClientId=c)
    body = p.createMultiBody(0, ground, -1, [150, 0, -0.5], physicsClientId=c)
    p.changeDynamics(body, -1, lateralFriction=SURFACES["asphalt"], physicsClientId=c)
    m = WheeledMachine(c, machine_spec(name))
    m.reset(0.0, 0.0, 0.0, 0.0)
    for _ in range(400):
        m.drive(1.0)
        p.stepSimulation(physicsClientId=c)
        m.sync()
    assert m.speed == pytest.approx(m.spec.v_max, rel=0.02)
    assert abs(m.position[1]) < 0.1 and abs(m.yaw) < math.radians(1) and abs(m.pitch) < math.radians(1)
    p.disconnect(c)


def test_a_commanded_speed_must_be_positive() -> None:
    with pytest.raises(ConfigError, match="speed must be a number of m/s above 0"):
        drive_forward("wheelchair", "slopes", speed=0.0)


def test_a_common_speed_is_held_by_every_machine_even_above_its_own_top_speed() -> None:
    # Table 4's protocol (PAPER_SPEED): the wheelchair (1.39 m/s top speed) meets the terrain at the same speed as
    # the others; at full throttle it cannot.
    held = drive_forward("wheelchair", "roughs", seed=0, speed=PAPER_SPEED, max_time=3.0)
    own = drive_forward("wheelchair", "roughs", seed=0, max_time=3.0)
    assert own["x_displacement"] < 1.39 * 3.0
    assert held["x_displacement"] > 0.6 * PAPER_SPEED * 3.0
