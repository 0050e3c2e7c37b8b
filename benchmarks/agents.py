"""Agent engine benchmarks: one ORCA step for 10/100/1,000 agents, global planning for 100 agents, SocialNav steps/s.

Run: `python benchmarks/agents.py [--quick]`. Prints the figures; nothing is asserted (speed targets live in
docs/agents.md: planning 100 agents in far less than MetaUrban's 5 s, >= 400 SocialNav env steps/s with 20 agents).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

# Run as a script, this folder comes first on sys.path and benchmarks/sim.py would shadow the `sim` package.
sys.path[:] = [q for q in sys.path if os.path.abspath(q or ".") != os.path.dirname(os.path.abspath(__file__))]

import numpy as np  # noqa: E402

from sim.agents import AgentManager  # noqa: E402
from sim.agents.navgrid import build_navgrid  # noqa: E402
from sim.scene import generate_scene  # noqa: E402


def orca_step(n: int, repeats: int) -> float:
    """Mean milliseconds of one AgentManager.step (planner look-ups + ORCA + bookkeeping) with n agents."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # A generated street of 3 blocks (~360 m of sidewalk); 1,000 agents need 6 blocks (~650 m) to fit.
        spec = generate_scene({"blocks": 3 if n <= 100 else 6}, 0)
    m = AgentManager({"counts": {"pedestrian": n}, "max_agents": max(n, 1000)})
    m.reset(spec, np.random.default_rng(0))
    for _ in range(5):
        m.step(0.1)
    t = time.perf_counter()
    for _ in range(repeats):
        m.step(0.1)
    return (time.perf_counter() - t) / repeats * 1e3


def planning_100(scene_seed: int) -> dict[str, float]:
    """Seconds to build the planning grid and plan 100 agents from scratch on a generated scene."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spec = generate_scene(None, scene_seed)
    t = time.perf_counter()
    grid = build_navgrid(spec)
    t_grid = time.perf_counter() - t
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    sites = rng.integers(len(grid.sites), size=100)
    starts = rng.integers(grid.n_nodes, size=100)
    grid.plan_all(sites)  # every distinct goal's distance field: each agent's full path is now known
    lengths = grid.distance(starts, sites)
    t_plan = time.perf_counter() - t
    return {
        "grid_s": t_grid,
        "plan_100_s": t_plan,
        "total_s": t_grid + t_plan,
        "nodes": grid.n_nodes,
        "mean_path_m": float(np.mean(lengths[np.isfinite(lengths)])),
    }


def socialnav_steps(n_agents: int, steps: int, env_id: str = "curbside/SocialNav-v0") -> tuple[float, float]:
    """Env steps per second (wall clock, CPU time) with `n_agents` agents and traffic, driving straight at 30 % throttle.

    CPU time is printed too because on a shared machine the wall-clock rate mostly measures the other load.
    """
    import gymnasium as gym

    from sim.envs import register_envs

    register_envs()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = {"agents": {"counts": {"pedestrian": n_agents}}} if "Social" in env_id else {}
        env = gym.make(env_id, config=cfg).unwrapped
    env.reset(seed=0)
    a = np.array([0.0, 0.3], dtype=np.float32)
    t, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t), steps / (time.process_time() - cpu)
    env.close()
    return rate


def main() -> None:
    """Run every benchmark and print its figure."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = ap.parse_args()
    reps = 20 if args.quick else 100
    for n in (10, 100, 1000):
        print(f"agent step, {n:>5} agents: {orca_step(n, reps if n < 1000 else max(reps // 5, 5)):8.3f} ms")
    r = planning_100(0)
    print(
        f"global planning, 100 agents: {r['total_s']:.3f} s (grid {r['grid_s']:.3f} s + fields {r['plan_100_s']:.3f} s; "
        f"{r['nodes']} cells, mean path {r['mean_path_m']:.1f} m; MetaUrban: 5 s on a Core i9)"
    )
    steps = 300 if args.quick else 1000
    wall, cpu = socialnav_steps(0, steps, "curbside/PointNav-v0")
    print(f"PointNav env (same scene, no agents): {wall:.0f} steps/s ({cpu:.0f} per CPU second)")
    wall, cpu = socialnav_steps(20, steps)
    print(f"SocialNav env, 20 agents + traffic: {wall:.0f} steps/s ({cpu:.0f} per CPU second; target >= 400)")


if __name__ == "__main__":
    main()
