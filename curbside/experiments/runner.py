"""Run an experiment: train every (run, seed) that has no result yet, evaluate it on its splits, write result.json.

Layout: ROOT/<experiment>/<budget>/<run id>/seed_<s>/ holds the training run (run.json, checkpoints, policy) and
result.json (written last, atomically): a run with a result.json is finished and never trained again; a run without
one resumes from its latest checkpoint. A run whose run.json records another env config or other hyper-parameters
than it would train with now (its protocol has changed: a new catalog, say), or demonstrations another policy drove
(a PPO of the task has finished at a larger budget since), is stale: it moves to
ROOT/<experiment>/<budget>/stale/ and trains again from scratch. A run that another experiment has already trained
the same way (its run.json records the same training, `trained_elsewhere`) copies that training and is evaluated on
its own splits (result.json's `trained_in` names the source). A finished run whose evaluations acted otherwise
than its protocol's rule has it act now (mean or sampled actions), or ran another number of episodes a split than
its budget asks, is evaluated again; `reevaluate` evaluates every finished run again with the simulator as it is
(after a physics fix, say) and rewrites its result.json, training nothing. Demonstrations for offline and imitation
runs are collected once per task under ROOT/<experiment>/<budget>/demos/<task>/.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from curbside.experiments.spec import BUDGETS, Experiment, Run, budget_of, check_run_ids, load_experiment
from curbside.train.protocols import Protocol

ONLINE = ("ppo", "ppo_lag", "ppo_et")
DEFAULT_ROOT = Path("outputs/experiments")


def run_dir(root: Path, exp: Experiment, budget: str, run: Run, seed: int) -> Path:
    """Where (run, seed) of `exp` at `budget` trains and keeps its result."""
    return Path(root) / exp.name / budget / run.id / f"seed_{seed}"


def _steps(b: dict[str, Any], method: str) -> int:
    if method in ONLINE or method == "gail":
        return int(b["online_steps"])
    return int(b["bc_steps"] if method == "bc" else b["offline_steps"])


def _write_json(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=str))
    os.replace(tmp, path)


def run_backend(run: Run, b: Mapping[str, Any]) -> str:
    """The backend (run, budget values `b`) trains on: the run's or the budget's, where it can train the run (the
    batched envs step the online learners and GAIL's generator), else the PyBullet envs."""
    backend = run.backend or b["backend"]
    return backend if run.method in ONLINE + ("gail",) else "pybullet"


def run_hparams(run: Run, b: Mapping[str, Any]) -> dict[str, Any]:
    """The hyper-parameters the runner gives `run`: the budget's are PPO's (the generator's for GAIL); the other
    learners take its network alone."""
    if run.method in ONLINE + ("gail",):
        return dict(b["hparams"])
    return {"net_arch": b["hparams"]["net_arch"]} if "net_arch" in b["hparams"] else {}


def run_scenes(run: Run, b: Mapping[str, Any]) -> int | None:
    """The scenes (run, budget values `b`) trains on: the run's own count (ablation (b)), else the budget's (None:
    the protocol's for the split)."""
    return run.env.get("num_scenes") or b["scenes"]


def _resolved(exp: Experiment, run: Run, budget: str) -> dict[str, Any]:
    """`train.run.resolve_run` for `run` of `exp` at `budget`: what the runner's `train` call trains it with."""
    from curbside.train.run import resolve_run

    b = budget_of(exp, budget)
    return resolve_run(
        run.method,
        run.task,
        protocol=exp.protocol,
        env_config=run.env,
        split=run.split,
        n_envs=b["n_envs"],
        num_scenes=run_scenes(run, b),
        hparams=run_hparams(run, b),
        backend=run_backend(run, b),
    )


def expected_training(exp: Experiment, run: Run, budget: str, root: Path) -> dict[str, Any]:
    """What `run` of `exp` at `budget` trains under now, as its run.json records it: env config (its protocol's, with
    the run's own keys and split) and hyper-parameters (the protocol's, with the budget's); for a run that learns
    from demonstrations, also who drives them (`demo_source`)."""
    r = _resolved(exp, run, budget)
    expected = {"env_config": r["env_config"], "hparams": r["hparams"]}
    if run.train and run.method not in ONLINE:
        expected["demos"] = demo_source(root, exp, run.task)
    return expected


def trained_elsewhere(root: Path, exp: Experiment, budget: str, run: Run, seed: int) -> Path | None:
    """A finished run of another experiment whose run.json records the very training (run, seed) of `exp` at
    `budget` would do (algorithm, task, split, steps, seed, envs, scenes, env config, hyper-parameters, backend and
    learning curve; from scratch): ablation (a)'s train run, Table 5's 410 m run and seed robustness's seed 0 are one
    training. None when there is none, or (run, seed) starts from another run or learns from demonstrations."""
    from curbside.train.run import as_recorded

    if not run.train or run.init or run.method not in ONLINE:
        return None
    b = budget_of(exp, budget)
    r = _resolved(exp, run, budget)
    want = as_recorded(
        {
            "algo": run.method,
            "task": run.task,
            "split": run.split,
            "steps": _steps(b, run.method),
            "seed": seed,
            "n_envs": r["n_envs"],
            "num_scenes": r["num_scenes"],
            "env_config": r["env_config"],
            "hparams": r["hparams"],
            "protocol": r["protocol"],
            "backend": run_backend(run, b),
            "init_from": None,
            "eval_every": int(b["eval_every"]),
            "eval_episodes": int(b["curve_episodes"]),
        }
    )
    mine = run_dir(root, exp, budget, run, seed)
    for done in sorted(Path(root).glob(f"*/*/*/seed_{seed}/result.json")):
        source = done.parent
        if source == mine or source.parts[-4] == exp.name or not (source / "run.json").is_file():
            continue
        recorded = json.loads((source / "run.json").read_text())
        if all(recorded.get(k, "missing") == v for k, v in want.items()):
            return source
    return None


def _copy_training(source: Path, out: Path) -> None:
    """`source`'s training (run.json, policy, curve, logs; not its checkpoints or result) as the run at `out`."""
    tmp = out.with_name(out.name + ".copying")
    if tmp.exists():
        shutil.rmtree(tmp)
    shutil.copytree(source, tmp, ignore=shutil.ignore_patterns("checkpoints", "result.json"))
    if out.exists():
        shutil.rmtree(out)  # a folder without run.json: nothing trained there yet
    os.replace(tmp, out)


def stale_keys(out: Path, expected: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The keys of each part of `expected` (env_config, hparams; demos) whose value in the run.json at `out` differs,
    as "part.key" (empty when they match or there is no run.json). The demonstrations a run learned from are recorded
    with their statistics (`demos_meta`); only the keys `expected["demos"]` names are compared."""
    from curbside.train.run import changed_keys

    path = out / "run.json"
    if not path.is_file():
        return []
    recorded = json.loads(path.read_text())
    changed = changed_keys(recorded, {part: want for part, want in expected.items() if part != "demos"})
    have = demo_identity(recorded.get("demos_meta") or {})
    want = demo_identity(expected.get("demos", {}))
    return changed + [f"demos.{k}" for k in sorted(want) if have.get(k) != want[k]]


def demo_identity(source: Mapping[str, Any]) -> dict[str, Any]:
    """The keys of a demonstrations record (`demo_source`'s, or a dataset's curbside.json) that say who drove them,
    the policy named by its run (experiment, budget, run id, seed: the last four parts of its folder), whatever root
    the experiments were run under. A record without a share from a policy reads as the expert alone."""
    policy = source.get("policy")
    return {
        "policy": "/".join(Path(policy).parts[-4:]) if policy is not None else None,
        "policy_fraction": float(source.get("policy_fraction", 0.0)),
        "noise": source.get("noise"),
    }


def _set_aside(root: Path, exp: Experiment, budget: str, run: Run, seed: int) -> Path:
    """Move (run, seed)'s folder to ROOT/<experiment>/<budget>/stale/<run id>/seed_<s> (replacing an older one)."""
    out = run_dir(root, exp, budget, run, seed)
    dest = Path(root) / exp.name / budget / "stale" / run.id / f"seed_{seed}"
    if dest.exists():
        shutil.rmtree(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    os.replace(out, dest)
    return dest


# The test SR from which a trained PPO drives demonstrations. One that succeeds less often (SocialNav's after a few
# updates: 0.00-0.02) would fill the dataset with failures where the paper's demonstrations succeed ~60 % of the time,
# and one evaluated again would flip the source on an episode or two.
DEMO_POLICY_MIN_SR = 0.1


def _demo_policy(root: Path, exp: Experiment, task: str) -> Path | None:
    """The trained PPO that drives the protocol's policy share of `task`'s demonstrations: this experiment's PPO run of
    the task (its first seed) at the largest budget that has finished (paper, then small, then smoke) with a test SR
    of at least DEMO_POLICY_MIN_SR, or None: the noisy expert drives instead."""
    ppo = next((r for r in exp.runs if r.task == task and r.method == "ppo" and r.train), None)
    if ppo is None:
        return None
    for budget in reversed(BUDGETS):
        source = run_dir(root, exp, budget, ppo, ppo.seeds[0])
        result = source / "result.json"
        if not result.is_file():
            continue
        if json.loads(result.read_text()).get("evals", {}).get("test", {}).get("sr", 0.0) >= DEMO_POLICY_MIN_SR:
            return source
    return None


def demo_source(root: Path, exp: Experiment, task: str) -> dict[str, Any]:
    """Who drives `task`'s demonstrations for `exp` now, as the demonstrations record it: the protocol's mix, a share
    of the episodes from the best trained PPO of the task this experiment has (a PPO of a few updates drives no
    better than chance, and its demonstrations would teach nothing) and the noisy expert the rest (or all, without
    one). A run that learned from demonstrations another source drove is stale: a PPO finishing at a larger budget,
    or one whose evaluation finds it succeeding where it did not (or no longer), changes its data."""
    from curbside.train.protocols import protocol

    proto = protocol(exp.protocol)
    source = _demo_policy(root, exp, task) if proto.demos.policy_fraction > 0 else None
    return {
        "policy": str(source) if source is not None else None,
        "policy_fraction": proto.demos.policy_fraction if source is not None else 0.0,
        "noise": proto.demos.expert_noise,
    }


def _demos(root: Path, exp: Experiment, budget: str, run: Run, b: dict[str, Any]) -> Path:
    """The task's demonstrations for this experiment and budget (collected on first use, and again when the policy
    that should drive them, the expert's noise or the scenes' catalog has changed since)."""
    from curbside.train.demos import collect_demos, dataset_id
    from curbside.train.protocols import deep_merge, protocol

    base = Path(root) / exp.name / budget / "demos" / run.task
    path = base / dataset_id(run.task)
    env_config = deep_merge(protocol(exp.protocol).env_for(run.task), run.env)
    source = demo_source(root, exp, run.task)
    meta = path / "curbside.json"
    have = json.loads(meta.read_text()) if meta.is_file() else None
    if have is None or demo_identity(have) != demo_identity(source) or have.get("catalog") != env_config.get("catalog"):
        collect_demos(
            run.task,
            base,
            steps=int(b["demos_steps"]),
            noise=source["noise"],
            env_config=env_config,
            num_scenes=int(b["scenes"] or 64),
            progress=False,
            policy=Path(source["policy"]) if source["policy"] is not None else None,
            policy_fraction=source["policy_fraction"],
        )
    return path


def run_experiment(
    name: str,
    budget: str,
    *,
    root: Path = DEFAULT_ROOT,
    only: list[str] | None = None,
    seeds: list[int] | None = None,
    reevaluate: bool = False,
    progress: bool = True,
    log: Callable[[str], None] = print,
) -> list[dict[str, Any]]:
    """Train and evaluate every (run, seed) of experiment `name` at `budget` that has no result (of the runs in
    `only` and the seeds in `seeds`, when given); with `reevaluate`, evaluate the finished ones again instead (their
    training untouched) and leave the unfinished alone. Return all results."""
    from curbside.train.protocols import protocol
    from curbside.train.run import train

    exp = load_experiment(name)
    b = budget_of(exp, budget)
    proto = protocol(exp.protocol)
    check_run_ids(exp, only)
    run_by_id = {r.id: r for r in exp.runs}
    results = []
    for run in exp.runs:
        if only and run.id not in only:
            continue
        for seed in run.seeds:
            if seeds is not None and seed not in seeds:
                continue
            out = run_dir(root, exp, budget, run, seed)
            init_from = run_dir(root, exp, budget, run_by_id[run.init], seed) if run.init else None
            policy_dir = out if run.train else init_from  # a run that trains nothing evaluates the one it starts from
            assert policy_dir is not None
            done = out / "result.json"
            if run.train and not reevaluate:
                changed = stale_keys(out, expected_training(exp, run, budget, root))
                if changed:
                    moved = _set_aside(root, exp, budget, run, seed)
                    for dependent in exp.runs:  # runs that start from this one are measured again too
                        if dependent.init == run.id and run_dir(root, exp, budget, dependent, seed).exists():
                            _set_aside(root, exp, budget, dependent, seed)
                    log(
                        f"[{exp.name} {budget}] {run.id} seed {seed}: trained under another env config, "
                        f"hyper-parameters or demonstrations ({', '.join(changed)}); moved to {moved}, training again"
                    )
            if done.is_file():
                result = json.loads(done.read_text())
                otherwise = evaluated_otherwise(result, policy_dir, proto, int(b["episodes"]))
                if reevaluate or otherwise:
                    why = f" (evaluated {otherwise})"
                    log(f"[{exp.name} {budget}] {run.id} seed {seed}: evaluating again{why if otherwise else ''}")
                    result["evals"] = _evaluate(run, policy_dir, b, proto, progress, log)
                    _write_json(done, result)
                results.append(result)
                continue
            if reevaluate:
                continue
            online = run.method in ONLINE
            backend = run_backend(run, b)
            demos = _demos(root, exp, budget, run, b) if not online and run.train else None
            steps = _steps(b, run.method)
            hparams = run_hparams(run, b)
            t0 = time.time()
            resumed = (out / "run.json").is_file()  # then train_s holds this call's part of the training alone
            source = None if resumed else trained_elsewhere(root, exp, budget, run, seed)
            if source is not None:
                log(f"[{exp.name} {budget}] {run.id} seed {seed}: trained as {source} was; copying its training")
                _copy_training(source, out)
                train_s = float(json.loads((source / "result.json").read_text()).get("train_s", 0.0))
            else:
                out.mkdir(parents=True, exist_ok=True)
                if run.train:
                    log(
                        f"[{exp.name} {budget}] {run.id} seed {seed}: training {run.method} on {run.task} "
                        f"{run.split} for {steps:,} steps"
                    )
                    train(
                        run.method,
                        run.task,
                        out,
                        steps=steps,
                        protocol=exp.protocol,
                        backend=backend,
                        split=run.split,
                        env_config=run.env,
                        n_envs=b["n_envs"],
                        num_scenes=run_scenes(run, b),
                        seed=seed,
                        demos=demos,
                        resume=resumed,
                        init_from=init_from,
                        eval_every=int(b["eval_every"]) if online else 0,
                        eval_episodes=int(b["curve_episodes"]),
                        hparams=hparams,
                        progress=progress,
                    )
                else:
                    steps = 0
                    log(f"[{exp.name} {budget}] {run.id} seed {seed}: evaluating the policy of {run.init}")
                train_s = time.time() - t0
            evals = _evaluate(run, policy_dir, b, proto, progress, log)
            result = {
                "experiment": exp.name,
                "budget": budget,
                "run": run.id,
                "task": run.task,
                "method": run.method,
                "split": run.split,
                "setting": run.setting,
                "seed": seed,
                "steps": steps,
                "backend": backend,
                "train_s": round(train_s, 1),
                "resumed": resumed,
                **({"trained_in": str(source)} if source is not None else {}),
                "protocol": exp.protocol,
                "evals": evals,
            }
            _write_json(done, result)
            results.append(result)
    return results


def evaluated_otherwise(result: Mapping[str, Any], policy_dir: Path, proto: Protocol, episodes: int) -> str | None:
    """How a finished run's evaluations differ from what `proto`'s rules and its budget have them do now, in words:
    acting otherwise than its `eval_actions` ("mean" for evaluations that predate the record), under other episode
    rules than its `eval_env` (none for evaluations that predate the record), or on another number of episodes a
    split than the budget's `episodes`; None when they do not."""
    from curbside.train.policies import eval_actions_of, read_run
    from curbside.train.run import as_recorded

    want = eval_actions_of(read_run(policy_dir), proto.eval_actions)
    evals = result.get("evals", {}).values()
    actions = next((a for a in sorted({ev.get("actions", "mean") for ev in evals}) if a != want), None)
    if actions is not None:
        return f"with {actions} actions; the protocol's are {want}"
    rules = as_recorded(proto.eval_env)
    other = next((ev.get("eval_env", {}) for ev in evals if ev.get("eval_env", {}) != rules), None)
    if other is not None:
        return f"under episode rules {json.dumps(other, sort_keys=True)}; the protocol's are {json.dumps(rules, sort_keys=True)}"
    counts = sorted({int(ev.get("episodes", episodes)) for ev in evals} - {episodes})
    if counts:
        return f"on {', '.join(map(str, counts))} episodes a split; the budget's are {episodes}"
    return None


def eval_config(env_config: Mapping[str, Any], run: Run | None, proto: Protocol) -> dict[str, Any]:
    """The env config a run's policy is evaluated under: its training config, then the run's env overrides, the
    protocol's episode rules (`eval_env`) and the run's own; without a run (`curbside train run`), the protocol's."""
    from curbside.train.protocols import deep_merge

    if run is None:
        return deep_merge(env_config, proto.eval_env)
    return deep_merge(deep_merge(deep_merge(env_config, run.env), proto.eval_env), run.eval_env)


def _evaluate(
    run: Run, policy_dir: Path, b: dict[str, Any], proto: Protocol, progress: bool, log: Callable[[str], None]
) -> dict[str, dict[str, Any]]:
    """The policy in `policy_dir` evaluated on each of the run's splits, under its training config plus the run's
    and the protocol's episode rules (`eval_env`, recorded in each evaluation), acting as the protocol's rule has it
    act."""
    from curbside.train.evaluate import evaluate_run
    from curbside.train.policies import eval_actions_of, read_run
    from curbside.train.run import as_recorded

    meta = read_run(policy_dir)
    cfg = eval_config(meta.get("env_config", {}), run, proto)
    actions = eval_actions_of(meta, proto.eval_actions)
    evals = {}
    for split in run.evaluate:
        evals[split] = evaluate_run(
            policy_dir,
            run.task,
            cfg,
            split=split,
            episodes=int(b["episodes"]),
            num_scenes=proto.eval_scenes,
            workers=int(b["eval_workers"]),
            progress=progress,
            actions=actions,
        )
        evals[split]["eval_env"] = as_recorded(proto.eval_env)
        log(
            f"    {split}: SR {evals[split]['sr']:.2f}  SPL {evals[split]['spl']:.2f}  Cost {evals[split]['cost']:.2f}"
            f"  ({actions} actions)"
        )
    return evals
