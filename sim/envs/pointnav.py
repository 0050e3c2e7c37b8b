"""PointNav: drive a mobile machine along a reference route to a goal in a static urban scene."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

from curbside.config import ConfigError, merge_strict
from sim.machines import Machine, machine_spec
from sim.metrics import make_measures
from sim.route import RoutePlanner
from sim.sensors import Lidar
from sim.tasks.pointnav import DEFAULT_CONFIG, Reward, load_scene
from sim.world import SURFACE_KINDS, World, check_spec

WALL_NZ = 0.5  # a contact whose normal is flatter than this is a wall (a curb side), not the ground
STATIC_COLLISION_KINDS = ("object", "building", "curb")


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class PointNavEnv(gym.Env):
    """Drive a machine (delivery robot, wheelchair, mobility scooter, legged robot) along a sidewalk route.

    ## Action space
    `Box(-1, 1, (2,), float32)`: `[steering, throttle_brake]`. Steering scales the machine's steering limit
    (wheeled) or yaw-rate limit (legged); positive throttle drives the engine, negative brakes (wheeled
    machines do not reverse). Out-of-range values are clipped to [-1, 1]; NaN or inf raise ValueError.

    ## Observation space
    `Box(float32)` of `B + 7 + 2 W + 3` values (B LiDAR beams, W waypoints; 270 by default), all in [-1, 1]:

    | index | name | meaning |
    |---|---|---|
    | 0 .. B-1 | `lidar_<k>` | beam k distance / range (1 = nothing within range); beam 0 points ahead, counter-clockwise |
    | B | `speed` | speed / v_max |
    | B+1 | `steering` | steering angle / steering limit |
    | B+2 | `yaw_rate` | yaw rate / 2 rad/s, clipped |
    | B+3 | `heading_error` | (heading - route heading) / pi |
    | B+4 | `lateral_offset` | signed offset from the route (left +) / out_of_route_distance, clipped |
    | B+5, B+6 | `last_steering`, `last_throttle` | the previous (clipped) action |
    | B+7 .. B+6+2W | `wp<i>_x`, `wp<i>_y` | next W route waypoints (spacing `waypoint_spacing`) in the ego frame / (W spacing) |
    | B+7+2W | `goal_distance` | straight-line distance to the goal / 100 m, clipped |
    | B+8+2W, B+9+2W | `goal_heading_sin`, `goal_heading_cos` | bearing of the goal in the ego frame |

    ## Rewards
    DESIGN.md: R = R_term + 0.5 R_disp + 1.0 R_lateral + 0.1 R_steering + 1.0 R_crash with R_term = +5 on
    success and -5 out of route, R_disp the progress along the route (m), R_lateral = -|lateral offset|,
    R_steering = -|s_t - s_{t-1}| v_t, R_crash = -1 per collision step. Weights: config `reward`.

    ## Episode end
    Terminated on success (route completion >= 0.95) or out of route (|lateral offset| >
    `out_of_route_distance`, or the machine's centre off the walkable area); truncated at `horizon` (1,000).
    `info["cost"]` is 1 on a step in collision. At episode end `info` holds the metrics (`success`, `spl`,
    `route_completion`, `cost`, `collisions_<kind>`, `path_length`, `time`) and `info["metrics"]` as a dict.

    ## Subclass hooks
    `_on_scene(spec)`, `_on_reset(rng)`, `_on_step()`, `_collision_kinds`, `collision_kinds_all`, `_episode_metrics()`:
    see docs/simulator.md.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    default_config: dict[str, Any] = DEFAULT_CONFIG

    def __init__(self, config: Mapping[str, Any] | None = None, render_mode: str | None = None) -> None:
        self.config = merge_strict(self.default_config, config, name="config")
        cfg = self.config
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"unknown render_mode {render_mode!r}; valid: rgb_array (or None)")
        self.render_mode = render_mode
        self.spec_machine = machine_spec(cfg["machine"])
        lo, hi = (float(v) for v in cfg["route_length"])
        if not 5.0 <= lo <= hi:
            raise ConfigError(f"config.route_length must be [min, max] with 5 <= min <= max, got {cfg['route_length']}")
        self.reward_fn = Reward(**merge_strict(DEFAULT_CONFIG["reward"], cfg["reward"], name="config.reward"))
        self.dt = float(cfg["dt"])
        self.substeps = int(cfg["physics_substeps"])
        if self.substeps < 1 or self.dt <= 0:
            raise ConfigError("config.dt must be > 0 and config.physics_substeps >= 1")
        if cfg["scene_spec"] is not None:
            check_spec(cfg["scene_spec"])
        self.measures = make_measures(list(cfg["measures"]))
        lid = cfg["lidar"]
        self.num_beams = int(lid["beams"])
        W = int(cfg["num_waypoints"])
        self.num_waypoints = W
        self.observation_names = (
            [f"lidar_{k}" for k in range(self.num_beams)]
            + ["speed", "steering", "yaw_rate", "heading_error", "lateral_offset", "last_steering", "last_throttle"]
            + [f"wp{i}_{a}" for i in range(W) for a in "xy"]
            + ["goal_distance", "goal_heading_sin", "goal_heading_cos"]
        )
        n = len(self.observation_names)
        low = -np.ones(n, dtype=np.float32)
        low[: self.num_beams] = 0.0
        self.observation_space = gym.spaces.Box(low, np.ones(n, dtype=np.float32), dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self._wp_offsets = np.arange(1, W + 1, dtype=np.float64) * float(cfg["waypoint_spacing"])
        self.client = p.connect(p.GUI if cfg["gui"] else p.DIRECT)
        self.world: World | None = None
        self.machine: Machine | None = None
        self.planner: RoutePlanner | None = None
        self._scene_key: Any = None
        # Subclass hook: body id -> collision kind for bodies the subclass adds (agents).
        self._collision_kinds: dict[int, str] = {}
        self.collision_kinds_all: list[str] = list(STATIC_COLLISION_KINDS)
        self.route = None
        self._renderer = None

    # -- scene -------------------------------------------------------------------------------------
    def _ensure_scene(self, rng: np.random.Generator) -> None:
        cfg = self.config
        if cfg["scene_spec"] is not None or cfg["scene_path"] is not None:
            key = ("fixed",)
            seed = int(cfg["scene_seed"])
        else:
            seed = int(cfg["scene_seed"]) + int(rng.integers(max(int(cfg["num_scenes"]), 1)))
            key = ("generated", seed)
        if key == self._scene_key:
            return  # same scene: keep every static body, only the machine moves
        spec = load_scene(cfg, seed)
        catalog = None
        if cfg["catalog"] is not None and (cfg["collision"] == "convex" or cfg["visual_meshes"]):
            from catalogs.reader import CatalogReader
            catalog = CatalogReader(cfg["catalog"])
        self.world = World(spec, client=self.client, collision=cfg["collision"], catalog=catalog,
                           visual_meshes=bool(cfg["visual_meshes"]), physics_dt=self.dt / self.substeps)
        self.machine = Machine(self.client, self.spec_machine)
        lid = cfg["lidar"]
        self.lidar = Lidar(self.client, beams=self.num_beams, range_m=float(lid["range"]), height=float(lid["height"]),
                           start_radius=self.machine.bounding_radius + 0.05)
        self.planner = RoutePlanner(spec, self.spec_machine.half_width, margin=float(cfg["route_margin"]))
        self.kinds = dict(self.world.kinds)
        self._scene_key = key
        self._on_scene(spec)

    @property
    def scene_spec(self) -> dict[str, Any]:
        """The spec of the scene the current episode runs in."""
        assert self.world is not None, "call reset() first"
        return self.world.spec  # type: ignore[return-value]

    # -- hooks -------------------------------------------------------------------------------------
    def _on_scene(self, spec: Mapping[str, Any]) -> None:
        """Called after a new scene's world is built (subclasses add their bodies here)."""

    def _on_reset(self, rng: np.random.Generator) -> None:
        """Called after the machine is placed at the route's start (subclasses place agents here)."""

    def _on_step(self) -> None:
        """Called after the machine's physics and before sensing (subclasses move agents here)."""

    def _episode_metrics(self) -> dict[str, float]:
        """The metrics of the finished episode, from the configured measures in order."""
        metrics: dict[str, float] = {}
        for m in self.measures:
            metrics.update(m.value(self, metrics))
        return metrics

    # -- gym API -----------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Draw a scene (if several), a route and the machine's forces; place the machine at the start.

        options: {"start": [x, y], "goal": [x, y]} plans the route between given points instead of drawing it.
        """
        super().reset(seed=seed)
        rng = self.np_random
        self._ensure_scene(rng)
        lo, hi = (float(v) for v in self.config["route_length"])
        if options and ("start" in options or "goal" in options):
            if not ("start" in options and "goal" in options):
                raise ValueError("reset options need both 'start' and 'goal' ([x, y] each), or neither")
            self.route = self.planner.plan(options["start"], options["goal"])
        else:
            self.route = self.planner.sample(rng, lo, hi)
        start = self.route.start
        yaw = self.route.heading_at(0.0)
        m = self.machine
        # Park the machine far away so the height probe sees the surface, not the machine itself.
        p.resetBasePositionAndOrientation(m.body, [0, 0, -50], [0, 0, 0, 1], physicsClientId=self.client)
        # With the machine away from everything, Bullet drops its cached contacts (warm-start impulses):
        # an episode then does not depend on the episodes before it.
        p.performCollisionDetection(physicsClientId=self.client)
        z = self.world.surface_height(float(start[0]), float(start[1]))
        m.reset(float(start[0]), float(start[1]), z, yaw, rng)
        self.steps = 0
        self.progress = 0.0
        self.max_progress = 0.0
        self.lateral = 0.0
        self.path_length = 0.0
        self.cost_total = 0
        self.collision_counts: dict[str, int] = {}
        self.succeeded = False
        self.out_of_route = False
        self.last_action = np.zeros(2, dtype=np.float64)
        self.step_collisions: set[str] = set()
        self.trajectory = [(float(start[0]), float(start[1]))]
        self._on_reset(rng)
        for meas in self.measures:
            meas.reset(self)
        return self._observe(), {"route_length": self.route.length}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Advance 0.1 s (config dt): apply the action, step physics, sense, reward."""
        if self.route is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,):
            raise ValueError(f"action must hold 2 values [steering, throttle_brake], got shape {np.shape(action)}")
        if not np.isfinite(a).all():
            raise ValueError(f"action {a.tolist()} holds NaN or inf; policies must output finite values in [-1, 1]")
        a = np.clip(a, -1.0, 1.0)
        steer, throttle = float(a[0]), float(a[1])
        m, c = self.machine, self.client
        x0, y0 = m.position[0], m.position[1]
        sub_dt = self.dt / self.substeps
        hits: set[str] = set()
        for _ in range(self.substeps):
            m.command(steer, throttle, sub_dt)
            p.stepSimulation(physicsClientId=c)
            m.sync()
            self._contacts(hits)
        self._on_step()
        x, y = m.position[0], m.position[1]
        self.path_length += math.hypot(x - x0, y - y0)
        self.trajectory.append((x, y))
        s, lat = self.route.project(x, y, self.progress)
        progress = s - self.progress
        self.progress, self.lateral = s, lat
        self.max_progress = max(self.max_progress, s)
        self.steps += 1
        collided = bool(hits)
        self.step_collisions = hits
        for k in hits:
            self.collision_counts[k] = self.collision_counts.get(k, 0) + 1
        self.cost_total += int(collided)
        cfg = self.config
        self.succeeded = self.max_progress >= cfg["success_completion"] * self.route.length
        self.out_of_route = (not self.succeeded) and (
            abs(lat) > cfg["out_of_route_distance"]
            or (cfg["terminate_off_walkable"] and self.planner.grid.label_at(x, y) == 0)
        )
        d_steer = steer - self.last_action[0]
        reward = self.reward_fn(progress, lat, d_steer, m.speed, collided, self.succeeded, self.out_of_route)
        self.last_action = a
        terminated = self.succeeded or self.out_of_route
        truncated = (not terminated) and self.steps >= cfg["horizon"]
        for meas in self.measures:
            meas.update(self)
        obs = self._observe()
        info: dict[str, Any] = {"cost": float(collided), "route_completion": min(self.max_progress / self.route.length, 1.0),
                                "collision_kinds": sorted(hits), "out_of_route": self.out_of_route}
        if terminated or truncated:
            metrics = self._episode_metrics()
            info.update(metrics)
            info["metrics"] = metrics
            info["is_success"] = self.succeeded
        return obs, reward, terminated, truncated, info

    def _contacts(self, hits: set[str]) -> None:
        kinds, extra = self.kinds, self._collision_kinds
        for cp in p.getContactPoints(bodyA=self.machine.body, physicsClientId=self.client):
            if cp[8] > 1e-3:
                continue  # within the contact margin but not touching
            body = cp[2]
            kind = extra.get(body) or kinds.get(body, "object")
            if kind in SURFACE_KINDS:
                if abs(cp[7][2]) < WALL_NZ:
                    hits.add("curb")
            else:
                hits.add(kind)

    def _observe(self) -> np.ndarray:
        m, route = self.machine, self.route
        x, y, z = m.position
        yaw = m.yaw
        lidar = self.lidar.scan(x, y, z, yaw)
        spec = m.spec
        steer_norm = m.steering / spec.steer_max if spec.kind == "wheeled" and spec.steer_max > 0 else m.steering
        heading_err = _wrap(yaw - route.heading_at(self.progress))
        c, s = math.cos(yaw), math.sin(yaw)
        wp = route.point_at(self.progress + self._wp_offsets)
        dx, dy = wp[:, 0] - x, wp[:, 1] - y
        scale = 1.0 / (self._wp_offsets[-1])
        ego = np.stack([(c * dx + s * dy) * scale, (-s * dx + c * dy) * scale], 1).ravel()
        gx, gy = route.goal[0] - x, route.goal[1] - y
        bearing = math.atan2(gy, gx) - yaw
        state = [
            m.speed / spec.v_max, steer_norm, m.yaw_rate / 2.0, heading_err / math.pi,
            self.lateral / self.config["out_of_route_distance"], self.last_action[0], self.last_action[1],
        ]
        tail = [math.hypot(gx, gy) / 100.0, math.sin(bearing), math.cos(bearing)]
        obs = np.concatenate([lidar, np.asarray(state), ego, np.asarray(tail)]).astype(np.float32)
        np.clip(obs, -1.0, 1.0, out=obs)
        return obs

    def render(self) -> np.ndarray | None:
        """An RGB frame (H, W, 3) from the configured camera ('top_down' or 'chase') via TinyRenderer."""
        if self.render_mode != "rgb_array":
            return None
        from sim.render import camera_image
        r = self.config["render"]
        return camera_image(self, camera=r["camera"], width=int(r["width"]), height=int(r["height"]),
                            top_down_height=float(r["top_down_height"]))

    def close(self) -> None:
        """Disconnect from PyBullet."""
        if getattr(self, "client", None) is not None:
            try:
                p.disconnect(physicsClientId=self.client)
            except p.error:
                pass
            self.client = None
