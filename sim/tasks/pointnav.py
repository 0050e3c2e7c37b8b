"""The PointNav task: its config defaults and reward presets (an episode's scene comes from `sim.tasks.scene_loader`).

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
from sim.metrics import POINTNAV_MEASURES
from sim.scene.dataset import SPLITS
from sim.schema import (
    Bool,
    Choice,
    Float,
    Int,
    Key,
    Pair,
    Pos,
    Rule,
    Table,
    check_table,
    dataclass_keys,
    defaults_of,
    key_field,
    table_of,
)
from sim.tasks.cost import COST_RULES, CostRule
from sim.tasks.sensors import CAMERA_KEYS, LIDAR_KEYS, RENDER_KEYS, check_clipping_planes
from sim.tasks.termination import StepContext, StepEnd

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


_WEIGHT = Float(-1e6, 1e6)


@dataclass(frozen=True)
class Reward:
    """R = R_term + w_disp R_disp - w_lat max(0, |lat| - free) - w_steer |ds| v - w_crash [collision], floored or not.

    progress "route": R_disp is the change of arc length along the route (negative when going back), as in the
    paper; "max": only growth of the largest arc length reached is paid (going back costs nothing, returning
    earns nothing). R_term: `success` on success, `out_of_route` off the route, `stuck` when the episode ends for
    lack of progress or a lasting collision. floor: the dense part is floored at zero (MetaUrban's released code).
    """

    # Weights are bounded so that one step cannot dwarf a return.
    success: float = key_field(10.0, _WEIGHT, "R_term of a successful episode")
    out_of_route: float = key_field(-5.0, _WEIGHT, "R_term of an episode that ends off the route")
    stuck: float = key_field(
        -5.0, _WEIGHT, "R_term of an episode that ends for lack of progress or a lasting collision"
    )
    disp: float = key_field(1.0, _WEIGHT, "w_disp: the weight of the progress term R_disp")
    progress: str = key_field("max", Choice("route", "max"), '"route": R_disp is arc length gained; "max": new ground')
    lateral: float = key_field(0.05, _WEIGHT, "w_lat: the cost per metre of lateral offset beyond lateral_free")
    lateral_free: float = key_field(0.5, _WEIGHT, "metres of lateral offset from the route that cost nothing")
    steering: float = key_field(0.05, _WEIGHT, "w_steer: the cost of |steering change| x speed")
    crash: float = key_field(0.5, _WEIGHT, "w_crash: the cost of a step in collision")
    floor: bool = key_field(False, Bool(), "floor the dense part of each step's reward at zero")
    speed: float = key_field(0.0, _WEIGHT, "w_speed: the reward of speed / top speed a step (MetaUrban's speed_reward)")
    steering_range: float = key_field(
        0.0, _WEIGHT, "w_range: the cost of |steering| beyond 1 / speed (MetaUrban's steering_range_penalty)"
    )
    replace: bool = key_field(
        False, Bool(), "a collision's and an episode end's terms replace the step's reward instead of adding to it"
    )

    def __post_init__(self) -> None:
        check_table(asdict(self), REWARD_TABLE, name="config.reward")

    def __call__(self, step: StepContext, end: StepEnd) -> float:
        """One step's reward from progress along the route, the offset, steering change and events: `batch`'s
        arithmetic in Python floats (the same IEEE doubles, in the same order) without a dozen numpy calls on
        scalars, for the env's every step (tests/sim/agents/test_socialnav_golden.py checks the two bit for bit)."""
        disp = step.new_progress if self.progress == "max" else step.progress
        over = abs(step.lateral) - self.lateral_free
        reward = self.disp * disp - self.lateral * max(0.0, over) - self.steering * abs(step.d_steer) * abs(step.speed)
        if self.speed:
            reward = reward + self.speed * step.speed_fraction
        if self.steering_range:
            reward = reward + self.steering_range * min(1.0 / max(step.speed, 1e-2) - abs(step.steer), 0.0)
        stuck = end.failed_in_place
        bonus = self.success if end.succeeded else self.out_of_route if end.out_of_route else self.stuck
        if self.replace:  # MetaUrban's order: the floored dense part, then a crash, then the episode's end
            if self.floor and 0.0 > reward:
                reward = 0.0
            if step.collided:
                reward = -self.crash
            return float(bonus if end.succeeded or end.out_of_route or stuck else reward)
        if step.collided:
            reward = reward - self.crash
        if self.floor and 0.0 > reward:
            reward = 0.0
        if end.succeeded or end.out_of_route or stuck:
            reward = reward + bonus
        return float(reward)

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
        steer: Any = 0.0,
        speed_fraction: Any = 0.0,
    ) -> np.ndarray:
        """The rewards of many steps at once (arrays or numbers; `sim.batched` steps many envs through it). Every
        branch is an np.where that picks what the scalar max/if would, so one step's double is the same either way."""
        disp = new_progress if self.progress == "max" else progress
        over = np.abs(lateral) - self.lateral_free
        reward = (
            self.disp * disp
            - self.lateral * np.where(over > 0.0, over, 0.0)
            - self.steering * np.abs(d_steer) * np.abs(speed)
        )
        if self.speed:
            reward = reward + self.speed * speed_fraction
        if self.steering_range:
            gap = 1.0 / np.maximum(speed, 1e-2) - np.abs(steer)
            reward = reward + self.steering_range * np.where(gap < 0.0, gap, 0.0)
        bonus = np.where(succeeded, self.success, np.where(out_of_route, self.out_of_route, self.stuck))
        ended = np.logical_or(np.logical_or(succeeded, out_of_route), stuck)
        if self.replace:
            if self.floor:
                reward = np.where(0.0 > reward, 0.0, reward)
            reward = np.where(collided, -self.crash, reward)
            return np.where(ended, bonus, reward)
        reward = np.where(collided, reward - self.crash, reward)
        if self.floor:
            reward = np.where(0.0 > reward, 0.0, reward)
        return np.where(ended, reward + bonus, reward)


# The Keys of the Reward fields; a config's `reward` overrides some of a preset's terms.
REWARD_KEYS: dict[str, Key] = dataclass_keys(Reward)
REWARD_TABLE: dict[str, Rule | Table] = table_of(REWARD_KEYS)
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
    # MetaUrban's released env and PointNav script (envs/sidewalk_static_env.py reward_function and
    # RL/PointNav/train_ppo.py at commit 6b8ff9a): 2 a metre along the route, 2 x |lateral| / max_lateral_dist (5 m),
    # steering beyond 1 / speed at 2, 0.5 x speed / top speed, floored at zero; a crash makes the step -2, success +8
    # and leaving the route -3. Its crash is the cost rule's charge (an object at its first contact; buildings, which
    # its static env also penalises, are left out: they are not charged).
    "metaurban": dict(
        success=8.0,
        out_of_route=-3.0,
        stuck=0.0,
        disp=2.0,
        progress="route",
        lateral=2.0 / 5.0,
        lateral_free=0.0,
        steering=0.0,
        crash=2.0,
        floor=True,
        speed=0.5,
        steering_range=2.0,
        replace=True,
    ),
}


COLLISION_KINDS = ("object", "building", "curb", "agent", "vehicle")
MAX_SEED = 1_000_000  # splits start 1,000,000 seeds apart: scene_seed + num_scenes stays below that
# PointNav's config: every key's default, its type and valid range, and what it means. Bounds are generous for
# research use but finite: a NaN, inf or absurd value fails at construction.
CONFIG_KEYS: dict[str, Key | dict[str, Key]] = {
    "preset": Key(
        None,
        Choice(*TASK_PRESETS, none=True),
        'a TASK_PRESETS name (e.g. "metaurban12k"): its values replace these defaults',
    ),
    # machine_spec and check_machine check a name or a dict of MachineSpec fields.
    "machine": Key("delivery_bot", Rule("any"), "a name from sim.machines.MACHINES or a dict of MachineSpec fields"),
    "scene": Key(
        {},
        Rule("mapping", hint="a partial scene generator config, see sim.scene.DEFAULT_CONFIG"),
        "generator config passed to sim.scene.generate_scene (partial is fine)",
    ),
    "split": Key(
        "train", Choice(*SPLITS, none=True), "train | test | unseen | finetune (sim.scene.dataset.SPLITS), or None"
    ),
    "scene_dir": Key(
        None, Rule("path", none=True), "a `curbside scenes dataset` folder: episodes draw its scenes of `split`"
    ),
    "scene_seed": Key(0, Int(0, MAX_SEED - 1), "first generated scene (within the split's seed range)"),
    "num_scenes": Key(
        1, Int(1, MAX_SEED, none=True), "episodes draw scene k in [0, num_scenes) (generated or from scene_dir)"
    ),
    "scene_cache": Key(
        8, Int(1, 1024), "built worlds kept (LRU), each in its own Bullet client: a repeat costs no build"
    ),
    "scene_steps": Key(
        0, Int(0, 10**9), "an env keeps its scene until it has stepped this many steps there (0: a draw every reset)"
    ),
    "scene_spec": Key(None, Rule("mapping", none=True), "an explicit scene spec (dict) instead of the generator"),
    "scene_path": Key(None, Rule("path", none=True), "or a path to a scene spec JSON file"),
    "catalog": Key(
        None,
        Rule("file", none=True, hint="build one with `curbside catalog build --catalog PATH`"),
        "catalog path for the generator and for mesh collision/visuals",
    ),
    "collision": Key(
        "box", Choice("box", "convex"), 'static objects: "box" from `size`, or "convex" hull of the catalog mesh'
    ),
    "visual_meshes": Key(
        "auto",
        Choice("auto", True, False),
        "catalog meshes (textured) as visual shapes; auto: with camera modalities",
    ),
    "gui": Key(False, Bool(), "PyBullet GUI instead of DIRECT"),
    "dt": Key(0.1, Pos(1.0, hint="seconds per env step"), "seconds per env step"),
    "physics_substeps": Key(5, Int(1, 100), "Bullet substeps per env step (0.02 s each by default)"),
    "horizon": Key(1000, Int(1, 10_000_000), "truncation after at most this many steps"),
    "horizon_min_speed": Key(
        0.5,
        Pos(100.0, none=True),
        "m/s: the horizon is also cut to route_length / this (None: fixed horizon)",
    ),
    "stl_cruise_speed": Key(
        2.5, Pos(50.0, hint="m/s"), "m/s: STL's t_ref = geodesic / min(this, v_max); the expert's cruise speed"
    ),
    "route_length": Key(
        [10.0, 60.0], Pair(Float(5.0, 100_000.0), hint="metres"), "reference route length range in metres (>= 5 m)"
    ),
    "route_margin": Key(0.25, Float(0.0, 5.0), "extra clearance beyond the machine's half-width when planning"),
    "success_completion": Key(0.95, Float(0.0, 1.0, lo_open=True), "route fraction that counts as success"),
    "out_of_route_distance": Key(3.0, Pos(1000.0), "lateral offset (m) that ends the episode as out of route"),
    "terminate_off_walkable": Key(True, Bool(), "leaving the walkable area (road, buildings) is out of route too"),
    "out_of_route_ends": Key(
        True,
        Bool(),
        "out of route ends the episode (False: the machine may come back; MetaUrban's static env never ends it)",
    ),
    "building_contact_ends": Key(
        False, Bool(), "a step in contact with a building ends the episode, failed (MetaUrban's SocialNav env)"
    ),
    "stuck_steps": Key(
        100,
        Int(0, 10_000_000),
        "end the episode when the route progress grew < stuck_distance in this many steps (0: never)",
    ),
    "stuck_distance": Key(0.5, Pos(1000.0), "metres of new progress that count as moving on"),
    "collision_steps": Key(
        30, Int(0, 10_000_000), "end the episode after this many consecutive steps in contact (0: never)"
    ),
    "max_episode_cost": Key(
        None,
        Float(0.0, 1e9, none=True),
        "end the episode, failed, once its cost exceeds this (PPO-ET's rule; None: never)",
    ),
    "topple_angle": Key(
        60.0, Float(1.0, 180.0, hint="degrees"), "degrees of roll or pitch that end the episode as toppled"
    ),
    "cost_kinds": Key(
        ["object", "building"],
        Rule("list", choices=COLLISION_KINDS),
        "contacts that cost (the paper: objects and buildings, not curbs)",
    ),
    "cost_rule": Key(
        "contact_steps",
        Choice(*COST_RULES),
        '"contact_steps": a step in contact with a cost kind costs 1; "metaurban": MetaUrban\'s cost function '
        "(sim.tasks.cost: an object once, at its first contact; agents and vehicles every step; leaving the route)",
    ),
    "lidar": LIDAR_KEYS,
    "speed_scale": Key(5.0, Pos(100.0), "m/s that maps to 1 in the `speed` observation (clipped)"),
    "num_waypoints": Key(10, Int(1, 1000), "route waypoints in the observation"),
    "waypoint_spacing": Key(1.0, Pos(100.0), "metres between the observed route waypoints"),
    "reward_preset": Key("learnable", Choice(*REWARD_PRESETS), '"learnable", "paper" or "metaurban" (REWARD_PRESETS)'),
    "reward": Key({}, REWARD_TABLE, "overrides of the preset's terms (Reward fields)"),
    "measures": Key(
        list(POINTNAV_MEASURES), Rule("list", item=Rule("str")), "the episode metrics reported (sim.metrics)"
    ),
    "render": RENDER_KEYS,
    "camera": CAMERA_KEYS,  # the ego camera (sim.camera): modalities rgb / depth / semantic, size, fov
    "observation": Key(
        "auto",
        Choice("auto", "flat", "dict"),
        '"flat" Box, or "dict" {lidar, state, nav, camera images}; auto: dict with a camera',
    ),
}
DEFAULT_CONFIG: dict[str, Any] = defaults_of(CONFIG_KEYS)
# tests/sim/test_bad_input.py checks that no key of DEFAULT_CONFIG is missing here.
CONFIG_TABLE: dict[str, Rule | Table] = table_of(CONFIG_KEYS)
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
            isinstance(value, (list, tuple))
            and len(value) == 4
            and all(_number(channel) and 0.0 <= channel <= 1.0 for channel in value)
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
    CostRule.from_config(cfg)
    check_clipping_planes(cfg["camera"])
    check_grid_lidar_collision(cfg)


def check_grid_lidar_collision(cfg: Mapping[str, Any]) -> None:
    """A ConfigError when the grid LiDAR would trace boxes while the objects collide as mesh hulls."""
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
