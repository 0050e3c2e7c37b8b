"""The PointNav task: its config defaults, the reward presets, and where an episode's scene comes from.

Two reward presets (docs/tasks.md explains each choice):
- `paper`: the MetaUrban paper's formula R = R_term + 0.5 R_disp + 1.0 R_lateral + 0.1 R_steering + 1.0 R_crash, kept
  for comparison. With it, standing still (return ~0) and leaving the route early beat honest attempts.
- `learnable` (default): progress is paid only for new ground (the largest arc length reached, so driving back
  and forth earns nothing), the lateral term is small and free within `lateral_free` of the route, a collision
  step costs less than a metre of progress, and an episode that makes no progress or stays pinned against an
  obstacle ends with the `stuck` penalty (so "stand still" and "stay pinned" are never the best plan).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from curbside.config import ConfigError, check_choice, merge_strict
from sim.metrics import POINTNAV_MEASURES

DEFAULT_CONFIG: dict[str, Any] = {
    "preset": None,                   # a TASK_PRESETS name (e.g. "metaurban12k"): its values replace these defaults
    "machine": "delivery_bot",        # a name from sim.machines.MACHINES or a dict of MachineSpec fields
    "scene": {},                      # generator config passed to sim.scene.generate_scene (partial is fine)
    "split": "train",                 # train | test | unseen | finetune (sim.scene.dataset.SPLITS), or None
    "scene_dir": None,                # a `curbside scenes dataset` folder: episodes draw its scenes of `split`
    "scene_seed": 0,                  # first generated scene (within the split's seed range)
    "num_scenes": 1,                  # episodes draw scene k in [0, num_scenes) (generated or from scene_dir)
    "scene_cache": 8,                 # built worlds kept (LRU), each in its own Bullet client: a repeat costs no build
    "scene_spec": None,               # an explicit scene spec (dict) instead of the generator
    "scene_path": None,               # or a path to a scene spec JSON file
    "catalog": None,                  # catalog path for the generator and for mesh collision/visuals
    "collision": "box",               # static objects: "box" from `size`, or "convex" hull of the catalog mesh
    "visual_meshes": False,           # catalog meshes as visual shapes (rendering only)
    "gui": False,                     # PyBullet GUI instead of DIRECT
    "dt": 0.1,                        # seconds per env step
    "physics_substeps": 5,            # Bullet substeps per env step (0.02 s each by default)
    "horizon": 1000,                  # truncation after at most this many steps
    "horizon_min_speed": 0.5,         # m/s: the horizon is also cut to route_length / this (None: fixed horizon)
    "route_length": [10.0, 60.0],     # reference route length range in metres (>= 5 m)
    "route_margin": 0.25,             # extra clearance beyond the machine's half-width when planning
    "success_completion": 0.95,       # route fraction that counts as success
    "out_of_route_distance": 3.0,     # lateral offset (m) that ends the episode as out of route
    "terminate_off_walkable": True,   # leaving the walkable area (road, buildings) is out of route too
    "stuck_steps": 100,               # end the episode when the route progress grew < stuck_distance in this many steps (0: never)
    "stuck_distance": 0.5,            # metres of new progress that count as moving on
    "collision_steps": 30,            # end the episode after this many consecutive steps in contact (0: never)
    "cost_kinds": ["object", "building"],  # contacts that cost (the paper: objects and buildings, not curbs)
    "lidar": {"beams": 240, "range": 50.0, "height": 0.4, "encoding": "log",
              "low_beams": 60, "low_range": 5.0, "low_height": 0.08},
    "speed_scale": 5.0,               # m/s that maps to 1 in the `speed` observation (clipped)
    "num_waypoints": 10,
    "waypoint_spacing": 1.0,          # metres between the observed route waypoints
    "reward_preset": "learnable",     # "learnable" or "paper" (REWARD_PRESETS)
    "reward": {},                     # overrides of the preset's terms (Reward fields)
    "measures": list(POINTNAV_MEASURES),
    "render": {"camera": "top_down", "width": 128, "height": 128, "top_down_height": 25.0},
}


# Named route-length ranges (metres). "metaurban12k": the paper's mean episode of ~410 m (chained legs, see
# sim.route.RoutePlanner.sample).
ROUTE_LENGTHS: dict[str, list[float]] = {"short": [10.0, 60.0], "metaurban12k": [250.0, 650.0]}
# Task presets: values that replace the defaults (explicit config keys still win). "metaurban12k": the paper's
# scenes (scene preset), routes and a horizon that fits them (route length / 1 m/s; the expert needs 4 s per 10 m).
TASK_PRESETS: dict[str, dict[str, Any]] = {
    "metaurban12k": {"scene": {"preset": "metaurban12k"}, "route_length": ROUTE_LENGTHS["metaurban12k"],
                     "horizon": 6500, "horizon_min_speed": 1.0},
}


def resolve_task_config(defaults: Mapping[str, Any], config: Mapping[str, Any] | None,
                        presets: Mapping[str, Mapping[str, Any]] = TASK_PRESETS) -> dict[str, Any]:
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
        if name not in presets:
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

    def __call__(self, progress: float, new_progress: float, lateral: float, d_steer: float, speed: float,
                 collided: bool, succeeded: bool, out_of_route: bool, stuck: bool) -> float:
        """One step's reward from progress along the route, the offset, steering change and events."""
        disp = new_progress if self.progress == "max" else progress
        r = (self.disp * disp - self.lateral * max(0.0, abs(lateral) - self.lateral_free)
             - self.steering * abs(d_steer) * abs(speed))
        if collided:
            r -= self.crash
        if self.floor:
            r = max(r, 0.0)
        if succeeded:
            r += self.success
        elif out_of_route:
            r += self.out_of_route
        elif stuck:
            r += self.stuck
        return float(r)


REWARD_PRESETS: dict[str, dict[str, Any]] = {
    # The MetaUrban paper: progress along the route, full lateral penalty, no stuck ending (stuck_steps and
    # collision_steps still end such episodes unless set to 0; their penalty is then 0).
    "paper": dict(success=5.0, out_of_route=-5.0, stuck=0.0, disp=0.5, progress="route", lateral=1.0,
                  lateral_free=0.0, steering=0.1, crash=1.0, floor=False),
    "learnable": asdict(Reward()),
}


COLLISION_KINDS = ("object", "building", "curb", "agent", "vehicle")


def _is_int(v: Any, lo: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= lo


def _is_pos(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < math.inf


def check_config(cfg: Mapping[str, Any]) -> None:
    """Validate the task config's values (types, ranges, finiteness); ConfigError names the key and the range."""
    lo, hi = (float(v) for v in cfg["route_length"])
    if not 5.0 <= lo <= hi < math.inf:
        raise ConfigError(f"config.route_length must be [min, max] with 5 <= min <= max, got {cfg['route_length']}")
    if not _is_pos(cfg["dt"]) or not _is_int(cfg["physics_substeps"], 1):
        raise ConfigError("config.dt must be a finite number > 0 and config.physics_substeps an integer >= 1")
    for key, low in (("stuck_steps", 0), ("collision_steps", 0), ("horizon", 1), ("num_waypoints", 1), ("scene_cache", 1)):
        if not _is_int(cfg[key], low):
            raise ConfigError(f"config.{key} must be an integer >= {low}, got {cfg[key]!r}")
    for key in ("stuck_distance", "waypoint_spacing", "speed_scale", "out_of_route_distance"):
        if not _is_pos(cfg[key]):
            raise ConfigError(f"config.{key} must be a positive finite number, got {cfg[key]!r}")
    if cfg["horizon_min_speed"] is not None and not _is_pos(cfg["horizon_min_speed"]):
        raise ConfigError(f"config.horizon_min_speed must be a positive number or None, got {cfg['horizon_min_speed']!r}")
    if cfg["split"] is not None:
        from sim.scene.dataset import SPLITS
        check_choice(cfg["split"], tuple(SPLITS), what="config.split")
    unknown = set(cfg["cost_kinds"]) - set(COLLISION_KINDS)
    if unknown:
        raise ConfigError(f"unknown config.cost_kinds {sorted(unknown)}; valid: {', '.join(COLLISION_KINDS)}")
    lid = cfg["lidar"]
    for key in ("range", "low_range", "height", "low_height"):
        if not _is_pos(lid[key]):
            raise ConfigError(f"config.lidar.{key} must be a positive finite number, got {lid[key]!r}")
    for key in ("beams", "low_beams"):
        if not _is_int(lid[key], 1 if key == "beams" else 0):
            raise ConfigError(f"config.lidar.{key} must be an integer >= {1 if key == 'beams' else 0}, got {lid[key]!r}")
    from sim.sensors import ENCODINGS
    check_choice(lid["encoding"], ENCODINGS, what="config.lidar.encoding")


def make_reward(preset: str, overrides: Mapping[str, Any] | None) -> Reward:
    """The Reward of a named preset with some of its terms overridden (unknown terms raise)."""
    if preset not in REWARD_PRESETS:
        raise ConfigError(f"unknown reward_preset {preset!r}; valid: {', '.join(REWARD_PRESETS)}")
    return Reward(**merge_strict(REWARD_PRESETS[preset], overrides, name="config.reward"))


def load_scene(config: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """The scene spec an episode runs in: `scene_spec`, else `scene_path`, else generated with `seed`."""
    if config["scene_spec"] is not None:
        return dict(config["scene_spec"])
    if config["scene_path"] is not None:
        return read_scene(config["scene_path"])
    try:
        from sim.scene import generate_scene
    except ImportError as e:  # the generator is a sibling subsystem; say what to do without it
        raise RuntimeError(
            f"sim.scene.generate_scene is unavailable ({e}); pass config={{'scene_spec': ...}} or 'scene_path'"
        ) from e
    scene_cfg = dict(config["scene"])
    if config.get("split") is not None:
        from sim.scene.dataset import split_config
        scene_cfg, _ = split_config(config["split"], scene_cfg)
    with warnings.catch_warnings():
        # Without a catalog the generator warns once per category; the env says it once per process instead.
        warnings.filterwarnings("ignore", message="no catalog was given")
        return generate_scene(scene_cfg, seed, config["catalog"])


def read_scene(path: str | Path) -> dict[str, Any]:
    """A scene spec from a JSON file, with a clear error when it is missing or not JSON."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no scene spec at {path}; write one with `curbside scenes generate --out {path}`")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path} is not a scene spec JSON file ({e}); regenerate it with `curbside scenes generate`") from e


def split_seed_offset(split: str | None) -> int:
    """First generator seed of `split` (0 without a split): splits draw from disjoint seed ranges."""
    if split is None:
        return 0
    from sim.scene.dataset import split_config
    return split_config(split)[1]


def dataset_scenes(scene_dir: str | Path, split: str | None) -> list[Path]:
    """Scene files of `split` in a dataset folder (its index.jsonl), sorted; a clear error when there are none."""
    from sim.scene.dataset import read_index
    d = Path(scene_dir)
    if not d.is_dir():
        raise ConfigError(f"config.scene_dir {d} is not a folder; create it with `curbside scenes dataset --out {d}`")
    rows = read_index(d)
    files = sorted(d / r["file"] for r in rows if split is None or r.get("split") == split)
    if not files:
        have = sorted({str(r.get("split")) for r in rows}) or ["none"]
        raise ConfigError(f"split {split!r} has no scenes in {d} (it holds: {', '.join(have)}); "
                          f"create them with `curbside scenes dataset --split {split} --out {d}`")
    return files
