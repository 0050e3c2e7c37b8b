"""The transfer gap of a trained policy: the same episodes on the PyBullet env (where every figure of docs/results.md is
measured) and on the batched env (where the online methods train), PointNav or SocialNav.

Usage: python benchmarks/transfer_gap.py RUN_DIR [--split test] [--episodes 50] [--actions mean|sampled]
       [--episode-ends training|protocol] [--envs both|batched] [--out FILE.json]

RUN_DIR is a folder written by `curbside train run` or `curbside experiment run` (policy.zip and run.json). Both envs
run episode k with seed k, so their episodes start alike (the same scene, route, crowd and traffic) and differ only
where the two simulators do (and, with sampled actions, in the draws). The policy acts with its mean action or draws
from its distribution (`--actions sampled`, the paper protocol's rule; the batched env's draws follow torch's seed 0);
the episodes end as the run's training env ends them or, with `--episode-ends protocol`, by the protocol's evaluation
rules (`paper_realistic`: no stuck or contact ending). `--envs batched` measures the batched env alone. Prints and
writes one JSON object: each env's SR, SPL, cost, route completion (and SNS for SocialNav), and the
PyBullet-minus-batched difference of each.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--workers", type=int, default=1, help="processes sharing the PyBullet episodes")
    ap.add_argument("--actions", choices=("mean", "sampled"), default="mean")
    ap.add_argument("--episode-ends", choices=("training", "protocol"), default="training")
    ap.add_argument("--envs", choices=("both", "batched"), default="both")
    ap.add_argument("--out", type=Path, default=None, help="JSON file to write (default: print only)")
    args = ap.parse_args()

    import torch

    from curbside.train.evaluate import evaluate_policy_batched, evaluate_run
    from curbside.train.policies import load_policy
    from curbside.train.protocols import deep_merge, protocol

    act_one, run = load_policy(args.run, deterministic=args.actions == "mean")
    task = run["task"]
    proto = protocol(run.get("protocol", "curbside"))
    cfg = deep_merge(run["env_config"], proto.eval_env if args.episode_ends == "protocol" else None)
    scenes = proto.eval_scenes
    # Sampled actions come from an SB3 policy (load_policy refuses the others), which draws for the whole batch in
    # one call (~10x faster on long episodes). Mean actions go one observation at a time, as the figures measured
    # that way were, since a batched matrix product may round differently.
    batches = args.actions == "sampled"

    def act(obs: np.ndarray) -> np.ndarray:
        if batches:
            return np.asarray(act_one(obs), dtype=np.float32)
        return np.stack([np.asarray(act_one(o), dtype=np.float32) for o in obs])

    t0 = time.perf_counter()
    pybullet = None
    if args.envs == "both":
        pybullet = evaluate_run(
            args.run,
            task,
            cfg,
            split=args.split,
            episodes=args.episodes,
            num_scenes=scenes,
            workers=args.workers,
            progress=False,
            actions=args.actions,
        )
    t1 = time.perf_counter()
    torch.manual_seed(0)
    batched = evaluate_policy_batched(
        act,
        cfg,
        task=task,
        split=args.split,
        episodes=args.episodes,
        num_scenes=scenes,
        n_envs=min(args.episodes, 50),
    )
    t2 = time.perf_counter()
    keys = [k for k in ("sr", "spl", "sns", "cost", "route_completion") if k in batched]
    out = {
        "command": "python benchmarks/" + " ".join(shlex.quote(a) for a in [Path(__file__).name, *sys.argv[1:]]),
        "run": str(args.run),
        "task": task,
        "split": args.split,
        "episodes": args.episodes,
        "actions": args.actions,
        "episode_ends": args.episode_ends,
        "env_config": cfg,
        "pybullet": None if pybullet is None else {k: float(pybullet[k]) for k in keys},
        "batched": {k: batched[k] for k in keys},
        "pybullet_minus_batched": None if pybullet is None else {k: float(pybullet[k]) - batched[k] for k in keys},
        "seconds": {"pybullet": None if pybullet is None else round(t1 - t0, 1), "batched": round(t2 - t1, 1)},
    }
    text = json.dumps(out, indent=2) + "\n"
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    print(text, end="")


if __name__ == "__main__":
    main()
