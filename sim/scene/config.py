"""Generator configuration: defaults, sidewalk templates, block codes, and strict validation."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from curbside.config import ConfigError, merge_strict

SPEC_VERSION = "curbside.scene/1"

BLOCK_CODES = {"S": "straight", "C": "curve", "X": "intersection", "T": "T-junction", "O": "roundabout"}

# Zones from the road outward with (min, max) widths in metres (DESIGN.md, MetaUrban's composition).
TEMPLATES: dict[str, tuple[tuple[str, float, float], ...]] = {
    "a": (("near_road_buffer", 0.6, 0.8), ("clear", 2.4, 2.8)),
    "b": (("furnishing", 1.5, 1.8), ("clear", 2.4, 2.8)),
    "c": (("furnishing", 1.5, 1.8), ("clear", 2.0, 2.4), ("frontage", 0.5, 0.8)),
    "d": (("near_road_buffer", 2.1, 2.4), ("furnishing", 1.0, 1.2), ("clear", 2.4, 2.8)),
    "e": (("furnishing", 1.5, 1.8), ("clear", 3.0, 3.3), ("frontage", 1.5, 1.8)),
    "f": (("furnishing", 1.5, 1.8), ("clear", 3.0, 3.3), ("frontage", 3.0, 3.3)),
    "g": (("furnishing", 1.5, 1.8), ("clear", 3.0, 3.3), ("frontage_buffer", 0.3, 0.5), ("frontage", 3.0, 3.3)),
}
TEMPLATE_NAMES = {
    "a": "narrow", "b": "narrow with trees", "c": "ribbon", "d": "neighborhood 1",
    "e": "neighborhood 2", "f": "medium commercial", "g": "wide commercial",
}

DEFAULT_CONFIG: dict[str, Any] = {
    "preset": None,                   # a name from PRESETS: its values replace the defaults (explicit keys still win)
    "blocks": 3,                      # a count, or a string of block codes such as "SXCT"
    "block_types": "SCXTO",           # codes drawn from when `blocks` is a count
    "templates": "abcdef",            # sidewalk templates drawn uniformly per sidewalk
    "lanes": [1, 2],                  # lanes per direction, inclusive range, drawn per block
    "lane_width": [3.0, 3.6],         # metres, drawn per block
    "straight_length": [30.0, 60.0],
    "curve_radius": [40.0, 70.0],     # centerline radius; large enough for inner sidewalks and buildings
    "curve_angle": [45.0, 90.0],      # degrees, either direction
    "arm_length": [20.0, 35.0],       # junction and roundabout arms
    "roundabout_radius": [8.0, 14.0], # central island radius
    "building_depth": [8.0, 12.0],    # depth of the building zone beyond the sidewalk
    "buildings": True,
    "curb_height": 0.15,
    "crosswalk_density": 0.5,         # probability that each crosswalk candidate is built
    "crosswalks": None,               # or an explicit list of candidate ids, e.g. ["r0.0:start", "r1.2:end"]
    "connect_crosswalks": True,       # also build the fewest extra candidates that join every sidewalk group
    "crosswalk_width": 3.0,
    "ramp_depth": 1.5,
    "object_density": 1.0,            # rho_s: scales standard spacing (1/rho) and zoned/clutter counts (rho)
    "standard_spacing": 12.0,         # metres between standard infrastructure at density 1
    "non_standard_per_100m": 8.0,
    "clutter_per_100m": 5.0,
    "density_model": "sparse",        # "sparse": counts per 100 m; "paper": rows along every furniture zone (MetaUrban-12K)
    "fill_gap": 0.9,                  # mean gap (m) between neighbours in a row at object_density 1 ("paper" model)
    "fill_clutter": 0.15,             # share of clutter items in the rows ("paper" model)
    "fill_row_width": 1.4,            # a zone holds floor(width / this) rows of objects ("paper" model)
    "min_objects": 0,                 # "paper" model: refill the gaps (smaller each round) until a scene holds this many
    "placement_tries": 4,             # positions tried per object before it counts as refused
    "min_clear_width": 1.2,           # free corridor kept along every clear path (wheelchair)
    "country": None,                  # None: uniform categories; else ISO alpha-2 row of the distribution table
    "distribution_path": "data/distribution/distribution.parquet",
    "exclude_categories": [],         # held-out categories (dataset splits)
    "grid_resolution": 0.25,
    "block_tries": 30,                # shapes/parameters tried per block before giving up
}


# Named bundles of settings. "metaurban12k": the paper's density (docs/scenes.md: each statistic of MetaUrban-12K
# within 25 % on 200 train scenes, measured by `curbside scenes stats --vs-paper`).
PRESETS: dict[str, dict[str, Any]] = {
    "metaurban12k": {"density_model": "paper", "building_depth": [18.0, 26.0], "fill_gap": 1.6, "fill_row_width": 1.0,
                     "crosswalk_density": 1.0, "min_objects": 300},
}


def _range(cfg: Mapping[str, Any], key: str, *, positive: bool = True) -> None:
    v = cfg[key]
    if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v) and v[0] <= v[1]):
        raise ConfigError(f"config.{key} must be a [min, max] pair with min <= max, got {v!r}")
    if positive and v[0] <= 0:
        raise ConfigError(f"config.{key} must be positive, got {v!r}")


def check_codes(codes: str, valid: Mapping[str, Any] | str, *, what: str) -> None:
    """Raise ConfigError listing the valid letters when `codes` holds one that is not valid."""
    bad = [c for c in codes if c not in valid]
    if bad or not codes:
        listing = ", ".join(f"{k} ({v})" for k, v in valid.items()) if isinstance(valid, Mapping) else ", ".join(valid)
        raise ConfigError(f"unknown {what} {''.join(bad) or repr(codes)!s}; valid: {listing}")


def resolve_config(config: Mapping[str, Any] | None) -> dict[str, Any]:
    """Merge `config` over DEFAULT_CONFIG strictly and validate every value."""
    from sim.scene.categories import ALL_CATEGORIES

    preset = (config or {}).get("preset")
    if preset is not None and preset not in PRESETS:
        raise ConfigError(f"unknown scene preset {preset!r}; valid: {', '.join(PRESETS)} (or null)")
    base = {**DEFAULT_CONFIG, **PRESETS[preset]} if preset else DEFAULT_CONFIG
    cfg = merge_strict(base, config, name="scene config")
    blocks = cfg["blocks"]
    if isinstance(blocks, bool) or not isinstance(blocks, (int, str)):
        raise ConfigError(f"config.blocks must be a count or a string of block codes, got {blocks!r}")
    if isinstance(blocks, int) and blocks < 1:
        raise ConfigError(f"config.blocks must be at least 1, got {blocks}")
    if isinstance(blocks, str):
        cfg["blocks"] = blocks = blocks.upper()
        check_codes(blocks, BLOCK_CODES, what="block code(s)")
    cfg["block_types"] = str(cfg["block_types"]).upper()
    check_codes(cfg["block_types"], BLOCK_CODES, what="block code(s) in block_types")
    cfg["templates"] = "".join(sorted(set(str(cfg["templates"]).lower())))
    check_codes(cfg["templates"], TEMPLATE_NAMES, what="sidewalk template(s)")
    for key in ("lane_width", "straight_length", "curve_radius", "curve_angle", "arm_length", "roundabout_radius", "building_depth"):
        _range(cfg, key)
    _range(cfg, "lanes")
    cfg["lanes"] = [int(cfg["lanes"][0]), int(cfg["lanes"][1])]
    if not 0.0 <= float(cfg["crosswalk_density"]) <= 1.0:
        raise ConfigError(f"config.crosswalk_density must lie in [0, 1], got {cfg['crosswalk_density']!r}")
    if not isinstance(cfg["connect_crosswalks"], bool):
        raise ConfigError(f"config.connect_crosswalks must be true or false, got {cfg['connect_crosswalks']!r}")
    if cfg["crosswalks"] is not None and not (isinstance(cfg["crosswalks"], list) and all(isinstance(c, str) for c in cfg["crosswalks"])):
        raise ConfigError("config.crosswalks must be null or a list of candidate ids such as 'r0.0:start'")
    for key in ("object_density", "standard_spacing", "non_standard_per_100m", "clutter_per_100m", "min_clear_width", "curb_height", "ramp_depth"):
        if not isinstance(cfg[key], (int, float)) or cfg[key] < 0:
            raise ConfigError(f"config.{key} must be a number >= 0, got {cfg[key]!r}")
    for key in ("crosswalk_width", "grid_resolution", "standard_spacing"):
        if cfg[key] <= 0:
            raise ConfigError(f"config.{key} must be > 0, got {cfg[key]!r}")
    if cfg["density_model"] not in ("sparse", "paper"):
        raise ConfigError(f"unknown config.density_model {cfg['density_model']!r}; valid: sparse, paper")
    if not isinstance(cfg["min_objects"], int) or isinstance(cfg["min_objects"], bool) or not 0 <= cfg["min_objects"] <= 100_000:
        raise ConfigError(f"config.min_objects must be an integer in [0, 100000], got {cfg['min_objects']!r}")
    if not isinstance(cfg["fill_row_width"], (int, float)) or not 0.3 <= cfg["fill_row_width"] < 100:
        raise ConfigError(f"config.fill_row_width must be a number in [0.3, 100), got {cfg['fill_row_width']!r}")
    for key in ("fill_gap", "fill_clutter"):
        if not isinstance(cfg[key], (int, float)) or not 0 <= cfg[key] < (1.0 if key == "fill_clutter" else 100.0):
            raise ConfigError(f"config.{key} must be a number in [0, {1 if key == 'fill_clutter' else 100}), got {cfg[key]!r}")
    if cfg["density_model"] == "paper" and cfg["fill_gap"] <= 0:
        raise ConfigError("config.fill_gap must be > 0 with density_model 'paper'")
    bad = [c for c in cfg["exclude_categories"] if c not in ALL_CATEGORIES]
    if bad:
        raise ConfigError(f"unknown categories {bad} in exclude_categories; valid: {', '.join(ALL_CATEGORIES)}")
    cfg["exclude_categories"] = sorted(set(cfg["exclude_categories"]))
    if cfg["country"] is not None:
        cfg["country"] = str(cfg["country"]).upper()
    return cfg


def max_sidewalk_width(templates: str) -> float:
    """Widest possible sidewalk (all zones at their maximum) over `templates`."""
    return max(sum(z[2] for z in TEMPLATES[t]) for t in templates)
