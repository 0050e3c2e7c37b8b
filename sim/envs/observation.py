"""The PointNav observation: LiDAR scans, ego state, route waypoints and the goal (table in PointNavEnv), as one
flat vector or, with a camera, a Dict of `lidar`, `state`, `nav` and the camera's images."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from kernel.config import ConfigError
from sim.camera import camera_spaces

GOAL_LOG_SCALE = math.log1p(500.0)  # goal distances up to 500 m span [0, 1] in the observation
Observation = np.ndarray | dict[str, np.ndarray]  # the flat vector, or the Dict of parts and camera images


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def observation_mode(cfg: Mapping[str, Any]) -> str:
    """ "flat" or "dict": config.observation, "auto" resolved by whether the camera has modalities."""
    mode, camera = cfg["observation"], bool(cfg["camera"]["modalities"])
    if mode == "flat" and camera:
        raise ConfigError(
            "config.observation 'flat' cannot hold camera images; use observation 'dict' (or 'auto'), "
            "or camera.modalities []"
        )
    return ("dict" if camera else "flat") if mode == "auto" else mode


class EgoObservation:
    """Names, space and values of the `B + L + 6 + 2 W + 3` observation of a PointNav-style task (flat or Dict)."""

    def __init__(self, cfg: Mapping[str, Any]) -> None:
        lid = cfg["lidar"]
        self.num_beams = int(lid["beams"])
        self.num_low_beams = int(lid["low_beams"])
        self.num_waypoints = num_wp = int(cfg["num_waypoints"])
        self.names = (
            [f"lidar_{k}" for k in range(self.num_beams)]
            + [f"low_{k}" for k in range(self.num_low_beams)]
            + ["speed", "yaw_rate", "heading_error", "lateral_offset", "last_steering", "last_throttle"]
            + [f"wp{i}_{axis}" for i in range(num_wp) for axis in "xy"]
            + ["goal_distance", "goal_heading_sin", "goal_heading_cos"]
        )
        num_obs = len(self.names)
        low = -np.ones(num_obs, dtype=np.float32)
        low[: self.num_beams + self.num_low_beams] = 0.0
        self.space: gym.spaces.Box | gym.spaces.Dict = gym.spaces.Box(
            low, np.ones(num_obs, dtype=np.float32), dtype=np.float32
        )
        self.mode = observation_mode(cfg)
        self.last_images: dict[str, np.ndarray] = {}  # the camera's latest images (the dashboard shows them)
        num_rays = self.num_beams + self.num_low_beams
        self._parts = {
            "lidar": slice(0, num_rays),
            "state": slice(num_rays, num_rays + 6),
            "nav": slice(num_rays + 6, num_obs),
        }
        if self.mode == "dict":
            self.space = gym.spaces.Dict(
                {
                    **{k: gym.spaces.Box(low[sl], 1.0, dtype=np.float32) for k, sl in self._parts.items()},
                    **camera_spaces(cfg["camera"]),
                }
            )
        self._wp_offsets = np.arange(1, num_wp + 1, dtype=np.float64) * float(cfg["waypoint_spacing"])
        self._wp_scale = 1.0 / (self._wp_offsets[-1])
        self.speed_scale = float(cfg["speed_scale"])
        self.lateral_scale = float(cfg["out_of_route_distance"])

    def __call__(
        self,
        machine: Any,
        route: Any,
        progress: float,
        lateral: float,
        last_action: np.ndarray,
        lidar: Any,
        low_lidar: Any | None,
        camera: Any = None,
        extra_kinds: Mapping[int, str] | None = None,
    ) -> Observation:
        """The observation of `machine` at arc length `progress` and offset `lateral` on `route` (scans now; the
        camera renders when the observation is a Dict, `extra_kinds` naming the bodies the world does not hold)."""
        x, y, z = machine.position
        yaw = machine.yaw
        lidar.scan(x, y, z, yaw)
        parts = [lidar.encoded()]
        if low_lidar is not None:
            parts.append(low_lidar.scan(x, y, z, yaw))
        heading_err = _wrap(yaw - route.heading_at(progress))
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        wp = route.point_at(progress + self._wp_offsets)
        dx, dy = wp[:, 0] - x, wp[:, 1] - y
        scale = self._wp_scale
        ego = np.stack([(cos_yaw * dx + sin_yaw * dy) * scale, (-sin_yaw * dx + cos_yaw * dy) * scale], 1).ravel()
        gx, gy = route.goal[0] - x, route.goal[1] - y
        bearing = math.atan2(gy, gx) - yaw
        state = [
            machine.speed / self.speed_scale,
            machine.yaw_rate / 2.0,
            heading_err / math.pi,
            lateral / self.lateral_scale,
            last_action[0],
            last_action[1],
        ]
        tail = [math.log1p(math.hypot(gx, gy)) / GOAL_LOG_SCALE, math.sin(bearing), math.cos(bearing)]
        obs = np.concatenate([*parts, np.asarray(state), ego, np.asarray(tail)]).astype(np.float32)
        np.clip(obs, -1.0, 1.0, out=obs)
        if self.mode == "flat":
            return obs
        images = self.last_images = camera.capture(machine, extra_kinds) if camera is not None else {}
        return {**{k: obs[sl] for k, sl in self._parts.items()}, **images}
