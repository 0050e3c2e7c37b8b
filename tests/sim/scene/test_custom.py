"""Custom scenes from YAML: the pool, named objects at their places, agent groups, determinism and clear errors."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from shapely.geometry import Point, Polygon

from kernel.config import ConfigError
from sim.envs import register_envs
from sim.scene.custom import check_custom, generate_custom, load_custom
from sim.scene.spec import dumps
from tests.helpers import cli, one_error_line

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "examples" / "custom_scene.yaml"
pytestmark = pytest.mark.filterwarnings("ignore:no catalog was given")


@pytest.fixture(scope="module")
def spec() -> dict:
    return generate_custom(load_custom(EXAMPLE))


def test_the_example_scene_has_its_pool_named_objects_and_agent_groups(spec) -> None:
    custom = load_custom(EXAMPLE)
    assert {o["category"] for o in spec["objects"]} <= set(custom["objects"]["pool"])
    named = {o["name"]: o for o in spec["objects"] if o.get("name")}
    assert set(named) == {"meeting_bench", "blocking_cone"}
    bench = named["meeting_bench"]
    sidewalk = next(s for s in spec["sidewalks"] if s["id"] == "r0-s0")
    zone = next(z for z in sidewalk["zones"] if z["kind"] == "furnishing")
    assert Polygon(zone["polygon"]).contains(Point(bench["position"][:2]))
    assert bench["position"][2] == spec["curb_height"] and bench["yaw"] == pytest.approx(1.5708)
    # Named objects win their place: no generated object or terrain patch overlaps them.
    for o in spec["objects"] + spec["terrain"]:
        if not o.get("name"):
            assert not any(Polygon(o["footprint"]).intersects(Polygon(n["footprint"])) for n in named.values())
    assert spec["terrain"] and [t["id"] for t in spec["terrain"]] == [f"t{k}" for k in range(len(spec["terrain"]))]
    assert spec["agents"] == {"delivery_robot": 1, "pedestrian": 12, "wheelchair_user": 2}
    assert [o["id"] for o in spec["objects"]] == [f"o{k}" for k in range(len(spec["objects"]))]


def test_the_same_yaml_gives_the_same_bytes(spec) -> None:
    assert dumps(generate_custom(load_custom(EXAMPLE))) == dumps(spec)


def test_socialnav_spawns_the_scenes_agent_groups(spec) -> None:
    register_envs()
    env = gym.make("curbside/SocialNav-v0", config={"scene_spec": spec, "traffic": False})
    env.reset(seed=0)
    kinds = env.unwrapped.agent_states()["kind"].tolist()
    assert sorted(kinds) == sorted(["pedestrian"] * 12 + ["wheelchair_user"] * 2 + ["delivery_robot"])
    env.close()
    # Explicit counts in the env config still win.
    env = gym.make(
        "curbside/SocialNav-v0", config={"scene_spec": spec, "traffic": False, "agents": {"counts": {"cyclist": 3}}}
    )
    env.reset(seed=0)
    assert env.unwrapped.agent_states()["kind"].tolist() == ["cyclist"] * 3
    env.close()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"colour": "red"}, "unknown key 'colour'.*valid keys: agents, blocks"),
        ({"objects": {"pool": ["bench", "hoverboard"]}}, "hoverboard.*not in the curbside vocabulary"),
        ({"place": [{"name": "a", "category": "bench", "at": [1.0]}]}, r"at must be \[x, y\]"),
        (
            {
                "place": [
                    {"name": "a", "category": "bench", "at": [0, 0]},
                    {"name": "a", "category": "tree", "at": [1, 1]},
                ]
            },
            "distinct names",
        ),
        ({"agents": {"unicorn": 2}}, "unicorn"),
        ({"agents": {"pedestrian": -1}}, r"agents.pedestrian must be a count"),
    ],
)
def test_bad_custom_scenes_name_the_problem(change: dict, message: str) -> None:
    base = yaml.safe_load(EXAMPLE.read_text())
    with pytest.raises(ConfigError, match=message):
        check_custom({**base, **change})


@pytest.mark.parametrize(
    ("at", "message"),
    [
        ({"sidewalk": "r9-s9"}, "no sidewalk 'r9-s9'; this scene has r0-s0"),
        ({"sidewalk": "r0-s0", "zone": "frontage"}, "no 'frontage' zone; its zones: furnishing, clear, building"),
        ([5000.0, 0.0], "outside the scene's bounds"),
    ],
)
def test_places_that_do_not_exist_are_refused(at, message: str) -> None:
    base = yaml.safe_load(EXAMPLE.read_text())
    base["place"] = [{"name": "x", "category": "bench", "at": at}]
    with pytest.raises(ConfigError, match=message):
        generate_custom(check_custom(base))


def test_the_cli_generates_from_yaml_and_refuses_bad_files(tmp_path, capsys) -> None:
    out = tmp_path / "scene.json"
    code, stdout, err = cli(["scenes", "generate", "--from", str(EXAMPLE), "--out", str(out)], capsys)
    assert code == 0, err
    assert "2 named" in stdout and "15 agents" in stdout and out.is_file()
    bad = tmp_path / "bad.yaml"
    bad.write_text("blocks: [unclosed\n")
    assert "not valid YAML" in one_error_line(
        *cli(["scenes", "generate", "--from", str(bad), "--out", str(out)], capsys)
    )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {
                "place": [
                    {"name": "a", "category": "bench", "at": [40.0, 8.0]},
                    {"name": "b", "category": "trash_bin", "at": [40.5, 8.0]},
                ]
            },
            "'a' and 'b' overlap",
        ),
        ({"generator": {"object_density": 3.0}}, "not under generator"),
        ({"place": [{"name": "a", "category": ["bench"], "at": [0, 0]}]}, "one category name"),
        ({"place": [{"name": "a", "category": "bench", "at": {"sidewalk": "r0-s0", "along": "half"}}]}, "fraction"),
    ],
)
def test_conflicting_or_malformed_custom_scenes_say_so(change: dict, message: str) -> None:
    base = yaml.safe_load(EXAMPLE.read_text())
    with pytest.raises(ConfigError, match=message):
        generate_custom(check_custom({**base, **change}))


def test_a_named_object_removes_the_terrain_patch_in_its_way() -> None:
    custom = load_custom(EXAMPLE)
    plain = generate_custom({**custom, "place": []})
    patch = plain["terrain"][0]
    cone = {"name": "on_patch", "category": "traffic_cone", "at": patch["position"][:2]}
    spec = generate_custom(check_custom({**load_custom(EXAMPLE), "place": [cone]}))
    assert len(spec["terrain"]) == len(plain["terrain"]) - 1
    assert patch["footprint"] not in [t["footprint"] for t in spec["terrain"]]
    assert sum(spec["stats"]["terrain"].values()) == len(spec["terrain"])
