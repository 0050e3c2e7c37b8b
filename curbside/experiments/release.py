"""The policy zoo: an experiment's finished policies copied to policies/<task>/<name>/ (the `paper` protocol's) or
policies/<protocol>/<task>/<name>/ (any other protocol's) with a card.json, each a run folder `curbside train eval`
loads as it is.

A released policy holds what evaluation needs: run.json, the policy file, and for PPO-family policies the weights
without the optimizer's moments (a third of the checkpoint), so the zoo stays small enough for git.
"""

from __future__ import annotations

import json
import re
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from curbside.experiments.runner import DEFAULT_ROOT, ONLINE, run_dir
from curbside.experiments.spec import Run, check_run_ids, load_experiment
from curbside.train.policies import POLICY_FILES, save_policy

ZOO = Path("policies")
# A compacted policy's zip holds the same bytes for the same weights, so a repacked, unchanged policy never churns
# git: SB3 stamps each entry with the time of saving, and writes reprs such as "<function f at 0x7f...>" (an address
# of the saving process) beside each serialized object of its "data".
ZIP_TIME = (1980, 1, 1, 0, 0, 0)
OBJECT_ADDRESS = re.compile(rb" at 0x[0-9a-f]+>")


def zoo_folder(zoo: Path, protocol: str, task: str, name: str) -> Path:
    """Where a released policy goes: ZOO/<task>/<name> for the `paper` protocol (the paper's baselines), else
    ZOO/<protocol>/<task>/<name>, so that no other world's policy stands where the paper's are looked for."""
    return Path(zoo) / task / name if protocol == "paper" else Path(zoo) / protocol / task / name


def release_name(run: Run, paper_kind: str) -> str:
    """The zoo folder name of a run: the method for Table 1, the method and setting otherwise."""
    if paper_kind == "table1" or not run.setting:
        return run.method
    setting = "".join(c if c.isalnum() or c in "-_" else "_" for c in run.setting).strip("_")
    return f"{run.method}-{setting}"


def compact_copy(src: Path, dst: Path, algo: str) -> None:
    """Copy the policy file; a PPO-family zip is written again with a fresh optimizer (no Adam moments) and
    nothing of the moment or process that saved it, so the same policy always compacts to the same bytes."""
    if algo in ONLINE + ("gail",):
        from stable_baselines3 import PPO

        model = PPO.load(str(src), device="cpu")
        policy = model.policy
        policy.optimizer = policy.optimizer_class(
            policy.parameters(), lr=model.learning_rate if isinstance(model.learning_rate, float) else 1e-4
        )
        save_policy(model, dst)
        _normalise_policy_zip(dst)
    else:
        shutil.copyfile(src, dst)


def _normalise_policy_zip(path: Path) -> None:
    """Rewrite the SB3 zip at `path` so that it holds nothing of the moment or process that saved it: every entry
    stamped ZIP_TIME, and the object addresses dropped from the readable reprs beside the serialized values of its
    "data" (SB3 loads the serialized values and ignores the reprs). Written beside `path` and swapped in whole."""
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    with zipfile.ZipFile(path) as old, zipfile.ZipFile(tmp, "w") as new:
        for info in old.infolist():
            content = old.read(info)
            if info.filename == "data":
                content = OBJECT_ADDRESS.sub(b">", content)
            pinned = zipfile.ZipInfo(info.filename, date_time=ZIP_TIME)
            pinned.compress_type = info.compress_type
            pinned.external_attr = info.external_attr
            new.writestr(pinned, content)
    tmp.replace(path)


def release(
    name: str,
    budget: str,
    *,
    root: Path = DEFAULT_ROOT,
    zoo: Path = ZOO,
    seed: int = 0,
    only: list[str] | None = None,
    log: Callable[[str], None] = print,
) -> list[Path]:
    """Copy the seed-`seed` policy of every finished training run of experiment `name` at `budget` (of the run ids in
    `only`, when given) into the zoo; return the folders written. A run without a result yet is skipped, and so is
    one trained or evaluated otherwise than its protocol says now (its card's figures would not be the protocol's),
    each with a line to `log`."""
    from curbside.experiments.report import evaluated_otherwise_runs, stale_runs

    exp = load_experiment(name)
    check_run_ids(exp, only)
    outdated = {
        **{k: f"trained otherwise ({', '.join(v)})" for k, v in stale_runs(exp, budget, root).items()},
        **{k: f"evaluated {v}" for k, v in evaluated_otherwise_runs(exp, budget, root).items()},
    }
    written = []
    for run in exp.runs:
        if not run.train or seed not in run.seeds or (only and run.id not in only):
            continue
        src = run_dir(root, exp, budget, run, seed)
        result_file = src / "result.json"
        if not result_file.is_file():
            continue
        why = outdated.get(f"{run.id} seed {seed}")
        if why:
            log(
                f"skipped {run.id} seed {seed}: {why}; `curbside experiment run {name} --budget {budget}` measures it "
                "again first"
            )
            continue
        result = json.loads(result_file.read_text())
        meta = json.loads((src / "run.json").read_text())
        dst = zoo_folder(Path(zoo), exp.protocol, run.task, release_name(run, exp.paper))
        tmp = dst.with_name(dst.name + ".tmp")
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        policy_file = POLICY_FILES[run.method]
        compact_copy(src / policy_file, tmp / policy_file, run.method)
        (tmp / "run.json").write_text(json.dumps(meta, indent=2) + "\n")
        (tmp / "card.json").write_text(
            json.dumps(card(exp.name, budget, run, seed, meta, result, dst), indent=2) + "\n"
        )
        if dst.exists():
            shutil.rmtree(dst)
        tmp.replace(dst)
        written.append(dst)
    return written


def card(
    experiment: str, budget: str, run: Run, seed: int, meta: dict[str, Any], result: dict[str, Any], folder: Path
) -> dict[str, Any]:
    """What a released policy is: protocol, task, method, setting, steps, seed, training time, metrics, command."""
    return {
        "task": run.task,
        "method": run.method,
        "setting": run.setting,
        "protocol": meta.get("protocol"),
        "experiment": experiment,
        "budget": budget,
        "run": run.id,
        "seed": seed,
        "steps": result["steps"],
        "backend": result.get("backend"),
        # A run resumed from a checkpoint records only its last part: its training time is unknown, not that part.
        "train_seconds": None if result.get("resumed", False) else result.get("train_s"),
        "env_config": meta.get("env_config", {}),
        "metrics": {
            split: {
                k: ev.get(k)
                for k in ("sr", "spl", "sns", "cost", "route_completion", "episodes", "actions", "eval_env")
                if k in ev
            }
            for split, ev in result["evals"].items()
        },
        "command": f"curbside experiment run {experiment} --budget {budget} --only {run.id} && curbside experiment "
        f"release {experiment} --budget {budget}",
        "evaluate": f"curbside train eval {folder.as_posix()}",
    }
