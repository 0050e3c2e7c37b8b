"""Machines on real wheels: a chassis with its centre of mass at its middle and four wheel links on revolute axles,
the rear pair driven by velocity motors whose torque is the machine's engine force at the rim (sim/machines.csv),
so stepping, tipping and traction come from Bullet's contacts and friction (docs/terrain.md).

Wheels are spheres of the wheel radius (one contact point each: cylinder-box contacts gave the solver four-point
patches that let driven wheels spin in place), and the rear wheels drive, as on wheelchairs, mobility scooters and
most delivery robots: with all four driven, the drive's reaction torque unloads the front pair, which then spins
and yaws the machine off its line.

Experimental: `sim.terrain.runway.drive_forward(..., model="wheels")` and `benchmarks/table4.py --model wheels`.
On flat ground every machine drives straight at its top speed; on the runways machines still topple over 6 cm
bumps at walking speed (1.4 m/s), which real ones do not, so the Table 4 default stays the force model of
sim/machines.py (the envs' model) until that is understood (docs/terrain.md).
"""

from __future__ import annotations

import math

import numpy as np

from kernel.quiet import pybullet as p
from sim.machines import MachineSpec

WHEEL_FRICTION = 1.0  # Bullet multiplies the two bodies' coefficients: the surface's then decides


class WheeledMachine:
    """A four-wheeled multibody of `spec`: chassis box, wheel cylinders (radius, width) at wheelbase and track."""

    def __init__(self, client: int, spec: MachineSpec) -> None:
        self.client, self.spec = client, spec
        s, r = spec, spec.wheel_radius
        clear = 0.9 * r
        hz = max(0.5 * (s.height - clear), 0.05)
        chassis = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=[s.length / 2, s.width / 2, hz], physicsClientId=client
        )
        look = p.createVisualShape(
            p.GEOM_BOX, halfExtents=[s.length / 2, s.width / 2, hz], rgbaColor=list(s.color), physicsClientId=client
        )
        wheel = p.createCollisionShape(p.GEOM_SPHERE, radius=r, physicsClientId=client)
        tyre = p.createVisualShape(
            p.GEOM_CYLINDER, radius=r, length=s.wheel_width, rgbaColor=[0.1, 0.1, 0.1, 1], physicsClientId=client
        )
        wx, wy = 0.5 * s.wheelbase, max(0.5 * s.width - 0.5 * s.wheel_width, r * 0.5)
        axle = p.getQuaternionFromEuler([math.pi / 2, 0, 0])  # cylinders along z, turned to lie along y
        # The chassis's frame is its centre, clear + hz above the ground; the wheels hang r above the ground.
        self.base_height = clear + hz
        wheels = [
            [wx, wy, r - self.base_height],
            [wx, -wy, r - self.base_height],
            [-wx, wy, r - self.base_height],
            [-wx, -wy, r - self.base_height],
        ]
        wheel_mass = 0.05 * s.mass  # the four wheels: a fifth of the machine
        self.body = p.createMultiBody(
            0.8 * s.mass,
            chassis,
            look,
            [0, 0, 1.0],
            linkMasses=[wheel_mass] * 4,
            linkCollisionShapeIndices=[wheel] * 4,
            linkVisualShapeIndices=[tyre] * 4,
            linkPositions=wheels,
            linkOrientations=[axle] * 4,
            linkInertialFramePositions=[[0, 0, 0]] * 4,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * 4,
            linkParentIndices=[0] * 4,
            linkJointTypes=[p.JOINT_REVOLUTE] * 4,
            linkJointAxis=[[0, 0, 1]] * 4,
            physicsClientId=client,
        )
        p.changeDynamics(
            self.body, -1, lateralFriction=0.3, linearDamping=0.0, angularDamping=0.0, physicsClientId=client
        )
        for j in range(4):
            p.changeDynamics(self.body, j, lateralFriction=WHEEL_FRICTION, physicsClientId=client)
        self.position, self.yaw, self.pitch, self.roll, self.speed = (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, 0.0
        self.engine_force = float(np.mean(spec.engine_force))

    def reset(self, x: float, y: float, z: float, yaw: float) -> None:
        """Place the machine at rest on the ground at (x, y, z) heading `yaw`."""
        p.resetBasePositionAndOrientation(
            self.body,
            [x, y, z + self.base_height + 0.005],
            p.getQuaternionFromEuler([0, 0, yaw]),
            physicsClientId=self.client,
        )
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)
        for j in range(4):
            p.resetJointState(self.body, j, 0.0, 0.0, physicsClientId=self.client)
        self.sync()

    def drive(self, throttle: float, speed: float | None = None) -> None:
        """Motor command for one substep: the rear wheels aim at `speed` (m/s, at most the top speed; default the
        top speed) x throttle, each with half the engine force at its rim (a velocity motor pushes with at most
        that torque); throttle <= 0 brakes."""
        s = self.spec
        top = s.v_max if speed is None else min(speed, s.v_max)
        # The joint axis points along the wheel's local z, which the axle turns to -y: positive spin rolls backwards.
        target = -(max(throttle, 0.0) * top) / s.wheel_radius
        drive = max(throttle, 0.0) * self.engine_force / 2.0 * s.wheel_radius  # per rear wheel
        brake = 0.0 if throttle > 0 else float(np.mean(s.brake_force)) * s.wheel_radius
        p.setJointMotorControlArray(
            self.body,
            [0, 1, 2, 3],
            p.VELOCITY_CONTROL,
            targetVelocities=[0.0, 0.0, target, target],
            forces=[brake, brake, drive + brake, drive + brake],
            physicsClientId=self.client,
        )

    def sync(self) -> None:
        """Read pose and speed (along the heading) back from Bullet."""
        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        lin, _ = p.getBaseVelocity(self.body, physicsClientId=self.client)
        self.roll, self.pitch, self.yaw = p.getEulerFromQuaternion(orn)
        self.position = (pos[0], pos[1], pos[2] - self.base_height)
        self.speed = lin[0] * math.cos(self.yaw) + lin[1] * math.sin(self.yaw)
