"""The unique challenges of urban micromobility (MetaUrban's appendix) as one script: a long horizon (10 m vs
410 m routes, PointNav) and crowds (pedestrian settings 1-4, SocialNav), for the expert or a trained policy.

Usage: python benchmarks/unique_challenges.py --budget {smoke,small,paper} [--policy RUN_DIR] [--out DIR]

`--policy` is a `curbside train run` output folder (its policy is loaded with curbside.train.policies.load_policy);
without it the pure-pursuit expert drives. Pedestrian settings are curbside's choice of increasing density (the
paper's appendix does not list its values): 1 = 0.5, 2 = 2 (the default), 3 = 5, 4 = 10 agents per 100 m of
sidewalk (MetaUrban's rho_d). Prints SR / SPL / Cost (and PSC for SocialNav) per setting and writes
unique_challenges.csv to --out.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

EPISODES = {"smoke": 3, "small": 50, "paper": 200}
HORIZONS = {"10 m": {"route_length": [9.0, 11.0]}, "410 m": {"preset": "metaurban12k", "route_length": [380.0, 440.0]}}
PEDESTRIANS = {1: 0.5, 2: 2.0, 3: 5.0, 4: 10.0}  # agents per 100 m of sidewalk


def _expert_summary(task: str, cfg: dict[str, Any], episodes: int) -> dict[str, Any]:
    """Mean metrics of the expert over `episodes` test-split episodes."""
    import gymnasium as gym

    from curbside.train.envs import env_id, split_config
    from sim.eval import summarize
    from sim.rollout import make_policy, rollout

    env = gym.make(env_id(task), config=split_config(cfg, "test", episodes))
    try:
        policy = make_policy("expert", env.unwrapped)
        return summarize([rollout(env, policy, s) for s in range(episodes)])
    finally:
        env.close()


def evaluate(task: str, cfg: dict[str, Any], episodes: int, policy_dir: Path | None) -> dict[str, Any]:
    """SR, SPL, cost (and PSC) of the expert or a trained policy under `cfg`."""
    if policy_dir is None:
        return _expert_summary(task, cfg, episodes)
    from curbside.train.evaluate import evaluate_policy
    from curbside.train.policies import load_policy

    act, _ = load_policy(policy_dir)
    return evaluate_policy(act, task, cfg, split="test", episodes=episodes, num_scenes=episodes, progress=False)


def main(budget: str, policy_dir: Path | None, out: Path | None) -> list[dict[str, Any]]:
    """Run both studies; print and return the rows."""
    n = EPISODES[budget]
    rows = []
    for name, cfg in HORIZONS.items():
        s = evaluate("PointNav", cfg, n, policy_dir)
        rows.append({"study": "long horizon", "setting": name, "task": "PointNav", **_pick(s)})
    for k, density in PEDESTRIANS.items():
        s = evaluate("SocialNav", {"agents": {"dynamic_density": density}}, n, policy_dir)
        rows.append(
            {"study": "pedestrians", "setting": f"{k} ({density:g} per 100 m)", "task": "SocialNav", **_pick(s)}
        )
    who = "expert" if policy_dir is None else str(policy_dir)
    print(f"{'study':14} {'setting':18} {'SR':>5} {'SPL':>5} {'Cost':>6} {'PSC':>5}   ({who}, {n} episodes each)")
    for r in rows:
        psc = "" if r["psc"] is None else f"{r['psc']:5.2f}"
        print(f"{r['study']:14} {r['setting']:18} {r['sr']:5.2f} {r['spl']:5.2f} {r['cost']:6.1f} {psc:>5}")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "unique_challenges.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    return rows


def _pick(summary: dict[str, Any]) -> dict[str, Any]:
    return {
        "sr": summary["sr"],
        "spl": summary["spl"],
        "cost": summary.get("cost", float("nan")),
        "psc": summary.get("psc"),
        "episodes": summary["episodes"],
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--budget", choices=tuple(EPISODES), default="smoke")
    ap.add_argument("--policy", type=Path, default=None, help="a `curbside train run` folder (default: the expert)")
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    main(a.budget, a.policy, a.out)
