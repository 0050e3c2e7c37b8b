"""Where an env's episodes happen: which scene an episode draws, and a bounded cache of built worlds.

Each cached scene lives in its own Bullet client (world, machine body, LiDARs, route planner), so going back
to a scene costs no build: training over thousands of scenes pays one build per new scene and milliseconds
per repeat. The least recently used scene's client is reused for the next new scene.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import ConfigError
from kernel.quiet import pybullet as p
from sim.camera import EgoCamera, forget_egl
from sim.machines import Machine
from sim.raycast.grids import build_grids
from sim.route import RoutePlanner
from sim.scene.config import resolve_config
from sim.scene.grid import SIDEWALK
from sim.scene.scene import Scene
from sim.sensors import GridLidar, Lidar
from sim.tasks.pointnav import MAX_SEED, static_lidar
from sim.tasks.scene_loader import dataset_scenes, generator_config, load_scene, read_scene, split_seed_offset
from sim.world import World


@dataclass
class SceneSlot:
    """One built scene: its Bullet client and the objects that live in it, plus the env managers' state there."""

    key: Any
    client: int
    scene: Scene | None = None
    world: Any = None
    machine: Any = None
    lidar: Any = None
    low_lidar: Any = None
    planner: Any = None
    camera: Any = None  # sim.camera.EgoCamera when config.camera has modalities
    collision_kinds: dict[int, str] = field(default_factory=dict)  # body id -> kind of the managers' bodies
    manager_states: list[Any] = field(default_factory=list)  # each manager's leave_scene(), saved when left


def check_has_sidewalks(scene: Scene, source: str) -> None:
    """A ConfigError unless `scene` lists a sidewalk and its walkable raster holds sidewalk cells: routes start and
    end on sidewalks, so a scene without them fails every reset."""
    if not scene.sidewalks or not (scene.walkable.mask == SIDEWALK).any():
        raise ConfigError(
            f"{source} has no sidewalk (its `sidewalks` list or its walkable raster is empty of them); "
            "routes run on sidewalks: generate a scene with `curbside scenes generate` or add them"
        )


class SceneSource:
    """Which scene an episode runs in: a fixed spec or file, a dataset folder's split, or generated seeds."""

    def __init__(self, config: Mapping[str, Any]) -> None:
        self.config = config
        num_scenes = config["num_scenes"]
        if num_scenes is not None and (
            not isinstance(num_scenes, int) or isinstance(num_scenes, bool) or num_scenes < 1
        ):
            raise ConfigError(f"config.num_scenes must be an integer >= 1 (or None), got {num_scenes!r}")
        seed = config["scene_seed"]
        if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < MAX_SEED:
            raise ConfigError(f"config.scene_seed must be an integer in [0, {MAX_SEED}), got {seed!r}")
        self.files: list[Path] = []
        self.fixed: Scene | None = None
        # Scene problems fail here, at construction, not at the first reset; a fixed scene is parsed only here.
        # The `scene` dict as given is checked too (a split overrides some of its keys; a fixed scene ignores it).
        resolve_config(config["scene"])
        if config["scene_spec"] is not None or config["scene_path"] is not None:
            self.kind = "fixed"
            self.fixed = load_scene(config, 0)
            check_has_sidewalks(
                self.fixed,
                "config.scene_spec"
                if config["scene_spec"] is not None
                else f"config.scene_path {config['scene_path']}",
            )
        elif config["scene_dir"] is not None:
            self.kind = "dir"
            self.files = dataset_scenes(config["scene_dir"], config["split"])
            if num_scenes is not None:
                self.files = self.files[seed : seed + num_scenes]
                if not self.files:
                    raise ConfigError(f"config.scene_seed {seed} is past the {config['scene_dir']} split's scenes")
        else:
            self.kind = "generated"
            if num_scenes is None:
                raise ConfigError(
                    "config.num_scenes must be an integer for generated scenes (None means all of scene_dir)"
                )
            if seed + num_scenes > MAX_SEED:
                raise ConfigError(
                    f"config.scene_seed + num_scenes must stay <= {MAX_SEED} so splits never share a scene"
                )
            self.offset = split_seed_offset(config["split"])
            resolve_config(generator_config(config))

    @property
    def count(self) -> int:
        """How many distinct scenes episodes draw from."""
        return {"fixed": 1, "dir": len(self.files)}.get(self.kind, int(self.config["num_scenes"] or 1))

    def draw(self, rng: np.random.Generator) -> tuple[Any, Callable[[], Scene]]:
        """(cache key, scene loader) of the next episode's scene; uses `rng` only when there is a choice."""
        cfg = self.config
        if self.kind == "fixed":
            fixed = self.fixed
            assert fixed is not None  # a "fixed" source parses its scene at construction
            return ("fixed",), lambda: fixed
        k = int(rng.integers(self.count)) if self.count > 1 else 0
        if self.kind == "dir":
            path = self.files[k]
            return ("file", str(path)), lambda: read_scene(path)
        seed = self.offset + int(cfg["scene_seed"]) + k
        return ("generated", cfg["split"], seed), lambda: load_scene(cfg, seed)


class SceneCache:
    """Least-recently-used built scenes, at most `size`, each in its own Bullet client."""

    def __init__(self, size: int, first_client: int, gui: bool) -> None:
        self.size = 1 if gui else size  # Bullet allows one GUI client
        self.gui = gui
        self.slots: OrderedDict[Any, SceneSlot] = OrderedDict()
        self._spare = [first_client]

    def get(self, key: Any) -> SceneSlot | None:
        """The cached slot of `key` (now the most recently used), or None."""
        slot = self.slots.get(key)
        if slot is not None:
            self.slots.move_to_end(key)
        return slot

    def new_slot(self, key: Any) -> SceneSlot:
        """An empty slot for `key` in a fresh client, or in the least recently used slot's client."""
        if self._spare:
            client = self._spare.pop()
        elif len(self.slots) < self.size:
            client = p.connect(p.DIRECT)
        else:
            _, old = self.slots.popitem(last=False)
            client = old.client
        slot = SceneSlot(key=key, client=client)
        self.slots[key] = slot
        return slot

    def discard(self, key: Any) -> None:
        """Forget the slot of `key` (its build failed); its client is kept for the next new scene."""
        slot = self.slots.pop(key, None)
        if slot is not None:
            self._spare.append(slot.client)

    def clients(self) -> list[int]:
        """Every Bullet client the cache holds."""
        return [slot.client for slot in self.slots.values()] + list(self._spare)

    def close(self) -> None:
        """Disconnect every client."""
        for client in self.clients():
            try:
                p.disconnect(physicsClientId=client)
            except p.error:
                pass
            forget_egl(client)
        self.slots.clear()
        self._spare = []


def build_slot(slot: SceneSlot, scene: Scene, cfg: Mapping[str, Any], machine: Any) -> None:
    """Build `scene` into `slot`: its world, the machine of spec `machine`, both LiDARs, the camera and the planner."""
    catalog = None
    meshes = cfg["visual_meshes"] is True or (cfg["visual_meshes"] == "auto" and bool(cfg["camera"]["modalities"]))
    if cfg["catalog"] is not None and (cfg["collision"] == "convex" or meshes):
        from catalogs.reader import read_catalog

        catalog = read_catalog(cfg["catalog"])
    dt = float(cfg["dt"])
    slot.scene = scene
    slot.world = World(
        scene,
        client=slot.client,
        collision=cfg["collision"],
        catalog=catalog,
        visual_meshes=meshes,
        physics_dt=dt / int(cfg["physics_substeps"]),
    )
    slot.machine = Machine(slot.client, machine)
    if scene.terrain:
        slot.machine.ground = slot.world.friction_at  # the patch under the machine limits its traction
    lid = cfg["lidar"]
    r0 = slot.machine.bounding_radius + 0.05
    high = {
        "beams": int(lid["beams"]),
        "range_m": float(lid["range"]),
        "height": float(lid["height"]),
        "start_radius": r0,
        "encoding": lid["encoding"],
    }
    low = (
        {
            "beams": int(lid["low_beams"]),
            "range_m": max(float(lid["low_range"]), r0 + 0.1),
            "height": float(lid["low_height"]),
            "start_radius": r0,
        }
        if int(lid["low_beams"])
        else None
    )
    if static_lidar(cfg) == "grid":
        grids = build_grids(scene, resolution=float(lid["resolution"]), lidar=lid, body_height=None)
        slot.lidar = GridLidar(grids, "high", **high)
        slot.low_lidar = GridLidar(grids, "low", **low) if low else None
    else:
        slot.lidar = Lidar(slot.client, **high)
        slot.low_lidar = Lidar(slot.client, **low) if low else None
    slot.planner = RoutePlanner(scene, machine.half_width, margin=float(cfg["route_margin"]))
    slot.camera = EgoCamera(slot.client, slot.world, cfg["camera"]) if cfg["camera"]["modalities"] else None


@lru_cache(maxsize=1)
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's `malloc_trim`, or None where the C library has none (macOS, musl)."""
    name = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):
        return None


def trim_heap() -> None:
    """Hand the heap's free pages back to the OS (glibc's `malloc_trim`; nothing where there is none).

    A scene's arrays (LiDAR grids, planner graphs) are several MB each. Past its first frees glibc serves such
    arrays from the heap and keeps the freed ones, so without this RSS wanders by up to +-120 MB with the scenes
    held before (benchmarks/results/sim_speed/bench_2026-11-25.txt); called after a new scene is built.
    """
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
