"""Mobile machines: MetaUrban's parameters (`machines.csv`, docs/design.md), PyBullet bodies, and their drive models.

Wheeled machines are rigid chassis bodies with four wheel contact spheres. Their longitudinal and yaw
dynamics come from a kinematic bicycle driven by one of two drives (`DRIVES`, the `drive` column of
`machines.csv`), integrated in Python at every physics substep: `force`, curbside's force model (engine, brake,
rolling resistance, drag, grade, tyre friction limit), and `vehicle`, MetaUrban's Bullet raycast vehicle
(`vehicle_drive`); the resulting planar velocity is handed to Bullet, which integrates the body and resolves
contacts (objects, buildings, curbs, ramps).
The velocity Bullet leaves after the substep is read back, so a blocked machine really loses its speed.
Legged machines (`robot_dog`, `humanoid`) follow speed and yaw-rate commands under velocity and
acceleration limits (a fixed locomotion layer), through the same body and contact path.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from importlib import resources
from typing import Any

import numpy as np

from kernel.config import ConfigError
from kernel.quiet import pybullet as p

G = 9.81
DRIVES = ("force", "vehicle")
# MetaUrban's ego holds every wheel with a brake of 2.0 whenever it applies no engine force (coasting, at rest, over
# its top speed): `EgoDeliveryRobot._apply_throttle_brake`, metaurban/component/delivery_robot/base_deliveryrobot.py
# at commit 6b8ff9a. Bullet's raycast vehicle takes a wheel's brake as the largest rolling-friction impulse (N s) it
# applies in one physics substep, and a wheel with engine force rolls free.
IDLE_BRAKE = 2.0
REVERSE_DEADZONE = 0.01  # m/s: below this forward speed a brake command holds the ego still (it never reverses)


@dataclass(frozen=True)
class MachineSpec:
    """Parameters of one mobile machine (SI units; forces in N, angles in degrees as in the paper's table).

    The built-in machines are the rows of `machines.csv` beside this module (its header gives units and sources);
    a custom machine is one of them with some fields replaced (`machine_spec`).
    """

    name: str
    kind: str  # "wheeled" (force model) or "legged" (velocity limits)
    v_max_kmh: float
    steer_max_deg: float
    friction: float
    engine_force: tuple[float, float]
    brake_force: tuple[float, float]  # per wheel, four wheels
    wheelbase: float
    wheel_radius: float
    wheel_width: float
    mass: float
    length: float
    width: float
    height: float
    drag_area: float  # Cd * A in m^2
    rolling_resistance: float
    accel_max: float  # legged only: m/s^2
    yaw_rate_max: float  # legged only: rad/s
    color: tuple[float, float, float, float]
    drive: str = "force"  # wheeled only: "force" (curbside's force model) or "vehicle" (`vehicle_drive`)

    @property
    def v_max(self) -> float:
        """Top speed in m/s."""
        return self.v_max_kmh / 3.6

    @property
    def steer_max(self) -> float:
        """Largest steering angle in radians."""
        return math.radians(self.steer_max_deg)

    @property
    def rides(self) -> bool:
        """Whether the machine rides on raycast wheels (drive "vehicle"): only its chassis collides."""
        return self.drive == "vehicle"

    @property
    def clearance(self) -> float:
        """Height of the lowest colliding part above the surface: a raycast vehicle's chassis floor (the body is
        built with its chassis from 0.9 wheel radii up), else 0 (the wheels touch what they roll into)."""
        return 0.9 * self.wheel_radius if self.rides else 0.0

    @property
    def half_width(self) -> float:
        """Half of the footprint's width, used to inflate obstacles for route planning."""
        return 0.5 * self.width


def _load_machines() -> dict[str, MachineSpec]:
    """The machines table `machines.csv` beside this module: one MachineSpec a row, in row order."""
    with resources.files("sim").joinpath("machines.csv").open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    types = {fh.name: str(fh.type) for fh in fields(MachineSpec)}

    def cell(key: str, text: str) -> Any:
        if types[key].startswith("tuple"):
            return tuple(float(token) for token in text.split())  # forces (low high) and colours (r g b a)
        return float(text) if types[key] == "float" else text

    return {row["name"]: MachineSpec(**{k: cell(k, v) for k, v in row.items()}) for row in rows}


MACHINES: dict[str, MachineSpec] = _load_machines()
WHEELED = tuple(n for n, m in MACHINES.items() if m.kind == "wheeled")


def machine_spec(machine: str | Mapping[str, Any]) -> MachineSpec:
    """Resolve a machine name, or a dict of MachineSpec fields (optionally `base`: a name), into a MachineSpec."""
    if isinstance(machine, str):
        if machine not in MACHINES:
            raise ConfigError(
                f"unknown machine {machine!r}; valid machines: {', '.join(MACHINES)} (or a dict of parameters)"
            )
        return MACHINES[machine]
    if not isinstance(machine, Mapping):
        raise ConfigError(f"machine must be a name or a dict of parameters, got {type(machine).__name__}")
    params = dict(machine)
    base = machine_spec(params.pop("base", "delivery_bot"))
    valid = {fld.name for fld in fields(MachineSpec)}
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
    if spec.drive not in DRIVES:
        raise ConfigError(f"machine drive must be one of {', '.join(DRIVES)}, got {spec.drive!r}")
    if spec.v_max <= 0 or spec.wheelbase <= 0 or spec.mass <= 0:
        raise ConfigError("machine v_max_kmh, wheelbase and mass must be positive")
    return spec


def vehicle_drive(
    spec: MachineSpec,
    speed: Any,
    steer: Any,
    throttle: Any,
    engine_force: Any,
    brake_force: Any,
    dt: float,
    friction: Any,
    grade_accel: Any = 0.0,
) -> tuple[Any, Any]:
    """(speed, yaw rate) after one physics substep of `dt` s of MetaUrban's Bullet raycast vehicle: numbers for one
    machine (`Machine.command`) or arrays for many (`sim.batched.kinematics.Drive.command`), the same doubles.

    As `EgoDeliveryRobot._apply_throttle_brake` drives its four wheels (base_deliveryrobot.py at commit 6b8ff9a):
    throttle >= 0 applies `throttle` x the engine force on every wheel, none above the top speed; throttle < 0 brakes
    every wheel with |throttle| x the brake force, and at rest (forward speed under REVERSE_DEADZONE) holds it: the ego
    never reverses. A wheel without engine force brakes with IDLE_BRAKE. Bullet takes a brake as the largest impulse
    a wheel's rolling friction applies in a substep (so its deceleration is 4 brake / (mass dt), and it never drives
    the machine backwards), and the tyres' friction caps what any wheel transmits (mu g in all). Steering turns the
    front wheels by `steer` x steer_max: the yaw rate of a bicycle of the spec's wheelbase, friction-limited in
    cornering. `friction` is the tyres' mu or the ground's, the lower; `grade_accel` the slope's pull (m/s^2).
    """
    forward = np.greater_equal(throttle, 0.0)
    engine = np.where(forward & (speed * 3.6 <= spec.v_max_kmh), throttle * engine_force, 0.0)
    brake = np.where(
        forward,
        np.where(engine != 0.0, 0.0, IDLE_BRAKE),
        np.where(speed < REVERSE_DEADZONE, IDLE_BRAKE, -throttle * brake_force),
    )
    limit = friction * G
    v_drive = speed + np.clip(4.0 * engine / spec.mass + grade_accel, -limit, limit) * dt
    # The brakes take at most 4 brake / mass off the speed in a substep (the friction limit too) and stop it at 0.
    slow = np.minimum(4.0 * brake / spec.mass, limit * dt)
    v_new = np.where(v_drive > 0.0, np.maximum(v_drive - slow, 0.0), np.minimum(v_drive + slow, 0.0))
    yaw_rate = v_new * np.tan(steer * spec.steer_max) / spec.wheelbase
    moving = v_new != 0.0
    max_rate = limit / np.where(moving, np.abs(v_new), 1.0)
    yaw_rate = np.where(moving, np.clip(yaw_rate, -max_rate, max_rate), yaw_rate)
    if np.ndim(v_new) == 0:
        return float(v_new), float(yaw_rate)
    return v_new, yaw_rate


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
        self.roll = 0.0
        self.position = (0.0, 0.0, 0.0)
        self.surface_friction = math.inf  # the ground's friction coefficient under the machine (terrain sets it)
        # (x, y) -> that coefficient (sim.world.World.friction_at), read at `reset` and every `sync`; None: set by
        # the caller.
        self.ground: Callable[[float, float], float] | None = None
        self.count_grade = True  # add the grade force (see command); terrain trials turn it off

    def _build_body(self) -> int:
        spec, client = self.spec, self.client
        wheel_r = spec.wheel_radius
        # Chassis starts just below the wheel centres so the spheres carry the load on the ground.
        clear = wheel_r * 0.9
        hz = max(0.5 * (spec.height - clear), 0.05)
        half = [0.5 * spec.length, 0.5 * spec.width, hz]
        chassis_z = clear + hz  # body origin sits at the ground; shapes are offset upwards
        rides = spec.rides
        if rides:
            # MetaUrban's ego is a Bullet raycast vehicle: its wheels are rays that touch nothing but the surface under
            # them (`Machine.ride` follows it), and only its chassis collides. Shown at the wheelbase's ends.
            wx, wy = 0.5 * spec.wheelbase, 0.5 * spec.width
        else:
            wx = 0.5 * spec.wheelbase
            wy = max(0.5 * spec.width - 0.5 * spec.wheel_width, wheel_r * 0.5)
        wheels = [[wx, wy, wheel_r], [wx, -wy, wheel_r], [-wx, wy, wheel_r], [-wx, -wy, wheel_r]]
        spheres = 0 if rides else 4
        col = p.createCollisionShapeArray(
            shapeTypes=[p.GEOM_BOX] + [p.GEOM_SPHERE] * spheres,
            halfExtents=[half] + [[0, 0, 0]] * spheres,
            radii=[0.0] + [wheel_r] * spheres,
            collisionFramePositions=[[0, 0, chassis_z]] + wheels[:spheres],
            physicsClientId=client,
        )
        vis = p.createVisualShapeArray(
            shapeTypes=[p.GEOM_BOX] + [p.GEOM_CYLINDER] * 4,
            halfExtents=[half] + [[0, 0, 0]] * 4,
            radii=[0.0] + [wheel_r] * 4,
            lengths=[0.0] + [spec.wheel_width] * 4,
            rgbaColors=[list(spec.color)] + [[0.1, 0.1, 0.1, 1]] * 4,
            visualFramePositions=[[0, 0, chassis_z]] + wheels,
            visualFrameOrientations=[[0, 0, 0, 1]] + [p.getQuaternionFromEuler([math.pi / 2, 0, 0])] * 4,
            physicsClientId=client,
        )
        body = p.createMultiBody(spec.mass, col, vis, basePosition=[0, 0, 1.0], physicsClientId=client)
        # Zero contact friction: traction and cornering come from the force model, Bullet only resolves
        # normal contacts (the ideal no-slip bicycle; sliding along walls instead of sticking to them).
        p.changeDynamics(
            body,
            -1,
            lateralFriction=0.0,
            spinningFriction=0.0,
            rollingFriction=0.0,
            linearDamping=0.0,
            angularDamping=0.0,
            restitution=0.0,
            ccdSweptSphereRadius=0.8 * wheel_r,
            physicsClientId=client,
        )
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
        if self.ground is not None:  # else the first substep would use the friction where the last episode ended
            self.surface_friction = self.ground(x, y)
        p.resetBasePositionAndOrientation(
            self.body, [x, y, z + 0.005], p.getQuaternionFromEuler([0, 0, yaw]), physicsClientId=self.client
        )
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)

    def command(self, steer: float, throttle: float, dt: float) -> None:
        """Update speed, steering and yaw rate for one substep of `dt` seconds and hand the velocity to Bullet."""
        spec = self.spec
        v = self.speed
        if spec.kind == "wheeled" and spec.drive == "vehicle":
            self.steering = steer * spec.steer_max
            grade = G * math.sin(self.pitch) if self.count_grade else 0.0
            mu = min(spec.friction, self.surface_friction)
            v_new, yaw_rate = vehicle_drive(
                spec, v, steer, throttle, self.engine_force, self.brake_force, dt, mu, grade
            )
        elif spec.kind == "wheeled":
            self.steering = steer * spec.steer_max
            if throttle >= 0.0:
                # The motor's force falls linearly to zero at v_max: the speed limit comes out of the drive.
                force = throttle * self.engine_force * max(0.0, 1.0 - v / spec.v_max)
            else:
                force = throttle * 4.0 * self.brake_force
            resist = spec.rolling_resistance * spec.mass * G + 0.5 * 1.2 * spec.drag_area * v * v
            # Bullet's pitch is positive nose-down, so uphill (negative pitch) adds a retarding grade force. The
            # contacts are frictionless, so Bullet's gravity pulls the body down a slope as well: on terrain (the
            # runways) `count_grade` is off and the grade is counted once. In the envs it stays on: it is also what
            # stops a machine driven into a wall at speed from riding up it (the drive sets its velocity).
            if self.count_grade:
                force += spec.mass * G * math.sin(self.pitch)
            mu = min(spec.friction, self.surface_friction)
            force -= resist
            accel = force / spec.mass
            limit = mu * G  # tyres cannot transmit more than mu * g (the tyre's mu or the surface's, the lower)
            accel = min(max(accel, -limit), limit)
            v_new = v + accel * dt
            if v_new < 0.0 and throttle <= 0.0:
                v_new = 0.0  # brakes and resistances stop the machine; they do not drive it backwards
            v_new = min(max(v_new, -0.2 * spec.v_max), spec.v_max)
            yaw_rate = v_new * math.tan(self.steering) / spec.wheelbase
            if v_new != 0.0:
                # Cornering is friction-limited too: lateral acceleration v * yaw_rate <= mu * g.
                max_rate = limit / abs(v_new)
                yaw_rate = min(max(yaw_rate, -max_rate), max_rate)
        else:
            target = max(throttle, 0.0) * spec.v_max
            dv = min(max(target - v, -2.0 * spec.accel_max * dt), spec.accel_max * dt)
            v_new = v + dv
            self.steering = steer
            yaw_rate = steer * spec.yaw_rate_max
        self.speed = v_new
        self.yaw_rate = yaw_rate
        cos_yaw, sn = math.cos(self.yaw), math.sin(self.yaw)
        if spec.rides:  # `ride` sets its height and tilt: Bullet moves it in the plane only
            lin, ang = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        else:
            lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.client)
        p.resetBaseVelocity(
            self.body, [v_new * cos_yaw, v_new * sn, lin[2]], [ang[0], ang[1], yaw_rate], physicsClientId=self.client
        )

    def ride(self) -> None:
        """Set a raycast vehicle's height and tilt to the surface under its wheels, as its suspension carries it.

        Each wheel is a vertical ray at a corner of the wheelbase (its end, the body's side) that finds the surface
        under it, up to a wheel radius above the wheel's contact (a curb lower than the axle is driven over, as
        Bullet's raycast wheels do; a higher step is not: the chassis meets it). The chassis rests on the mean of the
        four contacts and tilts with their plane."""
        spec = self.spec
        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        yaw = p.getEulerFromQuaternion(orn)[2]
        c, sn = math.cos(yaw), math.sin(yaw)
        hx, hy = 0.5 * spec.wheelbase, 0.5 * spec.width
        corners = ((hx, hy), (hx, -hy), (-hx, hy), (-hx, -hy))
        points = [(pos[0] + c * u - sn * w, pos[1] + sn * u + c * w) for u, w in corners]
        top = pos[2] + spec.wheel_radius
        hits = p.rayTestBatch(
            [[x, y, top] for x, y in points], [[x, y, pos[2] - 1.0] for x, y in points], physicsClientId=self.client
        )
        heights = [float(h[3][2]) if h[0] >= 0 and h[0] != self.body else pos[2] for h in hits]
        front, rear = 0.5 * (heights[0] + heights[1]), 0.5 * (heights[2] + heights[3])
        left, right = 0.5 * (heights[0] + heights[2]), 0.5 * (heights[1] + heights[3])
        pitch = math.atan2(rear - front, spec.wheelbase)  # Bullet's pitch is positive nose-down
        roll = math.atan2(left - right, spec.width)
        z = sum(heights) / 4.0
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.client)
        p.resetBasePositionAndOrientation(
            self.body, [pos[0], pos[1], z], p.getQuaternionFromEuler([roll, pitch, yaw]), physicsClientId=self.client
        )
        # A reset drops the body's velocity: the planar one is Bullet's result, kept for `sync` to read.
        p.resetBaseVelocity(self.body, [lin[0], lin[1], 0.0], [0.0, 0.0, ang[2]], physicsClientId=self.client)

    def sync(self) -> None:
        """Read pose and velocity back from Bullet after a substep (contacts may have changed them)."""
        if self.spec.rides:
            self.ride()
        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        lin, _ = p.getBaseVelocity(self.body, physicsClientId=self.client)
        roll, pitch, yaw = p.getEulerFromQuaternion(orn)
        self.position = pos
        if self.ground is not None:
            self.surface_friction = self.ground(pos[0], pos[1])
        self.yaw = yaw
        self.pitch = pitch
        self.roll = roll
        # Speed along the heading: a wall or a curb the machine runs into takes it away.
        self.speed = lin[0] * math.cos(yaw) + lin[1] * math.sin(yaw)
