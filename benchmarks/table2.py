"""MetaUrban Table 2 from one command: PPO per machine on PointNav, evaluated on straight (S) and intersection (X)
blocks, beside the paper's success rates.

Usage: python benchmarks/table2.py --budget {smoke,small,paper} [--machines delivery_bot,wheelchair,...]
       [--out benchmarks/results/table2_<budget>] [--fresh]

Each machine trains PPO through `curbside.train.run.train` on the train split (its own config: `machine`), then
is evaluated on test-split scenes of one S block and of one X block. Prints SR / SPL / Cost per machine and block
beside the paper's SR, writes table2.csv and table2.png. A rerun reuses finished runs; --fresh retrains.
Budgets: smoke (minutes, checks the plumbing), small (~1 h a machine on 2 cores), paper (5M steps; days).
"""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.plots import beside_paper, save_panels  # noqa: E402
from benchmarks.table1 import BUDGETS as TABLE1_BUDGETS  # noqa: E402

MACHINES = ("delivery_bot", "delivery_bot_mod1", "delivery_bot_mod2", "wheelchair", "mobility_scooter")
# MetaUrban (ICLR 2025) Table 2, PPO success rate (%) on S / X blocks: COCO base, mod-1, mod-2, wheelchair, scooter.
PAPER_SR = {
    "delivery_bot": (47, 41),
    "delivery_bot_mod1": (62, 56),
    "delivery_bot_mod2": (17, 22),
    "wheelchair": (13, 16),
    "mobility_scooter": (36, 31),
}
BLOCKS = ("S", "X")


def budget(name: str) -> dict[str, Any]:
    """Table 1's budget of that name, PointNav's online steps per machine."""
    b = TABLE1_BUDGETS[name]
    return {
        "steps": b["online"]["PointNav"],
        "envs": b["envs"],
        "scenes": b["scenes"],
        "episodes": b["episodes"],
        "hparams": b["hparams"],
    }


def run(budget_name: str, machines: list[str], out: Path, fresh: bool) -> list[dict[str, Any]]:
    """Train and evaluate every machine; return the table rows."""
    from curbside.train.evaluate import evaluate_policy
    from curbside.train.policies import POLICY_FILES, load_policy
    from curbside.train.run import train

    b = budget(budget_name)
    rows = []
    for machine in machines:
        run_dir = out / machine
        cfg = {"machine": machine}
        if fresh or not (run_dir / POLICY_FILES["ppo"]).is_file():
            t0 = time.time()
            if fresh and run_dir.exists():
                shutil.rmtree(run_dir)  # --fresh: this run starts over
            train(
                "ppo",
                "PointNav",
                run_dir,
                steps=b["steps"],
                env_config=cfg,
                n_envs=b["envs"],
                num_scenes=b["scenes"],
                hparams=b["hparams"],
                resume=(run_dir / "run.json").is_file(),
            )
            print(f"[{machine}] trained {b['steps']} steps in {time.time() - t0:.0f} s", flush=True)
        act, _ = load_policy(run_dir)
        for k, block in enumerate(BLOCKS):
            summary = evaluate_policy(
                act,
                "PointNav",
                {**cfg, "scene": {"blocks": block}},
                split="test",
                episodes=b["episodes"],
                num_scenes=b["episodes"],
            )
            rows.append(
                {
                    "machine": machine,
                    "block": block,
                    "sr": summary["sr"],
                    "spl": summary["spl"],
                    "cost": summary.get("cost", float("nan")),
                    "episodes": summary["episodes"],
                    "paper_sr": PAPER_SR[machine][k] / 100.0,
                    "steps": b["steps"],
                }
            )
            print(
                f"{machine:18} {block}  SR {summary['sr']:.2f} (paper {PAPER_SR[machine][k] / 100:.2f})  "
                f"SPL {summary['spl']:.2f}  Cost {rows[-1]['cost']:.2f}",
                flush=True,
            )
    return rows


def write(rows: list[dict[str, Any]], out: Path) -> None:
    """table2.csv and table2.png (SR beside the paper's, per machine and block)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(out / "table2.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    fig, axes = plt.subplots(1, len(BLOCKS), figsize=(11, 3.6), sharey=True)
    machines = list(dict.fromkeys(r["machine"] for r in rows))
    for ax, block in zip(axes, BLOCKS):
        ours = [next(r["sr"] for r in rows if r["machine"] == m and r["block"] == block) for m in machines]
        paper = [PAPER_SR[m][BLOCKS.index(block)] / 100 for m in machines]
        beside_paper(
            ax,
            [m.replace("delivery_bot", "bot").replace("mobility_", "") for m in machines],
            ours,
            paper,
            ours_label="curbside PPO",
            paper_label="MetaUrban Table 2",
            title=f"{block} block",
        )
    save_panels(fig, axes, "success rate", out / "table2.png")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--budget", choices=tuple(TABLE1_BUDGETS), default="smoke")
    ap.add_argument("--machines", default=",".join(MACHINES), help="comma-separated machine names")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--fresh", action="store_true", help="retrain finished runs")
    a = ap.parse_args()
    chosen = [m.strip() for m in a.machines.split(",") if m.strip()]
    bad = [m for m in chosen if m not in MACHINES]
    if bad:
        ap.error(f"unknown machines {bad}; valid: {', '.join(MACHINES)}")
    out = a.out or ROOT / "benchmarks" / "results" / f"table2_{a.budget}"
    out.mkdir(parents=True, exist_ok=True)
    rows = run(a.budget, chosen, out, a.fresh)
    write(rows, out)
    print(f"wrote {out / 'table2.csv'} and {out / 'table2.png'}")
