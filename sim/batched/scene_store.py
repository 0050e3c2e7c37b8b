"""The scenes the batched envs run in: built once each (distance grids in the atlas, route planner, route pool),
kept while any env uses them, and otherwise up to `scene_cache` least recently used ones.

Scene choice is the PyBullet env's: `sim.envs.worlds.SceneSource.draw` with the sub-env's generator, so sub-env i
reset with seed s draws the scene and route `PointNavEnv.reset(seed=s)` draws (with `route_pool` 0).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.batched.atlas import Atlas
from sim.envs.worlds import trim_heap
from sim.machines import MachineSpec
from sim.raycast.grids import build_grids
from sim.route import Route, RoutePlanner
from sim.scene.scene import Scene


@dataclass
class BuiltScene:
    """One scene's batched structures: its atlas slot, walkable grid and planner, and its pool of routes."""

    key: Any
    scene: Scene
    slot: int
    planner: RoutePlanner
    pool: list[Route] = field(default_factory=list)
    references: dict[int, float] = field(default_factory=dict)  # SPL's reference length of each pool route, by id
    users: int = 0  # envs whose episode runs in it now
    _circles: tuple[np.ndarray, np.ndarray] | None = None

    def object_circles(self) -> tuple[np.ndarray, np.ndarray]:
        """The scene's objects' footprint centres [n, 2] and bounding radii [n] (made on first use: contacts)."""
        if self._circles is None:
            feet = [np.asarray(o["footprint"], dtype=np.float64) for o in self.scene.objects]
            centres = np.array([f.mean(axis=0) for f in feet]).reshape(-1, 2)
            radii = np.array([np.hypot(*(f - f.mean(axis=0)).T).max() for f in feet]).reshape(-1)
            self._circles = (centres, radii)
        return self._circles


class SceneStore:
    """Built scenes by key; `acquire` builds or reuses one for an env, `release` when the env leaves it."""

    def __init__(self, cfg: Mapping[str, Any], spec: MachineSpec, atlas: Atlas) -> None:
        self.cfg = cfg
        self.spec = spec
        self.atlas = atlas
        self.size = int(cfg["scene_cache"])
        self.pool_size = int(cfg["route_pool"])
        self.built: OrderedDict[Any, BuiltScene] = OrderedDict()
        self.by_slot: dict[int, BuiltScene] = {}

    def acquire(self, key: Any, load: Callable[[], Scene]) -> BuiltScene:
        """The built scene of `key` (built now if new), counted as used by one more env."""
        b = self.built.get(key)
        if b is None:
            self._evict()
            scene = load()
            grids = build_grids(
                scene,
                resolution=float(self.cfg["lidar"]["resolution"]),
                lidar=self.cfg["lidar"],
                body_height=self.spec.height,
                step_max=self.spec.wheel_radius,  # a step up to the wheels' axle height is climbed
                clearance=self.spec.clearance,
            )
            planner = RoutePlanner(scene, self.spec.half_width, margin=float(self.cfg["route_margin"]))
            b = BuiltScene(key=key, scene=scene, slot=self.atlas.add(grids), planner=planner)
            self.built[key] = b
            self.by_slot[b.slot] = b
            trim_heap()  # the evicted scenes' grids and the atlas's old flat array are freed now
        self.built.move_to_end(key)
        b.users += 1
        return b

    def release(self, b: BuiltScene) -> None:
        """One env fewer runs in `b`."""
        b.users -= 1

    def _evict(self) -> None:
        """Drop least recently used scenes no env uses while the store holds `size` or more."""
        while len(self.built) >= self.size:
            idle = next((k for k, b in self.built.items() if b.users == 0), None)
            if idle is None:
                return  # every kept scene is in use: the store grows past `size`
            b = self.built.pop(idle)
            del self.by_slot[b.slot]
            self.atlas.remove(b.slot)

    def reference_length(self, b: BuiltScene, route: Route) -> float:
        """l of SPL, as PointNavEnv.reference_length: the geodesic to the route point where success is reached
        (computed once for a pool route)."""
        cached = b.references.get(id(route))
        if cached is not None:
            return cached
        length = b.planner.geodesic_length(route, float(self.cfg["success_completion"]) * route.length)
        if any(r is route for r in b.pool):
            b.references[id(route)] = length
        return length

    def route(self, b: BuiltScene, rng: np.random.Generator, options: Mapping[str, Any] | None, k: int) -> Route:
        """Env k's next route in `b`: between given points, drawn as PointNavEnv draws it, or from the pool."""
        if options:  # checked by the env (sim.envs.reset_options): (start, goal) arrays
            start, goal = options["start"], options["goal"]
            return b.planner.plan(start[k] if start.ndim == 2 else start, goal[k] if goal.ndim == 2 else goal)
        lo, hi = (float(v) for v in self.cfg["route_length"])
        if self.pool_size == 0:
            return b.planner.sample(rng, lo, hi)
        if len(b.pool) < self.pool_size:
            b.pool.append(b.planner.sample(rng, lo, hi))
            return b.pool[-1]
        return b.pool[int(rng.integers(len(b.pool)))]
