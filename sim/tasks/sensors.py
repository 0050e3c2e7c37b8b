"""Config declarations of the sensors a task reads: the LiDAR scans, the render() cameras and the ego camera
(whose behaviour is sim.camera). No pybullet import: the task config and the CLI read these without loading it."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from kernel.config import ConfigError
from sim.schema import Choice, Float, Int, Key, Pos, Rule, Table, defaults_of, table_of

# PointNav's `lidar`: a high scan and a low one (low_beams 0: none), both planar and 360 degrees.
LIDAR_KEYS: dict[str, Key] = {
    "beams": Key(240, Int(1, 4096), "beams of the high scan"),
    "range": Key(50.0, Pos(1000.0), "metres the high scan reaches"),
    "height": Key(0.4, Pos(10.0), "metres above the machine's base of the high scan (passes over curbs)"),
    "encoding": Key("log", Choice("linear", "log"), "high scan distances as d / range (linear) or log(1 + d) scaled"),
    "low_beams": Key(60, Int(0, 4096), "beams of the low scan (0: no low scan)"),
    "low_range": Key(5.0, Pos(1000.0), "metres the low scan reaches"),
    "low_height": Key(0.08, Pos(10.0), "metres above the machine's base of the low scan (sees curbs, small clutter)"),
    # Grids: ~0.1 ms for 300 rays against Bullet's ~0.7 ms.
    "static": Key(
        "auto",
        Choice("auto", "grid", "bullet"),
        'static geometry: "grid" traces distance grids of `resolution` m (sim.raycast), "bullet" ray-tests '
        'the Bullet world; "auto" is grid with box collision, else bullet',
    ),
    "resolution": Key(0.05, Float(0.01, 0.5, hint="metres per grid cell"), "metres per cell of the distance grids"),
}
LIDAR_TABLE: dict[str, Rule | Table] = table_of(LIDAR_KEYS)
# PointNav's `render`: the frames render() returns (sim.viewer).
RENDER_KEYS: dict[str, Key] = {
    "camera": Key("dashboard", Choice("dashboard", "top_down", "chase"), "the view render() draws"),
    "width": Key(768, Int(16, 4096), "frame width (pixels)"),
    "height": Key(384, Int(16, 4096), "frame height (pixels)"),
    "top_down_height": Key(25.0, Pos(1000.0), "metres above the machine of the top_down camera"),
}
RENDER_TABLE: dict[str, Rule | Table] = table_of(RENDER_KEYS)


def check_lidar_reach(lidar: Mapping[str, Any], length: float, width: float) -> None:
    """A ConfigError unless the high scan reaches past the machine: its rays start just outside the circle around
    the footprint (`length` x `width` m), 5 cm beyond the bounding radius."""
    start = 0.5 * math.hypot(length, width) + 0.05
    if float(lidar["range"]) <= start:
        raise ConfigError(
            f"config.lidar.range {lidar['range']!r} m ends inside this machine's {start:.2f} m start "
            f"radius (its rays start outside the footprint); use a range above {start:.2f} m"
        )


MODALITIES = ("rgb", "depth", "semantic")
# The ego camera's config (PointNav's `camera`): one Key per setting.
CAMERA_KEYS: dict[str, Key] = {
    "modalities": Key(
        [], Rule("list", choices=MODALITIES), "any of rgb, depth, semantic; none: no camera (the flat observation)"
    ),
    "width": Key(128, Int(8, 2048), "image width (pixels)"),
    "height": Key(128, Int(8, 2048), "image height (pixels)"),
    "fov": Key(90.0, Float(10.0, 170.0), "vertical field of view, degrees"),
    "near": Key(0.05, Float(0.001, 10.0), "near clipping plane (m), below `far`"),
    "far": Key(50.0, Float(1.0, 10_000.0), "far clipping plane (m); depth beyond `far` (or sky) reads `far`"),
    "mount_height": Key(None, Pos(20.0, none=True), "metres above the ground; None: the machine's height"),
    "pitch": Key(-10.0, Float(-89.0, 89.0), "degrees, negative looks down"),
    "renderer": Key(
        "tiny", Choice("tiny", "egl"), '"tiny" (CPU TinyRenderer), "egl" (GPU OpenGL through PyBullet\'s EGL plugin)'
    ),
}
CAMERA_DEFAULTS: dict[str, Any] = defaults_of(CAMERA_KEYS)
CAMERA_TABLE: dict[str, Rule | Table] = table_of(CAMERA_KEYS)


def check_clipping_planes(camera: Mapping[str, Any], name: str = "config.camera") -> None:
    """A ConfigError unless the near clipping plane lies before the far one (each is in range on its own)."""
    if camera["near"] >= camera["far"]:
        raise ConfigError(f"{name}.near ({camera['near']}) must be below {name}.far ({camera['far']})")
