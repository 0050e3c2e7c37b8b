"""The PyBullet bodies of one world's cohabitants: agent capsules and vehicle boxes, moved to their states each tick."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from kernel.quiet import pybullet as p
from sim.agents.figures import figure_shape
from sim.agents.kinds import AGENT_KINDS, KIND_NAMES
from sim.raycast.shapes import capsule_box_hits

VEHICLE_HEIGHT = 1.5
PARKED = [0, 0, -20]  # where unused bodies wait, below the ground
_NO_XYZ = np.zeros((0, 3))
_NO_BOXES = (np.zeros(0), np.zeros(0), np.zeros(0))


@njit(cache=True, nogil=True, error_model="numpy")
def moved_rows(xyz: np.ndarray, last: np.ndarray):  # pragma: no cover - numba
    """Rows of `xyz` [n, 3] that differ from `last` (nan differs from everything), and their xy steps [k, 2]."""
    moved = []
    for k in range(xyz.shape[0]):
        if xyz[k, 0] != last[k, 0] or xyz[k, 1] != last[k, 1] or xyz[k, 2] != last[k, 2]:
            moved.append(k)
    idx = np.array(moved, dtype=np.int64)
    step = np.empty((idx.size, 2))
    for pos in range(idx.size):
        step[pos, 0], step[pos, 1] = xyz[idx[pos], 0] - last[idx[pos], 0], xyz[idx[pos], 1] - last[idx[pos], 1]
    return idx, step


def capsule_shapes(kind_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per agent of kinds `kind_idx`: its capsule's half height (centre above the ground), radius, and half its
    straight part."""
    kinds = [AGENT_KINDS[KIND_NAMES[k]] for k in kind_idx]
    half_heights = np.array([max(kind.height, 2.0 * kind.radius) / 2 for kind in kinds])
    radii = np.array([kind.radius for kind in kinds])
    return half_heights, radii, np.maximum(half_heights - radii, 0.0)


class CohabitantBodies:
    """Bodies for a crowd and its traffic in one Bullet client; their ids go into `collision_kinds` by kind."""

    def __init__(self, client: int, collision_kinds: dict[int, str], vehicle_size: tuple[float, float]) -> None:
        self.client = client
        self.vehicle_size = vehicle_size  # (length, width) of every vehicle box
        self.collision_kinds = collision_kinds  # body id -> "agent" / "vehicle": the env classifies contacts by it
        self.agents: list[int] = []
        self.vehicles: list[int] = []
        self._shapes: dict[Any, tuple[int, int]] = {}
        self._kind_idx = self._kind_src = np.zeros(0, dtype=np.int16)
        self._vehicles_shown = -1
        self._half_heights = np.zeros(0)
        self._radii = np.zeros(0)
        self._xyz = _NO_XYZ  # the agents' body centres as last placed (nan: not placed since they were made)
        self._yaw = np.zeros(0)  # the agents' headings (their figures face their motion)
        self._vehicle_cols: tuple[np.ndarray, np.ndarray, np.ndarray] = _NO_BOXES  # x, y, yaw of the vehicles shown
        self._vehicle_ids = self._agent_ids = np.zeros(0, dtype=np.int64)
        self._shaft = np.zeros(0)

    def park(self) -> None:
        """Move every body out of the way (below the ground), e.g. while the next start's height is probed."""
        for body in self.agents + self.vehicles:
            p.resetBasePositionAndOrientation(body, PARKED, [0, 0, 0, 1], physicsClientId=self.client)
        self._vehicles_shown = -1
        self._xyz = np.full_like(self._xyz, np.nan)
        self._yaw[:] = 0.0  # an episode's pictures must not depend on where the last one left the figures
        self._vehicle_cols, self._vehicle_ids = _NO_BOXES, np.zeros(0, dtype=np.int64)

    def sync(
        self,
        kind_idx: np.ndarray,
        pos: np.ndarray,
        base_heights: np.ndarray,
        vehicles: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        """Place the agent bodies at `pos` (on `base_heights`) and the vehicle bodies at `vehicles`' (x, y, yaw)."""
        client = self.client
        self._ensure(kind_idx, len(vehicles[0]))
        if len(pos):
            xyz = np.empty((len(pos), 3))
            xyz[:, :2] = pos
            xyz[:, 2] = base_heights + self._half_heights
            # Standing agents keep their body where it is: a Bullet reset per body is the cost worth saving.
            moved, step = moved_rows(xyz, self._xyz)  # step: nan on the first sync (the figures keep their heading)
            walking = np.hypot(step[:, 0], step[:, 1]) > 1e-3
            self._yaw[moved[walking]] = np.arctan2(step[walking, 1], step[walking, 0])
            half = 0.5 * self._yaw[moved]
            for k, at, sz, cz in zip(moved.tolist(), xyz[moved].tolist(), np.sin(half).tolist(), np.cos(half).tolist()):
                p.resetBasePositionAndOrientation(self.agents[k], at, (0, 0, sz, cz), physicsClientId=client)
            self._xyz = xyz
        # The ray test's inputs: the shown vehicles' x, y and yaw (contiguous) and their body ids.
        vx, vy, vyaw = (np.ascontiguousarray(col, dtype=np.float64) for col in vehicles)
        self._vehicle_cols = (vx, vy, vyaw)
        self._vehicle_ids = np.asarray(self.vehicles[: len(vx)], dtype=np.int64)
        if len(vx):
            half_yaw = (0.5 * vyaw).tolist()
            for body, x, y, half_h in zip(self.vehicles, vx.tolist(), vy.tolist(), half_yaw):
                p.resetBasePositionAndOrientation(
                    body, [x, y, VEHICLE_HEIGHT / 2], [0, 0, math.sin(half_h), math.cos(half_h)], physicsClientId=client
                )

    def _shape(self, key: Any, make: Any) -> tuple[int, int]:
        if key not in self._shapes:
            self._shapes[key] = make()
        return self._shapes[key]

    def _match(self, kind_idx: np.ndarray) -> bool:
        """Whether the agent bodies still match the agents' kinds (a reset may change their number or kinds)."""
        if len(self.agents) != len(kind_idx):
            return False
        if self._kind_src is not kind_idx:  # a new episode: compare by value once, then by identity
            if not np.array_equal(self._kind_idx, kind_idx):
                return False
            self._kind_src = kind_idx
        return True

    def _ensure(self, kind_idx: np.ndarray, n_vehicles: int) -> None:
        client = self.client
        if not self._match(kind_idx):
            kinds = [KIND_NAMES[k] for k in kind_idx]
            for old_body in self.agents:
                p.removeBody(old_body, physicsClientId=client)
                self.collision_kinds.pop(old_body, None)
            self.agents = []
            for k in kinds:
                kind = AGENT_KINDS[k]
                # Capsules, not cylinders: Bullet ray-tests a cylinder about four times slower than a capsule, and
                # the LiDAR's rays made cylinders the costliest part of a SocialNav step. Cameras see a figure.
                shaft = max(kind.height - 2.0 * kind.radius, 0.0)
                col, vis = self._shape(
                    k,
                    lambda kind=kind, shaft=shaft, k=k: (
                        p.createCollisionShape(
                            p.GEOM_CAPSULE, radius=kind.radius, height=shaft, physicsClientId=client
                        ),
                        figure_shape(client, k, max(kind.height, 2.0 * kind.radius), kind.radius, kind.color),
                    ),
                )
                body = p.createMultiBody(0.0, col, vis, PARKED, physicsClientId=client)
                self.agents.append(body)
                self.collision_kinds[body] = "agent"
            self._kind_idx = self._kind_src = kind_idx
            self._half_heights, self._radii, self._shaft = capsule_shapes(kind_idx)
            self._xyz = np.full((len(kinds), 3), np.nan)  # nan != anything: every body moves on the first sync
            self._agent_ids = np.asarray(self.agents, dtype=np.int64)
            self._yaw = np.zeros(len(kinds))
        while len(self.vehicles) < n_vehicles:
            half = [self.vehicle_size[0] / 2, self.vehicle_size[1] / 2, VEHICLE_HEIGHT / 2]
            col, vis = self._shape(
                "vehicle",
                lambda half=half: (
                    p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client),
                    p.createVisualShape(
                        p.GEOM_BOX, halfExtents=half, rgbaColor=[0.25, 0.25, 0.65, 1.0], physicsClientId=client
                    ),
                ),
            )
            body = p.createMultiBody(0.0, col, vis, PARKED, physicsClientId=client)
            self.vehicles.append(body)
            self.collision_kinds[body] = "vehicle"
        if n_vehicles != self._vehicles_shown:  # park unused bodies once, not every step
            for body in self.vehicles[n_vehicles:]:
                p.resetBasePositionAndOrientation(body, PARKED, [0, 0, 0, 1], physicsClientId=client)
            self._vehicles_shown = n_vehicles

    def ray_hits(
        self, x: float, y: float, h: float, cos: np.ndarray, sin: np.ndarray, start: float, range_m: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(distance in m, body id) per horizontal ray from (x, y) at height `h` along (cos, sin), starting `start` m
        out: the first agent capsule or vehicle box it meets within `range_m` (inf and -1 for none).

        The bodies' own shapes, intersected exactly (a capsule at height h is a circle, a vehicle an oriented
        rectangle up to VEHICLE_HEIGHT): what Bullet's ray test of these bodies returns, for `sim.sensors.GridLidar`,
        whose grids hold only the static scene.
        """
        dist = np.full(cos.shape, np.inf)
        which = np.full(cos.shape, -1, dtype=np.int64)
        xyz = self._xyz
        bx, by, byaw = self._vehicle_cols if 0.0 <= h <= VEHICLE_HEIGHT else _NO_BOXES
        capsule_box_hits(
            float(x),
            float(y),
            float(h),
            cos,
            sin,
            float(start),
            float(range_m),
            xyz,
            self._shaft,
            self._radii,
            self._agent_ids,
            bx,
            by,
            byaw,
            0.5 * self.vehicle_size[0],
            0.5 * self.vehicle_size[1],
            self._vehicle_ids,
            dist,
            which,
        )
        return dist, which
