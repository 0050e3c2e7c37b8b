"""BatchedSocialNav: `num_envs` SocialNav envs stepped together (a `gymnasium.vector.VectorEnv`).

The machines, scenes, LiDAR grids, rewards and episode ends are BatchedPointNav's. Each env runs its own crowd and
traffic with the PyBullet env's managers (`sim.envs.cohabitants.CrowdAdapter`, `TrafficAdapter`: ORCA agents and IDM
vehicles, the same draws in the same order), and its machine meets them as shapes instead of Bullet bodies: agents
are upright capsules, vehicles boxes. docs/batched.md says what differs from the PyBullet env and by how much.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit

from kernel.config import ConfigError
from sim.batched.env import BATCHED_KEYS, BatchedPointNav
from sim.batched.episodes import SOCIAL_KIND_BITS
from sim.batched.lidar import BatchLidar
from sim.batched.scene_store import BuiltScene
from sim.envs.bodies import VEHICLE_HEIGHT, capsule_shapes
from sim.envs.cohabitants import CrowdAdapter, TrafficAdapter, agent_base_heights
from sim.envs.managers import EgoPose, ResetContext, TickContext
from sim.raycast.grids import SIDEWALK_LEVEL
from sim.raycast.shapes import capsule_box_hits
from sim.route import Route
from sim.schema import Rule, Table, defaults_of, table_of
from sim.sensors import encode
from sim.tasks.socialnav import CONFIG_KEYS, PRESETS, SPLIT_AGENT_BEHAVIOUR

SOCIAL_KEYS = {**CONFIG_KEYS, "route_pool": BATCHED_KEYS["route_pool"]}
SOCIAL_DEFAULTS: dict[str, Any] = defaults_of(SOCIAL_KEYS)
SOCIAL_TABLE: dict[str, Rule | Table] = table_of(SOCIAL_KEYS)
AGENT_BIT, VEHICLE_BIT = SOCIAL_KIND_BITS["agent"], SOCIAL_KIND_BITS["vehicle"]


@njit(cache=True, nogil=True, error_model="numpy")
def shape_contacts(
    envs: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    yaw: np.ndarray,
    half_l: float,
    half_w: float,
    agent_start: np.ndarray,
    agent_xy: np.ndarray,
    agent_r: np.ndarray,
    vehicle_start: np.ndarray,
    vehicle_pose: np.ndarray,
    vehicle_half_l: float,
    vehicle_half_w: float,
):  # pragma: no cover - numba
    """Per env `envs[j]` with its machine's footprint (half sizes half_l, half_w) at (x[j], y[j], yaw[j]): the kind
    bits of the agent circles (`agent_xy`, `agent_r`, env k's rows agent_start[k]:agent_start[k + 1]) and vehicle
    boxes (`vehicle_pose` rows x, y, yaw, likewise) it overlaps, and the deepest overlap's push-out direction (unit,
    from the shape towards the machine) and depth in metres (0 with no overlap)."""
    m = envs.size
    bits = np.zeros(m, dtype=np.int64)
    nx, ny, depth = np.zeros(m), np.zeros(m), np.zeros(m)
    for j in range(m):
        k = envs[j]
        c, s = math.cos(yaw[j]), math.sin(yaw[j])
        for a in range(agent_start[k], agent_start[k + 1]):
            dx, dy = agent_xy[a, 0] - x[j], agent_xy[a, 1] - y[j]
            u, w = c * dx + s * dy, -s * dx + c * dy  # the agent's centre in the machine's frame
            eu, ew = max(abs(u) - half_l, 0.0), max(abs(w) - half_w, 0.0)
            gap = math.sqrt(eu * eu + ew * ew) - agent_r[a]
            if gap < 0.0:
                bits[j] |= AGENT_BIT
                if -gap > depth[j]:
                    depth[j] = -gap
                    # From the agent's centre to the footprint's nearest point (to the centre when inside it).
                    eu = math.copysign(eu, u)
                    ew = math.copysign(ew, w)
                    if eu == 0.0 and ew == 0.0:
                        eu, ew = u, w
                    dist = math.sqrt(eu * eu + ew * ew)
                    if dist > 1e-9:
                        nx[j], ny[j] = -(c * eu - s * ew) / dist, -(s * eu + c * ew) / dist
                    else:
                        nx[j], ny[j] = -c, -s
        for b in range(vehicle_start[k], vehicle_start[k + 1]):
            bx, by, byaw = vehicle_pose[b, 0], vehicle_pose[b, 1], vehicle_pose[b, 2]
            bc, bs = math.cos(byaw), math.sin(byaw)
            dx, dy = bx - x[j], by - y[j]
            # Separating axes: the machine's two and the vehicle's two; the least overlap is the push-out.
            best, ax_x, ax_y = math.inf, 0.0, 0.0
            for axis in range(4):
                if axis == 0:
                    px, py = c, s
                elif axis == 1:
                    px, py = -s, c
                elif axis == 2:
                    px, py = bc, bs
                else:
                    px, py = -bs, bc
                reach = (
                    half_l * abs(c * px + s * py)
                    + half_w * abs(-s * px + c * py)
                    + vehicle_half_l * abs(bc * px + bs * py)
                    + vehicle_half_w * abs(-bs * px + bc * py)
                )
                along = dx * px + dy * py
                overlap = reach - abs(along)
                if overlap <= 0.0:
                    best = -1.0
                    break
                if overlap < best:
                    best = overlap
                    sign = -1.0 if along > 0.0 else 1.0
                    ax_x, ax_y = sign * px, sign * py
            if best > 0.0:
                bits[j] |= VEHICLE_BIT
                if best > depth[j]:
                    depth[j], nx[j], ny[j] = best, ax_x, ax_y
    return bits, nx, ny, depth


class BatchedSocialNav(BatchedPointNav):
    """`num_envs` SocialNav episodes: BatchedPointNav's machines among each env's own crowd and traffic.

    `config` is SocialNavEnv's (the same keys, defaults, presets and unseen-split agent behaviour) plus `route_pool`.
    Observations, actions, reward and episode ends are PointNav's (SocialNavEnv's spaces). Additions:

    | what | where |
    |---|---|
    | agents and vehicles | each env's `CrowdAdapter` and `TrafficAdapter` (`crowds[i]`, `traffics[i]`), moved after the substeps |
    | LiDAR | agents as upright capsules, vehicles as boxes (the PyBullet env's analytic bodies), nearer than the grid wins |
    | contacts | a footprint overlapping an agent or a vehicle stops there (as on a static body); one that a moving agent or vehicle walked into is pushed out of it, as Bullet does |
    | cost | agents and vehicles by default (`cost_kinds`); `collisions` bits `agent` 16, `vehicle` 32 |
    | `final_info` | PointNav's plus `psc`, `stl`, `sns`, `collisions_agent`, `collisions_vehicle` |
    """

    defaults = SOCIAL_DEFAULTS
    table = SOCIAL_TABLE
    presets = PRESETS
    kind_bits = SOCIAL_KIND_BITS

    def __init__(
        self, num_envs: int = 1, config: Mapping[str, Any] | None = None, render_mode: str | None = None, **kwargs: Any
    ) -> None:
        if config is not None and not isinstance(config, Mapping):
            raise ConfigError(f"config must be a mapping of SocialNav keys, got {type(config).__name__}")
        split = (config or {}).get("split", SOCIAL_DEFAULTS["split"])
        if split in SPLIT_AGENT_BEHAVIOUR:  # the unseen split's agents behave unseen ways (SocialNavEnv's rule)
            agents = (config or {}).get("agents") or {}
            config = {**(config or {}), "agents": {**SPLIT_AGENT_BEHAVIOUR[split], **agents}}
        super().__init__(num_envs, config, render_mode, **kwargs)
        cfg = self.config
        n = self.num_envs
        self.personal_space = float(cfg["personal_space"])
        self.crowds = [CrowdAdapter(cfg["agents"], self.personal_space) for _ in range(n)]
        self.traffics = [TrafficAdapter(cfg["vehicles"], bool(cfg["traffic"]), self.crowds[k]) for k in range(n)]
        self.vehicle_half = (0.5 * float(cfg["vehicles"]["length"]), 0.5 * float(cfg["vehicles"]["width"]))
        self.cruise_speed = min(float(cfg["stl_cruise_speed"]), self.spec_machine.v_max)
        self.curb = np.zeros(n)  # each env's scene's curb height (agents on sidewalks stand on it)
        self.psc_ok = np.zeros(n, dtype=np.int64)  # steps with every agent outside the personal space
        # Each env's capsules (centre x, y, z; half straight part; radius) and its vehicles' poses, flattened with
        # start offsets per env (`shape_contacts`' layout); rebuilt whenever the cohabitants move.
        self._capsule_shapes = [capsule_shapes(np.zeros(0, dtype=np.int64)) for _ in range(n)]  # fixed an episode
        self._capsules = [np.zeros((0, 5)) for _ in range(n)]
        self._vehicles = [np.zeros((0, 3)) for _ in range(n)]
        self._agent_start = np.zeros(n + 1, dtype=np.int64)
        self._vehicle_start = np.zeros(n + 1, dtype=np.int64)
        self._agent_xy, self._agent_r = np.zeros((0, 2)), np.zeros(0)
        self._vehicle_pose = np.zeros((0, 3))

    # -- the cohabitants -----------------------------------------------------------------------------
    def _ego(self, k: int) -> EgoPose:
        d, spec = self.drive, self.spec_machine
        return EgoPose(float(d.x[k]), float(d.y[k]), float(d.yaw[k]), float(d.speed[k]), spec.length, spec.width)

    def _start_episode(self, k: int, built: BuiltScene, route: Route) -> None:
        # SocialNavEnv's reset order: the crowd, then the traffic, drawing from the episode's generator.
        ctx = ResetContext(built.scene, self.rngs[k], self._ego(k), route)
        self.crowds[k].reset(ctx)
        self.traffics[k].reset(ctx)
        self.curb[k] = float(built.scene.curb_height)
        self.psc_ok[k] = 0
        self._capsule_shapes[k] = capsule_shapes(self.crowds[k].crowd.kind_idx)
        self._shapes_of(k)

    def _started_episodes(self, envs: np.ndarray) -> None:
        self._flatten()

    def _after_substeps(self, actions: np.ndarray) -> np.ndarray:
        ticks = [
            TickContext(self.dt, self._ego(k), (float(actions[k, 0]), float(actions[k, 1])))
            for k in range(self.num_envs)
        ]
        CrowdAdapter.after_steps(self.crowds, ticks)  # every env's ORCA in one compiled call
        for k in range(self.num_envs):
            self.traffics[k].after_step(ticks[k])
            self._shapes_of(k)
        self._flatten()
        pushed = self._push_out()
        for k in range(self.num_envs):
            self.psc_ok[k] += self.crowds[k].min_distance > self.personal_space
        return pushed

    def sync_shapes(self) -> None:
        """Re-read every env's agents and vehicles (after moving them by hand: `crowds[i].crowd.place(...)`)."""
        for k in range(self.num_envs):
            self._shapes_of(k)
        self._flatten()

    def _shapes_of(self, k: int) -> None:
        """Env k's capsules and vehicle poses, where its crowd and traffic stand now."""
        crowd = self.crowds[k].crowd
        half_h, radius, shaft = self._capsule_shapes[k]
        caps = np.zeros((len(radius), 5))
        if len(radius):
            caps[:, :2] = crowd.pos
            caps[:, 2] = agent_base_heights(crowd, self.curb[k]) + half_h
            caps[:, 3] = shaft
            caps[:, 4] = radius
        self._capsules[k] = caps
        self._vehicles[k] = np.stack(self.traffics[k].poses(), 1) if self.traffics[k].enabled else np.zeros((0, 3))

    def _flatten(self) -> None:
        self._agent_start[1:] = np.cumsum([len(c) for c in self._capsules])
        self._vehicle_start[1:] = np.cumsum([len(v) for v in self._vehicles])
        caps = np.concatenate(self._capsules)
        self._agent_xy, self._agent_r = np.ascontiguousarray(caps[:, :2]), np.ascontiguousarray(caps[:, 4])
        self._vehicle_pose = np.ascontiguousarray(np.concatenate(self._vehicles))

    def _contacts(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        spec = self.spec_machine
        return shape_contacts(
            envs.astype(np.int64),
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(y, dtype=np.float64),
            np.ascontiguousarray(yaw, dtype=np.float64),
            0.5 * spec.length,
            0.5 * spec.width,
            self._agent_start,
            self._agent_xy,
            self._agent_r,
            self._vehicle_start,
            self._vehicle_pose,
            *self.vehicle_half,
        )

    def _push_out(self) -> np.ndarray:
        """Machines an agent or a vehicle moved into are pushed out along the contact (Bullet's penetration
        recovery) where that pose is clear of the scene; returns the kind bits of those contacts."""
        d = self.drive
        every = np.arange(self.num_envs)
        bits, nx, ny, depth = self._contacts(every, d.x, d.y, d.yaw)
        hit = np.nonzero(bits)[0]
        if hit.size:
            step = depth[hit] + 0.01
            px, py = d.x[hit] + nx[hit] * step, d.y[hit] + ny[hit] * step
            blocked, _ = self._collide_static(hit, px, py, d.yaw[hit])
            free = hit[~blocked]
            d.x[free], d.y[free] = px[~blocked], py[~blocked]
        return bits

    # -- BatchedPointNav's hooks -----------------------------------------------------------------------
    def _collide(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        blocked, bits = self._collide_static(envs, x, y, yaw)
        moving, _, _, _ = self._contacts(envs, x, y, yaw)
        return blocked | (moving != 0), bits | moving

    def _contact_normals(self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray) -> np.ndarray:
        normals = super()._contact_normals(envs, x, y, yaw)
        static, _ = self._collide_static(envs, x[envs], y[envs], yaw[envs])
        moving, nx, ny, _ = self._contacts(envs, x[envs], y[envs], yaw[envs])
        use = ~static & (moving != 0)  # only a moving body in the way: the normal points from it to the machine
        normals[use] = np.stack([nx, ny], 1)[use]
        return normals

    def _scan(self, lidar: BatchLidar) -> np.ndarray:
        d = self.drive
        dist = lidar.distances(self.atlas, self.slots, self.level, d.x, d.y, d.yaw)
        base = np.where(self.level == SIDEWALK_LEVEL, self.curb, 0.0)
        for k in range(self.num_envs):
            caps, cars = self._capsules[k], self._vehicles[k]
            h = float(base[k] + lidar.height)
            if not len(caps) and not (len(cars) and 0.0 <= h <= VEHICLE_HEIGHT):
                continue
            angles = d.yaw[k] + lidar.angles
            hits = np.full(lidar.beams, np.inf)
            if not (0.0 <= h <= VEHICLE_HEIGHT):
                cars = np.zeros((0, 3))
            capsule_box_hits(
                float(d.x[k]),
                float(d.y[k]),
                h,
                np.cos(angles),
                np.sin(angles),
                lidar.start_radius,
                lidar.range_m,
                np.ascontiguousarray(caps[:, :3]),
                np.ascontiguousarray(caps[:, 3]),
                np.ascontiguousarray(caps[:, 4]),
                np.zeros(len(caps), dtype=np.int64),
                np.ascontiguousarray(cars[:, 0]),
                np.ascontiguousarray(cars[:, 1]),
                np.ascontiguousarray(cars[:, 2]),
                self.vehicle_half[0],
                self.vehicle_half[1],
                np.zeros(len(cars), dtype=np.int64),
                hits,
                np.full(lidar.beams, -1, dtype=np.int64),
            )
            np.minimum(dist[k], hits, out=dist[k])
        return encode(dist, lidar.range_m, lidar.encoding)

    def _final_info(self, info: dict[str, Any], done: np.ndarray, succeeded: np.ndarray) -> dict[str, Any]:
        out = super()._final_info(info, done, succeeded)
        steps = np.maximum(self.episodes.steps, 1)
        psc = np.where(self.episodes.steps > 0, self.psc_ok / steps, 1.0)
        t_ref = self.reference / self.cruise_speed
        stl = np.where(succeeded, np.minimum(1.0, t_ref / np.maximum(self.episodes.steps * self.dt, 1e-9)), 0.0)
        out.update({"psc": psc, "stl": stl, "sns": 0.5 * (psc + stl)})
        out.update({f"_{k}": done for k in ("psc", "stl", "sns")})
        return out
