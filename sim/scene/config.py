"""Generator configuration: its keys (default, rule and doc of each), sidewalk templates, block codes, and strict
validation."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from kernel.config import ConfigError, merge_strict
from sim.schema import Bool, Choice, Float, Int, Key, Pair, Pos, Rule, Table, check_table, defaults_of, table_of
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
# The generator's config: every key's default, its type and valid range, and what it means. The upper bounds keep
# one scene's generation within about a minute on one core (object counts scale with object_density and
# 1 / standard_spacing, the raster with 1 / grid_resolution^2).
CONFIG_KEYS: dict[str, Key | dict[str, Key]] = {
    "preset": Key(
        None,
        Choice(*PRESETS, none=True),
        "a name from PRESETS: its values replace the defaults (explicit keys still win)",
    ),
    # resolve_config checks a count or codes (1 to MAX_BLOCKS).
    "blocks": Key(3, Rule("any"), 'a count, or a string of block codes such as "SXCT"'),
    # check_codes checks the letters (its message lists them).
    "block_types": Key("SCXTO", Rule("str"), "codes drawn from when `blocks` is a count"),
    "templates": Key("abcdef", Rule("str"), "sidewalk templates drawn uniformly per sidewalk"),
    "lanes": Key(
        [1, 2],
        Pair(Int(1, 4), hint="lanes per direction, whole numbers"),
        "lanes per direction, inclusive range, drawn per block",
    ),
    "lane_width": Key([3.0, 3.6], Pair(Float(1.0, 10.0), hint=_M), "metres, drawn per block"),
    "straight_length": Key([30.0, 60.0], Pair(Float(5.0, 500.0), hint=_M), "metres of a straight block"),
    "curve_radius": Key(
        [40.0, 70.0],
        Pair(Float(5.0, 1000.0), hint=_M),
        "centerline radius; large enough for inner sidewalks and buildings",
    ),
    "curve_angle": Key([45.0, 90.0], Pair(Float(1.0, 180.0), hint="degrees"), "degrees, either direction"),
    "arm_length": Key([20.0, 35.0], Pair(Float(5.0, 500.0), hint=_M), "junction and roundabout arms"),
    "roundabout_radius": Key([8.0, 14.0], Pair(Float(1.0, 200.0), hint=_M), "central island radius"),
    "building_depth": Key(
        [8.0, 12.0], Pair(Float(0.5, 200.0), hint=_M), "depth of the building zone beyond the sidewalk"
    ),
    "buildings": Key(True, Bool(), "buildings along the sidewalks"),
    "curb_height": Key(0.15, Float(0.0, 1.0, hint=_M), "metres the sidewalk stands above the road"),
    "crosswalk_density": Key(0.5, Float(0.0, 1.0), "probability that each crosswalk candidate is built"),
    "crosswalks": Key(
        None,
        Rule("list", item=Rule("str"), none=True, hint="candidate ids such as 'r0.0:start'"),
        'or an explicit list of candidate ids, e.g. ["r0.0:start", "r1.2:end"]',
    ),
    "connect_crosswalks": Key(True, Bool(), "also build the fewest extra candidates that join every sidewalk group"),
    "crosswalk_width": Key(3.0, Pos(20.0, hint=_M), "metres across a crosswalk"),
    "ramp_depth": Key(1.5, Float(0.0, 20.0, hint=_M), "metres a curb ramp reaches into the sidewalk"),
    "object_density": Key(
        1.0,
        Float(0.0, 50.0, hint="rho_s: 1 is the default density"),
        "rho_s: scales standard spacing (1/rho) and zoned/clutter counts (rho)",
    ),
    "standard_spacing": Key(12.0, Float(0.5, 1000.0, hint=_M), "metres between standard infrastructure at density 1"),
    "non_standard_per_100m": Key(
        8.0, Float(0.0, 500.0), 'non-standard objects per 100 m of sidewalk at density 1 ("sparse" model)'
    ),
    "clutter_per_100m": Key(
        5.0, Float(0.0, 500.0), 'clutter items per 100 m of sidewalk at density 1 ("sparse" model)'
    ),
    "density_model": Key(
        "sparse",
        Choice("sparse", "paper"),
        '"sparse": counts per 100 m; "paper": rows along every furniture zone (MetaUrban-12K)',
    ),
    "fill_gap": Key(
        0.9,
        Float(0.0, 100.0, hi_open=True, hint=_M),
        'mean gap (m) between neighbours in a row at object_density 1 ("paper" model)',
    ),
    "fill_clutter": Key(0.15, Float(0.0, 1.0, hi_open=True), 'share of clutter items in the rows ("paper" model)'),
    "fill_row_width": Key(
        1.4,
        Float(0.3, 100.0, hi_open=True, hint=_M),
        'a zone holds floor(width / this) rows of objects ("paper" model)',
    ),
    "min_objects": Key(
        0,
        Int(0, 100_000),
        '"paper" model: refill the gaps (smaller each round) until a scene holds this many',
    ),
    "placement_tries": Key(4, Int(1, 100), "positions tried per object before it counts as refused"),
    "min_clear_width": Key(1.2, Float(0.0, 10.0, hint=_M), "free corridor kept along every clear path (wheelchair)"),
    "country": Key(
        None,
        Rule("str", none=True, hint="an ISO alpha-2 code such as FI"),
        "None: uniform categories; else ISO alpha-2 row of the distribution table",
    ),
    "distribution_path": Key(
        "data/distribution/distribution.parquet",
        Rule("path"),
        "the category distribution table (rows per country)",
    ),
    "exclude_categories": Key([], Rule("list", item=Rule("str")), "held-out categories (dataset splits)"),
    "assets": Key(
        "all",
        Choice("all", "seen", "held_out"),
        "catalog assets drawn: all, seen (train, test) or held_out (unseen, finetune)",
    ),
    "grid_resolution": Key(0.25, Float(0.05, 2.0, hint="metres per walkable cell"), "metres per walkable cell"),
    "block_tries": Key(30, Int(1, 1000), "shapes/parameters tried per block before giving up"),
    # Terrain patches on the sidewalks (sim.scene.terrain, docs/terrain.md).
    "terrain": {
        "density": Key(
            1.0,
            Float(0.0, 10.0, hint="1 is a city's typical share of terrain patches, 0 none"),
            "terrain patches: 1 is a city's typical share, 0 none",
        ),
        "kinds": Key(
            list(TERRAIN_KINDS),
            Rule("list", choices=TERRAIN_KINDS),
            "any of roots (tree-root heave), rough (uneven pavers), steps (entrances), slick (wet, gravel)",
        ),
    },
}
DEFAULT_CONFIG: dict[str, Any] = defaults_of(CONFIG_KEYS)
# tests/sim/test_bad_input.py checks that no key of DEFAULT_CONFIG is missing here.
CONFIG_TABLE: dict[str, Rule | Table] = table_of(CONFIG_KEYS)


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
