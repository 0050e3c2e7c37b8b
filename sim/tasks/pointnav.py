"""The PointNav task: its config defaults and reward presets (an episode's scene comes from `sim.tasks.scenes`).

Two reward presets (docs/tasks.md explains each choice):
- `paper`: the MetaUrban paper's formula R = R_term + 0.5 R_disp + 1.0 R_lateral + 0.1 R_steering + 1.0 R_crash, kept
  for comparison. With it, standing still (return ~0) and leaving the route early beat honest attempts.
- `learnable` (default): progress is paid only for new ground (the largest arc length reached, so driving back
  and forth earns nothing), the lateral term is small and free within `lateral_free` of the route, a collision
  step costs less than a metre of progress, and an episode that makes no progress or stays pinned against an
  obstacle ends with the `stuck` penalty (so "stand still" and "stay pinned" are never the best plan).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from kernel.config import ConfigError, excerpt, merge_strict
from sim.camera import CAMERA_DEFAULTS, CAMERA_TABLE
from sim.metrics import POINTNAV_MEASURES
from sim.scene.dataset import SPLITS
from sim.schema import Bool, Choice, Float, Int, Pair, Pos, Rule, check_table
from sim.tasks.sensors import LIDAR_TABLE, RENDER_TABLE
from sim.tasks.termination import StepContext, StepEnd

DEFAULT_CONFIG: dict[str, Any] = {
    "preset": None,  # a TASK_PRESETS name (e.g. "metaurban12k"): its values replace these defaults
    "machine": "delivery_bot",  # a name from sim.machines.MACHINES or a dict of MachineSpec fields
    "scene": {},  # generator config passed to sim.scene.generate_scene (partial is fine)
    "split": "train",  # train | test | unseen | finetune (sim.scene.dataset.SPLITS), or None
    "scene_dir": None,  # a `curbside scenes dataset` folder: episodes draw its scenes of `split`
    "scene_seed": 0,  # first generated scene (within the split's seed range)
    "num_scenes": 1,  # episodes draw scene k in [0, num_scenes) (generated or from scene_dir)
    "scene_cache": 8,  # built worlds kept (LRU), each in its own Bullet client: a repeat costs no build
    "scene_spec": None,  # an explicit scene spec (dict) instead of the generator
    "scene_path": None,  # or a path to a scene spec JSON file
    "catalog": None,  # catalog path for the generator and for mesh collision/visuals
    "collision": "box",  # static objects: "box" from `size`, or "convex" hull of the catalog mesh
    "visual_meshes": "auto",  # catalog meshes (textured) as visual shapes; auto: with camera modalities
    "gui": False,  # PyBullet GUI instead of DIRECT
    "dt": 0.1,  # seconds per env step
    "physics_substeps": 5,  # Bullet substeps per env step (0.02 s each by default)
    "horizon": 1000,  # truncation after at most this many steps
    "horizon_min_speed": 0.5,  # m/s: the horizon is also cut to route_length / this (None: fixed horizon)
    "stl_cruise_speed": 2.5,  # m/s: STL's t_ref = geodesic / min(this, v_max); the expert's cruise speed
    "route_length": [10.0, 60.0],  # reference route length range in metres (>= 5 m)
    "route_margin": 0.25,  # extra clearance beyond the machine's half-width when planning
    "success_completion": 0.95,  # route fraction that counts as success
    "out_of_route_distance": 3.0,  # lateral offset (m) that ends the episode as out of route
    "terminate_off_walkable": True,  # leaving the walkable area (road, buildings) is out of route too
    "stuck_steps": 100,  # end the episode when the route progress grew < stuck_distance in this many steps (0: never)
    "stuck_distance": 0.5,  # metres of new progress that count as moving on
    "collision_steps": 30,  # end the episode after this many consecutive steps in contact (0: never)
    "max_episode_cost": None,  # end the episode, failed, once its cost exceeds this (PPO-ET's rule; None: never)
    "topple_angle": 60.0,  # degrees of roll or pitch that end the episode as toppled
    "cost_kinds": ["object", "building"],  # contacts that cost (the paper: objects and buildings, not curbs)
    "lidar": {
        "beams": 240,
        "range": 50.0,
        "height": 0.4,
        "encoding": "log",
        "low_beams": 60,
        "low_range": 5.0,
        "low_height": 0.08,
        # Static geometry: "grid" traces distance grids of `resolution` m (sim.raycast; ~0.1 ms for 300 rays
        # against Bullet's ~0.7 ms), "bullet" ray-tests the Bullet world; "auto" is grid with box collision, else bullet.
        "static": "auto",
        "resolution": 0.05,
    },
    "speed_scale": 5.0,  # m/s that maps to 1 in the `speed` observation (clipped)
    "num_waypoints": 10,
    "waypoint_spacing": 1.0,  # metres between the observed route waypoints
    "reward_preset": "learnable",  # "learnable" or "paper" (REWARD_PRESETS)
    "reward": {},  # overrides of the preset's terms (Reward fields)
    "measures": list(POINTNAV_MEASURES),
    "render": {"camera": "dashboard", "width": 768, "height": 384, "top_down_height": 25.0},
    "camera": CAMERA_DEFAULTS,  # the ego camera (sim.camera): modalities rgb / depth / semantic, size, fov
    "observation": "auto",  # "flat" Box, or "dict" {lidar, state, nav, camera images}; auto: dict with a camera
}


# Named route-length ranges (metres). "metaurban12k": the paper's mean episode of ~410 m (chained legs, see
# sim.route.RoutePlanner.sample).
ROUTE_LENGTHS: dict[str, list[float]] = {"short": [10.0, 60.0], "metaurban12k": [250.0, 650.0]}
# Task presets: values that replace the defaults (explicit config keys still win). "metaurban12k": the paper's
# scenes (scene preset), routes and a horizon that fits them (route length / 1 m/s; the expert needs 4 s per 10 m).
TASK_PRESETS: dict[str, dict[str, Any]] = {
    "metaurban12k": {
        "scene": {"preset": "metaurban12k"},
        "route_length": ROUTE_LENGTHS["metaurban12k"],
        "horizon": 6500,
        "horizon_min_speed": 1.0,
    },
}


def resolve_task_config(
    defaults: Mapping[str, Any],
    config: Mapping[str, Any] | None,
    presets: Mapping[str, Mapping[str, Any]] = TASK_PRESETS,
) -> dict[str, Any]:
    """`config` merged strictly over `defaults`, after the values of the preset it names (config["preset"]).

    `scene` is a partial generator config (validated by the generator): a preset's scene keys and the caller's
    are combined key by key.
    """
    if config is not None and not isinstance(config, Mapping):
        raise ConfigError(f"config must be a mapping, got {type(config).__name__}")
    cfg = dict(config or {})
    base = dict(defaults)
    name = cfg.get("preset")
    if name is not None:
        if not isinstance(name, str) or name not in presets:
            raise ConfigError(f"unknown config.preset {name!r}; valid: {', '.join(presets)} (or None)")
        base = merge_strict(base, presets[name], name=f"preset {name}")
    if isinstance(cfg.get("scene"), Mapping):
        cfg["scene"] = {**base.get("scene", {}), **cfg["scene"]}
        base["scene"] = {}
    return merge_strict(base, cfg, name="config")


@dataclass(frozen=True)
class Reward:
    """R = R_term + w_disp R_disp - w_lat max(0, |lat| - free) - w_steer |ds| v - w_crash [collision], floored or not.

    progress "route": R_disp is the change of arc length along the route (negative when going back), as in the
    paper; "max": only growth of the largest arc length reached is paid (going back costs nothing, returning
    earns nothing). R_term: `success` on success, `out_of_route` off the route, `stuck` when the episode ends for
    lack of progress or a lasting collision. floor: the dense part is floored at zero (MetaUrban's released code).
    """

    success: float = 10.0
    out_of_route: float = -5.0
    stuck: float = -5.0
    disp: float = 1.0
    progress: str = "max"
    lateral: float = 0.05
    lateral_free: float = 0.5
    steering: float = 0.05
    crash: float = 0.5
    floor: bool = False

    def __post_init__(self) -> None:
        if self.progress not in ("route", "max"):
            raise ConfigError(f"config.reward.progress must be 'route' or 'max', got {self.progress!r}")
        for k, v in asdict(self).items():
            if k not in ("progress", "floor") and not (isinstance(v, (int, float)) and abs(v) < float("inf")):
                raise ConfigError(f"config.reward.{k} must be a finite number, got {v!r}")

    def __call__(self, step: StepContext, end: StepEnd) -> float:
        """One step's reward from progress along the route, the offset, steering change and events: `batch`'s
        arithmetic in Python floats (the same IEEE doubles, in the same order) without a dozen numpy calls on
        scalars, for the env's every step (tests/sim/agents/test_socialnav_golden.py checks the two bit for bit)."""
        disp = step.new_progress if self.progress == "max" else step.progress
        over = abs(step.lateral) - self.lateral_free
        r = self.disp * disp - self.lateral * max(0.0, over) - self.steering * abs(step.d_steer) * abs(step.speed)
        if step.collided:
            r = r - self.crash
        if self.floor and 0.0 > r:
            r = 0.0
        stuck = end.failed_in_place
        if end.succeeded or end.out_of_route or stuck:
            r = r + (self.success if end.succeeded else self.out_of_route if end.out_of_route else self.stuck)
        return float(r)

    def batch(
        self,
        progress: Any,
        new_progress: Any,
        lateral: Any,
        d_steer: Any,
        speed: Any,
        collided: Any,
        succeeded: Any,
        out_of_route: Any,
        stuck: Any,
    ) -> np.ndarray:
        """The rewards of many steps at once (arrays or numbers; `sim.batched` steps many envs through it). Every
        branch is an np.where that picks what the scalar max/if would, so one step's double is the same either way."""
        disp = new_progress if self.progress == "max" else progress
        over = np.abs(lateral) - self.lateral_free
        r = (
            self.disp * disp
            - self.lateral * np.where(over > 0.0, over, 0.0)
            - self.steering * np.abs(d_steer) * np.abs(speed)
        )
        r = np.where(collided, r - self.crash, r)
        if self.floor:
            r = np.where(0.0 > r, 0.0, r)
        bonus = np.where(succeeded, self.success, np.where(out_of_route, self.out_of_route, self.stuck))
        return np.where(np.logical_or(np.logical_or(succeeded, out_of_route), stuck), r + bonus, r)


REWARD_PRESETS: dict[str, dict[str, Any]] = {
    # The MetaUrban paper: progress along the route, full lateral penalty, no stuck ending (stuck_steps and
    # collision_steps still end such episodes unless set to 0; their penalty is then 0).
    "paper": dict(
        success=5.0,
        out_of_route=-5.0,
        stuck=0.0,
        disp=0.5,
        progress="route",
        lateral=1.0,
        lateral_free=0.0,
        steering=0.1,
        crash=1.0,
        floor=False,
    ),
    "learnable": asdict(Reward()),
}


COLLISION_KINDS = ("object", "building", "curb", "agent", "vehicle")
MAX_SEED = 1_000_000  # splits start 1,000,000 seeds apart: scene_seed + num_scenes stays below that
# Overrides of a reward preset's terms (Reward fields); weights are bounded so one step cannot dwarf a return.
REWARD_TABLE: dict[str, Rule] = {
    **{
        k: Float(-1e6, 1e6)
        for k in ("success", "out_of_route", "stuck", "disp", "lateral", "lateral_free", "steering", "crash")
    },
    "progress": Choice("route", "max"),
    "floor": Bool(),
}
# Every key of DEFAULT_CONFIG: its type and valid range (tests/sim/test_bad_input.py checks that none is missing).
# Bounds are generous for research use but finite: a NaN, inf or absurd value fails here, at construction.
CONFIG_TABLE: dict[str, Any] = {
    "preset": Choice(*TASK_PRESETS, none=True),
    "machine": Rule(
        "any"
    ),  # a name or a dict of MachineSpec fields: checked by sim.machines.machine_spec + check_machine
    "scene": Rule("mapping", hint="a partial scene generator config, see sim.scene.DEFAULT_CONFIG"),
    "split": Choice(*SPLITS, none=True),
    "scene_dir": Rule("path", none=True),
    "scene_seed": Int(0, MAX_SEED - 1),
    "num_scenes": Int(1, MAX_SEED, none=True),
    "scene_cache": Int(1, 1024),
    "scene_spec": Rule("mapping", none=True),
    "scene_path": Rule("path", none=True),
    "catalog": Rule("file", none=True, hint="build one with `curbside catalog build --catalog PATH`"),
    "collision": Choice("box", "convex"),
    "visual_meshes": Choice("auto", True, False),
    "gui": Bool(),
    "dt": Pos(1.0, hint="seconds per env step"),
    "physics_substeps": Int(1, 100),
    "horizon": Int(1, 10_000_000),
    "horizon_min_speed": Pos(100.0, none=True),
    "stl_cruise_speed": Pos(50.0, hint="m/s"),
    "route_length": Pair(Float(5.0, 100_000.0), hint="metres"),
    "route_margin": Float(0.0, 5.0),
    "success_completion": Float(0.0, 1.0, lo_open=True),
    "out_of_route_distance": Pos(1000.0),
    "terminate_off_walkable": Bool(),
    "stuck_steps": Int(0, 10_000_000),
    "stuck_distance": Pos(1000.0),
    "collision_steps": Int(0, 10_000_000),
    "max_episode_cost": Float(0.0, 1e9, none=True),
    "topple_angle": Float(1.0, 180.0, hint="degrees"),
    "cost_kinds": Rule("list", choices=COLLISION_KINDS),
    "lidar": LIDAR_TABLE,
    "speed_scale": Pos(100.0),
    "num_waypoints": Int(1, 1000),
    "waypoint_spacing": Pos(100.0),
    "reward_preset": Choice(*REWARD_PRESETS),
    "reward": REWARD_TABLE,
    "measures": Rule("list", item=Rule("str")),
    "render": RENDER_TABLE,
    "camera": CAMERA_TABLE,
    "observation": Choice("auto", "flat", "dict"),
}
# Numeric MachineSpec fields of a custom machine (a dict): finite and within these bounds.
MACHINE_TABLE: dict[str, Rule] = {
    "v_max_kmh": Pos(200.0),
    "steer_max_deg": Float(0.0, 89.0),
    "friction": Float(0.0, 5.0),
    "wheelbase": Pos(20.0),
    "wheel_radius": Pos(5.0),
    "wheel_width": Pos(5.0),
    "mass": Pos(100_000.0),
    "length": Pos(20.0),
    "width": Pos(20.0),
    "height": Pos(20.0),
    "drag_area": Float(0.0, 100.0),
    "rolling_resistance": Float(0.0, 1.0),
    "accel_max": Float(0.0, 100.0),
    "yaw_rate_max": Float(0.0, 100.0),
    "engine_force": Pair(Float(0.0, 1e6)),
    "brake_force": Pair(Float(0.0, 1e6)),
}


def check_machine(machine: Any, name: str = "config.machine") -> None:
    """Check a custom machine dict's numbers (finite, in range), its `base` dict's too, before sim.machines builds
    its spec."""
    if not isinstance(machine, Mapping):
        return  # a name (or a wrong type): machine_spec names the valid machines
    for key, value in machine.items():
        if key == "base" and isinstance(value, Mapping):
            check_machine(value, f"{name}.base")
            continue
        if key == "color" and not (
            isinstance(value, (list, tuple)) and len(value) == 4 and all(_number(c) and 0.0 <= c <= 1.0 for c in value)
        ):
            raise ConfigError(f"{name}.color must be [r, g, b, a], each in [0, 1], got {excerpt(value)}")
        rule = MACHINE_TABLE.get(key)
        if rule is not None and rule.kind == "pair" and _number(value):
            value = [value, value]  # a single force means a fixed force (machine_spec accepts it)
        if rule is not None:
            rule.check(value, f"{name}.{key}")


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def check_config(
    cfg: Mapping[str, Any], table: Mapping[str, Any] | None = None, defaults: Mapping[str, Any] | None = None
) -> None:
    """Validate every value of a task config (types, finiteness, ranges); ConfigError names the key and the range."""
    check_table(
        cfg,
        CONFIG_TABLE if table is None else table,
        name="config",
        defaults=DEFAULT_CONFIG if defaults is None else defaults,
    )
    check_machine(cfg["machine"])
    if cfg["camera"]["near"] >= cfg["camera"]["far"]:
        raise ConfigError(
            f"config.camera.near ({cfg['camera']['near']}) must be below config.camera.far ({cfg['camera']['far']})"
        )
    if cfg["lidar"]["static"] == "grid" and cfg["collision"] != "box":
        raise ConfigError(
            "config.lidar.static 'grid' traces the objects' boxes, but config.collision is "
            f"{cfg['collision']!r}; use lidar.static 'bullet' (or 'auto') to ray-test the mesh hulls"
        )


def static_lidar(cfg: Mapping[str, Any]) -> str:
    """Which backend traces the static scene: "grid" or "bullet" (`lidar.static`, "auto" resolved by `collision`)."""
    choice = cfg["lidar"]["static"]
    if choice == "auto":
        return "grid" if cfg["collision"] == "box" else "bullet"
    return choice


def make_reward(preset: str, overrides: Mapping[str, Any] | None) -> Reward:
    """The Reward of a named preset with some of its terms overridden (unknown terms raise)."""
    if preset not in REWARD_PRESETS:
        raise ConfigError(f"unknown reward_preset {preset!r}; valid: {', '.join(REWARD_PRESETS)}")
    return Reward(**merge_strict(REWARD_PRESETS[preset], overrides, name="config.reward"))
