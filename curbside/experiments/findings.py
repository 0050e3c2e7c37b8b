"""The MetaUrban paper's ten findings, each checked on the experiments' results.csv files: whether ours
reproduces it, the numbers on both sides, and the rule that decided it (`findings.json`). A cell measured at the
paper's budget (PPO PointNav's 5M steps in Table 1) stands in for the `small` one in the findings that read a
method's own level (1, 2); the findings that compare methods with each other (3, 4) compare them at the one budget
they all trained at, `small`, since a policy trained 17 times longer would win any such comparison by its budget.

A finding whose experiment has no results yet is reported with `reproduced: null` and the command that runs it.
Each rule is written to be checkable on our numbers whatever their level: it asks for the paper's direction (lower,
higher, harder), not its values; docs/results.md gives the rules in words.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from curbside.train import paper

RESULTS = Path("benchmarks/results")
METHODS = ("ppo", "ppo_lag", "ppo_et", "iql", "td3bc", "bc", "gail")
FAR_FROM_SOLVED = 0.8  # best test SR below this on both tasks: "far from solved"


def _fig(v: float) -> str:
    """A figure as the docs print it: two decimals, three where the third is not 0 (0.40, 0.365; not 0.36)."""
    text = f"{v:.3f}"
    return text[:-1] if text.endswith("0") else text


Cell = dict[str, float]
Table = dict[tuple[str, str, str, str], Cell]  # (task, method, split, setting) -> mean sr, spl, sns, cost


def read_table(path: Path) -> Table:
    """results.csv as means over seeds per (task, method, split, setting); {} when the file is absent."""
    if not path.is_file():
        return {}
    groups: dict[tuple[str, str, str, str], list[dict[str, str]]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            groups.setdefault((row["task"], row["method"], row["split"], row["setting"]), []).append(row)
    out: Table = {}
    for key, rows in groups.items():
        cell: Cell = {"seeds": float(len(rows))}
        for k in ("sr", "spl", "sns", "cost"):
            values = [float(r[k]) for r in rows if r.get(k) not in (None, "")]
            if values:
                cell[k] = round(sum(values) / len(values), 6)  # 0.495, not 0.49499999999999994
        out[key] = cell
    return out


@dataclass(frozen=True)
class Finding:
    """One of the paper's findings: what it says, which experiment shows it, and the rule checked on ours."""

    number: int
    claim: str
    experiment: str
    rule: str
    check: Callable[[Table], dict[str, Any]]


def _sr(t: Table, task: str, method: str, split: str, setting: str = "") -> float | None:
    cell = t.get((task, method, split, setting))
    return None if cell is None or "sr" not in cell else cell["sr"]


def _cost(t: Table, task: str, method: str, split: str) -> float | None:
    cell = t.get((task, method, split, ""))
    return None if cell is None or "cost" not in cell else cell["cost"]


def _judged(clauses: dict[str, bool]) -> dict[str, Any]:
    """A finding's verdict from its rule's clauses, each a sentence on ours with whether ours breaks it: reproduced
    when none is broken, else not, with "why": the broken ones as one sentence."""
    why = [clause for clause, is_broken in clauses.items() if is_broken]
    return {"reproduced": not why, **({"why": "; ".join(why) + "."} if why else {})}


def _far_from_solved(t: Table) -> dict[str, Any]:
    best = {
        task: max((v for m in METHODS if (v := _sr(t, task, m, "test")) is not None), default=None)
        for task in ("PointNav", "SocialNav")
    }
    found = [v for v in best.values() if v is not None]
    if len(found) < len(best):
        return {"reproduced": None, "ours": best}
    return {
        **_judged(
            {
                f"{task}'s best test SR {_fig(v)} reaches {FAR_FROM_SOLVED}": v >= FAR_FROM_SOLVED
                for task, v in best.items()
                if v is not None
            }
        ),
        "ours": {f"best_test_sr_{k}": v for k, v in best.items()},
        "paper": {"best_test_sr_PointNav": 0.66, "best_test_sr_SocialNav": 0.36},
    }


def _unseen_below_test(t: Table) -> dict[str, Any]:
    test, unseen = _sr(t, "PointNav", "ppo", "test"), _sr(t, "PointNav", "ppo", "unseen")
    ours = {"ppo_pointnav_test_sr": test, "ppo_pointnav_unseen_sr": unseen}
    if test is None or unseen is None:
        return {"reproduced": None, "ours": ours}
    broken = {
        f"PPO's PointNav unseen SR {_fig(unseen)} is not below its test SR {_fig(test)}": unseen >= test,
        f"PPO's PointNav unseen SR {_fig(unseen)} is below half its test SR {_fig(test)}": unseen < 0.5 * test,
    }
    return {
        **_judged(broken),
        "ours": ours,
        "paper": {"ppo_pointnav_test_sr": 0.66, "ppo_pointnav_unseen_sr": 0.49},
    }


def _socialnav_harder(t: Table) -> dict[str, Any]:
    have: dict[str, tuple[float, float]] = {}
    for m in METHODS:
        p, s = _sr(t, "PointNav", m, "test"), _sr(t, "SocialNav", m, "test")
        if p is not None and s is not None:
            have[m] = (p, s)
    ours = {m: {"PointNav": p, "SocialNav": s} for m, (p, s) in have.items()}
    if len(have) < len(METHODS):
        return {"reproduced": None, "ours": ours}
    harder = sum(s < p for p, s in have.values())
    mean_p = sum(p for p, _ in have.values()) / len(have)
    mean_s = sum(s for _, s in have.values()) / len(have)
    broken = {
        f"SocialNav's test SR is below PointNav's for {harder} of {len(have)} methods": harder < 5,
        f"SocialNav's mean test SR {_fig(mean_s)} is not below PointNav's {_fig(mean_p)}": mean_s >= mean_p,
    }
    return {
        **_judged(broken),
        "ours": {**ours, "methods_harder": harder},
        "paper": {
            m: {
                "PointNav": paper.PAPER_TABLE1[("PointNav", "test", m)]["sr"],
                "SocialNav": paper.PAPER_TABLE1[("SocialNav", "test", m)]["sr"],
            }
            for m in METHODS
        },
    }


def _safe_rl(t: Table) -> dict[str, Any]:
    ours: dict[str, Any] = {}
    broken: dict[str, bool] = {}
    missing = False
    for task in ("PointNav", "SocialNav"):
        base_sr, base_cost = _sr(t, task, "ppo", "test"), _cost(t, task, "ppo", "test")
        for m in ("ppo_lag", "ppo_et"):
            sr, cost = _sr(t, task, m, "test"), _cost(t, task, m, "test")
            ours[f"{task}_{m}"] = {"sr": sr, "cost": cost, "ppo_sr": base_sr, "ppo_cost": base_cost}
            if sr is None or cost is None or base_sr is None or base_cost is None:
                missing = True
                continue
            broken[f"{task} {m}'s test cost {_fig(cost)} is not below PPO's {_fig(base_cost)}"] = cost >= base_cost
            broken[f"{task} {m}'s test SR {_fig(sr)} is above PPO's {_fig(base_sr)}"] = sr > base_sr
    if missing:
        return {"reproduced": None, "ours": ours}
    return {
        **_judged(broken),
        "ours": ours,
        "paper": {
            f"{task}_{m}": {k: paper.PAPER_TABLE1[(task, "test", m)][k] for k in ("sr", "cost")}
            for task in ("PointNav", "SocialNav")
            for m in ("ppo", "ppo_lag", "ppo_et")
        },
    }


def _scaling(t: Table) -> dict[str, Any]:
    points = sorted(
        (int(setting), cell["sr"])
        for (_, _, split, setting), cell in t.items()
        if split == "test" and setting.isdigit() and "sr" in cell
    )
    ours = {str(n): sr for n, sr in points}
    if len(points) < 2:
        return {"reproduced": None, "ours": ours}
    xs, ys = [math.log(n) for n, _ in points], [sr for _, sr in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / max(sum((x - mx) ** 2 for x in xs), 1e-12)
    broken = {
        f"test SR at {points[-1][0]} scenes, {_fig(ys[-1])}, is not above {_fig(ys[0])} at {points[0][0]}": ys[-1]
        <= ys[0],
        f"test SR falls over log(scenes) (slope {slope:.3f})": slope <= 0,
    }
    return {
        **_judged(broken),
        "ours": {**ours, "slope_per_log_scene": slope},
        "paper": {str(n): c["sr"] for n, c in paper.PAPER_ABLATION_SCALING.items()},
    }


def _density(static: Table, dynamic: Table) -> dict[str, Any]:
    ours: dict[str, Any] = {}
    broken: dict[str, bool] = {}
    for name, t in (("static", static), ("dynamic", dynamic)):
        experiment = f"ablation_{name}_density"
        for split in ("train", "test"):
            low, high = (
                next((c["sr"] for (_, _, sp, st), c in t.items() if sp == split and st == s and "sr" in c), None)
                for s in ("0.01", "1.0")
            )
            ours[f"{name}_{split}"] = {"density_1pc": low, "density_100pc": high}
            if low is None or high is None:
                return {"reproduced": None, "ours": ours, "waits_for": experiment}
            broken[f"{name} density's {split} SR at 100 % ({_fig(high)}) is not below that at 1 % ({_fig(low)})"] = (
                high >= low
            )
    return {
        **_judged(broken),
        "ours": ours,
        "paper": "train and test SR both fall sharply from 1 % to 100 % (figure)",
    }


def _finetune(t: Table) -> dict[str, Any]:
    scratch = next((c["sr"] for (_, _, _, s), c in t.items() if s == "3" and "sr" in c), None)
    pretrained = next((c["sr"] for (_, _, _, s), c in t.items() if s == "4" and "sr" in c), None)
    ours = {"setting3_scratch_sr": scratch, "setting4_pretrained_sr": pretrained}
    if scratch is None or pretrained is None:
        return {"reproduced": None, "ours": ours}
    return {
        **_judged({f"fine-tuned SR {_fig(pretrained)} is not above scratch's {_fig(scratch)}": pretrained <= scratch}),
        "ours": ours,
        "paper": {k: v.get("sr") for k, v in paper.PAPER_ABLATION_GENERALISATION.items()},
    }


def _machines(t: Table) -> dict[str, Any]:
    by_machine: dict[str, list[float]] = {}
    for (_, _, split, setting), cell in t.items():
        if split == "test" and ":" in setting and "sr" in cell:
            by_machine.setdefault(setting.partition(":")[0], []).append(cell["sr"])
    ours = {m: sum(v) / len(v) for m, v in by_machine.items()}
    need = ("delivery_bot", "delivery_bot_mod1", "delivery_bot_mod2", "wheelchair", "mobility_scooter")
    if any(m not in ours for m in need):
        return {"reproduced": None, "ours": ours}
    ranked = sorted(ours, key=lambda m: ours[m], reverse=True)
    ok = ranked[0] == "delivery_bot_mod1" and set(ranked[-2:]) == {"delivery_bot_mod2", "wheelchair"}
    return {
        **_judged({f"the machines rank {', '.join(ranked)} by mean test SR": not ok}),
        "ours": {**ours, "ranking": ranked},
        "paper": {m: sum(c["sr"] for c in paper.PAPER_TABLE2[m].values()) / 2 for m in need},
    }


def _long_routes(t: Table) -> dict[str, Any]:
    short = next((c["sr"] for (_, _, _, s), c in t.items() if s == "10 m" and "sr" in c), None)
    long = next((c["sr"] for (_, _, _, s), c in t.items() if s == "410 m" and "sr" in c), None)
    ours = {"trained_10m_sr": short, "trained_410m_sr": long}
    if short is None or long is None:
        return {"reproduced": None, "ours": ours}
    return {
        **_judged(
            {f"the 410 m model's test SR {_fig(long)} is not above the 10 m model's {_fig(short)}": long <= short}
        ),
        "ours": ours,
        "paper": {k: v["sr"] for k, v in paper.PAPER_TABLE5_HORIZON.items()},
    }


def _pedestrians(t: Table) -> dict[str, Any]:
    sr = {s: next((c["sr"] for (_, _, _, st), c in t.items() if st == s and "sr" in c), None) for s in "1234"}
    one, two, three = sr["1"], sr["2"], sr["3"]
    if one is None or two is None or three is None:
        return {"reproduced": None, "ours": sr}
    return {
        **_judged(
            {
                f"setting {k}'s test SR {_fig(v)} is not below setting 1's {_fig(one)}": v >= one
                for k, v in (("2", two), ("3", three))
            }
        ),
        "ours": sr,
        "paper": {k: v["sr"] for k, v in paper.PAPER_TABLE5_PEDESTRIANS.items()},
    }


def _tables(root: Path) -> tuple[dict[str, Table], dict[str, Table], list[str]]:
    """Each experiment's `small` report (root/<name>/results.csv) with its cells measured at the `paper` budget
    (root/<name>/paper/results.csv) in place of the `small` ones; the `small` reports alone; and the replaced cells,
    named."""
    names = (
        "table1_paper",
        "table2",
        "table5_horizon",
        "table5_pedestrians",
        "ablation_generalisation",
        "ablation_scaling",
        "ablation_static_density",
        "ablation_dynamic_density",
    )
    tables, small, replaced = {}, {}, []
    for n in names:
        larger = read_table(root / n / "paper" / "results.csv")
        small[n] = read_table(root / n / "results.csv")
        tables[n] = {**small[n], **larger}
        replaced += [" ".join(x for x in (n, *key) if x) for key in sorted(larger)]
    return tables, small, replaced


def check_findings(t: dict[str, Table], small: dict[str, Table]) -> list[dict[str, Any]]:
    """The ten findings checked on each experiment's table, `t` with the paper-budget cells in place and `small`
    without them (`_tables`)."""
    table1, table1_small = t["table1_paper"], small["table1_paper"]
    items = [
        (
            1,
            "The tasks are far from solved: best test SR 66 % (PointNav) and 36 % (SocialNav).",
            "table1_paper",
            f"the best method's test SR is below {FAR_FROM_SOLVED} on both tasks",
            lambda: _far_from_solved(table1),
        ),
        (
            2,
            "Unseen is lower than test but generalises (PointNav PPO 49 % vs 66 %).",
            "table1_paper",
            "PPO PointNav unseen SR below its test SR and at least half of it",
            lambda: _unseen_below_test(table1),
        ),
        (
            3,
            "SocialNav is much harder than PointNav for every method.",
            "table1_paper",
            "at the `small` budget, SocialNav test SR below PointNav's for at least 5 of the 7 methods, and on average",
            lambda: _socialnav_harder(table1_small),
        ),
        (
            4,
            "Safe RL (PPO-Lag, PPO-ET) lowers cost at some cost in SR.",
            "table1_paper",
            "at the `small` budget, on both tasks, PPO-Lag and PPO-ET have a lower test cost than PPO and no higher SR",
            lambda: _safe_rl(table1_small),
        ),
        (
            5,
            "More training scenes give a higher test SR (5 -> 1,000 scenes: 12 % -> 46 %).",
            "ablation_scaling",
            "test SR at the most scenes above that at the fewest, and a positive slope over log(scenes)",
            lambda: _scaling(t["ablation_scaling"]),
        ),
        (
            6,
            "Higher static or dynamic density gives a lower SR.",
            "ablation_static_density, ablation_dynamic_density",
            "for static and dynamic density, train and test SR at 100 % below those at 1 %",
            lambda: _density(t["ablation_static_density"], t["ablation_dynamic_density"]),
        ),
        (
            7,
            "Fine-tuning a pretrained policy beats training from scratch on the finetune split.",
            "ablation_generalisation",
            "setting 4 (pretrained, fine-tuned) SR above setting 3 (scratch)",
            lambda: _finetune(t["ablation_generalisation"]),
        ),
        (
            8,
            "Machine design changes learning: mod-1 best, wheelchair and mod-2 worst.",
            "table2",
            "mean test SR over S and X: mod-1 first, wheelchair and mod-2 the last two",
            lambda: _machines(t["table2"]),
        ),
        (
            9,
            "Training on long routes is what makes long routes solvable.",
            "table5_horizon",
            "the 410 m-trained model's test SR above the 10 m-trained model's",
            lambda: _long_routes(t["table5_horizon"]),
        ),
        (
            10,
            "Fewer pedestrians, or pedestrians only at intersections, in training give a worse SocialNav test SR.",
            "table5_pedestrians",
            "settings 2 and 3 below setting 1 on the test split",
            lambda: _pedestrians(t["table5_pedestrians"]),
        ),
    ]
    out = []
    for number, claim, experiment, rule, check in items:
        result = check()
        # A check that reads two experiments says which one lacks its cells; the others read one.
        wait = result.pop("waits_for", experiment)
        entry = {"finding": number, "claim": claim, "experiment": experiment, "rule": rule, **result}
        if result["reproduced"] is None:
            entry["why"] = (
                f"not run yet: curbside experiment run {wait} --budget small && curbside experiment "
                f"report {wait} --budget small"
            )
        out.append(entry)
    return out


def write_findings(root: Path = RESULTS) -> Path:
    """Write root/findings.json (the ten findings, and how many are reproduced) and return its path."""
    tables, small, paper_budget_cells = _tables(Path(root))
    items = check_findings(tables, small)
    path = Path(root) / "findings.json"
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(
        json.dumps(
            {
                "reproduced": sum(f["reproduced"] is True for f in items),
                "not_reproduced": sum(f["reproduced"] is False for f in items),
                "not_run": sum(f["reproduced"] is None for f in items),
                "command": "curbside experiment findings",
                # cells of the `small` reports that a run at the paper's budget measured instead
                "paper_budget_cells": paper_budget_cells,
                "findings": items,
            },
            indent=2,
            default=str,
        )
        + "\n"
    )
    tmp.replace(path)
    return path
