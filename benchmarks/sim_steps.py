"""Simulator benchmark: PointNav steps/s vs the raw PyBullet floor, reset time, RSS growth over resets.

Usage: python benchmarks/sim_steps.py [--quick]   (same as `curbside sim bench`)
Targets on the 2-core dev machine: >= 600 steps/s, ratio >= 0.7, RSS growth < 50 MB over 1,000 resets.
"""

from __future__ import annotations

import json
import sys

from sim.bench import run_bench

if __name__ == "__main__":
    result = run_bench(quick="--quick" in sys.argv)
    for key, value in result.items():
        print(f"{key:>24}: {value}")
    print(json.dumps(result, sort_keys=True))
