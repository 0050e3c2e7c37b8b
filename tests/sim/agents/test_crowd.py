"""Cohabitant motion: no overlaps, on the walkable area, goals reached, deterministic, reacting to the ego."""

from __future__ import annotations

import numpy as np
import pytest

from kernel.config import ConfigError
from sim.agents import AGENT_DTYPE, AGENT_KINDS, AgentManager, EgoState
from sim.agents.crowd import sidewalk_length
from tests.street import NARROW, street

STEPS = 500
SEEDS = range(5)


def _run(spec: dict, seed: int, steps: int, config: dict | None = None, ego_path=None) -> dict:
    m = AgentManager(config or {"dynamic_density": 16})
    m.reset(spec, np.random.default_rng(seed))
    worst_gap, off, worst_ego = np.inf, 0, np.inf
    for k in range(steps):
        ego = ego_path(k) if ego_path else None
        s = m.step(0.1, ego)
        xy = np.stack([s["x"], s["y"]], 1)
        d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
        np.fill_diagonal(d, np.inf)
        worst_gap = min(worst_gap, float((d / (s["radius"][:, None] + s["radius"][None])).min()))
        off += int((~m.grid.is_walkable(xy)).sum())
        if ego is not None:
            de = np.hypot(s["x"] - ego.x, s["y"] - ego.y) / (s["radius"] + ego.radius)
            worst_ego = min(worst_ego, float(de.min()))
    return {
        "gap": worst_gap,
        "off": off,
        "stats": m.goal_stats(),
        "overdue": m.overdue(),
        "n": m.n,
        "ego": worst_ego,
        "final": m.states(),
    }


@pytest.fixture(scope="module")
def toy() -> dict:
    return street(90.0, seed=3, crosswalks=(8.0, 82.0), **NARROW)


@pytest.fixture(scope="module")
def runs(toy: dict) -> list[dict]:
    return [_run(toy, seed, STEPS) for seed in SEEDS]


def test_agents_never_overlap(runs: list[dict]) -> None:
    assert all(r["n"] >= 20 for r in runs)
    worst = min(r["gap"] for r in runs)
    assert worst >= 0.9, f"two agents came within {worst:.3f} x (r_i + r_j)"


def test_agents_stay_on_walkable_area(runs: list[dict]) -> None:
    assert sum(r["off"] for r in runs) == 0


def test_agents_reach_goals_within_budget(runs: list[dict]) -> None:
    in_time = sum(r["stats"]["in_time"] for r in runs)
    # Goals still running past their budget count as failures too, so nothing hides in "pending".
    failed = sum(r["stats"]["late"] + r["stats"]["abandoned"] + r["overdue"] for r in runs)
    assert in_time > 5 * len(runs), "too few goals finished to judge"
    assert in_time / (in_time + failed) >= 0.95, f"{in_time} in time, {failed} late/abandoned/overdue"


def test_deterministic_per_seed(toy: dict) -> None:
    a = _run(toy, 7, 120)["final"]
    b = _run(toy, 7, 120)["final"]
    c = _run(toy, 8, 120)["final"]
    assert a.dtype == AGENT_DTYPE
    assert np.array_equal(a, b)
    assert not (len(a) == len(c) and np.allclose(a["x"], c["x"]))


def test_reused_orca_part_gives_the_fresh_episode(toy: dict) -> None:
    # One manager runs episodes with other agent counts first (its ORCA part and obstacle index are reused);
    # the episode of seed 7 must be the one a fresh manager runs.
    def episode(m: AgentManager, seed: int, density: float) -> np.ndarray:
        m.config["dynamic_density"] = density
        m.reset(toy, np.random.default_rng(seed))
        for _ in range(60):
            s = m.step(0.1)
        return s

    used = AgentManager({"dynamic_density": 16})
    for seed, density in ((1, 30.0), (2, 5.0), (3, 16.0)):
        episode(used, seed, density)
    fresh = episode(AgentManager({"dynamic_density": 16}), 7, 16.0)
    again = episode(used, 7, 16.0)
    assert used.orca is not None and used.orca.n == len(again)  # the reused part holds this episode's agents
    assert np.array_equal(fresh, again)


def test_agents_make_room_for_the_ego(toy: dict) -> None:
    # The ego walks the right sidewalk's clear path at 1.2 m/s; ORCA does not move it, agents must.
    def ego(k: int) -> EgoState:
        return EgoState(x=5.0 + 0.12 * k, y=-6.0, vx=1.2, vy=0.0, radius=0.4)

    r = _run(toy, 2, 300, {"dynamic_density": 16}, ego_path=ego)
    assert r["ego"] >= 0.9, f"an agent came within {r['ego']:.3f} x (r + r_ego) of the ego"


def test_spawn_counts_and_density(toy: dict) -> None:
    m = AgentManager({"counts": {"cyclist": 3, "robot_dog": 2}})
    s = m.reset(toy, np.random.default_rng(0))
    assert sorted(s["kind"].tolist()) == ["cyclist"] * 3 + ["robot_dog"] * 2
    assert np.allclose(s["radius"][s["kind"] == "cyclist"], AGENT_KINDS["cyclist"].radius)
    m = AgentManager({"dynamic_density": 10.0})
    assert m.reset(toy, np.random.default_rng(0)).shape == (round(10.0 * sidewalk_length(toy) / 100.0),)


def test_bad_configs_name_the_fix(toy: dict) -> None:
    with pytest.raises(ValueError, match="valid kinds"):
        AgentManager({"counts": {"unicorn": 1}})
    with pytest.raises(ConfigError, match="valid keys"):
        AgentManager({"densty": 1.0})
    with pytest.raises(ValueError, match="lower dynamic_density"):
        AgentManager({"counts": {"pedestrian": 900}}).reset(toy, np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="before reset"):
        AgentManager().step(0.1)


def test_kind_table_is_complete() -> None:
    expected = {
        "pedestrian",
        "wheelchair_user",
        "cyclist",
        "skateboarder",
        "scooter_rider",
        "delivery_robot",
        "robot_dog",
    }
    assert set(AGENT_KINDS) == expected
    rng = np.random.default_rng(0)
    for k in AGENT_KINDS.values():
        assert 0.2 <= k.radius <= 0.6 and k.pref_speed > 0 and k.source
        v = [k.sample_speed(rng, "walking") for _ in range(200)]
        assert min(v) >= 0.5 * k.pref_speed and abs(np.mean(v) - k.pref_speed) < 0.25 * k.pref_speed
        assert k.sample_speed(rng, "idle") == 0.0
    assert AGENT_KINDS["pedestrian"].sample_speed(rng, "running") > AGENT_KINDS["pedestrian"].pref_speed
