"""Config tables of the sensors a task reads: the LiDAR scans and the render() cameras (the ego camera's
table lives with it in sim/camera.py)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from kernel.config import ConfigError
from sim.schema import Choice, Float, Int, Pos

LIDAR_TABLE = {
    "beams": Int(1, 4096),
    "range": Pos(1000.0),
    "height": Pos(10.0),
    "encoding": Choice("linear", "log"),
    "low_beams": Int(0, 4096),
    "low_range": Pos(1000.0),
    "low_height": Pos(10.0),
    "static": Choice("auto", "grid", "bullet"),
    "resolution": Float(0.01, 0.5, hint="metres per grid cell"),
}
RENDER_TABLE = {
    "camera": Choice("dashboard", "top_down", "chase"),
    "width": Int(16, 4096),
    "height": Int(16, 4096),
    "top_down_height": Pos(1000.0),
}


def check_lidar_reach(lidar: Mapping[str, Any], length: float, width: float) -> None:
    """A ConfigError unless the high scan reaches past the machine: its rays start just outside the circle around
    the footprint (`length` x `width` m), 5 cm beyond the bounding radius."""
    start = 0.5 * math.hypot(length, width) + 0.05
    if float(lidar["range"]) <= start:
        raise ConfigError(
            f"config.lidar.range {lidar['range']!r} m ends inside this machine's {start:.2f} m start "
            f"radius (its rays start outside the footprint); use a range above {start:.2f} m"
        )
