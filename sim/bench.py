"""Simulator benchmark: PointNav env steps/s against the raw PyBullet floor, reset time, RSS growth."""

from __future__ import annotations

import math
import os
import time
import warnings
from typing import Any

import numpy as np
import pybullet as p

BENCH_SCENE = {"blocks": 3, "object_density": 2.5}


def bench_scene(target_objects: int = 200, seed: int = 0) -> dict[str, Any]:
    """A 3-block generated scene with about `target_objects` static objects (first seed within 25 %)."""
    from sim.scene import generate_scene

    best = None
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="no catalog was given")
        for s in range(seed, seed + 10):
            spec = generate_scene(dict(BENCH_SCENE), s)
            n = len(spec["objects"])
            if best is None or abs(n - target_objects) < abs(len(best["objects"]) - target_objects):
                best = spec
            if abs(n - target_objects) <= 0.25 * target_objects:
                break
    return best


def _rss_mb() -> float:
    import psutil

    return psutil.Process(os.getpid()).memory_info().rss / 2**20


def run_bench(quick: bool = False, machine: str = "delivery_bot") -> dict[str, Any]:
    """Measure env steps/s, the floor (physics substeps + one rayTestBatch per step), reset time, RSS growth."""
    from sim.envs.pointnav import PointNavEnv
    from sim.expert import PurePursuitExpert

    steps = 1000 if quick else 5000
    resets = 100 if quick else 1000
    spec = bench_scene()
    env = PointNavEnv({"scene_spec": spec, "machine": machine})
    expert = PurePursuitExpert()
    env.reset(seed=0)
    # CPU time (process_time), not wall time: on a shared machine other processes' load would otherwise
    # count against the simulator. Wall-clock figures are reported next to them.
    clock = time.process_time
    # Env: expert actions (the realistic case: the machine moves, turns, touches things); time step() only.
    t_env, w_env, n, seed = 0.0, 0.0, 0, 0
    while n < steps:
        action = expert.act(env)
        t0, w0 = clock(), time.perf_counter()
        _, _, term, trunc, _ = env.step(action)
        t_env += clock() - t0
        w_env += time.perf_counter() - w0
        n += 1
        if term or trunc:
            seed += 1
            env.reset(seed=seed)
    steps_per_s = n / t_env
    # Floor: the same world and machine; only Bullet's substeps and one 240-ray batch per step.
    c, m, lid = env.client, env.machine, env.lidar
    x, y, z = m.position
    frm, to = lid.rays(x, y, z, m.yaw)
    t0, w0 = clock(), time.perf_counter()
    for _ in range(steps):
        for _ in range(env.substeps):
            p.stepSimulation(physicsClientId=c)
        p.rayTestBatch(frm, to, physicsClientId=c)
    floor = steps / (clock() - t0)
    floor_wall = steps / (time.perf_counter() - w0)
    # Resets on the same scene (bodies reused) and the memory they hold on to.
    for k in range(20):
        env.reset(seed=10_000 + k)
    rss0 = _rss_mb()
    t0 = time.perf_counter()
    for k in range(resets):
        env.reset(seed=k)
    reset_s = (time.perf_counter() - t0) / resets
    rss1 = _rss_mb()
    # A fresh scene (world build + planner) for reference.
    t0 = time.perf_counter()
    env2 = PointNavEnv({"scene_spec": spec, "machine": machine})
    env2.reset(seed=0)
    build_s = time.perf_counter() - t0
    env2.close()
    env.close()
    return {
        "machine": machine,
        "objects": len(spec["objects"]),
        "lidar_beams": lid.beams,
        "steps": n,
        "steps_per_s": round(steps_per_s, 1),
        "floor_steps_per_s": round(floor, 1),
        "ratio": round(steps_per_s / floor, 3),
        "wall_steps_per_s": round(n / w_env, 1),
        "wall_floor_steps_per_s": round(floor_wall, 1),
        "reset_ms": round(1000 * reset_s, 2),
        "scene_build_ms": round(1000 * build_s, 1),
        "resets": resets,
        "rss_growth_mb": round(rss1 - rss0, 2),
        "cpu_count": os.cpu_count() or 0,
        "loadavg_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else math.nan,
    }
