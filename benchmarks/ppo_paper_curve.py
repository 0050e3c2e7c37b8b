"""PPO's learning curve under the `paper_realistic` protocol on the batched backend, test SR measured on the PyBullet
env, and the transfer gap of the final policy (the same episodes on the PyBullet env and on the batched env).

Usage: python benchmarks/ppo_paper_curve.py [--steps 5000000] [--eval-every 500000] [--curve-episodes 20]
       [--final-episodes 200] [--run outputs/train/ppo_paper_batched] [--out benchmarks/results/ppo_paper_curve]

Training is `curbside train run --protocol paper_realistic --backend batched --resume`: a stopped run goes on from its
last checkpoint (every 25,000 env steps), and a finished one is only evaluated. The last checkpoint of a stopped run is
kept in git under OUT/checkpoint/ (with its curve): a run folder without checkpoints starts from it. Writes curve.csv
(env steps, test SR, SPL, cost, route completion on `--curve-episodes` PyBullet episodes), transfer.json (the final
policy on `--final-episodes` test episodes: PyBullet, batched, their SR difference) and curve.png.
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=5_000_000)
    ap.add_argument("--eval-every", type=int, default=500_000)
    ap.add_argument("--curve-episodes", type=int, default=20)
    ap.add_argument("--final-episodes", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2, help="processes sharing the final PyBullet episodes")
    ap.add_argument("--run", type=Path, default=ROOT / "outputs" / "train" / "ppo_paper_batched")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "ppo_paper_curve")
    args = ap.parse_args()

    from stable_baselines3 import PPO

    from curbside.train.evaluate import evaluate_policy_batched, evaluate_run
    from curbside.train.policies import read_run
    from curbside.train.protocols import protocol
    from curbside.train.run import train

    proto = protocol("paper_realistic")
    seed_run(args.run, args.out / "checkpoint")
    policy = args.run / "policy.zip"
    done = policy.is_file() and PPO.load(policy, device="cpu").num_timesteps >= args.steps
    t0 = time.perf_counter()
    if not done:
        train(
            "ppo",
            "PointNav",
            args.run,
            steps=args.steps,
            protocol="paper_realistic",
            backend="batched",
            resume=(args.run / "run.json").is_file(),
            eval_every=args.eval_every,
            eval_episodes=args.curve_episodes,
        )
    train_s = time.perf_counter() - t0
    model = PPO.load(policy, device="cpu")
    cfg = read_run(args.run)["env_config"]

    def act(obs: np.ndarray) -> np.ndarray:
        return model.predict(obs, deterministic=True)[0]

    pybullet = evaluate_run(
        policy.parent,
        "PointNav",
        cfg,
        split="test",
        episodes=args.final_episodes,
        num_scenes=proto.eval_scenes,
        workers=max(args.workers, 1),
        progress=False,
    )
    batched = evaluate_policy_batched(
        act, cfg, split="test", episodes=args.final_episodes, num_scenes=proto.eval_scenes
    )
    args.out.mkdir(parents=True, exist_ok=True)
    if (args.run / "eval_curve.csv").is_file():
        shutil.copy(args.run / "eval_curve.csv", args.out / "curve.csv")
    transfer = {
        "command": "python benchmarks/" + " ".join(shlex.quote(a) for a in [Path(__file__).name, *sys.argv[1:]]),
        "steps": int(model.num_timesteps),
        "episodes": args.final_episodes,
        "split": "test",
        "pybullet": {k: pybullet[k] for k in ("sr", "spl", "cost", "route_completion")},
        "batched": {k: batched[k] for k in ("sr", "spl", "cost", "route_completion")},
        "transfer_gap_sr": pybullet["sr"] - batched["sr"],
        "target_gap": 0.05,
        "train_seconds_this_call": round(train_s),
    }
    (args.out / "transfer.json").write_text(json.dumps(transfer, indent=2) + "\n")
    print(json.dumps(transfer, indent=2))
    plot(args.out)


def seed_run(run: Path, kept: Path) -> None:
    """Start a run folder without checkpoints from the checkpoint, curve and run.json kept in git (`kept`): a run stopped in
    one session goes on from there on another machine (the folder's own checkpoints stay out of git)."""
    if not kept.is_dir() or any((run / "checkpoints").glob("policy_*_steps.zip")):
        return
    zips = sorted(kept.glob("policy_*_steps.zip"))
    if not zips:
        return
    (run / "checkpoints").mkdir(parents=True, exist_ok=True)
    shutil.copy(zips[-1], run / "checkpoints" / zips[-1].name)
    for name in ("eval_curve.csv", "run.json"):
        if (kept / name).is_file() and not (run / name).is_file():
            shutil.copy(kept / name, run / name)


def plot(out: Path) -> None:
    """curve.png: test SR and route completion (PyBullet) over env steps, the final transfer points beside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows: list[dict[str, str]] = []
    if (out / "curve.csv").is_file():
        with open(out / "curve.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    transfer = json.loads((out / "transfer.json").read_text()) if (out / "transfer.json").is_file() else None
    fig, ax = plt.subplots(figsize=(6.5, 3.6))
    steps = [int(r["steps"]) / 1e6 for r in rows]
    ax.plot(steps, [float(r["sr"]) for r in rows], marker="o", label="test SR (PyBullet)")
    ax.plot(steps, [float(r["route_completion"]) for r in rows], marker=".", ls="--", label="test route completion")
    if transfer is not None:  # the final policy on the same episodes on both envs
        end = transfer["steps"] / 1e6
        ax.scatter(
            [end],
            [transfer["pybullet"]["sr"]],
            marker="*",
            s=120,
            color="C0",
            label=f"final SR, PyBullet ({transfer['episodes']} ep.)",
        )
        ax.scatter([end], [transfer["batched"]["sr"]], marker="x", s=80, color="C3", label="final SR, batched env")
    ax.axhline(0.66, color="gray", ls=":", lw=1, label="paper PPO test SR 0.66")
    ax.set_xlabel("env steps (millions), paper_realistic protocol, batched backend")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "curve.png", dpi=120)


if __name__ == "__main__":
    main()
