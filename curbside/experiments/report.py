"""An experiment's report under benchmarks/results/<experiment>/: results.csv (one row per run, seed and evaluated
split, beside the paper's numbers), summary.csv (mean and std over the seeds of each run and split) and a PNG of
success rates beside the paper's."""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from curbside.experiments.runner import DEFAULT_ROOT
from curbside.experiments.spec import Experiment, budget_of, load_experiment

COLUMNS = (
    "experiment",
    "task",
    "method",
    "split",
    "setting",
    "seed",
    "steps",
    "sr",
    "spl",
    "sns",
    "cost",
    "paper_sr",
    "paper_spl",
    "paper_sns",
    "paper_cost",
)


METRICS = ("sr", "spl", "sns", "cost")
SUMMARY_COLUMNS = (
    "experiment",
    "task",
    "method",
    "split",
    "setting",
    "seeds",
    "steps",
    *(f"{m}_{stat}" for m in METRICS for stat in ("mean", "std")),
    *(f"paper_{m}" for m in METRICS),
)


def paper_cell(exp: Experiment, task: str, method: str, split: str, setting: str) -> dict[str, float]:
    """The paper's numbers for one row of `exp` (empty where the paper publishes none)."""
    from curbside.train import paper

    kind = exp.paper
    if kind == "table1":
        return paper.PAPER_TABLE1.get((task, split, method), {})
    if kind == "table2" and split == "test":
        machine, _, block = setting.partition(":")
        return paper.PAPER_TABLE2.get(machine, {}).get(block, {})
    if kind == "table5_horizon" and split == "test":
        return paper.PAPER_TABLE5_HORIZON.get(setting, {})
    if kind == "table5_pedestrians" and split == "test":
        return paper.PAPER_TABLE5_PEDESTRIANS.get(setting, {})
    if kind == "ablation_generalisation":
        return paper.PAPER_ABLATION_GENERALISATION.get(setting, {})
    if kind == "ablation_scaling" and split == "test" and setting.isdigit():
        return paper.PAPER_ABLATION_SCALING.get(int(setting), {})
    if kind == "seed_robustness":
        cell = paper.PAPER_SEED_ROBUSTNESS.get(split, {})
        return {"sr": cell["sr"]} if cell else {}
    return {}


def stale_runs(exp: Experiment, budget: str, root: Path = DEFAULT_ROOT) -> dict[str, list[str]]:
    """ "<run id> seed <s>" -> the env config and hyper-parameter keys it trained with that differ from what it would
    train with now (`runner.stale_keys`), for every finished run trained otherwise (`curbside experiment run` trains
    those again)."""
    from curbside.experiments.runner import expected_training, run_dir, stale_keys

    stale = {}
    for run in exp.runs:
        if not run.train:
            continue
        expected = expected_training(exp, run, budget, root)
        for seed in run.seeds:
            out = run_dir(root, exp, budget, run, seed)
            changed = stale_keys(out, expected) if (out / "result.json").is_file() else []
            if changed:
                stale[f"{run.id} seed {seed}"] = changed
    return stale


def evaluated_otherwise_runs(exp: Experiment, budget: str, root: Path = DEFAULT_ROOT) -> dict[str, str]:
    """ "<run id> seed <s>" -> how its evaluations differ from what the protocol's rules have them do now
    (`runner.evaluated_otherwise`: other actions, episode rules or number of episodes), for every finished run
    evaluated otherwise (`curbside experiment run` evaluates those again)."""
    from curbside.experiments.runner import evaluated_otherwise, run_dir
    from curbside.train.protocols import protocol

    proto = protocol(exp.protocol)
    episodes = int(budget_of(exp, budget)["episodes"])
    by_id = {r.id: r for r in exp.runs}
    otherwise = {}
    for run in exp.runs:
        source = by_id[run.init] if not run.train and run.init else run
        for seed in run.seeds:
            f = run_dir(root, exp, budget, run, seed) / "result.json"
            policy_dir = run_dir(root, exp, budget, source, seed)
            if f.is_file() and (policy_dir / "run.json").is_file():
                why = evaluated_otherwise(json.loads(f.read_text()), policy_dir, proto, episodes)
                if why:
                    otherwise[f"{run.id} seed {seed}"] = why
    return otherwise


def rows_of(
    exp: Experiment, budget: str, root: Path, stale: Mapping[str, Any], otherwise: Mapping[str, Any] | None = None
) -> list[dict[str, Any]]:
    """The rows of every finished (run, seed) of `exp` at `budget`, the `stale` ones (`stale_runs`) and those
    evaluated `otherwise` (`evaluated_otherwise_runs`) left out."""
    from curbside.experiments.runner import run_dir

    by_id = {r.id: r for r in exp.runs}
    rows = []
    for run in exp.runs:
        for seed in run.seeds:
            f = run_dir(root, exp, budget, run, seed) / "result.json"
            source = by_id[run.init] if not run.train and run.init else run
            if not f.is_file() or f"{source.id} seed {seed}" in stale or f"{run.id} seed {seed}" in (otherwise or {}):
                continue
            result = json.loads(f.read_text())
            for split, ev in result["evals"].items():
                paper = paper_cell(exp, run.task, run.method, split, run.setting)
                rows.append(
                    {
                        "experiment": exp.name,
                        "task": run.task,
                        "method": run.method,
                        "split": split,
                        "setting": run.setting,
                        "seed": seed,
                        "steps": result["steps"],
                        **{k: ev.get(k, "") for k in METRICS},
                        **{f"paper_{k}": paper.get(k, "") for k in METRICS},
                    }
                )
    return rows


def summary_of(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (task, method, setting, split) of `rows`: the seeds measured, and the mean and the population std
    over them of each metric (the mean empty where the metric was not measured, the std where fewer than two seeds
    measured it)."""
    groups: dict[tuple[str, str, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["method"], r["setting"], r["split"]), []).append(r)
    out = []
    for (task, method, setting, split), group in groups.items():
        first = group[0]
        row: dict[str, Any] = {
            "experiment": first["experiment"],
            "task": task,
            "method": method,
            "split": split,
            "setting": setting,
            "seeds": " ".join(str(r["seed"]) for r in group),
            "steps": " ".join(sorted({str(r["steps"]) for r in group})),
        }
        for m in METRICS:
            values = [float(r[m]) for r in group if r[m] != ""]
            row[f"{m}_mean"] = round(float(np.mean(values)), 4) if values else ""
            row[f"{m}_std"] = round(float(np.std(values)), 4) if len(values) > 1 else ""
            row[f"paper_{m}"] = first[f"paper_{m}"]
        out.append(row)
    return out


def write_report(
    name: str, budget: str, *, root: Path = DEFAULT_ROOT, out_root: Path = Path("benchmarks/results")
) -> Path:
    """Write results.csv, summary.csv, results.png and report.json into out_root/<experiment>/ (the `small` budget,
    the one every experiment runs) or out_root/<experiment>/<budget>/ (another budget); return the CSV path."""
    exp = load_experiment(name)
    stale = stale_runs(exp, budget, root)
    otherwise = evaluated_otherwise_runs(exp, budget, root)
    rows = rows_of(exp, budget, root, stale, otherwise)
    out = Path(out_root) / exp.name if budget == "small" else Path(out_root) / exp.name / budget
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(COLUMNS))
        writer.writeheader()
        writer.writerows(rows)
    summary = summary_of(rows)
    with open(out / "summary.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(SUMMARY_COLUMNS))
        writer.writeheader()
        writer.writerows(summary)
    from curbside.experiments.runner import run_dir

    expected = sum(len(r.seeds) for r in exp.runs)
    finished = sum((run_dir(root, exp, budget, r, s) / "result.json").is_file() for r in exp.runs for s in r.seeds)
    (out / "report.json").write_text(
        json.dumps(
            {
                "experiment": exp.name,
                "title": exp.title,
                "budget": budget,
                "protocol": exp.protocol,
                "runs_finished": finished,
                "runs_declared": expected,
                "runs_stale": stale,  # trained otherwise than the protocol says now: left out of results.csv until trained again
                # evaluated otherwise than the protocol says now: left out of results.csv until evaluated again
                "runs_evaluated_otherwise": otherwise,
                "command": f"curbside experiment run {exp.name} --budget {budget} && curbside experiment report {exp.name} "
                f"--budget {budget}",
            },
            indent=2,
        )
        + "\n"
    )
    plot(exp, summary, out / "results.png", budget)
    return path


def plot(exp: Experiment, summary: list[dict[str, Any]], path: Path, budget: str) -> None:
    """Success rate per (task, method, setting) and split from `summary_of`'s rows: ours (mean, std over seeds)
    beside the paper's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    splits = sorted({r["split"] for r in summary}) or ["test"]
    fig, axes = plt.subplots(
        1, len(splits), figsize=(max(5.0, 0.6 * len(exp.runs) + 2) * len(splits) / 1.5, 4), squeeze=False
    )
    for ax, split in zip(axes[0], splits):
        sel = [r for r in summary if r["split"] == split]
        keys = [(r["task"], r["method"], r["setting"]) for r in sel]
        labels = [" ".join(x for x in (t[:1] + "N" if t else "", m, s) if x) for t, m, s in keys]
        x = np.arange(len(keys))
        ax.bar(
            x - 0.2,
            [float(r["sr_mean"]) for r in sel],
            0.4,
            yerr=[float(r["sr_std"] or 0.0) for r in sel],
            label=f"curbside ({budget})",
            color="#3b7dd8",
        )
        paper = [float(r["paper_sr"]) if r["paper_sr"] != "" else np.nan for r in sel]
        ax.bar(x + 0.2, paper, 0.4, label="MetaUrban paper", color="#bbbbbb")
        ax.set_xticks(x, labels, rotation=45, ha="right", fontsize=7)
        ax.set_ylim(0, 1)
        ax.set_title(f"{exp.title}: {split} SR", fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
