"""The LiDARs of many envs at once: both scans of every env traced in one call each (`sim.raycast.march.trace`)
through the atlas of every scene's grids."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sim.batched.atlas import Atlas
from sim.raycast.march import trace
from sim.sensors import encode


class BatchLidar:
    """One scan (high or low) of every env: beam angles, start radius, range, encoding (as `sim.sensors.Lidar`)."""

    def __init__(
        self,
        beams: int,
        range_m: float,
        start_radius: float,
        what: str,
        encoding: str = "linear",
        height: float = 0.4,
    ) -> None:
        self.beams = beams
        self.height = float(height)  # metres above the machine's base (the grids are cut there; moving bodies too)
        self.range_m = float(range_m)
        self.start_radius = float(start_radius)
        self.what = what
        self.encoding = encoding
        self.angles = np.linspace(0.0, 2.0 * math.pi, beams, endpoint=False)

    def scan(
        self, atlas: Atlas, scene_ids: np.ndarray, level: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> np.ndarray:
        """Normalised distances [n, beams] (1 = no hit), encoded as the PyBullet env observes them."""
        return encode(self.distances(atlas, scene_ids, level, x, y, yaw), self.range_m, self.encoding)

    def distances(
        self, atlas: Atlas, scene_ids: np.ndarray, level: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> np.ndarray:
        """Distances [n, beams] in metres to the scenes' static solids (range_m: no hit)."""
        frame = atlas.frames(scene_ids, level, self.what)
        return trace(
            atlas.flat, frame, x, y, yaw[:, None] + self.angles[None], self.start_radius, self.range_m, atlas.resolution
        )


def lidar_pair(cfg: dict[str, Any], bounding_radius: float) -> tuple[BatchLidar, BatchLidar | None]:
    """The high and (if low_beams) low scans of a PointNav config, with the start radii of `build_slot`."""
    lid = cfg["lidar"]
    r0 = bounding_radius + 0.05
    high = BatchLidar(int(lid["beams"]), float(lid["range"]), r0, "high", lid["encoding"], float(lid["height"]))
    low = (
        BatchLidar(
            int(lid["low_beams"]), max(float(lid["low_range"]), r0 + 0.1), r0, "low", height=float(lid["low_height"])
        )
        if int(lid["low_beams"])
        else None
    )
    return high, low
