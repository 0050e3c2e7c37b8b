"""Memory per world build: RSS before/after N scene builds, and over opening and closing PointNav envs.

Run: `python benchmarks/world_memory.py [--builds 1000] [--envs 200] [--specs 50] [--pybullet-leak]`.
- builds: `sim.world.World` built N times in one Bullet client (what an env's scene cache does when it moves to
  another scene), cycling over `--specs` generated scene specs (default generator config, seeds 0..specs-1);
- envs: `gym.make("curbside/PointNav-v0")`, one reset, close, N times (each env its own Bullet client).
`--pybullet-leak` builds with the plain pybullet calls instead of `sim.world.mesh_shape` (pybullet's leak of
mesh vertex lists) for comparison. RSS is read after gc.collect(); "trimmed" is after glibc's malloc_trim(0), which
returns freed heap pages, so growth that disappears there is allocator high-water, not a leak.
Target: 1,000 scene builds grow RSS < 20 MB. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pybullet as p

import sim.world
from sim.world import World

_PROC = psutil.Process()


def rss_mb() -> float:
    """Resident set size in MiB, after a garbage collection."""
    gc.collect()
    return _PROC.memory_info().rss / 2**20


def trimmed_rss_mb() -> float:
    """RSS after glibc hands freed heap pages back (malloc_trim); equals rss_mb() where that is unavailable."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except OSError:
        pass
    return rss_mb()


def plain_mesh_shape(
    create: Callable[..., int], vertices: Sequence, indices: Sequence | None = None, **kwargs: Any
) -> int:
    """The pybullet call without giving back its references (pybullet's own leak)."""
    if indices is None:
        return create(p.GEOM_MESH, vertices=vertices, **kwargs)
    return create(p.GEOM_MESH, vertices=vertices, indices=indices, **kwargs)


def bench_builds(n: int, n_specs: int) -> dict:
    """RSS before/after `n` World builds in one client, cycling over `n_specs` generated specs."""
    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="no catalog was given")
        specs = [generate_scene(None, seed) for seed in range(n_specs)]
    client = p.connect(p.DIRECT)
    for spec in specs:  # warm-up: first builds size Bullet's and the allocator's pools
        World(spec, client=client)
    before, t0 = rss_mb(), time.perf_counter()
    objects = sum(len(s["objects"]) for s in specs) / len(specs)
    for i in range(n):
        World(specs[i % n_specs], client=client)
    seconds = time.perf_counter() - t0
    after = rss_mb()
    trimmed = trimmed_rss_mb()
    p.disconnect(client)
    return {
        "what": f"{n} World builds, one client ({n_specs} specs, {objects:.0f} objects each)",
        "before_mb": before,
        "after_mb": after,
        "trimmed_mb": trimmed,
        "n": n,
        "seconds": seconds,
    }


def bench_envs(n: int) -> dict:
    """RSS before/after opening PointNav, resetting once and closing it, `n` times."""
    import gymnasium as gym

    import sim  # noqa: F401 - registers the envs

    def once(seed: int) -> None:
        env = gym.make("curbside/PointNav-v0")
        env.reset(seed=seed)
        env.close()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(5):
            once(seed)
        before, t0 = rss_mb(), time.perf_counter()
        for seed in range(n):
            once(seed)
    seconds = time.perf_counter() - t0
    after = rss_mb()
    return {
        "what": f"{n} PointNav envs opened, reset once, closed",
        "before_mb": before,
        "after_mb": after,
        "trimmed_mb": trimmed_rss_mb(),
        "n": n,
        "seconds": seconds,
    }


def main() -> None:
    """Run the measurements and print one line each (MB = MiB)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--builds", type=int, default=1000)
    ap.add_argument("--envs", type=int, default=200, help="0 skips the env measurement")
    ap.add_argument("--specs", type=int, default=50)
    ap.add_argument("--pybullet-leak", action="store_true", help="build with the plain (leaking) pybullet calls")
    args = ap.parse_args()
    if args.pybullet_leak:
        sim.world.mesh_shape = plain_mesh_shape
    mode = "plain pybullet calls (leaking)" if args.pybullet_leak else "sim.world.mesh_shape"
    print(f"mesh shapes via {mode}; pybullet {p.getAPIVersion()}")
    results = []
    if args.builds:
        results.append(bench_builds(args.builds, args.specs))
    if args.envs:
        results.append(bench_envs(args.envs))
    for r in results:
        grow = r["after_mb"] - r["before_mb"]
        print(
            f"{r['what']}: RSS {r['before_mb']:.1f} -> {r['after_mb']:.1f} MB ({grow:+.1f} MB, "
            f"{grow / r['n'] * 1024:+.1f} KB each); after malloc_trim {r['trimmed_mb']:.1f} MB "
            f"({r['trimmed_mb'] - r['before_mb']:+.1f}); {r['seconds'] / r['n'] * 1000:.0f} ms each"
        )


if __name__ == "__main__":
    main()
