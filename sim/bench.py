"""Simulator benchmark: env steps/s against the raw PyBullet floor, reset time, scene build time, RSS growth.

PointNav drives the machine in the bench scene (~150 static objects, 240 + 60 LiDAR beams); SocialNav adds 20
agents (ORCA) and traffic (IDM) to the same scene. Steps are timed in CPU seconds of this process, so load from
other processes does not count against the simulator; wall-clock figures are reported beside them.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from typing import Any

import numpy as np

from kernel.quiet import pybullet as p
from sim.tasks import DEFAULT_TASK
from sim.tasks.pointnav import DEFAULT_CONFIG as POINTNAV_DEFAULTS
from sim.tasks.sensors import CAMERA_DEFAULTS

# Terrain off: the bench times the step code on the scene its recorded figures (benchmarks/results/sim_speed) ran on;
# terrain patches (docs/terrain.md) add ~20 static meshes and a friction lookup, not step-code work worth timing.
BENCH_SCENE = {"blocks": 3, "object_density": 2.5, "terrain": {"density": 0.0}}
TASKS = ("PointNav", "SocialNav")
# SocialNav's bench crowd: 20 agents of the usual kinds, plus vehicles at the default traffic density.
SOCIALNAV_BENCH = {
    "agents": {"counts": {"pedestrian": 14, "cyclist": 2, "wheelchair_user": 2, "scooter_rider": 2}},
    "traffic": True,
}


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
    assert best is not None  # the loop generates at least one scene
    return best


def _rss_mb() -> float:
    import psutil

    return psutil.Process(os.getpid()).memory_info().rss / 2**20


def make_bench_env(task: str, config: dict[str, Any]) -> Any:
    """The env of `task` ("PointNav" or "SocialNav", with the bench crowd and traffic) for `config`."""
    if task not in TASKS:
        raise ValueError(f"unknown bench task {task!r}; valid: {', '.join(TASKS)}")
    if task == "PointNav":
        from sim.envs.pointnav import PointNavEnv

        return PointNavEnv(config)
    from sim.envs.socialnav import SocialNavEnv

    return SocialNavEnv({**SOCIALNAV_BENCH, **config})


def _env_steps(env: Any, steps: int) -> tuple[int, float, float]:
    """(steps, CPU seconds, wall seconds) of `steps` env steps under the expert's actions, step() only timed."""
    from sim.expert import PurePursuitExpert

    expert = PurePursuitExpert.for_machine(env.unwrapped.spec_machine)
    clock = time.process_time
    cpu, wall, n, seed = 0.0, 0.0, 0, 0
    env.reset(seed=seed)
    while n < steps:
        # Expert actions are the realistic case: the machine moves, turns and touches things.
        action = expert.act(env)
        t0, w0 = clock(), time.perf_counter()
        _, _, term, trunc, _ = env.step(action)
        cpu += clock() - t0
        wall += time.perf_counter() - w0
        n += 1
        if term or trunc:
            seed += 1
            env.reset(seed=seed)
    return n, cpu, wall


def _floor(env: Any, steps: int) -> tuple[float, float]:
    """(CPU, wall) steps/s of the raw floor: the same world's Bullet substeps and one 240-ray Bullet batch a step
    (the target's definition, whichever backend the env's LiDAR uses: with `lidar.static` grid the env can beat it)."""
    from sim.sensors import Lidar

    c, m, lid = env.client, env.machine, env.lidar
    x, y, z = m.position
    frm, to = Lidar(c, lid.beams, lid.range_m, lid.height, lid.start_radius).rays(x, y, z, m.yaw)
    clock = time.process_time
    t0, w0 = clock(), time.perf_counter()
    for _ in range(steps):
        for _ in range(env.substeps):
            p.stepSimulation(physicsClientId=c)
        p.rayTestBatch(frm, to, physicsClientId=c)
    return steps / (clock() - t0), steps / (time.perf_counter() - w0)


def _new_scenes(task: str, count: int, machine: str) -> dict[str, float]:
    """Reset time and RSS growth over `count` resets that each draw a new generated scene.

    One world is cached, so each new scene replaces the last: what grows is what the env leaks, not the cache's
    designed holding. RSS follows the size of the scene held (its world, planner and LiDAR grids: tens of MB
    between a small and a large scene), so growth is measured on one reference scene, reset before and after the
    `count` new ones (`new_scenes_rss_ref_growth_mb`), beside the end minus the start (`new_scenes_rss_growth_mb`,
    which also holds the difference in size between the first and the last scene), the least-squares trend over
    all resets and the peak.
    """
    env = make_bench_env(task, {"machine": machine, "num_scenes": 1_000_000, "scene_cache": 1})
    for k in range(min(20, count)):  # warm up: allocator arenas and lazy imports settle first
        env.reset(seed=100_000 + k)
    reference = 100_000  # the first warm-up seed: a scene seen before, so its first-time costs are paid
    env.reset(seed=reference)
    ref0 = _rss_mb()
    rss = [ref0]
    t0 = time.perf_counter()
    for k in range(count):
        env.reset(seed=k)
        rss.append(_rss_mb())
    dt = time.perf_counter() - t0
    env.reset(seed=reference)
    ref1 = _rss_mb()
    env.close()
    trend = float(np.polyfit(np.arange(len(rss)), rss, 1)[0]) * count if count > 1 else 0.0
    return {
        "new_scene_reset_ms": round(1000 * dt / count, 1),
        "new_scenes": count,
        "new_scenes_rss_ref_growth_mb": round(ref1 - ref0, 2),
        "new_scenes_rss_growth_mb": round(rss[-1] - rss[0], 2),
        "new_scenes_rss_trend_mb": round(trend, 2),
        "new_scenes_rss_max_mb": round(max(rss) - rss[0], 2),
    }


def run_bench(
    quick: bool = False, machine: str = POINTNAV_DEFAULTS["machine"], task: str = DEFAULT_TASK
) -> dict[str, Any]:
    """Measure env steps/s and the floor in the same run, reset and scene build time, RSS growth over resets."""
    steps = 1000 if quick else 5000
    resets = 100 if quick else 1000
    spec = bench_scene()
    env = make_bench_env(task, {"scene_spec": spec, "machine": machine})
    n, cpu, wall = _env_steps(env, steps)
    floor, floor_wall = _floor(env, steps)
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
    env2 = make_bench_env(task, {"scene_spec": spec, "machine": machine})
    env2.reset(seed=0)
    build_s = time.perf_counter() - t0
    env2.close()
    agents = len(env.crowd.states()) if task == "SocialNav" else 0
    vehicles = len(env.vehicle_states()) if task == "SocialNav" else 0
    lid = env.lidar
    env.close()
    steps_per_s = n / cpu
    return {
        "task": task,
        "machine": machine,
        "objects": len(spec["objects"]),
        "agents": agents,
        "vehicles": vehicles,
        "lidar_beams": lid.beams,
        "lidar_static": type(lid).__name__,
        "steps": n,
        "steps_per_s": round(steps_per_s, 1),
        "floor_steps_per_s": round(floor, 1),
        "ratio": round(steps_per_s / floor, 3),
        "wall_steps_per_s": round(n / wall, 1),
        "wall_floor_steps_per_s": round(floor_wall, 1),
        "reset_ms": round(1000 * reset_s, 2),
        "scene_build_ms": round(1000 * build_s, 1),
        "resets": resets,
        "rss_growth_mb": round(rss1 - rss0, 2),
        **_new_scenes(task, 20 if quick else 1000, machine),
        "cpu_count": os.cpu_count() or 0,
        "loadavg_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else math.nan,
    }


# The camera runs: no camera (the LiDAR-only env), each modality alone, all three from one render.
CAMERA_RUNS = ((), ("rgb",), ("depth",), ("semantic",), ("rgb", "depth", "semantic"))
PAPER_FPS = {"rgb": 50, "depth": 60, "lidar": 120}  # MetaUrban Table 6: 128x128, one process, V100


def run_camera_bench(
    quick: bool = False,
    machine: str = POINTNAV_DEFAULTS["machine"],
    size: int = CAMERA_DEFAULTS["width"],
    renderer: str = CAMERA_DEFAULTS["renderer"],
    task: str = DEFAULT_TASK,
) -> dict[str, Any]:
    """Env steps per CPU-second (and wall-second) in the bench scene with each camera modality at `size` pixels."""
    steps = 200 if quick else 1000
    spec = bench_scene()
    out: dict[str, Any] = {
        "task": task,
        "machine": machine,
        "objects": len(spec["objects"]),
        "size": size,
        "renderer": renderer,
        "steps": steps,
    }
    for mods in CAMERA_RUNS:
        cam = {"modalities": list(mods), "width": size, "height": size, "renderer": renderer}
        env = make_bench_env(task, {"scene_spec": spec, "machine": machine, "camera": cam})
        n, cpu, wall = _env_steps(env, steps)
        env.close()
        key = "+".join(mods) or "no_camera"
        out[f"{key}_steps_per_s"] = round(n / cpu, 1)
        out[f"{key}_wall_steps_per_s"] = round(n / wall, 1)
    out.update({f"paper_{k}_fps": v for k, v in PAPER_FPS.items()})
    out["cpu_count"] = os.cpu_count() or 0
    return out
