"""Experiment files: what an experiment runs (algorithm, task, protocol, split, setting, env overrides, seeds, init)
and its budgets, read strictly (unknown keys raise, listing the valid ones)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from kernel.config import ConfigError, load_yaml

HERE = Path(__file__).resolve().parent
BUDGETS = ("smoke", "small", "paper")
BUDGET_KEYS = {
    "online_steps",
    "offline_steps",
    "bc_steps",
    "demos_steps",
    "episodes",
    "eval_every",
    "curve_episodes",
    "n_envs",
    "scenes",
    "hparams",
    "backend",
    "eval_workers",
}
RUN_KEYS = {
    "id",
    "task",
    "method",
    "split",
    "setting",
    "env",
    "eval_env",
    "seeds",
    "init",
    "evaluate",
    "backend",
    "train",
}
EXPERIMENT_KEYS = {"name", "title", "paper", "protocol", "evaluate", "runs", "budgets", "description"}
PAPER_KINDS = (
    "table1",
    "table2",
    "table5_horizon",
    "table5_pedestrians",
    "ablation_generalisation",
    "ablation_scaling",
    "seed_robustness",
    "none",
)


@dataclass(frozen=True)
class Run:
    """One trained configuration of an experiment, trained once per seed."""

    id: str
    task: str
    method: str
    split: str = "train"
    setting: str = ""
    env: dict[str, Any] = field(default_factory=dict)  # env config overrides, training and evaluation
    eval_env: dict[str, Any] = field(default_factory=dict)  # overrides for evaluation alone
    seeds: tuple[int, ...] = (0,)
    init: str | None = None  # id of a run of this experiment whose policy (same seed) this run starts from
    evaluate: tuple[str, ...] = ()
    backend: str | None = None  # None: the budget's
    train: bool = True  # False: evaluate the `init` run's policy as it is (another test setting of one model)


@dataclass(frozen=True)
class Experiment:
    """An experiment file: its runs, the protocol they share, the paper numbers it is compared with, budgets."""

    name: str
    title: str
    paper: str
    protocol: str
    runs: tuple[Run, ...]
    budgets: dict[str, dict[str, Any]]
    description: str = ""


def _strict(d: Any, valid: set[str], where: str) -> dict[str, Any]:
    if not isinstance(d, dict):
        raise ConfigError(f"{where} must be a mapping, got {type(d).__name__}")
    unknown = sorted(set(d) - valid)
    if unknown:
        raise ConfigError(
            f"unknown key(s) {', '.join(map(repr, unknown))} in {where}; valid: {', '.join(sorted(valid))}"
        )
    return d


def names() -> list[str]:
    """The experiments shipped with curbside."""
    return sorted(p.stem for p in HERE.glob("*.yaml"))


def load_experiment(name: str) -> Experiment:
    """The experiment `name` (a shipped one, or a path to a .yaml file)."""
    path = Path(name) if name.endswith((".yaml", ".yml")) else HERE / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"unknown experiment {name!r}; valid: {', '.join(names())} (or a path to a .yaml file)")
    from curbside.train.envs import SPLITS, TASKS
    from curbside.train.policies import check_algo

    text = load_yaml(path.read_text(), f"experiment {path.name}")
    raw = _strict(text, EXPERIMENT_KEYS, f"experiment {path.name}")
    paper = raw.get("paper", "none")
    if paper not in PAPER_KINDS:
        raise ConfigError(f"experiment {path.name}: unknown paper table {paper!r}; valid: {', '.join(PAPER_KINDS)}")
    default_eval = tuple(raw.get("evaluate", ["test"]))
    runs = []
    for k, r in enumerate(raw.get("runs") or []):
        r = _strict(r, RUN_KEYS, f"{path.name} run {k}")
        if r.get("task") not in TASKS:
            raise ConfigError(f"{path.name} run {k}: unknown task {r.get('task')!r}; valid: {', '.join(TASKS)}")
        check_algo(r.get("method", "?"))
        for split in [r.get("split", "train"), *r.get("evaluate", default_eval)]:
            if split not in SPLITS:
                raise ConfigError(f"{path.name} run {k}: unknown split {split!r}; valid: {', '.join(SPLITS)}")
        runs.append(
            Run(
                id=str(r.get("id") or f"{r['task']}-{r['method']}"),
                task=r["task"],
                method=r["method"],
                split=r.get("split", "train"),
                setting=str(r.get("setting", "")),
                env=dict(r.get("env") or {}),
                eval_env=dict(r.get("eval_env") or {}),
                seeds=tuple(int(s) for s in r.get("seeds", [0])),
                init=r.get("init"),
                evaluate=tuple(r.get("evaluate", default_eval)),
                backend=r.get("backend"),
                train=bool(r.get("train", True)),
            )
        )
    ids = [r.id for r in runs]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{path.name}: run ids repeat: {sorted({i for i in ids if ids.count(i) > 1})}")
    for r in runs:
        if r.init is not None and (r.init not in ids or ids.index(r.init) >= ids.index(r.id)):
            raise ConfigError(f"{path.name} run {r.id}: init {r.init!r} must name an earlier run of the experiment")
        if not r.train and r.init is None:
            raise ConfigError(f"{path.name} run {r.id}: train: false evaluates another run's policy; name it with init")
    budgets = _strict(raw.get("budgets") or {}, set(BUDGETS), f"{path.name} budgets")
    for b, values in budgets.items():
        _strict(values, BUDGET_KEYS, f"{path.name} budget {b}")
    return Experiment(
        name=str(raw.get("name", path.stem)),
        title=str(raw.get("title", path.stem)),
        paper=paper,
        protocol=str(raw.get("protocol", "paper")),
        runs=tuple(runs),
        budgets=budgets,
        description=str(raw.get("description", "")),
    )


def check_run_ids(exp: Experiment, ids: list[str] | None) -> None:
    """A ConfigError naming the valid run ids when `ids` (a selection such as --only) holds one `exp` lacks."""
    unknown = sorted(set(ids or ()) - {r.id for r in exp.runs})
    if unknown:
        raise ConfigError(f"unknown run id(s) {unknown} in {exp.name}; valid: {', '.join(r.id for r in exp.runs)}")


def budget_of(exp: Experiment, budget: str) -> dict[str, Any]:
    """The values of `budget` for `exp`: the runner's defaults under the file's own."""
    if budget not in BUDGETS:
        raise ConfigError(f"unknown budget {budget!r}; valid: {', '.join(BUDGETS)}")
    defaults: dict[str, dict[str, Any]] = {
        # smoke checks the plumbing in minutes: tiny networks and rollouts, a few scenes and episodes.
        "smoke": {
            "online_steps": 2_048,
            "offline_steps": 200,
            "bc_steps": 200,
            "demos_steps": 1_000,
            "episodes": 3,
            "eval_every": 0,
            "curve_episodes": 2,
            "n_envs": 2,
            "scenes": 4,
            "backend": "pybullet",
            "eval_workers": 1,
            "hparams": {"n_steps": 128, "batch_size": 128, "n_epochs": 2, "net_arch": [64, 64]},
        },
        "small": {
            "online_steps": 500_000,
            "offline_steps": 20_000,
            "bc_steps": 20_000,
            "demos_steps": 30_000,
            "episodes": 50,
            "eval_every": 250_000,
            "curve_episodes": 10,
            "n_envs": None,
            "scenes": None,
            "backend": "batched",
            "hparams": {},
            "eval_workers": 2,
        },
        "paper": {
            "online_steps": 5_000_000,
            "offline_steps": 1_000_000,
            "bc_steps": 18_750,
            "demos_steps": 30_000,
            "episodes": 200,
            "eval_every": 500_000,  # a curve point costs ~2.5 min of PyBullet episodes: 10 points in 5M steps
            "curve_episodes": 20,
            "n_envs": None,
            "scenes": None,
            "backend": "batched",
            "hparams": {},
            "eval_workers": 2,
        },
    }
    return {**defaults[budget], **exp.budgets.get(budget, {})}
