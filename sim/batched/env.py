"""BatchedPointNav: `num_envs` PointNav envs stepped together in numpy (a `gymnasium.vector.VectorEnv`).

Machines drive on flat ground (`sim.batched.kinematics`), the LiDARs trace precomputed distance grids
(`sim.raycast.march`), collisions are a footprint test against the body grid; observations, rewards
(`Reward.batch`), episode ends and the reset draws are PointNav's. docs/batched.md says what differs from the
PyBullet env (the reference, and the env for terrain and contact-rich work) and by how much.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numba import typed

from kernel.config import ConfigError
from sim.batched.atlas import Atlas, touched_objects
from sim.batched.episodes import KIND_BITS, Episodes
from sim.batched.kinematics import Drive
from sim.batched.lidar import BatchLidar, lidar_pair
from sim.batched.routes import RouteBatch
from sim.batched.scene_store import BuiltScene, SceneStore
from sim.envs.observation import GOAL_LOG_SCALE, EgoObservation
from sim.envs.reset_options import check_reset_options
from sim.envs.worlds import SceneSource
from sim.machines import machine_spec
from sim.raycast.grids import CROSSWALK, KIND_NAMES, LOW_RAMP, OBJECT, ROAD_LEVEL, SIDEWALK_LEVEL, labels_at
from sim.route import ROUTE_REDRAWS, Route, RouteError
from sim.schema import Int, Key, Rule, Table, defaults_of, table_of
from sim.tasks.pointnav import (
    CONFIG_KEYS,
    TASK_PRESETS,
    check_config,
    make_reward,
    resolve_task_config,
)
from sim.tasks.sensors import check_lidar_reach

# PointNav's keys plus the batched env's own.
BATCHED_KEYS: dict[str, Key | dict[str, Key]] = {
    **CONFIG_KEYS,
    "route_pool": Key(
        0, Int(0, 1_000_000), "routes kept per scene and drawn from once full (0: plan every reset, as PointNav)"
    ),
}
BATCHED_DEFAULTS: dict[str, Any] = defaults_of(BATCHED_KEYS)
BATCHED_TABLE: dict[str, Rule | Table] = table_of(BATCHED_KEYS)
# Contacts (`BatchedPointNav._slide`): Bullet's frictionless contacts let a machine that runs into a wall at an angle
# slide along it, and the push on its front corner turns it parallel to the wall. Measured in the PyBullet env on the
# test street: the delivery robot into a building wall at 48 degrees turns parallel in ~3.2 s, at ~15 degrees a second
# whatever its speed (`tests/sim/test_batched.py`).
ALIGN_RATE = math.radians(16.0)  # rad/s: how fast a contact turns the machine towards the surface's tangent
# Past a critical angle between the heading and the surface the push on the front corner turns the machine the other
# way, to face the surface, and it stands: measured in the PyBullet env on the test street with the delivery robot at
# 2 and 5 m/s, into a building wall it slides at 50 degrees and faces the wall at 55 and more; into a curb from the
# road it slides at 45 and faces the curb at 50 and more, at any speed (`tests/sim/test_batched.py`).
STEEP_WALL = math.radians(52.5)  # buildings and objects
STEEP_CURB = math.radians(47.5)  # a curb alone
# The sideways shifts (m) a raycast vehicle's grazing contact may push it by in one substep (`_deflect`).
DEFLECT_STEPS = (0.02, 0.05, 0.1, 0.15)
RING_DIRS = np.stack([np.cos(np.arange(16) * np.pi / 8), np.sin(np.arange(16) * np.pi / 8)], 1)
RING_RADIUS_CELLS = 3  # the ring around a contact whose occupied cells give the surface's normal

# PointNav keys the batched env cannot honour: (key, the value it needs, why).
PYBULLET_ONLY = (
    ("gui", False, "there is no PyBullet world to show"),
    ("collision", "box", "objects are their spec boxes; convex hulls need the PyBullet env"),
)


class BatchedPointNav(VectorEnv):
    """`num_envs` PointNav episodes in one numpy pass; `config` as PointNavEnv's plus `route_pool` and `scene_steps`
        (scene builds cost seconds at paper scale: an env that keeps its scene for many steps amortises them).

        The LiDARs and the collision test read the scene's distance grids at `lidar.resolution` (sim.raycast.grids).

        Autoreset is SAME_STEP (as curbside.train.sharded): a finished env is reset within `step`; its last observation is
        `info["final_obs"][i]` and its last info (with the episode's metrics) is `info["final_info"]` under mask
        `info["_final_info"]`. Envs whose `autoreset[i]` is False are not reset when they finish (an evaluation that has
    all its episodes of env i sets it: a reset there would build a scene no one uses); they keep stepping their finished
    episode until the next `reset()`, which sets every flag back. Per-step info: `cost`, `route_completion`, `out_of_route`, `stuck`, `cost_exceeded`, and `collisions`
        (bit mask of the kinds touched: `sim.batched.episodes.KIND_BITS`).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}
    # The task's config (defaults, rules, presets) and collision kinds: a subclass for another task replaces them.
    defaults: dict[str, Any] = BATCHED_DEFAULTS
    table: dict[str, Rule | Table] = BATCHED_TABLE
    presets: Mapping[str, Mapping[str, Any]] = TASK_PRESETS
    kind_bits: Mapping[str, int] = KIND_BITS

    def __init__(
        self, num_envs: int = 1, config: Mapping[str, Any] | None = None, render_mode: str | None = None, **kwargs: Any
    ) -> None:
        if kwargs:
            raise ConfigError(f"unknown BatchedPointNav argument(s) {sorted(kwargs)}; valid: num_envs, config")
        if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
            raise ConfigError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if render_mode is not None:
            raise ConfigError("BatchedPointNav does not render; use the PyBullet env (curbside/PointNav-v0) for images")
        self.config = cfg = resolve_task_config(self.defaults, config, self.presets)
        check_config(cfg, self.table, self.defaults)
        for key, need, why in PYBULLET_ONLY:
            if cfg[key] != need:
                raise ConfigError(f"config.{key} must be {need!r} in the batched env: {why}")
        if cfg["camera"]["modalities"] or cfg["observation"] == "dict" or cfg["visual_meshes"] is True:
            raise ConfigError(
                "config.camera.modalities must be [], observation flat and visual_meshes not true in the "
                "batched env: there is nothing to render; use the PyBullet env (curbside/PointNav-v0)"
            )
        self.num_envs = n_envs = num_envs
        self.render_mode = None
        self.spec_machine = machine_spec(cfg["machine"])
        check_lidar_reach(cfg["lidar"], self.spec_machine.length, self.spec_machine.width)
        self.reward_fn = make_reward(cfg["reward_preset"], cfg["reward"])
        self.dt = float(cfg["dt"])
        self.substeps = int(cfg["physics_substeps"])
        self.observation = EgoObservation(cfg)
        self.observation_names = self.observation.names
        self.single_observation_space = self.observation.space
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, n_envs)
        self.action_space = batch_space(self.single_action_space, n_envs)
        self.sources = SceneSource(cfg)
        if cfg["lidar"]["static"] == "bullet":
            raise ConfigError(
                "config.lidar.static must be 'grid' (or 'auto') in the batched env: there is no Bullet "
                "world to ray-test"
            )
        self.atlas = Atlas(float(cfg["lidar"]["resolution"]))
        self.store = SceneStore(cfg, self.spec_machine, self.atlas)
        self.drive = Drive(self.spec_machine, n_envs)
        self.lidar, self.low_lidar = lidar_pair(cfg, self.drive.bounding_radius)
        self.routes = RouteBatch(n_envs)
        self.episodes = Episodes(n_envs, cfg, self.kind_bits)
        self.rngs = [np.random.default_rng() for _ in range(n_envs)]
        self.built: list[BuiltScene | None] = [None] * n_envs
        self.slots = np.zeros(n_envs, dtype=np.int64)
        self.scene_steps_left = np.zeros(n_envs, dtype=np.int64)
        self.level = np.zeros(n_envs, dtype=np.int64)
        self.body_level = np.zeros(n_envs, dtype=np.int64)  # the level the body collides at (`_locate_level`)
        self.reference = np.zeros(n_envs)  # SPL's reference length of each env's route
        self.labels = np.zeros(n_envs, dtype=np.int64)
        self._walk_grids: list[Any] = []  # the walkable grids `_locate_level` last read, and their numba list
        self._walk_masks: Any = None
        self._walk_frames: tuple[np.ndarray, np.ndarray] = (np.zeros((0, 2)), np.zeros(0))
        self._started = False
        self.autoreset = np.ones(n_envs, dtype=bool)
        hl, hw = 0.5 * self.spec_machine.length, 0.5 * self.spec_machine.width
        res = self.atlas.resolution
        u, w = np.meshgrid(
            np.linspace(-hl, hl, int(math.ceil(2 * hl / res)) + 1),
            np.linspace(-hw, hw, int(math.ceil(2 * hw / res)) + 1),
        )
        self._body_u, self._body_w = u.ravel(), w.ravel()  # points covering the footprint, a cell apart at most
        self._kind_bits = np.zeros(256, dtype=np.int64)  # a kind grid's code -> its collision bit
        for code, name in KIND_NAMES.items():
            self._kind_bits[code] = self.kind_bits[name]

    # -- resets --------------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env: `seed` an int gives env i seed + i (the draws of PointNavEnv.reset(seed=seed + i));
        options {"start": [x, y], "goal": [x, y]} (or one pair per env) plan that route in every env."""
        points = check_reset_options(options, self.num_envs)
        seeds = (
            [seed + i for i in range(self.num_envs)]
            if isinstance(seed, int)
            else (list(seed) if seed is not None else [None] * self.num_envs)
        )
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} envs")
        for i, s in enumerate(seeds):
            if s is not None or not self._started:
                self.rngs[i] = np.random.default_rng(s)
        self._started = True
        self.autoreset[:] = True
        info = self._reset_envs(
            np.arange(self.num_envs), None if points is None else dict(zip(("start", "goal"), points))
        )
        return self._observe(), info

    def _reset_envs(self, envs: np.ndarray, options: Mapping[str, Any] | None) -> dict[str, Any]:
        cfg = self.config
        lengths, horizons = np.zeros(self.num_envs), np.zeros(self.num_envs, dtype=np.int64)
        for k in envs.tolist():
            built, route = self._draw_route(k, options)
            yaw = route.heading_at(0.0)
            self.drive.reset(k, float(route.start[0]), float(route.start[1]), yaw, self.rngs[k])
            horizon = int(cfg["horizon"])
            if cfg["horizon_min_speed"] is not None:
                horizon = min(horizon, max(int(math.ceil(route.length / cfg["horizon_min_speed"] / self.dt)), 1))
            self.episodes.reset(k, horizon)
            self.routes.set(k, route)
            self.reference[k] = self.store.reference_length(built, route)
            lengths[k], horizons[k] = route.length, horizon
            self._start_episode(k, built, route)
        self.body_level[envs] = SIDEWALK_LEVEL  # a new episode's body level follows from its start alone
        self._locate_level(envs)
        self._started_episodes(envs)
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[envs] = True
        return {"route_length": lengths, "_route_length": mask, "horizon": horizons, "_horizon": mask.copy()}

    def _start_episode(self, k: int, built: BuiltScene, route: Route) -> None:
        """Hook: env k's episode starts on `route` in `built`, the machine at the start (its draws come next)."""

    def _started_episodes(self, envs: np.ndarray) -> None:
        """Hook: envs `envs` have started their episodes (levels located)."""

    def _draw_route(self, k: int, options: Mapping[str, Any] | None) -> tuple[BuiltScene, Route]:
        """Env k's scene (a new one when its `scene_steps` are spent) and next route; a scene with no route of
        the asked length is swapped for another draw, up to ROUTE_REDRAWS scenes."""
        rng = self.rngs[k]
        for attempt in range(ROUTE_REDRAWS):
            built = self.built[k]
            if built is None or self.scene_steps_left[k] <= 0 or attempt > 0:
                key, load = self.sources.draw(rng)
                if built is not None:
                    self.store.release(built)
                built = self.built[k] = self.store.acquire(key, load)
                self.scene_steps_left[k] = int(self.config["scene_steps"])
            self.slots[k] = built.slot
            try:
                return built, self.store.route(built, rng, options, k)
            except RouteError:
                if options or attempt == ROUTE_REDRAWS - 1:
                    raise
        raise AssertionError("unreachable")

    def _locate_level(self, envs: np.ndarray | None = None) -> None:
        """Walkable labels under the machines (off-walkable ends, which level the machine is on)."""
        drive = self.drive
        k = np.arange(self.num_envs) if envs is None else np.asarray(envs, dtype=np.int64)
        scenes: dict[int, int] = {}  # id of a built scene -> its index among this call's distinct scenes
        grids: list[Any] = []  # their walkable grids
        scene_of = np.empty(k.size, dtype=np.int64)
        for j, env in enumerate(k.tolist()):
            built = self.built[env]
            assert built is not None  # located envs have scenes
            at = scenes.setdefault(id(built), len(grids))
            if at == len(grids):
                grids.append(built.scene.walkable)
            scene_of[j] = at
        if len(grids) != len(self._walk_grids) or any(a is not b for a, b in zip(grids, self._walk_grids)):
            # Scenes change seldom: their masks as a numba list (one compiled kernel whatever their number).
            self._walk_grids = grids
            self._walk_masks = typed.List([g.mask for g in grids])
            self._walk_frames = (
                np.array([g.origin for g in grids], dtype=np.float64).reshape(-1, 2),
                np.array([g.resolution for g in grids], dtype=np.float64),
            )
        self.labels[k] = labels_at(self._walk_masks, *self._walk_frames, scene_of, drive.x[k], drive.y[k])
        if self.spec_machine.rides:
            # A raycast vehicle drives over curbs: off the sidewalks (the road, a crosswalk) it is at the road's level,
            # body and LiDAR alike, and no ramp's low part holds it back.
            self.level = np.where((self.labels == CROSSWALK) | (self.labels == 0), ROAD_LEVEL, SIDEWALK_LEVEL)
            self.body_level = self.level.copy()
            return
        self.level = np.where(self.labels == CROSSWALK, ROAD_LEVEL, SIDEWALK_LEVEL)
        # The body's level: the road's on the lower half of a curb ramp as well, where Bullet's wedge is low enough
        # that the sidewalk beside it is a curb to climb (the LiDAR keeps `level`, as the PyBullet env's grid LiDAR
        # does). A machine that comes down onto it from the sidewalk, part of its body still over the sidewalk, keeps
        # the sidewalk's level until its body is clear of it: dropping off a flank is free, climbing one is not.
        drive = self.drive
        kinds = self.atlas.frames(self.slots, np.zeros(self.num_envs, dtype=np.int64), "kinds")
        low_ramp = self.atlas.lookup(kinds, drive.x[:, None], drive.y[:, None])[:, 0] == LOW_RAMP
        was = self.body_level
        self.body_level = np.where(low_ramp & (was == ROAD_LEVEL), ROAD_LEVEL, self.level)
        entering = np.nonzero(low_ramp & (self.body_level == SIDEWALK_LEVEL))[0]
        if entering.size:
            self.body_level[entering] = ROAD_LEVEL
            over_sidewalk, _ = self._collide_static(entering, drive.x[entering], drive.y[entering], drive.yaw[entering])
            self.body_level[entering[over_sidewalk]] = SIDEWALK_LEVEL

    # -- stepping ------------------------------------------------------------------------------------
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance every env by dt (config, 0.1 s): drive, collide, sense, reward; finished envs reset in place."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if np.iscomplexobj(actions):
            raise ValueError("actions hold complex numbers; pass [steering, throttle_brake] per env as real numbers")
        act = np.asarray(actions, dtype=np.float64)
        if act.shape != (self.num_envs, 2):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, 2) [steering, throttle_brake], got {act.shape}"
            )
        bad = ~np.isfinite(act).all(axis=1)
        if bad.any():
            raise ValueError(
                f"actions of env(s) {np.nonzero(bad)[0].tolist()} hold NaN or inf; policies must output "
                "finite values in [-1, 1]"
            )
        act = np.clip(act, -1.0, 1.0)
        steer, throttle = act[:, 0], act[:, 1]
        drive, ep = self.drive, self.episodes
        x0, y0 = drive.x.copy(), drive.y.copy()
        sub_dt = self.dt / self.substeps
        hits = np.zeros(self.num_envs, dtype=np.int64)
        charge_once = ep.cost_rule.once and bool(ep.cost_bits & KIND_BITS["object"])
        new_static = np.zeros(self.num_envs, dtype=bool)
        every = np.arange(self.num_envs)
        for _ in range(self.substeps):
            v, w = drive.command(steer, throttle, sub_dt)
            x, y, yaw = drive.integrate(v, w, sub_dt)
            blocked, kinds = self._collide(every, x, y, yaw)
            hits |= kinds
            if charge_once:
                self._charge_objects(np.nonzero((kinds & KIND_BITS["object"]) > 0)[0], x, y, yaw, new_static)
            stopped = None
            if blocked.any():
                envs = np.nonzero(blocked)[0]
                normals = self._contact_normals(envs, x, y, yaw)
                rest_x, rest_y = self._back_off(envs, x, y, yaw)
                stopped = np.zeros(self.num_envs, dtype=bool)
                if self.spec_machine.rides:  # a chassis box glancing off a box is pushed aside (`_deflect`)
                    deflected = self._deflect(envs, normals, rest_x, rest_y, x, y, yaw)
                    envs, normals = envs[~deflected], normals[~deflected]
                    rest_x, rest_y = rest_x[~deflected], rest_y[~deflected]
                steep = np.where(kinds[envs] == KIND_BITS["curb"], STEEP_CURB, STEEP_WALL)
                stopped[envs] = self._slide(envs, normals, steep, rest_x, rest_y, x, y, yaw, v, sub_dt)
            drive.store(x, y, yaw, v, w, sub_dt, stopped)
        hits |= self._after_substeps(act)
        arclen, lat = self.routes.locate(drive.x, drive.y, ep.progress)
        progress, new_progress, collided = ep.advance(drive.x - x0, drive.y - y0, arclen, lat, hits, new_static)
        self._locate_level()
        building = (hits & KIND_BITS["building"]) > 0
        succeeded, out, stuck, over, crashed = ep.end(self.routes.length, self.labels != 0, hits != 0, building)
        reward = self.reward_fn.batch(
            progress,
            new_progress,
            lat,
            steer - ep.last_action[:, 0],
            drive.speed,
            collided,
            succeeded,
            out,
            stuck | over | crashed,
            steer,
            np.abs(drive.speed) / self.spec_machine.v_max,
        ).astype(np.float64)
        ep.last_action = act
        self.scene_steps_left -= 1
        terminated = succeeded | out | stuck | over | crashed
        truncated = ~terminated & (ep.steps >= ep.horizon)
        obs = self._observe()
        on = np.ones(self.num_envs, dtype=bool)
        info: dict[str, Any] = {
            "cost": collided.astype(np.float64),
            "route_completion": np.minimum(ep.max_progress / self.routes.length, 1.0),
            "out_of_route": out,
            "stuck": stuck,
            "cost_exceeded": over,
            "crashed": crashed,
            "collisions": hits,
        }
        info.update({f"_{k}": on for k in list(info)})
        done = terminated | truncated
        if done.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for k in np.nonzero(done)[0].tolist():
                final_obs[k] = obs[k].copy()
            final_info = self._final_info(info, done, succeeded)
            envs = np.nonzero(done & self.autoreset)[0]
            if len(envs):
                info.update(self._reset_envs(envs, None))
                obs[envs] = self._observe()[envs]
            info.update({"final_obs": final_obs, "_final_obs": done, "final_info": final_info, "_final_info": done})
        return obs, reward, terminated, truncated, info

    def _final_info(self, info: dict[str, Any], done: np.ndarray, succeeded: np.ndarray) -> dict[str, Any]:
        """The last step's info of the finished envs plus their episode's metrics (masks: `done`)."""
        ep = self.episodes
        out = {k: v.copy() for k, v in info.items() if not k.startswith("_")}
        spl = np.where(succeeded, self.reference / np.maximum(np.maximum(ep.path_length, self.reference), 1e-9), 0.0)
        out.update(
            {
                "is_success": succeeded.copy(),
                "success": succeeded.astype(np.float64),
                "spl": spl,
                "episode_cost": ep.cost_total.astype(np.float64),
                "path_length": ep.path_length.copy(),
                "time": ep.steps * self.dt,
                "steps": ep.steps.copy(),
            }
        )
        out.update({f"collisions_{k}": c.copy() for k, c in ep.collision_counts.items()})
        out.update({f"_{k}": done for k in list(out)})
        return out

    def _after_substeps(self, actions: np.ndarray) -> np.ndarray:
        """Hook: every machine has moved through the step's substeps (`actions` [n, 2], clipped); returns the kind
        bits of contacts made after them (PointNav: none)."""
        return np.zeros(self.num_envs, dtype=np.int64)

    def _collide(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(blocked, kind bits) of envs `envs` with footprints at (x, y, yaw) (arrays over `envs`): what the machines
        collide with (PointNav: the scene's solids, `_collide_static`)."""
        return self._collide_static(envs, x, y, yaw)

    def _collide_static(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(blocked, kind bits) of envs `envs` with footprints at (x, y, yaw) (arrays over `envs`): blocked when a
        point of the footprint lies on an occupied cell of the body grid; the bits say what those cells hold."""
        slots, level = self.slots[envs], self.body_level[envs]
        return self.atlas.footprints(
            self.atlas.frames(slots, level, "body"),
            self.atlas.frames(slots, level, "kinds"),
            x,
            y,
            np.cos(yaw),
            np.sin(yaw),
            self._body_u,
            self._body_w,
            self.drive.bounding_radius + 2.0 * self.atlas.resolution,
            self._kind_bits,
        )

    def _charge_objects(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, new_static: np.ndarray
    ) -> None:
        """Envs `envs`, whose footprints at (x, y, yaw) overlap object cells, charge the objects they touch that they
        have not touched before in the episode (`new_static`, `Episodes.charged`): the object of each overlapping
        point is the one whose footprint's bounding circle it lies deepest in (the PyBullet env knows its bodies)."""
        for k in envs.tolist():
            built = self.built[k]
            assert built is not None  # stepping envs have scenes
            centres, radii = built.object_circles()
            if centres.size == 0:
                continue
            slot, level = self.slots[k : k + 1], self.body_level[k : k + 1]
            body = self.atlas.frames(slot, level, "body")
            kinds = self.atlas.frames(slot, level, "kinds")
            touched = set(
                touched_objects(
                    self.atlas.flat,
                    int(body["offset"][0]),
                    int(kinds["offset"][0]),
                    float(body["x0"][0]),
                    float(body["y0"][0]),
                    int(body["cols"][0]),
                    int(body["rows"][0]),
                    1.0 / self.atlas.resolution,
                    float(x[k]),
                    float(y[k]),
                    math.cos(yaw[k]),
                    math.sin(yaw[k]),
                    self._body_u,
                    self._body_w,
                    OBJECT,
                    centres,
                    radii,
                ).tolist()
            )
            touched -= self.episodes.charged[k]
            if touched:
                self.episodes.charged[k] |= touched
                new_static[k] = True

    def _back_off(
        self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray, rounds: int = 5
    ) -> tuple[np.ndarray, np.ndarray]:
        """Move blocked envs' new poses (in place) back along the substep to the last free fraction of it (bisection:
        within 1/32 of the substep's motion), where the machine meets what it ran into; return the motion (x, y) the
        substep had left."""
        drive = self.drive
        x0, y0, yaw0 = drive.x[envs], drive.y[envs], drive.yaw[envs]
        dx, dy = x[envs] - x0, y[envs] - y0
        dyaw = (yaw[envs] - yaw0 + np.pi) % (2.0 * np.pi) - np.pi
        lo, hi = np.zeros(envs.size), np.ones(envs.size)
        for _ in range(rounds):
            mid = 0.5 * (lo + hi)
            blocked, _ = self._collide(envs, x0 + mid * dx, y0 + mid * dy, yaw0 + mid * dyaw)
            hi = np.where(blocked, mid, hi)
            lo = np.where(blocked, lo, mid)
        x[envs], y[envs], yaw[envs] = x0 + lo * dx, y0 + lo * dy, yaw0 + lo * dyaw
        return (1.0 - lo) * dx, (1.0 - lo) * dy

    def _contact_normals(self, envs: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray) -> np.ndarray:
        """Unit normals [len(envs), 2] of the obstacle surfaces that envs `envs` run into at poses (x, y, yaw): away
        from the occupied cells around the centroid of the footprint's points inside the obstacle (a flat wall
        occupies half the ring around that point, so the sum of the occupied directions is its inward normal)."""
        frame = self.atlas.frames(self.slots[envs], self.body_level[envs], "body")
        cos, sin = np.cos(yaw[envs])[:, None], np.sin(yaw[envs])[:, None]
        px = x[envs, None] + cos * self._body_u - sin * self._body_w
        py = y[envs, None] + sin * self._body_u + cos * self._body_w
        inside = self.atlas.lookup(frame, px, py) == 0
        count = np.maximum(inside.sum(axis=1), 1)
        cx, cy = (inside * px).sum(axis=1) / count, (inside * py).sum(axis=1) / count
        ring = RING_RADIUS_CELLS * self.atlas.resolution
        occupied = (
            self.atlas.lookup(frame, cx[:, None] + ring * RING_DIRS[:, 0], cy[:, None] + ring * RING_DIRS[:, 1]) == 0
        )
        normal = -(occupied[:, :, None] * RING_DIRS[None]).sum(axis=1)
        # A ring all free (a thin pole) or all occupied: the normal points from the contact to the machine's centre.
        flat = np.hypot(normal[:, 0], normal[:, 1]) < 1e-9
        normal[flat] = np.stack([x[envs] - cx, y[envs] - cy], 1)[flat]
        length = np.hypot(normal[:, 0], normal[:, 1])
        heading = np.stack([np.cos(yaw[envs]), np.sin(yaw[envs])], 1)
        return np.where((length > 1e-9)[:, None], normal / np.maximum(length, 1e-9)[:, None], -heading)

    def _deflect(
        self,
        envs: np.ndarray,
        normals: np.ndarray,
        rest_x: np.ndarray,
        rest_y: np.ndarray,
        x: np.ndarray,
        y: np.ndarray,
        yaw: np.ndarray,
    ) -> np.ndarray:
        """Blocked envs `envs` (raycast vehicles, at their contact poses) whose chassis only grazes the obstacle go on:
        Bullet resolves a box meeting a box along the shallowest overlap, so a corner that catches an object's corner
        is pushed aside and the machine passes (measured in the PyBullet env: MetaUrban's ego driven at the street's
        trash bin 0.7 m off its centre line passes it). The rest of the substep's motion plus a sideways shift of up
        to the largest of DEFLECT_STEPS m, away from the obstacle, is tried; poses change in place; returns which envs deflected."""
        done = np.zeros(envs.size, dtype=bool)
        c, sn = np.cos(yaw[envs]), np.sin(yaw[envs])
        lx, ly = -sn, c  # the machine's left
        side = np.where(normals[:, 0] * lx + normals[:, 1] * ly >= 0.0, 1.0, -1.0)  # away from the obstacle
        for shift in DEFLECT_STEPS:
            todo = np.nonzero(~done)[0]
            if todo.size == 0:
                break
            k = envs[todo]
            new_x = x[k] + rest_x[todo] + shift * side[todo] * lx[todo]
            new_y = y[k] + rest_y[todo] + shift * side[todo] * ly[todo]
            blocked, _ = self._collide(k, new_x, new_y, yaw[k])
            free = ~blocked
            x[k[free]], y[k[free]] = new_x[free], new_y[free]
            done[todo[free]] = True
        return done

    def _slide(
        self,
        envs: np.ndarray,
        normals: np.ndarray,
        steep: np.ndarray,
        rest_x: np.ndarray,
        rest_y: np.ndarray,
        x: np.ndarray,
        y: np.ndarray,
        yaw: np.ndarray,
        v: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Blocked envs `envs`, at their contact poses (x, y, yaw), slide along the surface for the rest of the
        substep (rest_x, rest_y) and turn towards it, as a machine on Bullet's frictionless contacts does: the
        motion into the surface is dropped, the speed read along the heading loses the part into it (v (1 - (h.n)^2)),
        and the contact turns the heading towards the surface's tangent at ALIGN_RATE. A machine meeting the surface
        at more than its `steep` angle (radians, per env) turns to face it instead, at the same rate, and stands.
        Poses and `v` change in place; returns the envs (of `envs`) that could not move at all, which stop."""
        nx, ny = normals[:, 0], normals[:, 1]
        heading = yaw[envs]
        hx, hy = np.cos(heading), np.sin(heading)
        hn = hx * nx + hy * ny
        head_on = -hn > np.sin(steep)
        into = np.minimum(rest_x * nx + rest_y * ny, 0.0)
        sx = np.where(head_on, 0.0, rest_x - into * nx)
        sy = np.where(head_on, 0.0, rest_y - into * ny)
        # The tangent nearer the heading (or, head on, the inward normal), and the turn towards it this substep (at
        # most ALIGN_RATE dt).
        side = np.where(hy * nx - hx * ny >= 0.0, 1.0, -1.0)
        tx, ty = np.where(head_on, -nx, -side * ny), np.where(head_on, -ny, side * nx)
        gap = np.arctan2(hx * ty - hy * tx, hx * tx + hy * ty)
        turn = np.where(hn < 0.0, np.clip(gap, -ALIGN_RATE * dt, ALIGN_RATE * dt), 0.0)
        moved = np.zeros(envs.size, dtype=bool)
        for dyaw in (turn, np.zeros_like(turn)):  # with the turn; else straight (the turned body does not fit)
            todo = np.nonzero(~moved)[0]
            if todo.size == 0:
                break
            k = envs[todo]
            new_x, new_y = x[k] + sx[todo], y[k] + sy[todo]
            new_yaw = (heading[todo] + dyaw[todo] + np.pi) % (2.0 * np.pi) - np.pi
            blocked, _ = self._collide(k, new_x, new_y, new_yaw)
            free = ~blocked
            x[k[free]], y[k[free]], yaw[k[free]] = new_x[free], new_y[free], new_yaw[free]
            moved[todo[free]] = True
        v[envs] = np.where(moved & (hn < 0.0), v[envs] * (1.0 - hn * hn), v[envs])
        return ~moved | head_on

    # -- observation ---------------------------------------------------------------------------------
    def _observe(self) -> np.ndarray:
        """Every env's observation (the layout of `EgoObservation`, PointNavEnv's table)."""
        drive, ep, routes, observation = self.drive, self.episodes, self.routes, self.observation
        parts = [self._scan(self.lidar)]
        if self.low_lidar is not None:
            parts.append(self._scan(self.low_lidar))
        heading_err = (drive.yaw - routes.heading_at(ep.progress) + np.pi) % (2.0 * np.pi) - np.pi
        cos, sin = np.cos(drive.yaw)[:, None], np.sin(drive.yaw)[:, None]
        wp = routes.point_at(ep.progress[:, None] + observation._wp_offsets[None])
        dx, dy = wp[..., 0] - drive.x[:, None], wp[..., 1] - drive.y[:, None]
        ego = np.stack(
            [(cos * dx + sin * dy) * observation._wp_scale, (-sin * dx + cos * dy) * observation._wp_scale], -1
        ).reshape(self.num_envs, -1)
        gx, gy = routes.goal[:, 0] - drive.x, routes.goal[:, 1] - drive.y
        bearing = np.arctan2(gy, gx) - drive.yaw
        state = np.stack(
            [
                drive.speed / observation.speed_scale,
                drive.yaw_rate / 2.0,
                heading_err / np.pi,
                ep.lateral / observation.lateral_scale,
                ep.last_action[:, 0],
                ep.last_action[:, 1],
            ],
            1,
        )
        tail = np.stack([np.log1p(np.hypot(gx, gy)) / GOAL_LOG_SCALE, np.sin(bearing), np.cos(bearing)], 1)
        obs = np.concatenate([*parts, state.astype(np.float32), ego.astype(np.float32), tail.astype(np.float32)], 1)
        np.clip(obs, -1.0, 1.0, out=obs)
        return obs

    def _scan(self, lidar: BatchLidar) -> np.ndarray:
        """`lidar`'s encoded scans [n, beams] of every env (PointNav: the scenes' static solids)."""
        drive = self.drive
        return lidar.scan(self.atlas, self.slots, self.level, drive.x, drive.y, drive.yaw)

    def close_extras(self, **kwargs: Any) -> None:
        """Drop the scenes' grids."""
        self.store.built.clear()
        self.atlas = Atlas(self.atlas.resolution)
