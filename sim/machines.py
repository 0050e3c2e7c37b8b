"""Mobile machines: MetaUrban's parameters (docs/design.md), PyBullet bodies, and their drive models.

Wheeled machines are rigid chassis bodies with four wheel contact spheres. Their longitudinal and yaw
dynamics come from a kinematic-bicycle force model (engine, brake, rolling resistance, drag, grade,
tyre friction limit) integrated in Python at every physics substep; the resulting planar velocity is
handed to Bullet, which integrates the body and resolves contacts (objects, buildings, curbs, ramps).
The velocity Bullet leaves after the substep is read back, so a blocked machine really loses its speed.
Legged machines (`robot_dog`, `humanoid`) follow speed and yaw-rate commands under velocity and
acceleration limits (a fixed locomotion layer), through the same body and contact path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
import pybullet as p

from curbside.config import ConfigError

G = 9.81


@dataclass(frozen=True)
class MachineSpec:
    """Parameters of one mobile machine (SI units; forces in N, angles in degrees as in the paper's table)."""

    name: str
    kind: str = "wheeled"  # "wheeled" (force model) or "legged" (velocity limits)
    v_max_kmh: float = 30.0
    steer_max_deg: float = 40.0
    friction: float = 0.7
    engine_force: tuple[float, float] = (350.0, 550.0)
    brake_force: tuple[float, float] = (35.0, 80.0)  # per wheel, four wheels
    wheelbase: float = 0.45
    wheel_radius: float = 0.10
    wheel_width: float = 0.10
    mass: float = 80.0
    length: float = 0.70
    width: float = 0.50
    height: float = 0.55
    drag_area: float = 0.3  # Cd * A in m^2
    rolling_resistance: float = 0.015
    accel_max: float = 1.5  # legged only: m/s^2
    yaw_rate_max: float = 1.5  # legged only: rad/s
    color: tuple[float, float, float, float] = field(default=(0.95, 0.55, 0.1, 1.0))

    @property
    def v_max(self) -> float:
        """Top speed in m/s."""
        return self.v_max_kmh / 3.6

    @property
    def steer_max(self) -> float:
        """Largest steering angle in radians."""
        return math.radians(self.steer_max_deg)

    @property
    def half_width(self) -> float:
        """Half of the footprint's width, used to inflate obstacles for route planning."""
        return 0.5 * self.width


_WHEELED_DEFAULTS = dict(kind="wheeled", friction=0.7, brake_force=(35.0, 80.0))

MACHINES: dict[str, MachineSpec] = {
    "delivery_bot": MachineSpec("delivery_bot", v_max_kmh=30, steer_max_deg=40, engine_force=(350, 550),
                                wheelbase=0.45, wheel_radius=0.10, wheel_width=0.10, mass=80, length=0.70,
                                width=0.50, height=0.55, **_WHEELED_DEFAULTS),
    "delivery_bot_mod1": MachineSpec("delivery_bot_mod1", v_max_kmh=10, steer_max_deg=40, engine_force=(350, 550),
                                     wheelbase=0.45, wheel_radius=0.10, wheel_width=0.10, mass=80, length=0.70,
                                     width=0.50, height=0.55, **_WHEELED_DEFAULTS),
    "delivery_bot_mod2": MachineSpec("delivery_bot_mod2", v_max_kmh=30, steer_max_deg=10, engine_force=(350, 550),
                                     wheelbase=0.45, wheel_radius=0.10, wheel_width=0.10, mass=80, length=0.70,
                                     width=0.50, height=0.55, **_WHEELED_DEFAULTS),
    "wheelchair": MachineSpec("wheelchair", v_max_kmh=5, steer_max_deg=5, engine_force=(100, 200),
                              wheelbase=0.50, wheel_radius=0.15, wheel_width=0.10, mass=120, length=0.80,
                              width=0.65, height=1.2, color=(0.2, 0.45, 0.9, 1.0), **_WHEELED_DEFAULTS),
    "mobility_scooter": MachineSpec("mobility_scooter", v_max_kmh=45, steer_max_deg=45, engine_force=(450, 650),
                                    wheelbase=0.60, wheel_radius=0.20, wheel_width=0.15, mass=150, length=1.20,
                                    width=0.65, height=1.1, color=(0.8, 0.15, 0.2, 1.0), **_WHEELED_DEFAULTS),
    "robot_dog": MachineSpec("robot_dog", kind="legged", v_max_kmh=5.4, steer_max_deg=0, engine_force=(0, 0),
                             brake_force=(0, 0), wheelbase=0.40, wheel_radius=0.08, wheel_width=0.05, mass=30,
                             length=0.70, width=0.35, height=0.45, accel_max=2.0, yaw_rate_max=2.0,
                             color=(0.3, 0.3, 0.3, 1.0)),
    "humanoid": MachineSpec("humanoid", kind="legged", v_max_kmh=5.0, steer_max_deg=0, engine_force=(0, 0),
                            brake_force=(0, 0), wheelbase=0.30, wheel_radius=0.08, wheel_width=0.05, mass=65,
                            length=0.35, width=0.50, height=1.7, accel_max=1.2, yaw_rate_max=1.5,
                            color=(0.5, 0.3, 0.7, 1.0)),
}

WHEELED = tuple(n for n, m in MACHINES.items() if m.kind == "wheeled")


def machine_spec(machine: str | Mapping[str, Any]) -> MachineSpec:
    """Resolve a machine name, or a dict of MachineSpec fields (optionally `base`: a name), into a MachineSpec."""
    if isinstance(machine, str):
        if machine not in MACHINES:
            raise ConfigError(f"unknown machine {machine!r}; valid machines: {', '.join(MACHINES)} (or a dict of parameters)")
        return MACHINES[machine]
    if not isinstance(machine, Mapping):
        raise ConfigError(f"machine must be a name or a dict of parameters, got {type(machine).__name__}")
    params = dict(machine)
    base = machine_spec(params.pop("base", "delivery_bot"))
    valid = {f.name for f in fields(MachineSpec)}
    unknown = sorted(set(params) - valid)
    if unknown:
        raise ConfigError(f"unknown machine parameter(s) {unknown}; valid: {', '.join(sorted(valid))}")
    for key in ("engine_force", "brake_force"):
        if key in params:
            lo, hi = params[key] if isinstance(params[key], (list, tuple)) else (params[key], params[key])
            params[key] = (float(lo), float(hi))
    params.setdefault("name", "custom")
    spec = replace(base, **params)
    if spec.kind not in ("wheeled", "legged"):
        raise ConfigError(f"machine kind must be 'wheeled' or 'legged', got {spec.kind!r}")
    if spec.v_max <= 0 or spec.wheelbase <= 0 or spec.mass <= 0:
        raise ConfigError("machine v_max_kmh, wheelbase and mass must be positive")
    return spec


class Machine:
    """One machine's body in a PyBullet world plus its drive state (speed, steering, yaw rate)."""

    def __init__(self, client: int, spec: MachineSpec) -> None:
        self.client = client
        self.spec = spec
        self.body = self._build_body()
        self.engine_force = float(np.mean(spec.engine_force))
        self.brake_force = float(np.mean(spec.brake_force))
        self.speed = 0.0
        self.steering = 0.0  # radians (wheeled) / commanded yaw-rate fraction (legged)
        self.yaw_rate = 0.0
        self.yaw = 0.0
        self.pitch = 0.0
        self.position = (0.0, 0.0, 0.0)

    def _build_body(self) -> int:
        s, c = self.spec, self.client
        r = s.wheel_radius
        # Chassis starts just above the wheel centres so the spheres carry the load on the ground.
        clear = r * 0.9
        hz = max(0.5 * (s.height - clear), 0.05)
        half = [0.5 * s.length, 0.5 * s.width, hz]
        chassis_z = clear + hz  # body origin sits at the ground; shapes are offset upwards
        wx, wy = 0.5 * s.wheelbase, max(0.5 * s.width - 0.5 * s.wheel_width, r * 0.5)
        wheels = [[wx, wy, r], [wx, -wy, r], [-wx, wy, r], [-wx, -wy, r]]
        col = p.createCollisionShapeArray(
            shapeTypes=[p.GEOM_BOX] + [p.GEOM_SPHERE] * 4,
            halfExtents=[half] + [[0, 0, 0]] * 4,
            radii=[0.0] + [r] * 4,
            collisionFramePositions=[[0, 0, chassis_z]] + wheels,
            physicsClientId=c,
        )
        vis = p.createVisualShapeArray(
            shapeTypes=[p.GEOM_BOX] + [p.GEOM_CYLINDER] * 4,
            halfExtents=[half] + [[0, 0, 0]] * 4,
            radii=[0.0] + [r] * 4,
            lengths=[0.0] + [s.wheel_width] * 4,
            rgbaColors=[list(s.color)] + [[0.1, 0.1, 0.1, 1]] * 4,
            visualFramePositions=[[0, 0, chassis_z]] + wheels,
            visualFrameOrientations=[[0, 0, 0, 1]] + [p.getQuaternionFromEuler([math.pi / 2, 0, 0])] * 4,
            physicsClientId=c,
        )
        body = p.createMultiBody(s.mass, col, vis, basePosition=[0, 0, 1.0], physicsClientId=c)
        # Zero contact friction: traction and cornering come from the force model, Bullet only resolves
        # normal contacts (the ideal no-slip bicycle; sliding along walls instead of sticking to them).
        p.changeDynamics(body, -1, lateralFriction=0.0, spinningFriction=0.0, rollingFriction=0.0,
                         linearDamping=0.0, angularDamping=0.0, restitution=0.0,
                         ccdSweptSphereRadius=0.8 * r, physicsClientId=c)
        return body

    @property
    def bounding_radius(self) -> float:
        """Radius of the circle around the body origin that contains the footprint."""
        return 0.5 * math.hypot(self.spec.length, self.spec.width)

    def reset(self, x: float, y: float, z: float, yaw: float, rng: np.random.Generator) -> None:
        """Place the machine at rest and draw this episode's engine and brake forces within their ranges."""
        lo, hi = self.spec.engine_force
        self.engine_force = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        lo, hi = self.spec.brake_force
        self.brake_force = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        self.speed = self.steering = self.yaw_rate = self.pitch = 0.0
        self.yaw = yaw
        self.position = (x, y, z)
        p.resetBasePositionAndOrientation(self.body, [x, y, z + 0.005], p.getQuaternionFromEuler([0, 0, yaw]),
                                          physicsClientId=self.client)
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)

    def command(self, steer: float, throttle: float, dt: float) -> None:
        """Update speed, steering and yaw rate for one substep of `dt` seconds and hand the velocity to Bullet."""
        s = self.spec
        v = self.speed
        if s.kind == "wheeled":
            self.steering = steer * s.steer_max
            if throttle >= 0.0:
                # The motor's force falls linearly to zero at v_max: the speed limit comes out of the drive.
                force = throttle * self.engine_force * max(0.0, 1.0 - v / s.v_max)
            else:
                force = throttle * 4.0 * self.brake_force
            resist = s.rolling_resistance * s.mass * G + 0.5 * 1.2 * s.drag_area * v * v
            # Bullet's pitch is positive nose-down, so uphill (negative pitch) adds a retarding grade force.
            force += s.mass * G * math.sin(self.pitch) - resist
            accel = force / s.mass
            limit = s.friction * G  # tyres cannot transmit more than mu * g
            accel = min(max(accel, -limit), limit)
            v_new = v + accel * dt
            if v_new < 0.0 and throttle <= 0.0:
                v_new = 0.0  # brakes and resistances stop the machine; they do not drive it backwards
            v_new = min(max(v_new, -0.2 * s.v_max), s.v_max)
            yaw_rate = v_new * math.tan(self.steering) / s.wheelbase
            if v_new != 0.0:
                # Cornering is friction-limited too: lateral acceleration v * yaw_rate <= mu * g.
                max_rate = limit / abs(v_new)
                yaw_rate = min(max(yaw_rate, -max_rate), max_rate)
        else:
            target = max(throttle, 0.0) * s.v_max
            dv = min(max(target - v, -2.0 * s.accel_max * dt), s.accel_max * dt)
            v_new = v + dv
            self.steering = steer
            yaw_rate = steer * s.yaw_rate_max
        self.speed = v_new
        self.yaw_rate = yaw_rate
        c, sn = math.cos(self.yaw), math.sin(self.yaw)
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.client)
        p.resetBaseVelocity(self.body, [v_new * c, v_new * sn, lin[2]], [ang[0], ang[1], yaw_rate],
                            physicsClientId=self.client)

    def sync(self) -> None:
        """Read pose and velocity back from Bullet after a substep (contacts may have changed them)."""
        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        lin, _ = p.getBaseVelocity(self.body, physicsClientId=self.client)
        roll, pitch, yaw = p.getEulerFromQuaternion(orn)
        self.position = pos
        self.yaw = yaw
        self.pitch = pitch
        # Speed along the heading: a wall or a curb the machine runs into takes it away.
        self.speed = lin[0] * math.cos(yaw) + lin[1] * math.sin(yaw)
