"""Runways of terrain in PyBullet and the paper's Table 4 trial: one machine drives straight ahead until it stops
progressing, falls far below its speed, topples, or reaches the end (MetaUrban Sec. 4, Table 4).

Three runways of increasing difficulty, each a Wave Function Collapse terrain (sim.terrain.wfc) of its shapes
after a flat lead-in: `slopes` (slopes and ramps), `stairs` (steps and two-step stairs), `roughs` (rough ground).
Each tile is its own static triangle-mesh body with its surface's friction and colour.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

import numpy as np

from kernel.config import ConfigError
from kernel.quiet import pybullet as p
from sim.machines import G, Machine, machine_spec
from sim.meshes import mesh_shape
from sim.palette import TERRAIN
from sim.terrain.heights import TileGeometry, grid_mesh, tile_surface
from sim.terrain.wfc import SURFACES, Tile, collapse, tile_set

# Each runway: its tile shapes and weights, and its level height (m): slopes and ramps rise a 0.15 m level (7.5 %
# and 10 % grades over 2 m tiles); stairs are small steps of 6 cm (3 cm curb lips to 8 cm garden steps decide
# whether a wheel climbs them); rough ground has 6 cm bumps (tree roots, broken pavement).
RUNWAYS: dict[str, dict[str, Any]] = {
    "slopes": {
        "shapes": ("flat", "slope_up", "slope_down", "ramp_up", "ramp_down"),
        "weights": {"flat": 0.5},
        "geometry": TileGeometry(level_height=0.15),
    },
    "stairs": {
        "shapes": ("flat", "step_up", "step_down", "stairs_up", "stairs_down"),
        "weights": {"flat": 0.5},
        "geometry": TileGeometry(level_height=0.06),
    },
    "roughs": {"shapes": ("flat", "rough"), "weights": {"flat": 0.25}, "geometry": TileGeometry(bump_height=0.06)},
}
TOPPLE_DEG = 60.0  # roll or pitch past this is a fall
# MetaUrban's Table 4 trials move every machine at about the same speed: x-displacement over time to fall on its
# slopes runway is 31.90 / 6.3 = 5.06, 34.58 / 6.9 = 5.01 and 38.07 / 7.7 = 4.94 m/s for the delivery bot,
# wheelchair and scooter (a wheelchair's own top speed is 1.39 m/s). `drive_forward(speed=PAPER_SPEED)` does the same.
PAPER_SPEED = 5.0


@dataclass
class Runway:
    """A built runway: its tiles, geometry and bodies in one Bullet client."""

    name: str
    tiles: list[list[Tile]]
    geometry: TileGeometry
    client: int
    bodies: list[int] = field(default_factory=list)

    @property
    def length(self) -> float:
        """Length along x (m)."""
        return len(self.tiles[0]) * self.geometry.size

    @property
    def width(self) -> float:
        """Width along y (m)."""
        return len(self.tiles) * self.geometry.size


def build_runway(
    client: int,
    name: str,
    seed: int = 0,
    cols: int = 50,
    rows: int = 2,
    geometry: TileGeometry | None = None,
    surfaces: tuple[str, ...] = ("asphalt", "concrete", "pavers"),
    levels: int = 4,
) -> Runway:
    """Collapse runway `name`'s terrain from `seed` and add its tiles to `client` (x from 0, y from 0)."""
    if name not in RUNWAYS:
        raise ConfigError(f"unknown runway {name!r}; valid: {', '.join(RUNWAYS)}")
    spec = RUNWAYS[name]
    geo = geometry or spec["geometry"]
    rng = np.random.default_rng(seed)
    grid = collapse(
        rows, cols, rng, tile_set(levels, spec["shapes"], surfaces), spec["weights"], west_level=0, start_flat=True
    )
    runway = Runway(name, grid, geo, client)
    ground = p.createCollisionShape(p.GEOM_BOX, halfExtents=[runway.length, runway.width, 0.5], physicsClientId=client)
    runway.bodies.append(
        p.createMultiBody(0, ground, -1, [runway.length / 2, runway.width / 2, -0.5], physicsClientId=client)
    )
    for r, row in enumerate(grid):
        for c, tile in enumerate(row):
            u, v, z = tile_surface(tile, geo, rng)
            verts, tris = grid_mesh(c * geo.size + u * geo.size, r * geo.size + v * geo.size, z)
            col = mesh_shape(p.createCollisionShape, verts, tris, physicsClientId=client)
            vis = mesh_shape(
                p.createVisualShape, verts, tris, rgbaColor=[*TERRAIN[tile.surface], 1.0], physicsClientId=client
            )
            body = p.createMultiBody(0, col, vis, [0, 0, 0], physicsClientId=client)
            p.changeDynamics(body, -1, lateralFriction=SURFACES[tile.surface], physicsClientId=client)
            runway.bodies.append(body)
    return runway


def surface_at(runway: Runway, x: float, y: float) -> float:
    """Height (m) of the runway's surface under (x, y), from a vertical ray."""
    hit = p.rayTest([x, y, 20.0], [x, y, -1.0], physicsClientId=runway.client)[0]
    return float(hit[3][2]) if hit[0] >= 0 else 0.0


def friction_at(runway: Runway, x: float, y: float) -> float:
    """Friction coefficient of the tile under (x, y) (asphalt's off the runway)."""
    c, r = int(x // runway.geometry.size), int(y // runway.geometry.size)
    if 0 <= r < len(runway.tiles) and 0 <= c < len(runway.tiles[0]):
        return SURFACES[runway.tiles[r][c].surface]
    return SURFACES["asphalt"]


def drive_forward(
    machine: str | Mapping[str, Any],
    runway_name: str,
    seed: int = 0,
    *,
    model: str = "force",
    speed: float | None = None,
    dt: float = 0.02,
    max_time: float = 200.0,
    stuck_time: float = 2.0,
    slow_fraction: float = 0.25,
) -> dict[str, Any]:
    """Table 4's trial: straight ahead, no steering, on a fresh runway; returns the x-displacement (m), the time
    (s) until the trial ended, and why: `toppled`, `stuck` (less than 0.1 m in `stuck_time` s), `slow` (below
    `slow_fraction` of the top speed, or of `speed`, for `stuck_time` s once it had reached it), `end` or `time`.
    `model`: "wheels" (sim.terrain.wheels, driven wheel links) or "force" (the envs' machine model).
    `speed`: None drives the machine at full throttle with its own engine and top speed; a number (m/s) is held by
    every machine through an ideal drive (top speed raised to at least twice `speed`, engine force twice the
    traction limit), so that all meet the terrain at the same speed (the paper's trials did: see PAPER_SPEED)."""
    from sim.terrain.wheels import WheeledMachine

    if model not in ("wheels", "force"):
        raise ConfigError(f"unknown machine model {model!r}; valid: wheels, force")
    if speed is not None and not (isinstance(speed, (int, float)) and 0.0 < speed < 100.0):
        raise ConfigError(f"speed must be a number of m/s above 0 (or None for full throttle), got {speed!r}")
    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=client)
        p.setTimeStep(dt, physicsClientId=client)
        runway = build_runway(client, runway_name, seed)
        spec = machine_spec(machine)
        if speed is not None:
            # An ideal drive holds the common speed wherever traction allows: top speed well above it and an
            # engine force of twice the traction limit, so the machines differ only in their bodies and wheels.
            spec = replace(
                spec,
                v_max_kmh=max(spec.v_max, 2.0 * speed) * 3.6,
                engine_force=(2.0 * spec.mass * G * spec.friction,) * 2,
            )
        x0, y0 = 1.0, runway.width / 2
        if model == "wheels":
            m: Any = WheeledMachine(client, spec)
            m.reset(x0, y0, surface_at(runway, x0, y0), 0.0)
        else:
            m = Machine(client, spec)
            m.ground = partial(friction_at, runway)  # the tile under the machine limits its traction
            m.count_grade = False  # the slopes' pull comes from Bullet's gravity alone (sim/machines.py)
            m.reset(x0, y0, surface_at(runway, x0, y0), 0.0, np.random.default_rng(seed))
        m.engine_force = float(np.max(spec.engine_force))  # the same strongest drive in every trial
        t, mark, reached, slow_since, reason = 0.0, (0.0, x0), False, None, "time"
        while t < max_time:
            if model == "wheels":
                m.drive(1.0, speed)  # the tiles' friction acts on the wheels' contacts
            else:
                # A common `speed` is held by throttling the drive towards it (full throttle below it).
                m.command(0.0, 1.0 if speed is None else min(max(4.0 * (speed - m.speed) / speed, 0.0), 1.0), dt)
            p.stepSimulation(physicsClientId=client)
            m.sync()
            t += dt
            x = m.position[0]
            if max(abs(m.roll), abs(m.pitch)) > math.radians(TOPPLE_DEG):
                reason = "toppled"
                break
            if x >= runway.length - 0.5 * spec.length:
                reason = "end"
                break
            if x > mark[1] + 0.1:
                mark = (t, x)
            elif t - mark[0] > stuck_time:
                reason = "stuck"
                break
            top = spec.v_max if speed is None else min(speed, spec.v_max)
            reached = reached or m.speed >= 0.9 * top
            slow = reached and m.speed < slow_fraction * top
            slow_since = (slow_since if slow_since is not None else t) if slow else None
            if slow_since is not None and t - slow_since > stuck_time:
                reason = "slow"
                break
        return {
            "machine": spec.name,
            "runway": runway_name,
            "seed": seed,
            "model": model,
            "x_displacement": m.position[0] - x0,
            "time": t,
            "reason": reason,
        }
    finally:
        p.disconnect(physicsClientId=client)
