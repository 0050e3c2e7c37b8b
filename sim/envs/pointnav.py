"""PointNav: drive a mobile machine along a reference route to a goal in a static urban scene."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from kernel.config import ConfigError
from kernel.quiet import pybullet as p
from sim.envs.episode import Episode
from sim.envs.managers import EgoPose, Manager, ResetContext, SceneContext, TickContext
from sim.envs.observation import EgoObservation, Observation
from sim.envs.reset_options import check_reset_options
from sim.envs.worlds import SceneCache, SceneSlot, SceneSource, build_slot, trim_heap
from sim.machines import Machine, machine_spec
from sim.metrics import EpisodeView, make_measures
from sim.route import ROUTE_REDRAWS, Route, RouteError, RoutePlanner
from sim.scene.scene import Scene
from sim.sensors import GridLidar, Lidar
from sim.tasks.cost import MOVING_KINDS, STATIC_KINDS, CostRule
from sim.tasks.pointnav import (
    CONFIG_TABLE,
    DEFAULT_CONFIG,
    TASK_PRESETS,
    check_config,
    make_reward,
    resolve_task_config,
)
from sim.tasks.sensors import check_lidar_reach
from sim.tasks.termination import StepContext, Termination
from sim.viewer import close_window, render_frame, served_render_modes
from sim.world import World, touching

STATIC_COLLISION_KINDS = (
    "object",
    "building",
    "curb",
)  # with "agent" and "vehicle": sim.tasks.pointnav.COLLISION_KINDS


class PointNavEnv(gym.Env):
    """Drive a machine (delivery robot, wheelchair, mobility scooter, legged robot) along a sidewalk route.

    ## Action space
    `Box(-1, 1, (2,), float32)`: `[steering, throttle_brake]`. Steering scales the machine's steering limit
    (wheeled) or yaw-rate limit (legged); positive throttle drives the engine, negative brakes (wheeled
    machines do not reverse). Out-of-range values are clipped to [-1, 1]; NaN or inf raise ValueError.

    ## Observation space
    `Box(float32)` of `B + L + 6 + 2 W + 3` values (B LiDAR beams, L low beams, W waypoints; 329 by default). With
    `camera.modalities` (or `observation: dict`) a `Dict`: `lidar` (the first B + L values), `state` (the next 6),
    `nav` (the rest), and the camera's `rgb` (H, W, 3) uint8, `depth` (H, W, 1) metres, `semantic` (H, W) class
    ids of sim.camera.SEMANTIC_CLASSES (docs/cameras.md).

    | index | name | meaning |
    |---|---|---|
    | 0 .. B-1 | `lidar_<k>` | beam k at `lidar.height` (0.4 m): log(1 + d) / log(1 + range) (`encoding` "log") or d / range; 1 = no hit; beam 0 ahead, counter-clockwise |
    | B .. B+L-1 | `low_<k>` | beam k of the low scan at `low_height` (0.08 m, sees curbs and clutter): d / low_range |
    | B+L | `speed` | speed / `speed_scale` (5 m/s), clipped to [-1, 1] |
    | B+L+1 | `yaw_rate` | yaw rate / 2 rad/s, clipped |
    | B+L+2 | `heading_error` | (heading - route heading) / pi |
    | B+L+3 | `lateral_offset` | signed offset from the route (left +) / out_of_route_distance, clipped |
    | B+L+4, B+L+5 | `last_steering`, `last_throttle` | the previous (clipped) action (= the steering state) |
    | B+L+6 .. B+L+5+2W | `wp<i>_x`, `wp<i>_y` | next W route waypoints (spacing `waypoint_spacing`) in the ego frame / (W spacing) |
    | B+L+6+2W | `goal_distance` | log(1 + straight-line distance to the goal) / log(1 + 500 m) |
    | B+L+7+2W, B+L+8+2W | `goal_heading_sin`, `goal_heading_cos` | bearing of the goal in the ego frame |

    ## Rewards
    `reward_preset` "learnable" (default) or "paper" (the MetaUrban paper's R = R_term + 0.5 R_disp + 1.0 R_lateral +
    0.1 R_steering + 1.0 R_crash), terms overridable in `reward`; see sim.tasks.pointnav.Reward and
    docs/tasks.md for why the default differs.

    ## Episode end
    Terminated on success (route completion >= 0.95), out of route (|lateral offset| > `out_of_route_distance`, or
    the centre off the walkable area; only with `out_of_route_ends`), stuck (< `stuck_distance` of new progress in `stuck_steps` steps, or
    `collision_steps` steps in contact), toppled, or cost past `max_episode_cost`. Truncated at the horizon:
    min(`horizon`, route length / `horizon_min_speed` / dt). `info["cost"]` is the step's cost under `cost_rule`
    (sim.tasks.cost): 1 on a step in contact with a `cost_kinds` body ("contact_steps"), or MetaUrban's rule
    ("metaurban": an object at its first contact only), else 0. At episode end `info` also holds the metrics (`success`, `spl`, `route_completion`,
    `episode_cost`, `collisions_<kind>`, `path_length`, `time`, ...) and `info["metrics"]` (`cost`: the total).

    ## Managers
    `managers` (sim.envs.managers; none here, SocialNav's crowd, traffic and bodies): the env calls each one's
    hooks in list order when a world is built, left or re-entered, at reset and before and after the physics of
    every step; see docs/simulator.md.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    default_config: dict[str, Any] = DEFAULT_CONFIG
    presets: dict[str, dict[str, Any]] = TASK_PRESETS
    config_table: dict[str, Any] = CONFIG_TABLE  # (key -> type, range) of every config key; subclasses extend it
    has_agents = False  # cohabitants (SocialNav): measures that need them are refused without

    def __init__(self, config: Mapping[str, Any] | None = None, render_mode: str | None = None) -> None:
        self.config = resolve_task_config(self.default_config, config, self.presets)
        cfg = self.config
        # This machine's modes (check_env probes each): "human" only where a window can open.
        self.metadata = {**self.metadata, "render_modes": served_render_modes(render_mode)}
        self.render_mode = render_mode
        check_config(cfg, self.config_table, self.default_config)  # every value, before anything is built on it
        self.spec_machine = machine_spec(cfg["machine"])
        check_lidar_reach(cfg["lidar"], self.spec_machine.length, self.spec_machine.width)
        self.reward_fn = make_reward(cfg["reward_preset"], cfg["reward"])
        self.dt = float(cfg["dt"])
        self.substeps = int(cfg["physics_substeps"])
        self.cost_kinds = frozenset(cfg["cost_kinds"])
        self.cost_rule = CostRule.from_config(cfg)
        self._moving_cost_kinds = self.cost_kinds & frozenset(MOVING_KINDS)
        self._static_cost_kinds = self.cost_kinds & frozenset(STATIC_KINDS)
        self.scenes = SceneSource(cfg)  # parses and checks a given scene_spec / scene_path now
        self.measures = make_measures(list(cfg["measures"]), agents=self.has_agents)
        self.observation = EgoObservation(cfg)
        self.observation_names = self.observation.names
        self.observation_space = self.observation.space
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        if cfg["gui"] and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            # PyBullet's GUI connect waits forever for a display that is not there.
            raise ConfigError(
                "config.gui needs a display, and DISPLAY is not set; use gui: false (render() draws "
                "images without one) or run under a desktop or xvfb-run"
            )
        self.client = p.connect(p.GUI if cfg["gui"] else p.DIRECT)
        self.cache: SceneCache | None = SceneCache(cfg["scene_cache"], self.client, bool(cfg["gui"]))  # None: closed
        self.slot: SceneSlot | None = None
        self.world: World | None = None
        self.machine: Machine | None = None
        self.planner: RoutePlanner | None = None
        # Body id -> collision kind of the bodies the managers add (agents, vehicles): the current world's table.
        self._collision_kinds: dict[int, str] = {}
        self.collision_kinds_all: list[str] = list(STATIC_COLLISION_KINDS)
        self.managers: list[Manager[Any]] = []  # called in this order by every hook (sim.envs.managers)
        self.route: Route | None = None  # None: no episode to step (no reset yet, or the last one failed)
        self._reference_length: float | None = None  # the episode's SPL geodesic, planned on first use
        self.scene_steps_left = 0  # steps this env may still take in its scene before a reset draws another

    # -- scene -------------------------------------------------------------------------------------
    def _ensure_scene(self, rng: np.random.Generator, redraw: bool) -> None:
        """Put the env in its episode's scene: the current one while its `scene_steps` last (and no `redraw` is
        asked), else a new draw from the scene source."""
        if self.slot is not None and self.scene_steps_left > 0 and not redraw:
            return
        key, load = self.scenes.draw(rng)
        self.scene_steps_left = int(self.config["scene_steps"])
        if self.slot is not None and key == self.slot.key:
            return  # same scene: keep every static body, only the machine moves
        if self.slot is not None:
            self.slot.manager_states = [mg.leave_scene() for mg in self.managers]
        cache = self._check_open()
        slot = cache.get(key)
        if slot is None:
            slot = cache.new_slot(key)
            try:
                scene = load()
                build_slot(slot, scene, self.config, self.spec_machine)
                self._use(slot)
                ctx = SceneContext(scene, slot.client, self._lidars(), slot.collision_kinds)
                for mg in self.managers:
                    mg.on_scene(ctx)
                trim_heap()  # the scene it replaced is freed now
            except BaseException:
                cache.discard(key)
                self.slot = self.route = None
                raise
        else:
            self._use(slot)
            for mg, state in zip(self.managers, slot.manager_states, strict=True):
                mg.enter_scene(state)

    def _use(self, slot: SceneSlot) -> None:
        self.slot = slot
        self.client, self.world, self.machine = slot.client, slot.world, slot.machine
        self.lidar, self.low_lidar, self.planner, self.camera = slot.lidar, slot.low_lidar, slot.planner, slot.camera
        self.kinds = dict(slot.world.kinds)
        self._collision_kinds = slot.collision_kinds

    def _lidars(self) -> tuple[Lidar | GridLidar, ...]:
        return tuple(lidar for lidar in (self.lidar, self.low_lidar) if lidar is not None)

    @property
    def scene(self) -> Scene:
        """The scene (parsed once, when it was loaded) the current episode runs in."""
        self._check_open()
        if self.slot is None or self.slot.scene is None:
            raise RuntimeError("the env has no scene yet: call reset() first")
        return self.slot.scene

    @property
    def scene_spec(self) -> dict[str, Any]:
        """The raw spec dict of the current scene (`scene.spec`; read it, never write it)."""
        return self.scene.spec  # type: ignore[return-value]

    # -- managers and measures --------------------------------------------------------------------
    def _ego(self) -> EgoPose:
        """The machine as the managers see it."""
        machine = self.machine
        assert machine is not None  # the managers run once reset has placed the machine
        x, y, _ = machine.position
        return EgoPose(float(x), float(y), machine.yaw, machine.speed, machine.spec.length, machine.spec.width)

    def _episode_metrics(self) -> dict[str, float]:
        """The metrics of the finished episode, from the configured measures in order."""
        metrics: dict[str, float] = {}
        for measure in self.measures:
            metrics.update(measure.value(self.measure_view, metrics))
        return metrics

    def _measure_view(self) -> EpisodeView:
        """What the measures read of the episode just reset, with the fields the managers supply."""
        route, machine = self.route, self.machine
        assert route is not None and machine is not None  # reset calls this once it has placed the machine on a route
        fields: dict[str, Any] = {}
        for mg in self.managers:
            fields.update(mg.view_fields())
        return EpisodeView(
            episode=self.episode,
            route_length=float(route.length),
            dt=self.dt,
            cruise_speed=min(float(self.config["stl_cruise_speed"]), machine.spec.v_max),
            collision_kinds=tuple(self.collision_kinds_all),
            reference_length=self.reference_length,
            **fields,
        )

    def reference_length(self) -> float:
        """l of SPL and STL: the geodesic from the start to the route point where success is reached (cached)."""
        if self._reference_length is None:
            route, planner = self.route, self.planner
            if route is None or planner is None:
                raise RuntimeError("the env has no route yet: call reset() first")
            upto = float(self.config["success_completion"]) * route.length
            self._reference_length = planner.geodesic_length(route, upto)
        return self._reference_length

    # -- gym API -----------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Observation, dict]:
        """Draw a scene (if several), a route and the machine's forces; place the machine at the start.

        options: {"start": [x, y], "goal": [x, y]} plans the route between given points instead of drawing it.
        """
        self._check_open()
        route_points = check_reset_options(options)
        self.route = None  # a reset that fails leaves no episode to step
        super().reset(seed=seed)
        rng = self.np_random
        lo, hi = (float(bound) for bound in self.config["route_length"])
        for attempt in range(ROUTE_REDRAWS):
            self._ensure_scene(rng, redraw=attempt > 0)
            planner = self.planner
            assert planner is not None  # _ensure_scene has put the env in a built scene slot
            try:
                self.route = planner.plan(*route_points) if route_points else planner.sample(rng, lo, hi)
                break
            except RouteError:
                if route_points or attempt == ROUTE_REDRAWS - 1:
                    raise
        route, machine, world = self.route, self.machine, self.world
        assert route is not None and machine is not None and world is not None  # the last redraw's RouteError is raised
        start = route.start
        yaw = route.heading_at(0.0)
        # Park the machine (and the managers' bodies) far away so the height probe sees the surface only.
        p.resetBasePositionAndOrientation(machine.body, [0, 0, -50], [0, 0, 0, 1], physicsClientId=self.client)
        for mg in self.managers:
            mg.park()
        # With the machine away from everything, Bullet drops its cached contacts (warm-start impulses):
        # an episode then does not depend on the episodes before it.
        p.performCollisionDetection(physicsClientId=self.client)
        z = world.surface_height(float(start[0]), float(start[1]))
        machine.reset(float(start[0]), float(start[1]), z, yaw, rng)
        cfg = self.config
        horizon = int(cfg["horizon"])
        if cfg["horizon_min_speed"] is not None:
            horizon = min(horizon, max(int(math.ceil(route.length / cfg["horizon_min_speed"] / self.dt)), 1))
        self.episode = Episode(horizon, [(float(start[0]), float(start[1]))])
        self.termination = Termination.from_config(cfg)
        self._reference_length = None
        if self.managers:
            reset_ctx = ResetContext(self.scene, rng, self._ego(), route)
            for mg in self.managers:
                mg.reset(reset_ctx)
        self.measure_view = self._measure_view()
        for meas in self.measures:
            meas.reset(self.measure_view)
        return self._observe(), {"route_length": route.length, "horizon": horizon}

    def step(self, action: Any) -> tuple[Observation, float, bool, bool, dict]:
        """Advance 0.1 s (config dt): apply the action, step physics, sense, reward."""
        self._check_open()
        if self.route is None:
            raise RuntimeError("call reset() before step() (no reset yet, or the last one failed)")
        if np.iscomplexobj(action):
            raise ValueError("the action holds complex numbers; pass [steering, throttle_brake] as real numbers")
        act = np.asarray(action, dtype=np.float64).reshape(-1)
        if act.shape != (2,):
            raise ValueError(f"action must hold 2 values [steering, throttle_brake], got shape {np.shape(action)}")
        if not np.isfinite(act).all():
            raise ValueError(f"action {act.tolist()} holds NaN or inf; policies must output finite values in [-1, 1]")
        act = np.clip(act, -1.0, 1.0)
        steer, throttle = float(act[0]), float(act[1])
        machine, client, planner = self.machine, self.client, self.planner
        assert machine is not None and planner is not None  # placed with the route by the reset
        x0, y0 = machine.position[0], machine.position[1]
        if self.managers:  # PointNav has none: its steps build no contexts
            tick = TickContext(self.dt, self._ego(), (steer, throttle))
            for mg in self.managers:
                mg.before_step(tick)
        hits: set[str] = set()
        touched: set[int] | None = set() if self.cost_rule.once else None
        for _ in range(self.substeps):
            machine.command(steer, throttle, self.dt / self.substeps)
            p.stepSimulation(physicsClientId=client)
            machine.sync()
            self._contacts(hits, touched)
        if self.managers:
            tick = TickContext(self.dt, self._ego(), (steer, throttle))
            for mg in self.managers:
                mg.after_step(tick)
        x, y = machine.position[0], machine.position[1]
        ep = self.episode
        s, lat = self.route.locate(x, y, ep.progress)
        new_static = False
        if touched:
            kind_of = lambda b: self._collision_kinds.get(b) or self.kinds.get(b, "object")  # noqa: E731 (touching's)
            new = {b for b in touched - ep.charged if kind_of(b) in self._static_cost_kinds}
            ep.charged |= new
            new_static = bool(new)
        collided = bool(
            self.cost_rule(bool(hits & self.cost_kinds), new_static, bool(hits & self._moving_cost_kinds), lat)
        )
        progress, new_progress = ep.advance((x0, y0), (x, y), s, lat, hits, collided)
        self.scene_steps_left -= 1
        step = StepContext(
            ep.steps,
            progress,
            new_progress,
            ep.max_progress,
            self.route.length,
            lat,
            steer - ep.last_action[0],
            machine.speed,
            max(abs(machine.roll), abs(machine.pitch)),
            collided,
            bool(hits),
            ep.cost_total,
            lambda: planner.grid.label_at(x, y) != 0,
            "building" in hits,
            steer,
            abs(machine.speed) / machine.spec.v_max,
        )
        end = self.termination(step)
        ep.succeeded, ep.out_of_route, ep.stuck = end.succeeded, end.out_of_route, end.stuck
        ep.toppled, ep.cost_exceeded, ep.crashed = end.toppled, end.cost_exceeded, end.crashed
        reward = self.reward_fn(step, end)
        ep.last_action = act
        terminated = end.terminated
        truncated = (not terminated) and ep.steps >= ep.horizon
        for meas in self.measures:
            meas.update(self.measure_view)
        obs = self._observe()
        info: dict[str, Any] = ep.step_info(collided, hits, self.route.length)
        if terminated or truncated:
            metrics = self._episode_metrics()
            info.update(metrics)
            info["metrics"] = metrics
            # The per-step cost stays 0/1 on the last step too; the episode's total has its own key.
            info["episode_cost"] = metrics.get("cost", float(ep.cost_total))
            info["cost"] = float(collided)
            info["is_success"] = ep.succeeded
        return obs, reward, terminated, truncated, info

    def _contacts(self, hits: set[str], bodies: set[int] | None = None) -> None:
        machine = self.machine
        assert machine is not None  # step runs only after a reset placed the machine
        touching(self.client, machine.body, self.kinds, self._collision_kinds, hits, bodies)

    def _observe(self) -> Observation:
        ep = self.episode
        obs = self.observation(
            self.machine,
            self.route,
            ep.progress,
            ep.lateral,
            ep.last_action,
            self.lidar,
            self.low_lidar,
            self.camera,
            self._collision_kinds,
        )
        if self.render_mode == "human":
            self.render()
        return obs

    def render(self) -> np.ndarray | None:
        """An RGB frame (H, W, 3) of `render.camera` (sim.viewer): "dashboard" (chase view, map, camera panels,
        metrics), "top_down" or "chase"; in "human" mode it goes to a pygame window instead."""
        self._check_open()
        if self.machine is None:
            raise RuntimeError("call reset() before render(): there is no scene to draw yet")
        return render_frame(self)

    def _check_open(self) -> SceneCache:
        """The scene cache of the open env; RuntimeError once it is closed."""
        if self.cache is None:
            raise RuntimeError("the env is closed; make a new one (gymnasium.make) to run more episodes")
        return self.cache

    def close(self) -> None:
        """Close the viewer window and disconnect every Bullet client of the scene cache."""
        close_window(self)
        cache = getattr(self, "cache", None)
        if cache is not None:
            cache.close()
            self.cache, self.client = None, None
