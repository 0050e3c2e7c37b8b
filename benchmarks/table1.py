"""MetaUrban Table 1 from one command: train every baseline on the train split, evaluate on test and unseen.

Usage: python benchmarks/table1.py --budget {smoke,small,paper} [--tasks PointNav,SocialNav]
       [--algos ppo,ppo_lag,...] [--out benchmarks/results/table1_<budget>] [--fresh]

For each task: collect expert demonstrations (Minari), train PPO, PPO-Lag, PPO-ET (online, env steps), IQL, TD3+BC
(offline, gradient steps), BC (minibatches) and GAIL (env steps), evaluate each on the test and unseen splits,
and print ours beside the paper's Table 1. Writes table1.csv, table1.png (SR beside the paper's) and
learning_curves.png (test-split SR/SPL during online training). A rerun reuses finished runs (crash-safe);
--fresh retrains everything. Budgets: smoke (a minute, checks the plumbing), small (about an hour on 2 cores),
paper (the paper's 5M online steps; days on 2 cores).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from curbside.train.paper import PAPER_TABLE1  # noqa: E402  (after the sys.path line above)

BUDGETS: dict[str, dict[str, Any]] = {
    "smoke": {
        "online": {"PointNav": 2_048, "SocialNav": 2_048},
        "gail": 2_048,
        "offline": 200,
        "bc": 200,
        "demos": 1_000,
        "envs": 2,
        "scenes": 4,
        "episodes": 3,
        "eval_every": 0,
        "hparams": {"n_steps": 128, "batch_size": 128, "n_epochs": 2},
    },
    "small": {
        "online": {"PointNav": 200_000, "SocialNav": 100_000},
        "gail": 100_000,
        "offline": 10_000,
        "bc": 10_000,
        "demos": 30_000,
        "envs": 8,
        "scenes": 64,
        "episodes": 50,
        "eval_every": 50_000,
        "hparams": {},
    },
    "paper": {
        "online": {"PointNav": 5_000_000, "SocialNav": 5_000_000},
        "gail": 2_000_000,
        "offline": 1_000_000,
        "bc": 200_000,
        "demos": 30_000,
        "envs": 8,
        "scenes": 1_000,
        "episodes": 200,
        "eval_every": 250_000,
        "hparams": {},
    },
}
ALGOS = ["ppo", "ppo_lag", "ppo_et", "iql", "td3bc", "bc", "gail"]
NAMES = {
    "ppo": "PPO",
    "ppo_lag": "PPO-Lag",
    "ppo_et": "PPO-ET",
    "iql": "IQL",
    "td3bc": "TD3+BC",
    "bc": "BC",
    "gail": "GAIL",
}


def _steps(budget: dict[str, Any], algo: str, task: str) -> int:
    if algo in ("ppo", "ppo_lag", "ppo_et"):
        return int(budget["online"][task])
    return int(budget["gail" if algo == "gail" else "bc" if algo == "bc" else "offline"])


def run(budget_name: str, tasks: list[str], algos: list[str], out: Path, fresh: bool) -> list[dict[str, Any]]:
    """Train and evaluate every (task, algo); return the table rows (also written as CSV)."""
    from curbside.train.demos import collect_demos, dataset_id
    from curbside.train.evaluate import evaluate_policy
    from curbside.train.policies import POLICY_FILES, load_policy
    from curbside.train.run import train

    budget = BUDGETS[budget_name]
    rows: list[dict[str, Any]] = []
    out.mkdir(parents=True, exist_ok=True)
    for task in tasks:
        demos = out / "demos" / dataset_id(task)
        if fresh or not (demos / "curbside.json").is_file():
            t0 = time.time()
            summary = collect_demos(task, out / "demos", steps=budget["demos"], num_scenes=budget["scenes"])
            print(
                f"[{task}] demos: {summary['steps']} steps, {summary['episodes']} episodes, success rate "
                f"{summary['success_rate']:.2f} ({time.time() - t0:.0f} s)",
                flush=True,
            )
        for algo in algos:
            run_dir = out / task / algo
            steps = _steps(budget, algo, task)
            done = (run_dir / POLICY_FILES[algo]).is_file() and (run_dir / "timing.json").is_file()
            if fresh or not done:
                t0 = time.time()
                if fresh and run_dir.exists():
                    shutil.rmtree(run_dir)  # --fresh: this run starts over
                online = algo in ("ppo", "ppo_lag", "ppo_et", "gail")  # the budget's hparams are PPO's
                train(
                    algo,
                    task,
                    run_dir,
                    steps=steps,
                    n_envs=budget["envs"],
                    num_scenes=budget["scenes"],
                    demos=demos,
                    eval_every=budget["eval_every"] if algo in ("ppo", "ppo_lag", "ppo_et") else 0,
                    hparams=budget["hparams"] if online else {},
                    resume=(run_dir / "run.json").is_file(),
                )
                (run_dir / "timing.json").write_text(json.dumps({"train_seconds": time.time() - t0, "steps": steps}))
            timing = json.loads((run_dir / "timing.json").read_text())
            act, _ = load_policy(run_dir)
            for split in ("test", "unseen"):
                r = evaluate_policy(act, task, {}, split=split, episodes=budget["episodes"], progress=True)
                paper = PAPER_TABLE1.get((task, split, algo), {})
                row = {
                    "task": task,
                    "split": split,
                    "algo": NAMES[algo],
                    "steps": steps,
                    "train_s": round(timing["train_seconds"]),
                    "sr": r["sr"],
                    "spl": r["spl"],
                    "sns": r.get("sns", float("nan")),
                    "cost": r["cost"],
                    "route_completion": r["route_completion"],
                    "episodes": budget["episodes"],
                    **{f"paper_{k}": v for k, v in paper.items()},
                }
                rows.append(row)
                print(
                    f"[{task} {split}] {NAMES[algo]:8s} SR {r['sr']:.2f} SPL {r['spl']:.2f} "
                    f"{'SNS {:.2f} '.format(r['sns']) if 'sns' in r else ''}Cost {r['cost']:.2f}   (paper: "
                    f"{', '.join(f'{k} {v}' for k, v in paper.items()) or 'n/a'})",
                    flush=True,
                )
            _write(rows, out)
    return rows


def _write(rows: list[dict[str, Any]], out: Path) -> None:
    keys = sorted(
        {k for r in rows for k in r},
        key=lambda k: (k.startswith("paper_"), list(rows[0]).index(k) if k in rows[0] else 99),
    )
    with open(out / "table1.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def plot(rows: list[dict[str, Any]], out: Path) -> None:
    """table1.png: SR per baseline, ours beside the paper's; learning_curves.png: online runs' test SR and SPL."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    import numpy as np

    panels = sorted({(r["task"], r["split"]) for r in rows})
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6), squeeze=False)
    for ax, (task, split) in zip(axes[0], panels):
        sel = [r for r in rows if r["task"] == task and r["split"] == split]
        x = np.arange(len(sel))
        ax.bar(x - 0.2, [r["sr"] for r in sel], 0.4, label="curbside", color="#1565c0")
        ax.bar(x + 0.2, [r.get("paper_sr", np.nan) for r in sel], 0.4, label="MetaUrban paper", color="#9e9e9e")
        ax.set_xticks(x, [r["algo"] for r in sel], rotation=45, fontsize=8)
        ax.set_ylim(0, 1)
        ax.set_title(f"{task} {split}: success rate", fontsize=10)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "table1.png", dpi=120)
    plt.close(fig)
    curves = sorted(out.glob("*/*/eval_curve.csv"))
    if curves:
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
        for f in curves:
            with open(f, newline="") as fh:
                data = list(csv.DictReader(fh))
            steps = [int(d["steps"]) for d in data]
            label = f"{f.parent.parent.name} {NAMES[f.parent.name]}"
            axes[0].plot(steps, [float(d["sr"]) for d in data], marker="o", label=label)
            axes[1].plot(steps, [float(d.get("spl") or d.get("sns") or 0) for d in data], marker="o", label=label)
        for ax, name in zip(axes, ("test-split SR", "test-split SPL")):
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda x, _: f"{x / 1000:.0f}k"))
            ax.set_xlabel("env steps")
            ax.set_ylabel(name)
            ax.set_ylim(0, 1)
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "learning_curves.png", dpi=120)
        plt.close(fig)


def main() -> None:
    """Parse the arguments, run the benchmark, write CSV and PNGs."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", choices=list(BUDGETS), default="small")
    ap.add_argument("--tasks", default="PointNav,SocialNav")
    ap.add_argument("--algos", default=",".join(ALGOS))
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--fresh", action="store_true", help="Retrain everything instead of reusing finished runs.")
    a = ap.parse_args()
    tasks = [t for t in a.tasks.split(",") if t]
    algos = [x for x in a.algos.split(",") if x]
    bad = [x for x in algos if x not in ALGOS] + [t for t in tasks if t not in ("PointNav", "SocialNav")]
    if bad:
        sys.exit(f"error: unknown {', '.join(bad)}; algorithms: {', '.join(ALGOS)}; tasks: PointNav, SocialNav")
    out = a.out or ROOT / "benchmarks" / "results" / f"table1_{a.budget}"
    t0 = time.time()
    rows = run(a.budget, tasks, algos, out, a.fresh)
    plot(rows, out)
    print(f"wrote {out}/table1.csv, table1.png, learning_curves.png in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
