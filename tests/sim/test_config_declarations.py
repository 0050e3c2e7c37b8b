"""Every simulator config is declared once: each key's default, rule and doc in one `Key` beside its component,
with the defaults dicts and rule tables that other modules import derived from those declarations."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import asdict, fields
from typing import Any

import pytest

from kernel.config import ConfigError
from sim.agents.crowd_config import AGENT_DEFAULTS, AGENT_KEYS, AGENTS_TABLE
from sim.agents.vehicle_config import VEHICLE_DEFAULTS, VEHICLE_KEYS, VEHICLES_TABLE
from sim.batched import env as batched
from sim.camera import CAMERA_DEFAULTS, CAMERA_KEYS, CAMERA_TABLE, check_clipping_planes
from sim.scene import config as scene
from sim.schema import Key, Rule, check_table, dataclass_keys, defaults_of, table_of
from sim.tasks import pointnav, socialnav
from sim.tasks.sensors import LIDAR_KEYS, LIDAR_TABLE, RENDER_KEYS, RENDER_TABLE

# (name, declaration, derived defaults, derived table) of every config.
CONFIGS: list[tuple[str, Mapping[str, Any], dict[str, Any], Mapping[str, Any]]] = [
    ("pointnav", pointnav.CONFIG_KEYS, pointnav.DEFAULT_CONFIG, pointnav.CONFIG_TABLE),
    ("socialnav", socialnav.CONFIG_KEYS, socialnav.DEFAULT_CONFIG, socialnav.CONFIG_TABLE),
    ("batched", batched.BATCHED_KEYS, batched.BATCHED_DEFAULTS, batched.BATCHED_TABLE),
    ("scene", scene.CONFIG_KEYS, scene.DEFAULT_CONFIG, scene.CONFIG_TABLE),
    ("camera", CAMERA_KEYS, CAMERA_DEFAULTS, CAMERA_TABLE),
    ("agents", AGENT_KEYS, AGENT_DEFAULTS, AGENTS_TABLE),
    ("vehicles", VEHICLE_KEYS, VEHICLE_DEFAULTS, VEHICLES_TABLE),
    ("lidar", LIDAR_KEYS, pointnav.DEFAULT_CONFIG["lidar"], LIDAR_TABLE),
    ("render", RENDER_KEYS, pointnav.DEFAULT_CONFIG["render"], RENDER_TABLE),
    ("reward", pointnav.REWARD_KEYS, pointnav.REWARD_PRESETS["learnable"], pointnav.REWARD_TABLE),
]
IDS = [c[0] for c in CONFIGS]


def declared(keys: Mapping[str, Any], defaults: Mapping[str, Any], path: str = "") -> Iterator[tuple[str, Key, Any]]:
    """(dotted path, its Key, its derived default) for every key of `defaults`, asserting that the declaration has
    the same keys in the same order, and a nested mapping of Keys exactly where the default is a sub-config."""
    assert list(keys) == list(defaults), path or "top level"
    for name, key in keys.items():
        full = f"{path}.{name}" if path else name
        if isinstance(key, Key):
            yield full, key, defaults[name]
        else:
            assert isinstance(key, Mapping) and isinstance(defaults[name], dict), full
            yield from declared(key, defaults[name], full)


@pytest.mark.parametrize(("name", "keys", "defaults", "table"), CONFIGS, ids=IDS)
def test_every_key_has_one_declaration_with_a_doc_and_a_rule(
    name: str, keys: Mapping[str, Any], defaults: dict[str, Any], table: Mapping[str, Any]
) -> None:
    seen = list(declared(keys, defaults))
    assert len(seen) == len({p for p, _, _ in seen}) > 0
    for path, key, default in seen:
        assert isinstance(key.doc, str) and key.doc.strip() and "\n" not in key.doc, (name, path)
        assert isinstance(key.rule, (Rule, Mapping)), (name, path)
        assert default == key.default, (name, path)


@pytest.mark.parametrize(("name", "keys", "defaults", "table"), CONFIGS, ids=IDS)
def test_each_default_passes_its_own_rule(
    name: str, keys: Mapping[str, Any], defaults: dict[str, Any], table: Mapping[str, Any]
) -> None:
    for path, key, default in declared(keys, defaults):
        if isinstance(key.rule, Rule):
            assert key.rule.ok(default), (name, path, default, key.rule.describe())
        else:
            check_table(default, key.rule, name=path)
    check_table(defaults, table, name=name, defaults=defaults)


@pytest.mark.parametrize(("name", "keys", "defaults", "table"), CONFIGS, ids=IDS)
def test_the_public_dicts_are_derived_from_the_declaration(
    name: str, keys: Mapping[str, Any], defaults: dict[str, Any], table: Mapping[str, Any]
) -> None:
    assert defaults == defaults_of(keys)
    assert table == table_of(keys)
    assert list(table) == list(defaults)  # no rule without a default, no default without a rule


def test_derived_defaults_are_fresh_copies() -> None:
    a, b = defaults_of(AGENT_KEYS), defaults_of(AGENT_KEYS)
    a["mix"]["pedestrian"] = -1.0
    a["idle_time"].append(99.0)
    assert b == AGENT_DEFAULTS == defaults_of(AGENT_KEYS)
    assert socialnav.DEFAULT_CONFIG["agents"]["mix"] is not AGENT_DEFAULTS["mix"]
    assert pointnav.DEFAULT_CONFIG["camera"] is not CAMERA_DEFAULTS
    assert pointnav.DEFAULT_CONFIG["camera"]["modalities"] is not CAMERA_KEYS["modalities"].default


def test_tasks_compose_the_components_declarations() -> None:
    assert pointnav.CONFIG_KEYS["lidar"] is LIDAR_KEYS and pointnav.CONFIG_KEYS["camera"] is CAMERA_KEYS
    assert pointnav.CONFIG_KEYS["render"] is RENDER_KEYS
    assert socialnav.CONFIG_KEYS["agents"] is AGENT_KEYS and socialnav.CONFIG_KEYS["vehicles"] is VEHICLE_KEYS
    assert socialnav.AGENTS_TABLE is AGENTS_TABLE and socialnav.VEHICLES_TABLE is VEHICLES_TABLE
    # PointNav's keys that SocialNav and the batched env inherit are the same declarations.
    redeclared = {"cost_kinds", "measures", "render"}
    for key, declaration in pointnav.CONFIG_KEYS.items():
        assert batched.BATCHED_KEYS[key] is declaration
        if key not in redeclared:
            assert socialnav.CONFIG_KEYS[key] is declaration
    for key in ("cost_kinds", "measures"):  # another default, the same rule
        social, point = socialnav.CONFIG_KEYS[key], pointnav.CONFIG_KEYS[key]
        assert isinstance(social, Key) and isinstance(point, Key) and social.rule is point.rule
    assert set(socialnav.DEFAULT_CONFIG["cost_kinds"]) > set(pointnav.DEFAULT_CONFIG["cost_kinds"])


def test_reward_fields_are_its_declaration() -> None:
    assert pointnav.REWARD_KEYS == dataclass_keys(pointnav.Reward)
    assert [f.name for f in fields(pointnav.Reward)] == list(pointnav.REWARD_KEYS)
    assert asdict(pointnav.Reward()) == defaults_of(pointnav.REWARD_KEYS)
    assert pointnav.CONFIG_TABLE["reward"] is pointnav.REWARD_TABLE
    for preset in pointnav.REWARD_PRESETS.values():
        check_table(preset, pointnav.REWARD_TABLE, name="config.reward")


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"success": math.nan}, "config.reward.success must be a finite number in [-1e+06, 1e+06], got nan"),
        ({"progress": "back"}, "unknown config.reward.progress 'back'; valid: route, max"),
        ({"floor": 1}, "config.reward.floor must be true or false, got 1"),
    ],
)
def test_a_reward_is_checked_by_the_table_with_the_config_message(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError) as built:
        pointnav.Reward(**overrides)
    with pytest.raises(ConfigError) as configured:
        pointnav.check_config(pointnav.resolve_task_config(pointnav.DEFAULT_CONFIG, {"reward": overrides}))
    assert str(built.value) == str(configured.value) == message


def test_the_agent_manager_checks_the_agents_table() -> None:
    from sim.agents.crowd import AgentManager

    for key, value in [("group_size", [1, 3]), ("push_window", -1.0), ("lookahead_cells", 3), ("spawn_area", "x")]:
        with pytest.raises(ConfigError) as direct:
            AgentManager({key: value})
        with pytest.raises(ConfigError) as task:
            check_table({key: value}, AGENTS_TABLE, name="config.agents")  # SocialNav's table of `agents`
        assert str(direct.value) == str(task.value).replace("config.agents.", "agents config.")


def test_presets_override_declared_keys_with_valid_values() -> None:
    for preset in pointnav.TASK_PRESETS.values():
        check_table(preset, pointnav.CONFIG_TABLE, name="preset", defaults=pointnav.DEFAULT_CONFIG)
    for preset in socialnav.PRESETS.values():
        check_table(preset, socialnav.CONFIG_TABLE, name="preset", defaults=socialnav.DEFAULT_CONFIG)
    for behaviour in socialnav.SPLIT_AGENT_BEHAVIOUR.values():
        check_table(behaviour, AGENTS_TABLE, name="agents")
        assert set(behaviour) <= set(AGENT_KEYS)
    for preset in scene.PRESETS.values():
        check_table(preset, scene.CONFIG_TABLE, name="scene preset")
        assert set(preset) <= set(scene.CONFIG_KEYS)


def test_cross_key_checks_stay_small_named_functions() -> None:
    check_clipping_planes({"near": 0.1, "far": 10.0})
    with pytest.raises(ConfigError, match=r"^config.camera.near \(5.0\) must be below config.camera.far \(2.0\)$"):
        check_clipping_planes({"near": 5.0, "far": 2.0})
    cfg = pointnav.resolve_task_config(pointnav.DEFAULT_CONFIG, {"lidar": {"static": "grid"}, "collision": "convex"})
    with pytest.raises(ConfigError, match="config.lidar.static 'grid' traces the objects' boxes"):
        pointnav.check_grid_lidar_collision(cfg)
