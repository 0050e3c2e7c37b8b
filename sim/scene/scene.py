"""The typed scene: `Scene.parse(spec)` checks a `curbside.scene/1` document once (version, fields, types,
finiteness) and gives the world, the route planner, the agents and the renderers one frozen view of it.

The generator still returns the plain dict (that is what `sim.scene.spec` serialises, byte-identical);
`Scene.parse(generate_scene(...))` is its typed view, and `scene.spec` the dict itself for serialisation and
for code that still reads it. docs/scene_spec.md describes the fields.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import ConfigError
from sim.scene.grid import WalkableGrid, decode_walkable

SPEC_VERSION = "curbside.scene/1"  # the one place the spec version is defined and checked (Scene.parse)
SPEC_FIELDS = ("bounds", "roads", "sidewalks", "crosswalks", "objects", "walkable")
DEFAULT_CURB_HEIGHT = 0.15  # metres, for hand-built specs without `curb_height`
_REGENERATE = "regenerate it with `curbside scenes generate` (docs/scene_spec.md describes the fields)"

Record = Mapping[str, Any]  # one road, sidewalk, crosswalk or object: a JSON object of the spec


class SceneError(ConfigError):
    """A scene spec this simulator cannot read (wrong version, missing, malformed or non-finite fields)."""


@dataclass(frozen=True, eq=False)  # eq=False: scenes compare and hash by identity (managers cache per scene)
class Scene:
    """One validated scene spec: typed top-level fields, records as read-only tuples, the walkable grid decoded once.

    `spec` is the parsed document itself (shared, not copied): read it, never write it.
    """

    spec: Mapping[str, Any]
    version: str
    seed: int
    bounds: tuple[float, float, float, float]
    curb_height: float
    roads: tuple[Record, ...]
    sidewalks: tuple[Record, ...]
    crosswalks: tuple[Record, ...]
    objects: tuple[Record, ...]
    config: Mapping[str, Any]
    stats: Mapping[str, Any]
    catalog: str | None
    source: str = "scene spec"
    terrain: tuple[Record, ...] = ()  # terrain patches (sim.terrain.patches); specs from before terrain have none

    @classmethod
    def parse(cls, spec: Scene | Mapping[str, Any], source: str = "scene spec") -> Scene:
        """Check `spec` (a Scene is returned as it is) and return its typed view; SceneError names the bad field."""
        if isinstance(spec, Scene):
            return spec
        check_spec(spec, source)
        return cls(
            spec=spec,
            version=str(spec["version"]),
            seed=int(spec.get("seed", 0)),
            bounds=tuple(float(v) for v in spec["bounds"]),  # type: ignore[arg-type]
            curb_height=float(spec.get("curb_height", DEFAULT_CURB_HEIGHT)),
            roads=tuple(spec["roads"]),
            sidewalks=tuple(spec["sidewalks"]),
            crosswalks=tuple(spec["crosswalks"]),
            objects=tuple(spec["objects"]),
            config=spec.get("config") or {},
            stats=spec.get("stats") or {},
            catalog=spec.get("catalog"),
            source=source,
            terrain=tuple(spec.get("terrain") or ()),
        )

    @classmethod
    def load(cls, path: str | Path) -> Scene:
        """Read and parse a scene spec JSON file; clear errors for a missing file, bad JSON or bad fields."""
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"no scene spec at {p}; create one with `curbside scenes generate --out {p}`")
        try:
            spec = json.loads(p.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise SceneError(f"{p} is not a scene spec JSON file ({e}); {_REGENERATE}") from e
        return cls.parse(spec, source=str(p))

    @cached_property
    def walkable(self) -> WalkableGrid:
        """The decoded walkable grid (sim.scene.grid), decoded on first use and shared: its mask is read-only."""
        grid = decode_walkable(self.spec)
        grid.mask.flags.writeable = False  # the planners share it; a write would leak into every other one
        return grid

    def footprints(self) -> list[list[list[float]]]:
        """The [x, y] footprint rings of the objects that have one, in object order."""
        return [o["footprint"] for o in self.objects if o.get("footprint")]


def as_scene(spec: Scene | Mapping[str, Any], cached: Scene | None = None) -> Scene:
    """`spec` as a Scene: itself, `cached` when that was parsed from this very dict, else `Scene.parse(spec)`."""
    if isinstance(spec, Scene):
        return spec
    if cached is not None and cached.spec is spec:
        return cached  # the same dict again (a caller passing dicts each reset): parse it once
    return Scene.parse(spec)


def _finite(value: Any, n: int | None = None) -> bool:
    """Whether `value` is an array-like of finite numbers (n of them when n is given; [k, 2] points when n is 0)."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    if n == 0:
        return a.ndim == 2 and a.shape[1] == 2 and a.shape[0] > 0 and bool(np.isfinite(a).all())
    return a.ndim == 1 and (n is None or a.shape[0] == n) and bool(np.isfinite(a).all())


def check_spec(spec: Any, source: str = "scene spec") -> None:
    """Raise SceneError unless `spec` is a `curbside.scene/1` document whose geometry is all finite numbers.

    Catches what json.loads lets through (NaN, Infinity, strings, missing fields) where the spec is read, before a
    world is built: Bullet and shapely would otherwise drop such objects silently.
    """
    if not isinstance(spec, Mapping):
        raise SceneError(f"{source} must be a JSON object, got {type(spec).__name__}; {_REGENERATE}")
    if spec.get("version") != SPEC_VERSION:
        raise SceneError(
            f"{source} has version {spec.get('version')!r}; this curbside reads {SPEC_VERSION!r}: {_REGENERATE}"
        )
    missing = [k for k in SPEC_FIELDS if k not in spec]
    if missing:
        raise SceneError(f"{source} lacks {', '.join(missing)}; {_REGENERATE}")
    b = spec["bounds"]
    if not _finite(b, 4) or b[0] > b[2] or b[1] > b[3]:
        raise SceneError(f"{source} bounds must be 4 finite numbers [xmin, ymin, xmax, ymax], got {b!r}; {_REGENERATE}")
    ch = spec.get("curb_height", DEFAULT_CURB_HEIGHT)
    if not _finite([ch], 1) or not 0.0 <= ch <= 1.0:
        raise SceneError(f"{source} curb_height must be a finite number in [0, 1] m, got {ch!r}; {_REGENERATE}")
    seed = spec.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise SceneError(f"{source} seed must be an integer >= 0, got {seed!r}; {_REGENERATE}")
    for key in ("config", "stats"):
        if spec.get(key) is not None and not isinstance(spec[key], Mapping):
            raise SceneError(f"{source} {key} must be a JSON object, got {type(spec[key]).__name__}; {_REGENERATE}")
    for key in ("roads", "sidewalks", "crosswalks", "objects"):
        if not isinstance(spec[key], list):
            raise SceneError(f"{source} {key} must be a list, got {type(spec[key]).__name__}; {_REGENERATE}")
    for key in ("roads", "sidewalks", "crosswalks"):
        if _records_ok(spec[key], "polygon"):
            continue
        for k, item in enumerate(spec[key]):
            if not isinstance(item, Mapping) or not _finite(item.get("polygon"), 0):
                raise SceneError(f"{source} {key}[{k}] needs a polygon of finite [x, y] points; {_REGENERATE}")
    if not _objects_ok(spec["objects"]):
        _check_objects(spec["objects"], source)
    _check_terrain(spec.get("terrain") or [], source)
    _check_walkable(spec["walkable"], source)


def _rings_ok(rings: list[Any]) -> bool:
    """Whether every ring is a non-empty list of finite [x, y] points (one numpy call for all of them)."""
    points = []
    for ring in rings:
        if type(ring) is not list or not ring:
            return False
        points += ring
    if not points:
        return True
    try:
        a = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return a.ndim == 2 and a.shape[1] == 2 and bool(np.isfinite(a).all())


def _records_ok(records: list[Any], key: str) -> bool:
    """Whether every record is a JSON object whose `key` is a finite ring (the fast path of `check_spec`)."""
    return all(isinstance(r, Mapping) for r in records) and _rings_ok([r.get(key) for r in records])


def _objects_ok(objects: list[Any]) -> bool:
    """Whether every object passes `_check_objects`, checked in a few numpy calls; False means look closer."""
    if not objects:
        return True
    if not all(isinstance(o, Mapping) for o in objects):
        return False
    try:
        pos = np.asarray([o.get("position") for o in objects], dtype=np.float64)
        size = np.asarray([o.get("size") for o in objects], dtype=np.float64)
        yaw = np.asarray([o.get("yaw", 0.0) for o in objects], dtype=np.float64)
    except (TypeError, ValueError):
        return False
    n = len(objects)
    if pos.shape != (n, 3) or size.shape != (n, 3) or yaw.shape != (n,):
        return False
    if not (np.isfinite(pos).all() and np.isfinite(size).all() and np.isfinite(yaw).all() and size.min() >= 0):
        return False
    return _rings_ok([o["footprint"] for o in objects if "footprint" in o])


def _check_objects(objects: list[Any], source: str) -> None:
    """Raise SceneError naming the first object with a bad position, size, yaw or footprint."""
    for k, o in enumerate(objects):
        if not isinstance(o, Mapping):
            raise SceneError(f"{source} objects[{k}] must be a JSON object; {_REGENERATE}")
        what = f"{source} objects[{k}] (id {o.get('id')!r})"
        for field, n in (("position", 3), ("size", 3)):
            if not _finite(o.get(field), n):
                raise SceneError(f"{what} {field} must be {n} finite numbers, got {o.get(field)!r}; {_REGENERATE}")
        if min(o["size"]) < 0:
            raise SceneError(f"{what} size must be >= 0, got {o['size']!r}; {_REGENERATE}")
        if not _finite([o.get("yaw", 0.0)], 1):
            raise SceneError(f"{what} yaw must be a finite number, got {o.get('yaw')!r}; {_REGENERATE}")
        if "footprint" in o and not _finite(o["footprint"], 0):
            raise SceneError(f"{what} footprint must be finite [x, y] points; {_REGENERATE}")


def _check_terrain(records: Any, source: str) -> None:
    """Raise SceneError naming the first malformed terrain record (sim.terrain.patches.check says what is wrong)."""
    from sim.terrain.patches import check

    if not isinstance(records, list):
        raise SceneError(f"{source} terrain must be a list, got {type(records).__name__}; {_REGENERATE}")
    for k, rec in enumerate(records):
        problem = check(rec)
        if problem is None and not _finite(rec.get("footprint"), 0):
            problem = "needs a footprint of finite [x, y] points"
        if problem is not None:
            raise SceneError(f"{source} terrain[{k}] {problem}; {_REGENERATE}")


def _check_walkable(w: Any, source: str) -> None:
    """Raise SceneError unless `w` is a walkable object with a finite origin, a resolution, a shape and cells."""
    shape = w.get("shape") if isinstance(w, Mapping) else None
    if (
        not isinstance(w, Mapping)
        or not _finite(w.get("origin"), 2)
        or not _finite([w.get("resolution")], 1)
        or not w["resolution"] > 0
        or not (isinstance(shape, list) and len(shape) == 2 and all(isinstance(v, int) and v > 0 for v in shape))
        or not isinstance(w.get("cells"), str)
    ):
        raise SceneError(
            f"{source} walkable must hold a finite origin, a resolution > 0, a [rows, cols] shape "
            f"and encoded cells; {_REGENERATE}"
        )
