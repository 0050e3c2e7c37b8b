"""Benchmark the scene generator: scenes/s and ms per 3-block scene, and the projected time for 12,800 scenes.

Usage: python benchmarks/scenes.py [--count 60] [--blocks 3] [--preset metaurban12k] [--catalog PATH] [--profile]
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings


def main() -> None:
    """Time `generate_scene` over consecutive seeds and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--blocks", default="3")
    ap.add_argument("--catalog", default=None)
    ap.add_argument("--preset", default=None, help="scene preset, e.g. metaurban12k (the paper's density)")
    ap.add_argument("--profile", action="store_true", help="print the top functions by cumulative time")
    args = ap.parse_args()
    from sim.scene import dumps, generate_scene
    from sim.scene.dataset import split_config

    blocks = int(args.blocks) if args.blocks.isdigit() else args.blocks
    cfg, _ = split_config("train", {"blocks": blocks, **({"preset": args.preset} if args.preset else {})})
    reader = None
    if args.catalog:
        from catalogs.reader import CatalogReader

        reader = CatalogReader(args.catalog)
    warnings.simplefilter("ignore")
    generate_scene(cfg, 10_000, reader)  # warm imports and caches
    if args.profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.enable()
    times, objects, ser = [], 0, []
    for seed in range(args.count):
        t = time.perf_counter()
        spec = generate_scene(cfg, seed, reader)
        t1 = time.perf_counter()
        dumps(spec)
        ser.append(time.perf_counter() - t1)
        times.append(t1 - t)
        objects += spec["stats"]["objects"]
    if args.profile:
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
    total = sum(times) + sum(ser)
    ms = [1000 * t for t in times]
    per = total / args.count
    print(f"blocks={args.blocks} scenes={args.count} objects/scene={objects / args.count:.0f}")
    print(
        f"generate: mean {statistics.mean(ms):.1f} ms, median {statistics.median(ms):.1f} ms, "
        f"p95 {sorted(ms)[int(0.95 * (len(ms) - 1))]:.1f} ms per scene"
    )
    print(f"serialise (dumps): mean {1000 * statistics.mean(ser):.1f} ms per scene")
    print(f"throughput: {1 / per:.1f} scenes/s on one core")
    print(
        f"projected 12,800 scenes: {12800 * per / 60:.1f} min on one core, {12800 * per / 120:.1f} min on two workers"
    )


if __name__ == "__main__":
    main()
