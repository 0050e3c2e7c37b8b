"""`curbside sim bench`'s parts: the task's env with the bench crowd, the timed step loop, the floor."""

from __future__ import annotations

import pytest

from sim.bench import SOCIALNAV_BENCH, _env_steps, _floor, bench_scene, make_bench_env


def test_bench_rejects_an_unknown_task_naming_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="PointNav, SocialNav"):
        make_bench_env("ObjectNav", {})


def test_socialnav_bench_env_has_its_twenty_agents_and_traffic_and_steps_are_timed() -> None:
    spec = bench_scene()
    env = make_bench_env("SocialNav", {"scene_spec": spec, "horizon": 30})
    try:
        n, cpu, wall = _env_steps(env, 40)  # crosses at least one reset (horizon 30)
        assert n == 40 and 0 < cpu and 0 < wall
        assert len(env.crowd.states()) == sum(SOCIALNAV_BENCH["agents"]["counts"].values())
        assert len(env.vehicle_states()) > 0
        floor, floor_wall = _floor(env, 5)
        assert floor > 0 and floor_wall > 0
    finally:
        env.close()
