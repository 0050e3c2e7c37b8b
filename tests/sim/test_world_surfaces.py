"""The world's sidewalk surfaces carry a fast machine flat: no bounce off the edges between a slab's triangles."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
from shapely.geometry import Polygon, box

from sim.machines import Machine, machine_spec
from sim.meshes import extrusion_mesh, welded
from sim.world import World
from tests.street import CURB, street


def _jagged_street() -> dict:
    """The test street, 120 m, no objects or crosswalks, its left sidewalk's edges (y = 4 and 9 m) a vertex every
    5 m, up to 0.3 m in: its slab's top triangulates into long thin triangles whose edges cross the clear path
    (y = 7 m), as a generated sidewalk's curves and ramp cut-outs make them."""
    spec = street(120.0, crosswalks=())
    spec["objects"] = []
    left = next(sw for sw in spec["sidewalks"] if sw["id"] == "r0-s1")
    x0, y0, x1, y1 = Polygon(left["polygon"]).bounds
    rng = np.random.default_rng(0)
    xs = np.linspace(x0, x1, 25)
    inner = [[float(x), float(y0 + rng.uniform(0.0, 0.3))] for x in xs]
    outer = [[float(x), float(y1 - rng.uniform(0.0, 0.3))] for x in xs[::-1]]
    left["polygon"] = inner + outer
    return spec


def test_welded_keeps_every_triangle_over_shared_vertices() -> None:
    verts, idx = extrusion_mesh(box(0.0, 0.0, 10.0, 3.0), 0.0, 0.15)
    points, shared = welded(verts, idx)
    assert len(points) < len(verts)  # the top's triangles and the walls share their corners
    assert len(shared) == len(idx)
    assert [points[k] for k in shared] == [[float(c) for c in verts[k]] for k in idx]


def test_a_machine_at_top_speed_rolls_flat_over_a_triangulated_sidewalk() -> None:
    world = World(_jagged_street())
    try:
        machine = Machine(world.client, machine_spec("delivery_bot"))
        # On the left sidewalk's clear path, heading +x at full throttle.
        machine.reset(10.0, 7.0, CURB, 0.0, np.random.default_rng(0))
        dt = 0.02  # the world's physics step
        tilt, top_speed = 0.0, 0.0
        while machine.position[0] < 110.0:
            machine.command(0.0, 1.0, dt)
            p.stepSimulation(physicsClientId=world.client)
            machine.sync()
            tilt = max(tilt, abs(machine.roll), abs(machine.pitch))
            top_speed = max(top_speed, machine.speed)
        assert top_speed > 7.0  # the delivery robot's top speed is 30 km/h
        assert math.degrees(tilt) < 2.0
        assert abs(machine.position[2] - CURB) < 0.02
    finally:
        world.close()
