"""What keeping the best checkpoint, rather than the last, is worth: a run's checkpoints every `--every` env steps are
scored on a held-out selection split, the best one is evaluated on the test split, and its figures stand beside the
final policy's.

Usage: python benchmarks/checkpoint_selection.py RUN_DIR [--every 500000] [--select-split finetune]
       [--select-episodes 50] [--test-episodes 200] [--unseen-episodes 0] [--workers 2] --out FILE.json

RUN_DIR is a folder written by `curbside train run` or `curbside experiment run` that still holds its `checkpoints/`
(policy_<steps>_steps.zip). MetaUrban's released PointNav training keeps the best model of an SB3 `EvalCallback`
(`best_model_save_path`), so a figure of that model is the best of many draws; this measures how much that choice adds
here. Every evaluation uses the run's protocol's rules (`curbside train eval`'s: its actions and episode ends), episode k
with seed k. The selection split must be disjoint from the test split (finetune or unseen scenes), or the test figure
of the chosen checkpoint is biased upward. `--unseen-episodes N` evaluates the chosen checkpoint on N unseen-split
episodes too (the paper's second column). Each checkpoint's score is written to `--out` as it lands; a rerun skips the
scored ones and the evaluations already made.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SUMMARY_KEYS = ("sr", "spl", "cost", "route_completion", "episodes")


def checkpoints_every(run: Path, every: int) -> dict[int, Path]:
    """The run's checkpoints nearest each multiple of `every` env steps (SB3 saves a few steps past the multiple),
    keyed by the steps they hold."""
    found = {}
    for f in (run / "checkpoints").glob("policy_*_steps.zip"):
        m = re.fullmatch(r"policy_(\d+)_steps\.zip", f.name)
        if m:
            found[int(m.group(1))] = f
    nearest: dict[int, int] = {}
    for steps in sorted(found):
        mark = round(steps / every) * every
        if mark > 0 and abs(steps - mark) < every // 10 and abs(steps - mark) < abs(nearest.get(mark, -every) - mark):
            nearest[mark] = steps
    return {steps: found[steps] for steps in nearest.values()}


def experiment_run(run: Path):
    """The experiment run (`curbside.experiments.spec.Run`) that `run` holds, named by its result.json; None for a run
    of `curbside train run`."""
    from curbside.experiments.spec import load_experiment

    f = run / "result.json"
    meta = json.loads(f.read_text()) if f.is_file() else {}
    if "experiment" not in meta:
        return None
    return next(r for r in load_experiment(meta["experiment"]).runs if r.id == meta["run"])


def evaluate(run: Path, policy: Path, split: str, episodes: int, workers: int, work: Path) -> dict:
    """`curbside train eval`'s figures for `policy` under the run's record (a folder with its run.json and the policy)."""
    from curbside.experiments.runner import eval_config
    from curbside.train.evaluate import evaluate_run
    from curbside.train.policies import eval_actions_of, read_run
    from curbside.train.protocols import protocol

    folder = work / policy.stem
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(run / "run.json", folder / "run.json")
    shutil.copyfile(policy, folder / "policy.zip")
    record = read_run(folder)
    proto = protocol(record.get("protocol", "curbside"))
    # An experiment's run evaluates under its own env and eval_env overrides too, so its checkpoints are scored as its
    # reported figures are (Table 5's routes and crowds differ from training's).
    summary = evaluate_run(
        folder,
        record["task"],
        eval_config(record.get("env_config", {}), experiment_run(run), proto),
        split=split,
        episodes=episodes,
        num_scenes=proto.eval_scenes,
        workers=workers,
        progress=False,
        actions=eval_actions_of(record, proto.eval_actions),
    )
    return {k: summary[k] for k in SUMMARY_KEYS}


def logged_steps(run: Path) -> int | None:
    """The env steps of a run's last logged update (logs/progress.csv): its final policy's, where no result.json
    records them (a run whose evaluation did not run)."""
    import csv

    log = run / "logs" / "progress.csv"
    if not log.is_file():
        return None
    with open(log, newline="") as f:
        steps = [row.get("time/total_timesteps") for row in csv.DictReader(f)]
    return max((int(float(x)) for x in steps if x), default=None)


def write(out: Path, result: dict) -> None:
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    tmp.replace(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--every", type=int, default=500_000)
    ap.add_argument("--select-split", default="finetune", choices=("finetune", "unseen", "train"))
    ap.add_argument("--select-episodes", type=int, default=50)
    ap.add_argument("--test-episodes", type=int, default=200)
    ap.add_argument("--unseen-episodes", type=int, default=0, help="also evaluate the chosen checkpoint on unseen")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()

    ckpts = checkpoints_every(args.run, args.every)
    if not ckpts:
        sys.exit(f"error: {args.run}/checkpoints holds no policy_<steps>_steps.zip; pass a run that keeps them")
    work = (
        ROOT / "outputs" / "checkpoint_selection" / args.out.stem
    )  # one folder a scored checkpoint, removed at the end
    # What decides the scores and the choice; --unseen-episodes only adds an evaluation of the chosen checkpoint.
    settings = {k: v for k, v in vars(args).items() if k not in ("out", "unseen_episodes")}
    settings["run"] = str(args.run)
    result = json.loads(args.out.read_text()) if args.out.is_file() else {}
    if result.get("settings") != settings:
        result = {"settings": settings}  # another selection's scores are not this one's
    result["command"] = "python benchmarks/checkpoint_selection.py " + shlex.join(sys.argv[1:])
    scores = result.setdefault(f"{args.select_split}_scores", {})
    for steps, path in sorted(ckpts.items()):
        if str(steps) in scores:
            continue
        t0 = time.perf_counter()
        scores[str(steps)] = evaluate(args.run, path, args.select_split, args.select_episodes, args.workers, work)
        print(
            f"{steps:>9,} steps: {args.select_split} SR {scores[str(steps)]['sr']:.2f} "
            f"({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
        write(args.out, result)
    # The best selection SR; among equals, the higher route completion, then the later checkpoint.
    best = int(max(scores, key=lambda s: (scores[s]["sr"], scores[s]["route_completion"], int(s))))
    final = json.loads((args.run / "result.json").read_text()) if (args.run / "result.json").is_file() else {}
    splits = {"test": args.test_episodes, "unseen": args.unseen_episodes}
    for split, episodes in splits.items():
        chosen = result.get(f"best_{split}", {})
        if episodes > 0 and (chosen.get("steps"), chosen.get("episodes")) != (best, episodes):
            t0 = time.perf_counter()
            figures = evaluate(args.run, ckpts[best], split, episodes, args.workers, work)
            result[f"best_{split}"] = {"steps": best, **figures}
            print(
                f"best ({best:,} steps): {split} SR {figures['sr']:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True
            )
            write(args.out, result)
        # The final policy's figures are the run's own evaluation (result.json) where it ran on as many episodes.
        own = final.get("evals", {}).get(split, {})
        if episodes > 0 and own.get("episodes") == episodes:
            result[f"final_{split}"] = {"steps": final.get("steps"), **{k: own[k] for k in SUMMARY_KEYS}}
        elif episodes > 0 and (args.run / "policy.zip").is_file():
            figures = result.get(f"final_{split}") or evaluate(
                args.run, args.run / "policy.zip", split, episodes, args.workers, work
            )
            figures = {k: figures[k] for k in SUMMARY_KEYS}
            result[f"final_{split}"] = {"steps": final.get("steps") or logged_steps(args.run), **figures}
    write(args.out, result)
    shutil.rmtree(work, ignore_errors=True)
    print(json.dumps({k: result.get(k) for k in result if k.startswith(("best_", "final_"))}, indent=2))


if __name__ == "__main__":
    main()
