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
    # Add the throttle that holds the machine against the slope under it (a raycast vehicle straddling a curb).
    hold_grade: bool = False
    # "pursuit": steer by pure pursuit; "arcs": among `arcs` steering angles, the one whose arc (the footprint swept
    # along it, checked against the last scan) runs free longest towards the pursuit point `arc_lookahead` m ahead on
    # the route: a long wheelbase that cannot reverse must turn before it meets what it cannot turn away from.
    steering: str = "pursuit"
    arcs: int = 11
    arc_lookahead: float = 5.0
    arc_reach: float = 6.0  # metres of each arc checked

    @classmethod
    def for_machine(cls, spec: Any) -> PurePursuitExpert:
        """The expert's settings for a machine: MetaUrban's ego (a raycast vehicle, `spec.rides`) cruises at 5 m/s,
        chooses its steering among free arcs and holds its grade; every other machine takes the defaults."""
        if getattr(spec, "rides", False):
            return cls(cruise_speed=5.0, hold_grade=True, steering="arcs", stop_distance=0.25)
        return cls()

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
        if spec.kind == "wheeled" and self.steering == "arcs":
            steer, curvature, free = self._free_arc(u, route.point_at(u.episode.progress + self.arc_lookahead))
            alpha = 0.0  # the arc already turns towards the route
        elif spec.kind == "wheeled":
            delta = math.atan(spec.wheelbase * curvature)
            steer = delta / spec.steer_max if spec.steer_max > 0 else 0.0
        else:
            steer = curvature * max(v, 0.3) / spec.yaw_rate_max
        v_target = min(self.cruise_speed, spec.v_max)
        v_target = min(v_target, math.sqrt(self.lateral_accel / max(abs(curvature), 1e-3)))
        if self.steering == "arcs":  # slow down in time for the route's turns ahead, not only the arc being driven
            v_target = min(v_target, self._turn_speed(route, u.episode.progress))
        if abs(alpha) > math.pi / 2:
            v_target = min(v_target, 0.5)  # facing away from the route: creep while turning back
        if self.steering == "arcs":
            gap = free  # the swept footprint's free length along the chosen arc (margins included)
            if free >= self.arc_reach:
                gap = math.inf
        else:
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
            if self.hold_grade and err > -0.05:
                # Pitch is positive nose-down: uphill needs 4 F throttle = m g sin(-pitch) more.
                throttle += spec.mass * 9.81 * max(-math.sin(m.pitch), 0.0) / (4.0 * max(m.engine_force, 1e-6))
            if v_target <= 0.01:
                throttle = -1.0
        else:
            throttle = v_target / spec.v_max
        return np.clip(np.array([steer, throttle], dtype=np.float32), -1.0, 1.0)

    def _points(self, u: Any, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Obstacle points within `reach` m in the machine's frame (x ahead, y left): the last scan's hits and, for
        the "arcs" steering, the outlines of the scene's objects tall enough to meet the chassis (privileged, as the
        route is: a box lower than the LiDAR but higher than a raycast vehicle's floor stops it unseen)."""
        lid = u.lidar
        d = lid.distances.astype(np.float64) * lid.range_m
        near = (d < reach) & (d < lid.range_m * 0.999)
        px, py = d[near] * np.cos(lid.angles[near]), d[near] * np.sin(lid.angles[near])
        if self.steering != "arcs":
            return px, py
        m = u.machine
        outline, tops = self._outlines(u.scene)
        c, sn = math.cos(m.yaw), math.sin(m.yaw)
        dx, dy = outline[:, 0] - m.position[0], outline[:, 1] - m.position[1]
        ox, oy = c * dx + sn * dy, -sn * dx + c * dy
        keep = (np.hypot(ox, oy) < reach) & (tops > m.position[2] + m.spec.clearance)
        return np.concatenate([px, ox[keep]]), np.concatenate([py, oy[keep]])

    def _outlines(self, scene: Any, spacing: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
        """Points every `spacing` m along each object's footprint [n, 2] and each point's object top (z), per scene."""
        cached = getattr(self, "_outline_cache", None)
        if cached is not None and cached[0] is scene:
            return cached[1], cached[2]
        pts, tops = [np.zeros((0, 2))], [np.zeros(0)]
        for o in scene.objects:
            foot = np.asarray(o["footprint"], dtype=np.float64)
            ring = np.vstack([foot, foot[:1]])
            for a, b in zip(ring[:-1], ring[1:]):
                k = max(int(math.ceil(float(np.hypot(*(b - a))) / spacing)), 1)
                t = np.linspace(0.0, 1.0, k, endpoint=False)[:, None]
                pts.append(a + t * (b - a))
                tops.append(np.full(k, float(o["position"][2]) + float(o["size"][2])))
        self._outline_cache = (scene, np.concatenate(pts), np.concatenate(tops))
        return self._outline_cache[1], self._outline_cache[2]

    def _turn_speed(self, route: Any, progress: float, reach: float = 20.0, brake: float = 1.5) -> float:
        """The highest speed from which the machine can still slow (at `brake` m/s^2) to each turn's comfortable
        speed (`lateral_accel` over the route's curvature, measured over 2 m) within the next `reach` m."""
        ahead = np.arange(0.0, reach, 1.0)
        h0 = np.array([route.heading_at(progress + a) for a in ahead])
        h1 = np.array([route.heading_at(progress + a + 2.0) for a in ahead])
        bend = np.abs((h1 - h0 + np.pi) % (2.0 * np.pi) - np.pi) / 2.0
        turn = np.sqrt(self.lateral_accel / np.maximum(bend, 1e-3))
        return float(np.min(np.sqrt(turn**2 + 2.0 * brake * ahead)))

    def _free_arc(self, u: Any, target: np.ndarray) -> tuple[float, float, float]:
        """(steering, curvature, free metres) of the arc to drive: each of `arcs` steering values sweeps the
        footprint (plus `corridor_margin`) along its arc for `arc_reach` m against the last scan's points; the arc
        whose free part passes nearest `target` wins, a fully free one before a blocked one."""
        m = u.machine
        spec = m.spec
        px, py = self._points(u, self.arc_reach + spec.length)
        hl, hw = 0.5 * spec.length + self.corridor_margin, 0.5 * spec.width + self.corridor_margin
        touching = (np.abs(px) < hl) & (np.abs(py) < hw)  # what the body already touches does not block a turn
        px, py = px[~touching], py[~touching]
        c, sn = math.cos(m.yaw), math.sin(m.yaw)
        dx, dy = float(target[0]) - m.position[0], float(target[1]) - m.position[1]
        gx, gy = c * dx + sn * dy, -sn * dx + c * dy  # the target in the machine's frame
        steps = np.arange(0.25, self.arc_reach + 1e-9, 0.25)
        best: tuple[float, float, float, float] | None = None
        for steer in np.linspace(-1.0, 1.0, self.arcs):
            k = math.tan(steer * spec.steer_max) / spec.wheelbase
            if abs(k) < 1e-6:
                ax, ay, th = steps, np.zeros_like(steps), np.zeros_like(steps)
            else:
                th = k * steps
                ax, ay = np.sin(th) / k, (1.0 - np.cos(th)) / k
            free = self.arc_reach
            if px.size:
                ct, st = np.cos(th)[:, None], np.sin(th)[:, None]
                qx = ct * (px[None] - ax[:, None]) + st * (py[None] - ay[:, None])
                qy = -st * (px[None] - ax[:, None]) + ct * (py[None] - ay[:, None])
                hit = ((np.abs(qx) < hl) & (np.abs(qy) < hw)).any(axis=1)
                if hit.any():
                    free = float(steps[int(np.argmax(hit))] - 0.25)
            j = int(round(free / 0.25))  # poses on the free part of the arc
            reach = float(np.min(np.hypot(gx - ax[:j], gy - ay[:j]))) if j > 0 else math.hypot(gx, gy)
            score = reach + (0.0 if free >= self.arc_reach else 2.0 + (self.arc_reach - free))
            if best is None or score < best[0] - 1e-9:
                best = (score, float(steer), k, free)
        assert best is not None
        return best[1], best[2], best[3]

    def _corridor_gap(self, u: Any) -> float:
        """Free distance ahead of the machine's front along a corridor of its width, from the last scan."""
        fx, fy = self._points(u, math.inf)
        half = 0.5 * u.machine.spec.width + self.corridor_margin
        front = 0.5 * u.machine.spec.length
        ahead = (fx > 0.0) & (np.abs(fy) < half)
        if not ahead.any():
            return math.inf
        return float(fx[ahead].min() - front)


def random_policy(env: Any) -> np.ndarray:
    """A uniformly random action from the env's action space (seeded by the env's action_space.seed)."""
    return env.action_space.sample()
