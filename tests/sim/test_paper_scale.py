"""The metaurban12k presets: paper-density scenes, long routes without U-turns, task presets."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from kernel.config import ConfigError
from sim.envs.pointnav import PointNavEnv
from sim.envs.socialnav import SocialNavEnv
from sim.expert import PurePursuitExpert
from sim.route import RoutePlanner
from sim.scene import generate_scene
from sim.scene.dataset import split_config


def _scene(seed: int, **extra) -> dict:
    cfg, off = split_config("train", {"preset": "metaurban12k", **extra})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return generate_scene(cfg, off + seed)


@pytest.mark.parametrize("blocks", [2, 3])
def test_preset_scenes_hold_at_least_300_objects(blocks: int) -> None:
    for seed in range(2):
        spec = _scene(seed, blocks=blocks)
        assert len(spec["objects"]) >= 300, (blocks, seed, len(spec["objects"]))
        assert spec["config"]["density_model"] == "paper" and spec["config"]["crosswalk_density"] == 1.0


def test_explicit_keys_override_the_preset_and_unknown_presets_raise() -> None:
    spec = _scene(0, blocks=1, fill_gap=3.0, min_objects=0)
    assert spec["config"]["fill_gap"] == 3.0 and spec["config"]["min_objects"] == 0
    with pytest.raises(ConfigError, match="valid: metaurban12k"):
        generate_scene({"preset": "dense"}, 0)


def test_long_routes_are_in_range_and_never_turn_back() -> None:
    spec = _scene(1)
    planner = RoutePlanner(spec, 0.3)
    rng = np.random.default_rng(0)
    for _ in range(3):
        route = planner.sample(rng, 250.0, 650.0)
        assert 250.0 <= route.length <= 650.0
        # Heading change over any 2 m of route stays below 120 degrees: no U-turn a wheeled machine cannot make.
        s = np.arange(0.0, route.length - 2.0, 0.5)
        h0 = np.array([route.heading_at(x) for x in s])
        h1 = np.array([route.heading_at(x + 2.0) for x in s])
        turn = np.abs((h1 - h0 + math.pi) % (2 * math.pi) - math.pi)
        assert turn.max() < math.radians(120), f"U-turn of {math.degrees(turn.max()):.0f} deg"


def test_long_route_legs_searched_within_their_reach_are_the_legs_of_a_full_search(monkeypatch) -> None:
    import sim.route

    spec = _scene(1)
    limited = [RoutePlanner(spec, 0.3).sample(np.random.default_rng(s), 250.0, 650.0).points for s in range(3)]
    full_search = sim.route.dijkstra

    def unlimited(graph, indices, return_predecessors=False, limit=np.inf, **kw):
        # A leg's search (the one that returns predecessors) runs over the whole graph; `_goes_on` keeps its limit.
        return full_search(
            graph,
            indices=indices,
            return_predecessors=return_predecessors,
            limit=np.inf if return_predecessors else limit,
            **kw,
        )

    monkeypatch.setattr(sim.route, "dijkstra", unlimited)
    full = [RoutePlanner(spec, 0.3).sample(np.random.default_rng(s), 250.0, 650.0).points for s in range(3)]
    assert all(np.array_equal(a, b) for a, b in zip(limited, full, strict=True))


def test_task_preset_sets_routes_horizon_and_agents_and_the_expert_completes_a_long_route() -> None:
    env = PointNavEnv({"preset": "metaurban12k", "scene": {"blocks": 2}, "lidar": {"beams": 60}})
    assert env.config["route_length"] == [250.0, 650.0] and env.config["scene"]["preset"] == "metaurban12k"
    assert env.config["scene"]["blocks"] == 2  # the caller's scene keys combine with the preset's
    _, info = env.reset(seed=0)
    assert info["horizon"] >= 4 * info["route_length"] / 2.5 / 0.1 * 0.25  # room for the expert at 2.5 m/s
    expert, done, steps = PurePursuitExpert(), False, 0
    while not done:
        _, _, term, trunc, info = env.step(expert.act(env))
        steps += 1
        done = term or trunc
    assert info["is_success"] and steps > 800
    env.close()
    social = SocialNavEnv({"preset": "metaurban12k", "route_length": [10.0, 60.0]})
    assert social.config["agents"]["dynamic_density"] == 7.2 and social.config["route_length"] == [10.0, 60.0]
    with pytest.raises(ConfigError, match="valid: metaurban12k"):
        PointNavEnv({"preset": "paper"})


def test_agents_spawn_along_the_route_at_a_rate_per_100_m() -> None:
    from shapely.geometry import LineString, Point

    env = SocialNavEnv(
        {
            "traffic": False,
            "route_length": [40.0, 60.0],
            "agents": {"spawn_area": "route", "dynamic_density": 10.0, "route_band": 4.0},
        }
    )
    env.reset(seed=0)
    line = LineString(env.route.points)
    pos = env.crowd.pos
    assert len(pos) == round(10.0 * line.length / 100.0) > 0
    assert max(line.distance(Point(p)) for p in pos) <= 4.0 + 0.5
    env.close()


def test_agents_spawn_only_around_intersections() -> None:
    from shapely.geometry import Point, Polygon
    from shapely.ops import unary_union

    env = SocialNavEnv(
        {
            "traffic": False,
            "scene": {"blocks": "SXS"},
            "agents": {"spawn_area": "intersections", "dynamic_density": 8.0},
        }
    )
    env.reset(seed=1)
    spec = env.scene_spec
    area = unary_union([Polygon(r["polygon"]) for r in spec["roads"] if r["block"] == "X"]).buffer(10.0)
    assert env.crowd.n > 0 and all(area.contains(Point(p)) for p in env.crowd.pos)
    env.close()
    with pytest.raises(ConfigError, match="valid: sidewalks, intersections, route"):
        SocialNavEnv({"agents": {"spawn_area": "everywhere"}})


def test_unseen_split_agents_behave_differently_unless_told_otherwise() -> None:
    train = SocialNavEnv({"split": "train", "traffic": False})
    unseen = SocialNavEnv({"split": "unseen", "traffic": False})
    mine = SocialNavEnv({"split": "unseen", "traffic": False, "agents": {"run_prob": 0.0}})
    assert train.config["agents"]["run_prob"] == 0.1 and unseen.config["agents"]["run_prob"] == 0.3
    assert unseen.config["agents"]["mix"]["pedestrian"] < train.config["agents"]["mix"]["pedestrian"]
    assert mine.config["agents"]["run_prob"] == 0.0 and mine.config["agents"]["idle_prob"] == 0.1
    for env in (train, unseen, mine):
        env.close()
