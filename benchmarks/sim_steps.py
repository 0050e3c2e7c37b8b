"""Simulator benchmark: env steps/s vs the raw PyBullet floor, reset time, RSS growth over resets and new scenes.

Usage: python benchmarks/sim_steps.py [--quick] [--task PointNav|SocialNav]   (same as `curbside sim bench`)
Targets on the 2-core dev machine: PointNav >= 1,000 steps per CPU-second and >= 0.8 of the floor;
SocialNav (20 agents + traffic) >= 800; RSS growth < 20 MB over 1,000 resets and over 1,000 new scenes.
"""

from __future__ import annotations

import json
import sys

from sim.bench import run_bench

if __name__ == "__main__":
    task = sys.argv[sys.argv.index("--task") + 1] if "--task" in sys.argv else "PointNav"
    result = run_bench(quick="--quick" in sys.argv, task=task)
    for key, value in result.items():
        print(f"{key:>24}: {value}")
    print(json.dumps(result, sort_keys=True))
