"""Runs of one configuration over several seeds, aggregated as mean +/- std (the paper's seed robustness)."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

METRICS = ("sr", "spl", "cost", "route_completion", "sns", "path_length")


def final_evaluation(run_dir: Path) -> dict[str, float] | None:
    """The last row of a run's learning curve (eval_curve.csv), or None when it has none."""
    curve = Path(run_dir) / "eval_curve.csv"
    if not curve.is_file():
        return None
    with open(curve, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: float(v) for k, v in rows[-1].items() if v != ""} if rows else None


def aggregate_seeds(out: Path, seeds: list[int]) -> dict[str, Any]:
    """Mean and std over `seeds` (runs in out/seed_<s>) of each final-evaluation metric; written to out/seeds.json."""
    finals = {s: final_evaluation(Path(out) / f"seed_{s}") for s in seeds}
    have = {s: f for s, f in finals.items() if f is not None}
    summary: dict[str, Any] = {"seeds": seeds, "evaluated": sorted(have), "runs": {str(s): f for s, f in have.items()}}
    for k in METRICS:
        values = [f[k] for f in have.values() if k in f]
        if values:
            summary[k] = {"mean": float(np.mean(values)), "std": float(np.std(values)), "n": len(values)}
    if not have:
        summary["note"] = "no run has a learning curve: train with --eval-every N to evaluate each seed"
    Path(out).mkdir(parents=True, exist_ok=True)
    (Path(out) / "seeds.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
    return summary
