"""LiDAR: a horizontal fan of beams in the ego frame, traced by Bullet (`Lidar`) or through the scene's distance
grids (`GridLidar`, the default; docs/raycast.md)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from kernel.quiet import pybullet as p
from sim.raycast.grids import ROAD_LEVEL, SIDEWALK_LEVEL, WHAT, SceneGrids
from sim.raycast.march import trace_fan

ENCODINGS = ("linear", "log")
# (x, y, height, cos, sin, start, range_m) -> (distances in m, inf for none; body ids): GridLidar's moving bodies.
MovingHits = Callable[[float, float, float, np.ndarray, np.ndarray, float, float], tuple[np.ndarray, np.ndarray]]


def encode(d: np.ndarray, range_m: float, encoding: str) -> np.ndarray:
    """Distances `d` (m) as observed: `linear` d / range, or `log` log(1 + d) / log(1 + range) (both 1 = no hit).

    The log encoding gives the near field room: with a 50 m range, 0.5-5 m spans 0.10-0.46 instead of
    0.01-0.10, which is where obstacles decide what to do next.
    """
    if encoding == "log":
        return (np.log1p(d) / math.log1p(range_m)).astype(np.float32)
    return (d / range_m).astype(np.float32)


class PlanarLidar:
    """A planar 360-degree LiDAR: `beams` rays of length `range_m` at `height` above the machine's base.

    A scan at 0.4 m passes over curbs (0.15 m) and small clutter; PointNav adds a second, short-range scan
    a few centimetres above the ground for those.

    Rays start just outside the machine's bounding circle, so the ego never sees itself; distances are
    still measured from the machine's centre. A subclass's `scan(x, y, z, yaw)` returns distances normalised by
    `range_m` (1 = no hit) and stores what each beam hit in `hit_ids` (-1 for none).
    """

    def __init__(
        self,
        beams: int = 240,
        range_m: float = 50.0,
        height: float = 0.4,
        start_radius: float = 0.5,
        encoding: str = "linear",
    ) -> None:
        if beams < 1 or not range_m > start_radius or not math.isfinite(range_m):
            raise ValueError(
                f"lidar needs beams >= 1 and a finite range_m > {start_radius}, got beams={beams}, range_m={range_m}"
            )
        if encoding not in ENCODINGS:
            raise ValueError(f"unknown lidar encoding {encoding!r}; valid: {', '.join(ENCODINGS)}")
        self.encoding = encoding
        self.beams = beams
        self.range_m = float(range_m)
        self.height = float(height)
        self.start_radius = float(start_radius)
        self.angles = np.linspace(0.0, 2.0 * math.pi, beams, endpoint=False)
        self.distances = np.ones(beams, dtype=np.float32)
        self.hit_ids = -np.ones(beams, dtype=np.int64)

    def scan(self, x: float, y: float, z: float, yaw: float) -> np.ndarray:
        """Normalised distances (beams,) in [0, 1] for a machine at (x, y, z) heading `yaw`; stores `hit_ids`."""
        raise NotImplementedError

    def encoded(self) -> np.ndarray:
        """The last scan as observed (`encode`: linear d / range, or log)."""
        if self.encoding == "linear":
            return self.distances
        return encode(self.distances.astype(np.float64) * self.range_m, self.range_m, self.encoding)


class Lidar(PlanarLidar):
    """The planar LiDAR as one Bullet `rayTestBatch` a scan: every body of the world (`lidar.static: bullet`);
    `hit_ids` holds the body ids, which tell objects, buildings and agents apart."""

    def __init__(
        self,
        client: int,
        beams: int = 240,
        range_m: float = 50.0,
        height: float = 0.4,
        start_radius: float = 0.5,
        encoding: str = "linear",
    ) -> None:
        super().__init__(beams, range_m, height, start_radius, encoding)
        self.client = client

    def rays(self, x: float, y: float, z: float, yaw: float) -> tuple[list, list]:
        """World-frame ray start and end points for a machine at (x, y, z) heading `yaw`."""
        a = self.angles + yaw
        c, s = np.cos(a), np.sin(a)
        h = z + self.height
        frm = np.stack([x + self.start_radius * c, y + self.start_radius * s, np.full(self.beams, h)], 1)
        to = np.stack([x + self.range_m * c, y + self.range_m * s, np.full(self.beams, h)], 1)
        return frm.tolist(), to.tolist()

    def scan(self, x: float, y: float, z: float, yaw: float) -> np.ndarray:
        """Normalised distances (beams,) in [0, 1]; also stores `hit_ids`."""
        frm, to = self.rays(x, y, z, yaw)
        hits = p.rayTestBatch(frm, to, physicsClientId=self.client)
        frac = np.fromiter((h[2] for h in hits), dtype=np.float64, count=self.beams)
        self.hit_ids = np.fromiter((h[0] for h in hits), dtype=np.int64, count=self.beams)
        r0 = self.start_radius
        self.distances = ((r0 + frac * (self.range_m - r0)) / self.range_m).astype(np.float32)
        return self.distances


class GridLidar(PlanarLidar):
    """The planar LiDAR with the static scene traced through distance grids (`sim.raycast`), not Bullet.

    The grids hold the world's static solids (buildings, object boxes, sidewalk slabs and curb ramps) at the scan's
    height for a machine on the sidewalk and on the road; a scan takes the level nearer the machine's base height
    `z`. Bodies that move (SocialNav's agents and vehicles) are not in the grids: `moving(x, y, h, cos, sin, start,
    range_m)` (the env's hook, or None) returns their distances (m, inf for none) and body ids per beam; the nearer
    hit wins. Distances match Bullet's ray test to within the grid's rasterisation (docs/raycast.md); `hit_ids`
    holds a moving body's id, STATIC_HIT for a grid hit, -1 for none.
    """

    STATIC_HIT = -2

    def __init__(
        self,
        grids: SceneGrids,
        what: str,
        beams: int = 240,
        range_m: float = 50.0,
        height: float = 0.4,
        start_radius: float = 0.5,
        encoding: str = "linear",
    ) -> None:
        super().__init__(beams, range_m, height, start_radius, encoding)
        self.grids = grids
        self.moving: MovingHits | None = None
        table = WHAT.index(what)
        # Per level: the flat table and the one-env frame `sim.raycast.march.trace_fan` reads.
        self._frames = [
            (
                tables[table].ravel(),
                {
                    "x0": np.array([grids.origin[0]]),
                    "y0": np.array([grids.origin[1]]),
                    "cols": np.array([grids.shape[1]]),
                    "offset": np.zeros(1, dtype=np.int64),
                },
            )
            for tables in grids.tables
        ]

    def scan(self, x: float, y: float, z: float, yaw: float) -> np.ndarray:
        """Normalised distances (beams,) in [0, 1]; also stores `hit_ids`."""
        level = SIDEWALK_LEVEL if z > 0.5 * self.grids.curb_height else ROAD_LEVEL
        flat, frame = self._frames[level]
        a = self.angles + yaw
        cos, sin = np.cos(a), np.sin(a)
        d = trace_fan(
            flat,
            float(frame["x0"][0]),
            float(frame["y0"][0]),
            int(frame["cols"][0]),
            x,
            y,
            cos,
            sin,
            self.start_radius,
            self.range_m,
            self.grids.resolution,
        )
        ids = np.where(d < self.range_m, self.STATIC_HIT, -1)
        if self.moving is not None:
            dm, idm = self.moving(x, y, z + self.height, cos, sin, self.start_radius, self.range_m)
            nearer = dm < d
            d = np.where(nearer, dm, d)
            ids = np.where(nearer, idm, ids)
        self.hit_ids = ids
        self.distances = (d / self.range_m).astype(np.float32)
        return self.distances
