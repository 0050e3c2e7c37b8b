"""Peak RSS of the batched training env drawing from N paper-scale training scenes (the `paper_realistic`
protocol's env).

Usage: python benchmarks/scene_memory.py [--scenes 1000] [--envs 64] [--out benchmarks/results/scene_memory]

The env is the one `curbside train run --protocol paper_realistic --backend batched` trains on (64 envs, the
metaurban12k preset, 0.1 m grids) with `num_scenes` N, `scene_steps` 1 (every reset draws a scene) and the default LRU
of built scenes (`scene_cache`, 2 x envs): one env at a time is reset into the next scene of the N, in order, until
every one has been built once (random draws would need ~N ln N resets to visit them all), and the process's RSS is
sampled after every reset. Scenes are generated lazily from their seeds (a scene spec costs nothing until drawn); a
built scene (distance grids, planner) lives while an env uses it or while it is among the most recently used. Writes
summary.json (peak RSS, RSS after each 100 scenes, build time) and a PNG.
"""

from __future__ import annotations

import argparse
import json
import resource
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def rss_mb() -> float:
    """The resident set of this process now (MB), from /proc (falls back to the peak elsewhere)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class InOrder:
    """A scene source that hands out its scenes in order, the next unbuilt one at every draw."""

    def __init__(self, source: Any) -> None:
        self.source, self.next = source, 0

    def draw(self, rng: np.random.Generator) -> tuple[Any, Callable[[], Any]]:
        k, self.next = self.next % self.source.count, self.next + 1
        return self.source.draw(Fixed(k))


class Fixed:
    """An rng stand-in whose only draw is a given index (SceneSource.draw asks for one integer)."""

    def __init__(self, k: int) -> None:
        self.k = k

    def integers(self, n: int) -> int:
        return self.k


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=1000)
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "scene_memory")
    args = ap.parse_args()

    from curbside.train.envs import split_config
    from curbside.train.protocols import protocol
    from sim.batched import BatchedPointNav

    proto = protocol("paper_realistic")
    cfg = split_config({**proto.env_config, "route_pool": 1}, "train", args.scenes)
    cfg["scene_cache"] = 2 * args.envs
    t0 = time.perf_counter()
    env = BatchedPointNav(args.envs, config=cfg)
    env.sources = InOrder(env.sources)  # type: ignore[assignment]
    env.reset(seed=0)
    built: set = {b.key for b in env.store.built.values()}
    samples = [(len(built), rss_mb(), time.perf_counter() - t0)]
    rng = np.random.default_rng(0)
    peak = samples[-1][1]
    args.out.mkdir(parents=True, exist_ok=True)

    def write(done: bool) -> dict:
        """summary.json after every sample: a stopped run leaves what it measured."""
        summary = {
            "command": "python benchmarks/" + " ".join(shlex.quote(a) for a in [Path(__file__).name, *sys.argv[1:]]),
            "env_config": {k: v for k, v in cfg.items() if k not in ("split", "scene_seed", "num_scenes")},
            "scenes_target": args.scenes,
            "envs": args.envs,
            "scene_cache": cfg["scene_cache"],
            "finished": done,
            "scenes_built": len(built),
            "peak_rss_mb": round(peak),
            "target_mb": 8192,
            "seconds": round(time.perf_counter() - t0),
            "build_s_per_scene": round((time.perf_counter() - t0) / max(len(built), 1), 2),
            "samples": [{"scenes_built": n, "rss_mb": round(r), "seconds": round(s)} for n, r, s in samples],
        }
        (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        return summary

    while len(built) < args.scenes:
        # One env at a time moves to the next scene: its old one is released to the LRU.
        k = int(rng.integers(args.envs))
        env._reset_envs(np.array([k]), None)
        built.add(env.built[k].key)
        rss = rss_mb()
        peak = max(peak, rss)
        if len(built) % 25 == 0 and samples[-1][0] != len(built):
            samples.append((len(built), rss, time.perf_counter() - t0))
            write(False)
            print(
                f"{len(built)} scenes built, RSS {rss:,.0f} MB (peak {peak:,.0f}), {samples[-1][2]:.0f} s", flush=True
            )
    env.close()
    summary = write(True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.plot([s[0] for s in samples], [s[1] / 1024 for s in samples], marker=".")
    ax.axhline(8, color="k", ls="--", lw=1, label="target 8 GB")
    ax.set_xlabel("paper-scale training scenes built")
    ax.set_ylabel("RSS (GB)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "summary.png", dpi=120)
    print(f"peak RSS {peak:,.0f} MB over {len(built)} scenes ({summary['seconds']} s)")


if __name__ == "__main__":
    main()
