"""The typed Scene: parsed and checked once, typed fields, one decoded grid, and the consumers that take it."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from kernel.config import ConfigError
from sim.scene import SPEC_VERSION, Scene, SceneError, load
from sim.scene.scene import as_scene
from tests.street import NARROW, street


@pytest.fixture(scope="module")
def spec() -> dict:
    return street()


def test_parse_gives_typed_fields_and_keeps_the_dict(spec: dict) -> None:
    scene = Scene.parse(spec)
    assert scene.spec is spec and scene.version == SPEC_VERSION == "curbside.scene/1"
    assert scene.bounds == tuple(float(v) for v in spec["bounds"]) and isinstance(scene.seed, int)
    assert scene.curb_height == spec["curb_height"] and scene.objects == tuple(spec["objects"])
    assert len(scene.roads) == len(spec["roads"]) and scene.stats == spec["stats"]
    assert Scene.parse(scene) is scene and as_scene(scene) is scene
    assert as_scene(spec, cached=scene) is scene  # the same dict again is not parsed again
    with pytest.raises(AttributeError):
        scene.seed = 3  # type: ignore[misc]  # frozen


def test_walkable_is_decoded_once_and_read_only(spec: dict) -> None:
    scene = Scene.parse(spec)
    grid = scene.walkable
    assert scene.walkable is grid and grid.shape == tuple(spec["walkable"]["shape"])
    with pytest.raises(ValueError):
        grid.mask[0, 0] = 1


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda s: s.update(version="curbside.scene/0"), "curbside.scene/1"),
        (lambda s: s.pop("walkable"), "lacks walkable"),
        (lambda s: s.update(seed="zero"), "seed must be an integer"),
        (lambda s: s["objects"][1].update(position=[math.nan, 0.0, 0.0]), r"objects\[1\] \(id 'o1'\) position"),
        (lambda s: s["objects"][2].update(footprint=[[0.0, 1.0], [2.0]]), r"objects\[2\] \(id 'o2'\) footprint"),
        (lambda s: s["crosswalks"][0].update(polygon=[[0.0, math.inf]]), r"crosswalks\[0\] needs a polygon"),
    ],
)
def test_parse_names_the_bad_field(spec: dict, change, message: str) -> None:
    bad = copy.deepcopy(spec)
    change(bad)
    with pytest.raises(SceneError, match=message) as err:
        Scene.parse(bad)
    assert isinstance(err.value, ConfigError) and "curbside scenes generate" in str(err.value)


def test_load_reads_a_file_and_refuses_bad_json(spec: dict, tmp_path: Path) -> None:
    path = tmp_path / "s.json"
    path.write_text(json.dumps(spec))
    assert Scene.load(path).spec == spec == load(path)
    path.write_text("not json")
    with pytest.raises(SceneError, match="not a scene spec JSON file"):
        Scene.load(path)
    with pytest.raises(FileNotFoundError, match="curbside scenes generate"):
        Scene.load(tmp_path / "missing.json")


def test_consumers_take_a_scene_or_a_dict() -> None:
    from sim.agents import AgentManager
    from sim.agents.lanes import build_lanes
    from sim.agents.vehicles import VehicleManager
    from sim.route import RoutePlanner

    spec = street(60.0, crosswalks=(8.0, 52.0), **NARROW)
    scene = Scene.parse(spec)
    a, b = RoutePlanner(scene, 0.3), RoutePlanner(spec, 0.3)
    assert a.grid is scene.walkable and np.array_equal(a.free, b.free)
    assert [ln.length for ln in build_lanes(scene)] == [ln.length for ln in build_lanes(spec)]
    crowd = AgentManager({"counts": {"pedestrian": 2}})
    crowd.reset(spec, np.random.default_rng(0))
    grid = crowd.grid
    crowd.reset(spec, np.random.default_rng(1))  # the same dict: its grid is kept, not rebuilt
    assert crowd.grid is grid
    crowd.reset(scene, np.random.default_rng(0))
    assert crowd.grid is not grid
    VehicleManager().reset(scene, np.random.default_rng(0))


def test_world_and_env_hold_the_scene(spec: dict) -> None:
    from sim.envs.pointnav import PointNavEnv
    from sim.world import World

    world = World(spec)
    assert isinstance(world.scene, Scene) and world.scene.spec is spec
    world.close()
    env = PointNavEnv({"scene_spec": spec})
    env.reset(seed=0)
    assert isinstance(env.scene, Scene) and env.scene is env.world.scene is env.planner.scene
    assert env.scene_spec == spec
    env.close()
