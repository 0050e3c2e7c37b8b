"""Custom scenes from a short YAML: blocks, templates, the object pool and density, named objects at given places
and agent groups, turned into a scene spec by the generator (`curbside scenes generate --from custom.yaml`).

```yaml
seed: 7
blocks: SXC                # a count (1-64) or block codes: S straight, C curve, X intersection, T, O roundabout
templates: abc             # sidewalk templates a-g
objects:
  density: 1.5             # rho_s
  pool: [bench, trash_bin, street_lamp, tree, bicycle]   # only these categories (default: all)
  country: FI              # category frequencies of a country (default: uniform)
place:                     # named objects; generated objects and terrain in their way are removed
  - {name: my_bench, category: bench, at: {sidewalk: r0-s0, along: 0.5, zone: furnishing}, yaw: 90}
  - {name: cone_1, category: traffic_cone, at: [12.0, -7.5]}
agents:                    # agent groups for SocialNav (kind: count)
  pedestrian: 12
  wheelchair_user: 2
generator: {crosswalk_density: 1.0}   # any other generator key (sim.scene.DEFAULT_CONFIG)
```
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import LineString, Point, Polygon

from catalogs.categories import CATEGORIES, NAMES, category
from kernel.config import ConfigError, excerpt, load_yaml, merge_strict
from sim.scene.occupancy import rect
from sim.scene.spec import round_points, round_value

KEYS = {"seed": 0, "blocks": 3, "templates": "abcdef", "objects": {}, "place": [], "agents": {}, "generator": {}}
OBJECT_KEYS = {"density": 1.0, "pool": None, "country": None}
PLACE_KEYS = {"name": None, "category": None, "at": None, "yaw": 0.0, "size": None, "asset_id": None}
AT_KEYS = {"sidewalk": None, "along": 0.5, "zone": "clear"}


def load_custom(path: str | Path) -> dict[str, Any]:
    """Read a custom scene YAML into its checked, complete form (unknown keys are refused listing the valid ones)."""
    file_path = Path(path)
    if not file_path.is_file():
        raise ConfigError(f"no custom scene file at {file_path}; write one as in docs/scenes.md (Custom scenes)")
    data = load_yaml(file_path.read_text(encoding="utf-8"), str(file_path)) or {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{file_path} must hold a mapping of {', '.join(KEYS)}; got {type(data).__name__}")
    return check_custom(data, str(file_path))


def check_custom(data: Mapping[str, Any], where: str = "custom scene") -> dict[str, Any]:
    """Merge `data` over the defaults strictly and check its categories, kinds and named objects."""
    from sim.agents.kinds import agent_kind

    cfg = merge_strict(KEYS, data, name=where)
    seed = cfg["seed"]
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**32:
        raise ConfigError(f"{where}: seed must be an integer in [0, 2**32), got {excerpt(seed)}")
    if not isinstance(cfg["generator"], Mapping):
        raise ConfigError(f"{where}: generator must be a mapping of scene generator keys, got {cfg['generator']!r}")
    taken = sorted(set(cfg["generator"]) & {"blocks", "templates", "object_density", "country"})
    if taken:
        raise ConfigError(
            f"{where}: set {', '.join(taken)} at the top level (blocks, templates) or under objects "
            "(density, country), not under generator"
        )
    cfg["objects"] = merge_strict(OBJECT_KEYS, cfg["objects"] or {}, name=f"{where}: objects")
    pool = cfg["objects"]["pool"]
    if pool is not None:
        if not isinstance(pool, list) or not pool or not all(isinstance(n, str) for n in pool):
            raise ConfigError(f"{where}: objects.pool must be a non-empty list of categories, got {pool!r}")
        for name in pool:
            category(name, where=f"{where}: objects.pool")
    if not isinstance(cfg["place"], list):
        raise ConfigError(f"{where}: place must be a list of named objects")
    cfg["place"] = [_check_place(item, f"{where}: place[{k}]") for k, item in enumerate(cfg["place"])]
    names = [item["name"] for item in cfg["place"]]
    if len(set(names)) != len(names):
        raise ConfigError(f"{where}: named objects need distinct names, got {names}")
    if not isinstance(cfg["agents"], Mapping):
        raise ConfigError(f"{where}: agents must map kinds to counts, e.g. {{pedestrian: 10}}")
    for kind, count in cfg["agents"].items():
        try:
            agent_kind(kind)
        except ValueError as e:
            raise ConfigError(f"{where}: agents: {e}") from None
        if not isinstance(count, int) or isinstance(count, bool) or not 0 <= count <= 1000:
            raise ConfigError(f"{where}: agents.{kind} must be a count in [0, 1000], got {count!r}")
    return cfg


def _check_place(item: Any, where: str) -> dict[str, Any]:
    if not isinstance(item, Mapping):
        raise ConfigError(f"{where} must be a mapping with name, category and at")
    place = merge_strict(PLACE_KEYS, item, name=where)
    if not isinstance(place["name"], str) or not place["name"]:
        raise ConfigError(f"{where}: give the object a name")
    if not isinstance(place["category"], str):
        raise ConfigError(f"{where}.category must be one category name, got {place['category']!r}")
    category(place["category"], where=f"{where}.category")
    at = place["at"]
    if isinstance(at, Mapping):
        place["at"] = merge_strict(AT_KEYS, at, name=f"{where}.at")
        along = place["at"]["along"]
        if not isinstance(along, (int, float)) or isinstance(along, bool) or not 0.0 <= float(along) <= 1.0:
            raise ConfigError(f"{where}.at.along must be a fraction of the sidewalk's length in [0, 1]")
    elif not (
        isinstance(at, list) and len(at) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in at)
    ):
        raise ConfigError(f"{where}.at must be [x, y] in metres or {{sidewalk: ID, along: 0..1, zone: KIND}}")
    size = place["size"]
    if size is not None and not (
        isinstance(size, list) and len(size) == 3 and all(isinstance(v, (int, float)) and 0 < v < 100 for v in size)
    ):
        raise ConfigError(f"{where}.size must be [depth, width, height] in metres (0-100)")
    if not (isinstance(place["yaw"], (int, float)) and math.isfinite(place["yaw"])):
        raise ConfigError(f"{where}.yaw must be a finite number of degrees")
    return place


def generator_config(c: Mapping[str, Any]) -> dict[str, Any]:
    """The scene generator config a checked custom scene asks for."""
    blocks = c["blocks"]
    cfg = {
        **c["generator"],
        "blocks": int(blocks) if str(blocks).strip().isdigit() else blocks,
        "templates": c["templates"],
        "object_density": c["objects"]["density"],
        "country": c["objects"]["country"],
    }
    pool = c["objects"]["pool"]
    if pool is not None:
        cfg["exclude_categories"] = sorted(set(cfg.get("exclude_categories", [])) | (set(NAMES) - set(pool)))
    return cfg


def generate_custom(c: Mapping[str, Any], catalog: Any = None) -> dict[str, Any]:
    """The scene spec of a checked custom scene: generated, then its named objects placed and its agent groups set."""
    from sim.scene import generate_scene
    from sim.scene.terrain import terrain_stats

    spec = generate_scene(generator_config(c), int(c["seed"]), catalog)
    objects, terrain = list(spec["objects"]), list(spec["terrain"])
    curb = float(spec.get("curb_height", 0.15))
    for item in c["place"]:
        x, y, sidewalk = _locate(spec, item)
        cat = CATEGORIES[item["category"]]
        d, w, h = item["size"] or cat.size
        yaw = math.radians(float(item["yaw"]))
        corners, _ = rect(x, y, math.cos(yaw), math.sin(yaw), d, w)
        box = Polygon(corners)
        hit = [obj["name"] for obj in objects if obj.get("name") and Polygon(obj["footprint"]).intersects(box)]
        if hit:
            raise ConfigError(f"named objects {hit[0]!r} and {item['name']!r} overlap; move one of them")
        objects = [
            obj for obj in objects if obj.get("name") or not Polygon(obj["footprint"]).intersects(box)
        ]  # named win
        terrain = [
            patch for patch in terrain if not Polygon(patch["footprint"]).intersects(box)
        ]  # over terrain patches too
        objects.append(
            {
                "id": "",
                "name": item["name"],
                "asset_id": item["asset_id"],
                "category": cat.name,
                "object_class": cat.object_class,
                "zone": item["at"]["zone"] if isinstance(item["at"], Mapping) else None,
                "sidewalk_id": sidewalk,
                "position": [round_value(x), round_value(y), curb if sidewalk else 0.0],
                "yaw": round_value(math.atan2(math.sin(yaw), math.cos(yaw))),
                "size": [round_value(float(v)) for v in (d, w, h)],
                "footprint": round_points(corners),
            }
        )
    for k, obj in enumerate(objects):
        obj["id"] = f"o{k}"
    for k, patch in enumerate(terrain):
        patch["id"] = f"t{k}"
    spec["objects"], spec["terrain"] = objects, terrain
    spec["stats"] = {**spec["stats"], "objects": len(objects), "terrain": terrain_stats(terrain)}
    if c["agents"]:
        spec["agents"] = {k: int(v) for k, v in sorted(c["agents"].items())}
    spec["custom"] = {"place": [item["name"] for item in c["place"]]}
    return spec


def _locate(spec: Mapping[str, Any], item: Mapping[str, Any]) -> tuple[float, float, str | None]:
    """World (x, y) and sidewalk id of a named object's `at`: a point, or a fraction along a sidewalk's zone."""
    at = item["at"]
    sidewalks = {sidewalk["id"]: sidewalk for sidewalk in spec["sidewalks"]}
    if not isinstance(at, Mapping):
        x, y = (float(v) for v in at)
        x0, y0, x1, y1 = spec["bounds"]
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            raise ConfigError(
                f"named object {item['name']!r} at [{x}, {y}] lies outside the scene's bounds "
                f"[{x0}, {y0}, {x1}, {y1}]; render the scene (`curbside scenes render`) to pick a place"
            )
        on = next(
            (sid for sid, sidewalk in sidewalks.items() if Polygon(sidewalk["polygon"]).covers(Point(x, y))), None
        )
        return x, y, on
    sw = sidewalks.get(at["sidewalk"])
    if sw is None:
        raise ConfigError(
            f"named object {item['name']!r}: no sidewalk {at['sidewalk']!r}; this scene has {', '.join(sidewalks)}"
        )
    zone = next((z for z in sw["zones"] if z["kind"] == at["zone"]), None)
    if zone is None:
        raise ConfigError(
            f"named object {item['name']!r}: sidewalk {sw['id']} has no {at['zone']!r} zone; its zones: "
            f"{', '.join(z['kind'] for z in sw['zones'])}"
        )
    edge = LineString(sw["edge"])
    point = edge.interpolate(float(at["along"]), normalized=True)
    ahead = edge.interpolate(min(float(at["along"]) + 0.01, 1.0), normalized=True)
    if ahead.distance(point) < 1e-9:
        ahead, point = point, edge.interpolate(max(float(at["along"]) - 0.01, 0.0), normalized=True)
    tangent = np.array([ahead.x - point.x, ahead.y - point.y]) / max(ahead.distance(point), 1e-9)
    normal = np.array([-tangent[1], tangent[0]]) * 200.0
    across = LineString([(point.x - normal[0], point.y - normal[1]), (point.x + normal[0], point.y + normal[1])])
    cut = across.intersection(Polygon(zone["polygon"]))
    if cut.is_empty:
        raise ConfigError(
            f"named object {item['name']!r}: no {at['zone']} zone across sidewalk {sw['id']} at "
            f"along={at['along']}; try another fraction"
        )
    # The nearest piece of the zone across the curb at that point, and its middle.
    pieces = list(getattr(cut, "geoms", [cut]))
    piece = min(pieces, key=lambda g: g.distance(point))
    mid = piece.interpolate(0.5, normalized=True)
    return float(mid.x), float(mid.y), sw["id"]
