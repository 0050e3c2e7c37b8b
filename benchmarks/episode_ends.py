"""How a PointNav policy's episodes end, the same test episodes on the PyBullet env and on the batched env: success,
stuck (and whether the machine never moved), out of route, toppled; the top speed each episode reached.

Usage: python benchmarks/episode_ends.py [--policy policies/paper_realistic/PointNav/ppo] [--episodes 30] [--split test] [--stochastic]
       [--protocol-endings] [--out benchmarks/results/episode_ends/<task>-<method>.json]

`--stochastic` draws each action from the policy's distribution (torch seeded with 0 before each env's episodes) instead
of taking its mean. `--protocol-endings` runs the episodes under the protocol's evaluation rules (`eval_env`: the
`paper_realistic` protocol ends an episode on success, out of route, toppling or the horizon, never on being stuck or in
contact) instead of the training env's. The policy folder's card.json (or run.json) gives the env config it was trained
under. Episode k uses seed k on both envs (the batched env's sub-env reset with seed k draws the PyBullet env's scene
and route). Writes one JSON with a row per episode and the counts of each end, per env.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

NEVER_MOVED = 0.05  # m/s: an episode whose top speed stays below this never left its start


def end_name(flags: dict[str, Any]) -> str:
    """One name for how a batched episode ended, in the order the PyBullet env's `end_reason` names them (the
    batched env's final_info has the flags, not the name)."""
    for name in ("success", "toppled", "out_of_route", "stuck", "cost_exceeded"):
        if flags.get(name):
            return name
    return "horizon"


def pybullet_ends(
    act: Any, env_config: dict[str, Any], split: str, episodes: int, num_scenes: int
) -> list[dict[str, Any]]:
    """Each episode's end, step count and top speed on the PyBullet env."""
    import gymnasium as gym

    import sim  # noqa: F401
    from curbside.train.envs import split_config

    cfg = split_config(env_config, split, num_scenes)
    cfg["scene_cache"] = 1
    env = gym.make("curbside/PointNav-v0", config=cfg)
    rows = []
    try:
        for seed in range(episodes):
            obs, _ = env.reset(seed=seed)
            top = 0.0
            while True:
                obs, _, term, trunc, info = env.step(np.asarray(act(obs), dtype=np.float32).reshape(2))
                top = max(top, abs(float(env.unwrapped.machine.speed)))
                if term or trunc:
                    break
            ep = env.unwrapped.episode
            rows.append(
                {"seed": seed, "end": info["end_reason"] or "horizon", "steps": ep.steps, "top_speed": round(top, 2)}
            )
            print(f"pybullet seed {seed}: {rows[-1]['end']} after {ep.steps} steps", flush=True)
    finally:
        env.close()
    return rows


def batched_ends(
    act: Any, env_config: dict[str, Any], split: str, episodes: int, num_scenes: int
) -> list[dict[str, Any]]:
    """Each episode's end, step count and top speed on the batched env (one sub-env an episode)."""
    from curbside.train.envs import split_config
    from sim.batched import BatchedPointNav

    cfg = split_config(env_config, split, num_scenes)
    cfg.update(scene_cache=episodes, route_pool=0, scene_steps=0)
    env = BatchedPointNav(episodes, config=cfg)
    rows: dict[int, dict[str, Any]] = {}
    top = np.zeros(episodes)
    try:
        obs, _ = env.reset(seed=list(range(episodes)))
        while len(rows) < episodes:
            actions = np.stack([np.asarray(act(o), dtype=np.float32).reshape(2) for o in obs])
            obs, _, term, trunc, info = env.step(actions)
            top = np.maximum(top, np.abs(env.drive.speed))
            for i in np.nonzero(term | trunc)[0].tolist():
                if i in rows:
                    continue
                env.autoreset[i] = False
                fi = info["final_info"]
                flags = {k: bool(fi[k][i]) for k in ("success", "out_of_route", "stuck", "cost_exceeded")}
                rows[i] = {
                    "seed": i,
                    "end": end_name(flags),
                    "steps": int(fi["steps"][i]),
                    "top_speed": round(float(top[i]), 2),
                }
    finally:
        env.close()
    return [rows[i] for i in range(episodes)]


def counts(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Episodes per end, with the stuck ones that never moved counted apart."""
    out = Counter(r["end"] for r in rows)
    out["stuck_never_moved"] = sum(1 for r in rows if r["end"] == "stuck" and r["top_speed"] < NEVER_MOVED)
    return dict(sorted(out.items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--policy", type=Path, default=ROOT / "policies" / "PointNav" / "ppo")
    ap.add_argument("--episodes", type=int, default=30)
    ap.add_argument("--split", default="test")
    ap.add_argument("--stochastic", action="store_true", help="sample actions instead of the policy's mean")
    ap.add_argument(
        "--protocol-endings",
        action="store_true",
        help="end episodes as the protocol's evaluation does (its eval_env), not as the training env does",
    )
    ap.add_argument(
        "--out", type=Path, default=None, help="default: benchmarks/results/episode_ends/<task>-<method>.json"
    )
    args = ap.parse_args()
    if args.out is None:
        args.out = (
            ROOT
            / "benchmarks"
            / "results"
            / "episode_ends"
            / (
                f"{args.policy.parent.name}-{args.policy.name}{'-stochastic' if args.stochastic else ''}"
                f"{'-protocol-endings' if args.protocol_endings else ''}.json"
            )
        )

    import torch

    from curbside.train.policies import load_policy
    from curbside.train.protocols import protocol

    torch.set_num_threads(1)
    act, run = load_policy(args.policy, deterministic=not args.stochastic)
    card_path = args.policy / "card.json"
    env_config = json.loads(card_path.read_text())["env_config"] if card_path.is_file() else run["env_config"]
    card = json.loads(card_path.read_text()) if card_path.is_file() else {}
    proto = protocol(card.get("protocol", run.get("protocol", "curbside")))
    num_scenes = proto.eval_scenes
    if args.protocol_endings:
        from curbside.experiments.runner import eval_config

        env_config = eval_config(env_config, None, proto)
    torch.manual_seed(0)
    pybullet = pybullet_ends(act, env_config, args.split, args.episodes, num_scenes)
    torch.manual_seed(0)
    batched = batched_ends(act, env_config, args.split, args.episodes, num_scenes)
    result = {
        "command": "python " + shlex.join(["benchmarks/episode_ends.py", *sys.argv[1:]]),
        "policy": str(args.policy.resolve().relative_to(ROOT))
        if args.policy.resolve().is_relative_to(ROOT)
        else str(args.policy),
        "split": args.split,
        "actions": "sampled" if args.stochastic else "mean",
        "endings": "protocol" if args.protocol_endings else "training",
        "episodes": args.episodes,
        "counts": {"pybullet": counts(pybullet), "batched": counts(batched)},
        "episodes_by_seed": [
            {
                "seed": p["seed"],
                "pybullet": {k: p[k] for k in ("end", "steps", "top_speed")},
                "batched": {k: b[k] for k in ("end", "steps", "top_speed")},
            }
            for p, b in zip(pybullet, batched)
        ],
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result, indent=1) + "\n")
    tmp.replace(args.out)
    print(json.dumps(result["counts"]))


if __name__ == "__main__":
    main()
