"""Generator configuration: defaults, sidewalk templates, block codes, and strict validation."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from kernel.config import ConfigError, merge_strict
from sim.schema import Bool, Choice, Float, Int, Pair, Pos, Rule, check_table
from sim.terrain.patches import KINDS as TERRAIN_KINDS

BLOCK_CODES = {"S": "straight", "C": "curve", "X": "intersection", "T": "T-junction", "O": "roundabout"}

# Zones from the road outward with (min, max) widths in metres (MetaUrban's composition, docs/design.md).
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
    "a": "narrow",
    "b": "narrow with trees",
    "c": "ribbon",
    "d": "neighborhood 1",
    "e": "neighborhood 2",
    "f": "medium commercial",
    "g": "wide commercial",
}

DEFAULT_CONFIG: dict[str, Any] = {
    "preset": None,  # a name from PRESETS: its values replace the defaults (explicit keys still win)
    "blocks": 3,  # a count, or a string of block codes such as "SXCT"
    "block_types": "SCXTO",  # codes drawn from when `blocks` is a count
    "templates": "abcdef",  # sidewalk templates drawn uniformly per sidewalk
    "lanes": [1, 2],  # lanes per direction, inclusive range, drawn per block
    "lane_width": [3.0, 3.6],  # metres, drawn per block
    "straight_length": [30.0, 60.0],
    "curve_radius": [40.0, 70.0],  # centerline radius; large enough for inner sidewalks and buildings
    "curve_angle": [45.0, 90.0],  # degrees, either direction
    "arm_length": [20.0, 35.0],  # junction and roundabout arms
    "roundabout_radius": [8.0, 14.0],  # central island radius
    "building_depth": [8.0, 12.0],  # depth of the building zone beyond the sidewalk
    "buildings": True,
    "curb_height": 0.15,
    "crosswalk_density": 0.5,  # probability that each crosswalk candidate is built
    "crosswalks": None,  # or an explicit list of candidate ids, e.g. ["r0.0:start", "r1.2:end"]
    "connect_crosswalks": True,  # also build the fewest extra candidates that join every sidewalk group
    "crosswalk_width": 3.0,
    "ramp_depth": 1.5,
    "object_density": 1.0,  # rho_s: scales standard spacing (1/rho) and zoned/clutter counts (rho)
    "standard_spacing": 12.0,  # metres between standard infrastructure at density 1
    "non_standard_per_100m": 8.0,
    "clutter_per_100m": 5.0,
    "density_model": "sparse",  # "sparse": counts per 100 m; "paper": rows along every furniture zone (MetaUrban-12K)
    "fill_gap": 0.9,  # mean gap (m) between neighbours in a row at object_density 1 ("paper" model)
    "fill_clutter": 0.15,  # share of clutter items in the rows ("paper" model)
    "fill_row_width": 1.4,  # a zone holds floor(width / this) rows of objects ("paper" model)
    "min_objects": 0,  # "paper" model: refill the gaps (smaller each round) until a scene holds this many
    "placement_tries": 4,  # positions tried per object before it counts as refused
    "min_clear_width": 1.2,  # free corridor kept along every clear path (wheelchair)
    "country": None,  # None: uniform categories; else ISO alpha-2 row of the distribution table
    "distribution_path": "data/distribution/distribution.parquet",
    "exclude_categories": [],  # held-out categories (dataset splits)
    "assets": "all",  # catalog assets drawn: all, seen (train, test) or held_out (unseen, finetune)
    "grid_resolution": 0.25,
    "block_tries": 30,  # shapes/parameters tried per block before giving up
    # Terrain patches on the sidewalks (sim.scene.terrain, docs/terrain.md): density 1 is a city's typical share,
    # 0 none; kinds any of roots (tree-root heave), rough (uneven pavers), steps (entrances), slick (wet, gravel).
    "terrain": {"density": 1.0, "kinds": list(TERRAIN_KINDS)},
}


# Named bundles of settings. "metaurban12k": the paper's density (docs/scenes.md: each statistic of MetaUrban-12K
# within 25 % on 200 train scenes, measured by `curbside scenes stats --vs-paper`).
PRESETS: dict[str, dict[str, Any]] = {
    "metaurban12k": {
        "density_model": "paper",
        "building_depth": [18.0, 26.0],
        "fill_gap": 1.6,
        "fill_row_width": 1.0,
        "crosswalk_density": 1.0,
        "min_objects": 300,
    },
}


MAX_BLOCKS = 64
MAX_BLOCK_DENSITY = 640.0  # blocks x max(object_density, 1): 20 x 50 (11,000 objects) took 74 s, 64 x 50 took 3 min
MIN_FILL_GAP = 0.1
_M = "metres"
# Every key of DEFAULT_CONFIG: its type and valid range. The upper bounds keep one scene's generation within
# about a minute on one core (object counts scale with object_density and 1 / standard_spacing, the raster with
# 1 / grid_resolution^2); tests/sim/test_bad_input.py checks that no key is missing.
CONFIG_TABLE: dict[str, Rule] = {
    "preset": Choice(*PRESETS, none=True),
    "blocks": Rule("any"),  # a count or codes: checked in resolve_config (1 to MAX_BLOCKS)
    "block_types": Rule("str"),  # letters checked by check_codes (its message lists them)
    "templates": Rule("str"),
    "lanes": Pair(Int(1, 4), hint="lanes per direction, whole numbers"),
    "lane_width": Pair(Float(1.0, 10.0), hint=_M),
    "straight_length": Pair(Float(5.0, 500.0), hint=_M),
    "curve_radius": Pair(Float(5.0, 1000.0), hint=_M),
    "curve_angle": Pair(Float(1.0, 180.0), hint="degrees"),
    "arm_length": Pair(Float(5.0, 500.0), hint=_M),
    "roundabout_radius": Pair(Float(1.0, 200.0), hint=_M),
    "building_depth": Pair(Float(0.5, 200.0), hint=_M),
    "buildings": Bool(),
    "curb_height": Float(0.0, 1.0, hint=_M),
    "crosswalk_density": Float(0.0, 1.0),
    "crosswalks": Rule("list", item=Rule("str"), none=True, hint="candidate ids such as 'r0.0:start'"),
    "connect_crosswalks": Bool(),
    "crosswalk_width": Pos(20.0, hint=_M),
    "ramp_depth": Float(0.0, 20.0, hint=_M),
    "object_density": Float(0.0, 50.0, hint="rho_s: 1 is the default density"),
    "standard_spacing": Float(0.5, 1000.0, hint=_M),
    "non_standard_per_100m": Float(0.0, 500.0),
    "clutter_per_100m": Float(0.0, 500.0),
    "density_model": Choice("sparse", "paper"),
    "fill_gap": Float(0.0, 100.0, hi_open=True, hint=_M),
    "fill_clutter": Float(0.0, 1.0, hi_open=True),
    "fill_row_width": Float(0.3, 100.0, hi_open=True, hint=_M),
    "min_objects": Int(0, 100_000),
    "placement_tries": Int(1, 100),
    "min_clear_width": Float(0.0, 10.0, hint=_M),
    "country": Rule("str", none=True, hint="an ISO alpha-2 code such as FI"),
    "distribution_path": Rule("path"),
    "exclude_categories": Rule("list", item=Rule("str")),
    "assets": Choice("all", "seen", "held_out"),
    "grid_resolution": Float(0.05, 2.0, hint="metres per walkable cell"),
    "block_tries": Int(1, 1000),
    "terrain": {
        "density": Float(0.0, 10.0, hint="1 is a city's typical share of terrain patches, 0 none"),
        "kinds": Rule("list", choices=TERRAIN_KINDS),
    },
}


def check_codes(codes: str, valid: Mapping[str, Any] | str, *, what: str) -> None:
    """Raise ConfigError listing the valid letters when `codes` holds one that is not valid."""
    bad = [c for c in codes if c not in valid]
    if bad or not codes:
        listing = ", ".join(f"{k} ({v})" for k, v in valid.items()) if isinstance(valid, Mapping) else ", ".join(valid)
        raise ConfigError(f"unknown {what} {''.join(bad) or repr(codes)!s}; valid: {listing}")


def resolve_config(config: Mapping[str, Any] | None) -> dict[str, Any]:
    """Merge `config` over DEFAULT_CONFIG strictly and validate every value."""
    from catalogs.categories import NAMES

    preset = (config or {}).get("preset")
    if preset is not None and preset not in PRESETS:
        raise ConfigError(f"unknown scene preset {preset!r}; valid: {', '.join(PRESETS)} (or null)")
    base = {**DEFAULT_CONFIG, **PRESETS[preset]} if preset else DEFAULT_CONFIG
    cfg = merge_strict(base, config, name="scene config")
    check_table(cfg, CONFIG_TABLE, name="scene config")
    blocks = cfg["blocks"]
    if isinstance(blocks, bool) or not isinstance(blocks, (int, str)):
        raise ConfigError(f"scene config.blocks must be a count or a string of block codes, got {blocks!r}")
    if isinstance(blocks, str):
        cfg["blocks"] = blocks = blocks.upper()
        check_codes(blocks, BLOCK_CODES, what="block code(s)")
    # A count or code string past MAX_BLOCKS would run for minutes (50 blocks take ~6 s).
    if (blocks if isinstance(blocks, int) else len(blocks)) > MAX_BLOCKS or blocks in (0, ""):
        raise ConfigError(
            f"scene config.blocks must be 1 to {MAX_BLOCKS} blocks, got {blocks!r}; "
            "generate several scenes (`curbside scenes dataset`) for more street"
        )
    if isinstance(blocks, int) and blocks < 1:
        raise ConfigError(f"scene config.blocks must be at least 1, got {blocks}")
    # Work grows with blocks x density (64 blocks at density 50 took 3 minutes): keep a scene within about a minute.
    n = blocks if isinstance(blocks, int) else len(blocks)
    if n * max(float(cfg["object_density"]), 1.0) > MAX_BLOCK_DENSITY:
        raise ConfigError(
            f"scene config.blocks x object_density must be <= {MAX_BLOCK_DENSITY:g}, got {n} x "
            f"{cfg['object_density']:g}; use fewer blocks or a lower object_density"
        )
    cfg["block_types"] = str(cfg["block_types"]).upper()
    check_codes(cfg["block_types"], BLOCK_CODES, what="block code(s) in block_types")
    cfg["templates"] = "".join(sorted(set(str(cfg["templates"]).lower())))
    check_codes(cfg["templates"], TEMPLATE_NAMES, what="sidewalk template(s)")
    if cfg["density_model"] == "paper" and cfg["fill_gap"] < MIN_FILL_GAP:
        raise ConfigError(
            f"scene config.fill_gap must be >= {MIN_FILL_GAP} m with density_model 'paper', got {cfg['fill_gap']!r}"
        )
    bad = [c for c in cfg["exclude_categories"] if c not in NAMES]
    if bad:
        raise ConfigError(f"unknown categories {bad} in exclude_categories; valid: {', '.join(NAMES)}")
    cfg["exclude_categories"] = sorted(set(cfg["exclude_categories"]))
    cfg["terrain"]["kinds"] = [k for k in TERRAIN_KINDS if k in cfg["terrain"]["kinds"]]  # one order, no repeats
    if cfg["country"] is not None:
        cfg["country"] = str(cfg["country"]).upper()
    return cfg


def max_sidewalk_width(templates: str) -> float:
    """Widest possible sidewalk (all zones at their maximum) over `templates`."""
    return max(sum(z[2] for z in TEMPLATES[t]) for t in templates)
