"""The machines' drive model for many envs at once, on flat ground: `sim.machines.Machine.command` as array code.

PyBullet's path (the reference) runs `Machine.command` at every physics substep, hands the velocity to Bullet,
which integrates the body explicitly (position += velocity dt along the old heading, yaw += yaw rate dt) and
resolves contacts, and reads the speed back along the new heading (so a turning machine reads back
v cos(yaw_rate dt)). Here the same update runs on arrays of envs with no contact solver: the grade term is zero
(flat ground); a substep whose new footprint overlaps an obstacle ends where the footprint meets it, and the env
slides the machine along the obstacle or stops it (`BatchedPointNav._slide`, `Drive.store` with `blocked`).
`tests/sim/test_batched.py` checks the two against each other on the same actions.

`Machine.command` stays the scalar reference (its doubles make the PyBullet episodes' hashes): this file restates
its formulas once for arrays (np.where for its branches), as docs/batched.md says.
"""

from __future__ import annotations

import numpy as np

from sim.machines import G, MachineSpec, vehicle_drive


class Drive:
    """Pose and drive state of `n` machines of one spec: x, y, yaw, speed, yaw rate, and episode forces."""

    def __init__(self, spec: MachineSpec, n: int) -> None:
        self.spec = spec
        self.n = n
        self.x = np.zeros(n)
        self.y = np.zeros(n)
        self.yaw = np.zeros(n)
        self.speed = np.zeros(n)
        self.yaw_rate = np.zeros(n)
        self.engine_force = np.full(n, float(np.mean(spec.engine_force)))
        self.brake_force = np.full(n, float(np.mean(spec.brake_force)))
        self.bounding_radius = 0.5 * float(np.hypot(spec.length, spec.width))

    def reset(self, i: np.ndarray | int, x: float, y: float, yaw: float, rng: np.random.Generator) -> None:
        """Machine `i` at rest at (x, y) heading `yaw`; its engine and brake forces drawn as `Machine.reset` does."""
        lo, hi = self.spec.engine_force
        self.engine_force[i] = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        lo, hi = self.spec.brake_force
        self.brake_force[i] = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        self.x[i], self.y[i], self.yaw[i] = x, y, yaw
        self.speed[i] = self.yaw_rate[i] = 0.0

    def command(self, steer: np.ndarray, throttle: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """New (speed, yaw rate) of every machine for one substep of `dt` s (`Machine.command` on flat ground)."""
        s, v = self.spec, self.speed
        if s.kind != "wheeled":
            target = np.maximum(throttle, 0.0) * s.v_max
            v_new = v + np.clip(target - v, -2.0 * s.accel_max * dt, s.accel_max * dt)
            return v_new, steer * s.yaw_rate_max
        if s.drive == "vehicle":  # one function for both backends
            return vehicle_drive(s, v, steer, throttle, self.engine_force, self.brake_force, dt, s.friction)
        steering = steer * s.steer_max
        drive = throttle * self.engine_force * np.maximum(0.0, 1.0 - v / s.v_max)
        force = np.where(throttle >= 0.0, drive, throttle * 4.0 * self.brake_force)
        force = force - (s.rolling_resistance * s.mass * G + 0.5 * 1.2 * s.drag_area * v * v)
        limit = s.friction * G
        v_new = v + np.clip(force / s.mass, -limit, limit) * dt
        v_new = np.where((v_new < 0.0) & (throttle <= 0.0), 0.0, v_new)
        v_new = np.clip(v_new, -0.2 * s.v_max, s.v_max)
        yaw_rate = v_new * np.tan(steering) / s.wheelbase
        moving = v_new != 0.0
        max_rate = limit / np.where(moving, np.abs(v_new), 1.0)
        return v_new, np.where(moving, np.clip(yaw_rate, -max_rate, max_rate), yaw_rate)

    def integrate(self, v: np.ndarray, yaw_rate: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pose after `dt` at (v, yaw rate), as Bullet integrates a body: (x, y, yaw), not yet stored."""
        c, sn = np.cos(self.yaw), np.sin(self.yaw)
        yaw = self.yaw + yaw_rate * dt
        yaw = (yaw + np.pi) % (2.0 * np.pi) - np.pi  # Bullet reports yaw in (-pi, pi]
        return self.x + v * c * dt, self.y + v * sn * dt, yaw

    def store(
        self,
        x: np.ndarray,
        y: np.ndarray,
        yaw: np.ndarray,
        v: np.ndarray,
        yaw_rate: np.ndarray,
        dt: float,
        blocked: np.ndarray | None,
    ) -> None:
        """Accept the substep's pose; where `blocked` (the pose is then where the machine met the obstacle) the
        machine also stops.

        The speed read back is the velocity along the new heading (`Machine.sync`): v cos(yaw rate dt).
        """
        speed = v * np.cos(yaw_rate * dt)
        if blocked is not None and blocked.any():
            speed = np.where(blocked, 0.0, speed)
            yaw_rate = np.where(blocked, 0.0, yaw_rate)
        self.x, self.y, self.yaw, self.speed, self.yaw_rate = x, y, yaw, speed, yaw_rate

    def footprint(self, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
        """World points [n, k] on the outline of each machine's rectangle, at most `spacing` apart."""
        s = self.spec
        hl, hw = 0.5 * s.length, 0.5 * s.width
        nl = max(int(np.ceil(s.length / spacing)), 1)
        nw = max(int(np.ceil(s.width / spacing)), 1)
        u = np.concatenate(
            [np.linspace(-hl, hl, nl + 1), np.linspace(-hl, hl, nl + 1), np.full(nw - 1, -hl), np.full(nw - 1, hl)]
        )
        w = np.concatenate(
            [
                np.full(nl + 1, -hw),
                np.full(nl + 1, hw),
                np.linspace(-hw, hw, nw + 1)[1:-1],
                np.linspace(-hw, hw, nw + 1)[1:-1],
            ]
        )
        c, sn = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        return x[:, None] + c * u - sn * w, y[:, None] + sn * u + c * w
