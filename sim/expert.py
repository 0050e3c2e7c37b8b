"""The built-in expert: pure-pursuit route following with LiDAR-based slowing and stopping.

It reads the privileged route and machine state from the env (not the observation), which is what a
demonstrator and a sanity baseline need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class PurePursuitExpert:
    """Pure pursuit on the reference route; slows for curvature and stops for obstacles in its corridor.

    cruise_speed: target speed (m/s), capped by the machine's v_max. lookahead: base look-ahead distance,
    grown with speed. lateral_accel: comfort limit that caps speed on curves. stop_distance: gap (m, from
    the machine's front) at which it stops for an obstacle in its corridor; it slows linearly before.
    """

    cruise_speed: float = 2.5
    lookahead: float = 1.2
    lookahead_gain: float = 0.5
    lateral_accel: float = 1.2
    stop_distance: float = 0.6
    slow_distance: float = 4.0
    corridor_margin: float = 0.15
    speed_gain: float = 1.5

    def act(self, env: Any) -> np.ndarray:
        """The action [steering, throttle_brake] for the env's current state (env or a wrapper of it)."""
        u = env.unwrapped
        m, route = u.machine, u.route
        spec = m.spec
        x, y, _ = m.position
        v = m.speed
        ld = self.lookahead + self.lookahead_gain * max(v, 0.0)
        tx, ty = route.point_at(u.episode.progress + ld)
        dx, dy = tx - x, ty - y
        alpha = math.atan2(dy, dx) - m.yaw
        alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
        dist = max(math.hypot(dx, dy), 1e-3)
        curvature = 2.0 * math.sin(alpha) / dist
        if spec.kind == "wheeled":
            delta = math.atan(spec.wheelbase * curvature)
            steer = delta / spec.steer_max if spec.steer_max > 0 else 0.0
        else:
            steer = curvature * max(v, 0.3) / spec.yaw_rate_max
        v_target = min(self.cruise_speed, spec.v_max)
        v_target = min(v_target, math.sqrt(self.lateral_accel / max(abs(curvature), 1e-3)))
        if abs(alpha) > math.pi / 2:
            v_target = min(v_target, 0.5)  # facing away from the route: creep while turning back
        gap = self._corridor_gap(u)
        if gap < self.slow_distance:
            v_target = min(
                v_target, spec.v_max * max(0.0, (gap - self.stop_distance) / (self.slow_distance - self.stop_distance))
            )
        remaining = route.length - u.episode.progress
        v_target = min(v_target, max(0.5, math.sqrt(2.0 * 1.0 * max(remaining, 0.0))))
        err = v_target - v
        if spec.kind == "wheeled":
            throttle = self.speed_gain * err if err > -0.05 else 4.0 * err
            if v_target <= 0.01:
                throttle = -1.0
        else:
            throttle = v_target / spec.v_max
        return np.clip(np.array([steer, throttle], dtype=np.float32), -1.0, 1.0)

    def _corridor_gap(self, u: Any) -> float:
        """Free distance ahead of the machine's front along a corridor of its width, from the last scan."""
        lid = u.lidar
        d = lid.distances.astype(np.float64) * lid.range_m
        fx, fy = d * np.cos(lid.angles), d * np.sin(lid.angles)
        half = 0.5 * u.machine.spec.width + self.corridor_margin
        front = 0.5 * u.machine.spec.length
        ahead = (fx > 0.0) & (np.abs(fy) < half) & (d < lid.range_m * 0.999)
        if not ahead.any():
            return math.inf
        return float(fx[ahead].min() - front)


def random_policy(env: Any) -> np.ndarray:
    """A uniformly random action from the env's action space (seeded by the env's action_space.seed)."""
    return env.action_space.sample()
