"""The PointNav task: its config defaults, scene sources, and DESIGN.md's reward and cost."""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.metrics import POINTNAV_MEASURES

DEFAULT_CONFIG: dict[str, Any] = {
    "machine": "delivery_bot",        # a name from sim.machines.MACHINES or a dict of MachineSpec fields
    "scene": {},                      # generator config passed to sim.scene.generate_scene (partial is fine)
    "scene_seed": 0,                  # seed of the first generated scene
    "num_scenes": 1,                  # episodes draw scene_seed + k, k in [0, num_scenes)
    "scene_spec": None,               # an explicit scene spec (dict) instead of the generator
    "scene_path": None,               # or a path to a scene spec JSON file
    "catalog": None,                  # catalog path for the generator and for mesh collision/visuals
    "collision": "box",               # static objects: "box" from `size`, or "convex" hull of the catalog mesh
    "visual_meshes": False,           # catalog meshes as visual shapes (rendering only)
    "gui": False,                     # PyBullet GUI instead of DIRECT
    "dt": 0.1,                        # seconds per env step
    "physics_substeps": 5,            # Bullet substeps per env step (0.02 s each by default)
    "horizon": 1000,                  # truncation after this many steps
    "route_length": [10.0, 60.0],     # reference route length range in metres (>= 5 m)
    "route_margin": 0.25,             # extra clearance beyond the machine's half-width when planning
    "success_completion": 0.95,       # route fraction that counts as success
    "out_of_route_distance": 3.0,     # lateral offset (m) that ends the episode as out of route
    "terminate_off_walkable": True,   # leaving the walkable area (road, buildings) is out of route too
    "lidar": {"beams": 240, "range": 50.0, "height": 0.4},
    "num_waypoints": 10,
    "waypoint_spacing": 1.0,          # metres between the observed route waypoints
    "reward": {"success": 5.0, "out_of_route": -5.0, "disp": 0.5, "lateral": 1.0, "steering": 0.1, "crash": 1.0},
    "measures": list(POINTNAV_MEASURES),
    "render": {"camera": "top_down", "width": 128, "height": 128, "top_down_height": 25.0},
}


@dataclass(frozen=True)
class Reward:
    """R = R_term + w_disp R_disp + w_lat R_lateral + w_steer R_steering + w_crash R_crash (DESIGN.md)."""

    success: float = 5.0
    out_of_route: float = -5.0
    disp: float = 0.5
    lateral: float = 1.0
    steering: float = 0.1
    crash: float = 1.0

    def __call__(self, progress: float, lateral: float, d_steer: float, speed: float, collided: bool,
                 succeeded: bool, out_of_route: bool) -> float:
        """One step's reward from the displacement along the route, the offset, steering change and events."""
        r = self.disp * progress - self.lateral * abs(lateral) - self.steering * abs(d_steer) * abs(speed)
        if collided:
            r -= self.crash
        if succeeded:
            r += self.success
        elif out_of_route:
            r += self.out_of_route
        return float(r)


def load_scene(config: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """The scene spec an episode runs in: `scene_spec`, else `scene_path`, else generated with `seed`."""
    if config["scene_spec"] is not None:
        return dict(config["scene_spec"])
    if config["scene_path"] is not None:
        path = Path(config["scene_path"])
        if not path.exists():
            raise FileNotFoundError(f"no scene spec at {path}; write one with `curbside scenes generate`")
        return json.loads(path.read_text())
    try:
        from sim.scene import generate_scene
    except ImportError as e:  # the generator is a sibling subsystem; say what to do without it
        raise RuntimeError(
            f"sim.scene.generate_scene is unavailable ({e}); pass config={{'scene_spec': ...}} or 'scene_path'"
        ) from e
    with warnings.catch_warnings():
        # Without a catalog the generator warns once per category; the env says it once per process instead.
        warnings.filterwarnings("ignore", message="no catalog was given")
        return generate_scene(dict(config["scene"]), seed, config["catalog"])
