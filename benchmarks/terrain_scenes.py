"""Terrain in generated scenes (docs/terrain.md): patches per scene by kind at the default density, and
what terrain costs scene generation, the PyBullet world build and the grid LiDAR's grids at the PointNav defaults
(terrain density 0 against the default, the two interleaved per seed so that load from other processes falls on
both alike).

Usage: python benchmarks/terrain_scenes.py [--count 30] [--blocks 3] [--out benchmarks/results/terrain/terrain_scenes]
Writes terrain_scenes.json (per-seed rows and the summary) and terrain_scene.png (the first seed's scene plot).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import warnings
from pathlib import Path


def main() -> None:
    """Generate and build `--count` scenes with and without terrain; print and write the figures."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--count", type=int, default=30)
    ap.add_argument("--blocks", type=int, default=3)
    ap.add_argument("--out", default="benchmarks/results/terrain/terrain_scenes")
    args = ap.parse_args()
    from rich.progress import track

    from sim.raycast.grids import build_grids
    from sim.scene import generate_scene
    from sim.scene.config import DEFAULT_CONFIG
    from sim.scene.plot import render_scene
    from sim.scene.scene import Scene
    from sim.tasks.pointnav import DEFAULT_CONFIG as TASK
    from sim.terrain.patches import KINDS
    from sim.world import World

    warnings.simplefilter("ignore")  # no catalog: fallback boxes
    density = DEFAULT_CONFIG["terrain"]["density"]
    configs = {"off": {"blocks": args.blocks, "terrain": {"density": 0.0}}, "on": {"blocks": args.blocks}}
    World(Scene.parse(generate_scene(configs["on"], 10_000))).close()  # warm imports and caches
    lidar = TASK["lidar"]
    rows = []
    for seed in track(range(args.count), description="scenes"):
        row: dict = {"seed": seed}
        for name, cfg in configs.items():
            t0 = time.perf_counter()
            spec = generate_scene(cfg, seed)
            t1 = time.perf_counter()
            scene = Scene.parse(spec)
            world = World(scene)
            t2 = time.perf_counter()
            world.close()
            t3 = time.perf_counter()
            build_grids(scene, resolution=float(lidar["resolution"]), lidar=lidar, body_height=None)
            t4 = time.perf_counter()
            row[f"generate_ms_{name}"] = 1000 * (t1 - t0)
            row[f"world_ms_{name}"] = 1000 * (t2 - t1)
            row[f"grids_ms_{name}"] = 1000 * (t4 - t3)
            if name == "on":
                row.update(spec["stats"]["terrain"])
                row["sidewalk_m"] = spec["stats"]["clear_path_length_m"]
                if seed == 0:
                    render_scene(spec, Path(args.out) / "terrain_scene.png", title="seed 0 with terrain (default)")
        rows.append(row)
    mean = {k: statistics.mean(r[k] for r in rows) for k in rows[0] if k != "seed"}
    summary = {
        "count": args.count,
        "blocks": args.blocks,
        "density": density,
        "patches_per_scene": {k: round(mean[k], 2) for k in KINDS},
        "patches_per_scene_total": round(sum(mean[k] for k in KINDS), 2),
        "patches_per_100m_clear_path": round(100 * sum(mean[k] for k in KINDS) / mean["sidewalk_m"], 2),
        **{f"{k}_ms_{x}": round(mean[f"{k}_ms_{x}"], 1) for k in ("generate", "world", "grids") for x in ("off", "on")},
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "terrain_scenes.json").write_text(json.dumps({"summary": summary, "rows": rows}, indent=1) + "\n")
    print(f"{args.count} scenes of {args.blocks} blocks, terrain density {density}:")
    print(
        "patches per scene: "
        + ", ".join(f"{k} {v}" for k, v in summary["patches_per_scene"].items())
        + f" (total {summary['patches_per_scene_total']}, {summary['patches_per_100m_clear_path']} per 100 m of "
        "clear path)"
    )
    print(f"generate: {summary['generate_ms_off']} ms without terrain, {summary['generate_ms_on']} ms with")
    print(f"world build: {summary['world_ms_off']} ms without terrain, {summary['world_ms_on']} ms with")
    print(f"LiDAR grids: {summary['grids_ms_off']} ms without terrain, {summary['grids_ms_on']} ms with")


if __name__ == "__main__":
    main()
