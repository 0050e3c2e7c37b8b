"""An experiment's runs carried between machines: `pack` copies what each run needs to go on into a folder that
travels (benchmarks/runs/ in git, a shared drive), `unpack` puts it back under the runs' root.

A finished run (result.json) travels with its run.json, result.json, learning curve, progress log and final policy
(PPO-family policies without the optimizer's moments, as in the zoo): the runner finds it finished and trains it
never again, the report and the zoo read it as they would the original. An unfinished run travels with its run.json,
learning curve, progress log and its newest whole checkpoint: `curbside experiment run` resumes it from there. The
archive mirrors the root's layout, <experiment>/<budget>/<run id>/seed_<s>/, and each run folder in it is written
beside the old one and swapped in whole.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from curbside.experiments.runner import DEFAULT_ROOT, run_dir
from curbside.experiments.spec import load_experiment

ARCHIVE = Path("benchmarks/runs")
STEP_CHECKPOINT = "policy_*_steps.zip"  # online trainers keep one per CHECKPOINT_EVERY steps; the newest travels


def _is_temporary(path: Path) -> bool:
    return ".tmp" in path.name or path.name.startswith("tmp_")


def _swap_in(tmp: Path, dst: Path) -> None:
    """Put the folder `tmp`, written whole, in the place of `dst`."""
    if dst.exists():
        shutil.rmtree(dst)
    tmp.replace(dst)


def pack_run(src: Path, dst: Path, method: str) -> bool:
    """Copy what the run in `src` needs to go on to `dst` (replaced whole); False when `src` holds no run."""
    from curbside.experiments.release import compact_copy
    from curbside.train.online import latest_checkpoint
    from curbside.train.policies import POLICY_FILES

    finished = (src / "result.json").is_file()
    if not finished and not (src / "run.json").is_file():
        return False
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for f in sorted(src.iterdir()):
        if not f.is_file() or _is_temporary(f):
            continue
        if finished and f.name == POLICY_FILES.get(method):
            compact_copy(f, tmp / f.name, method)
        else:
            shutil.copyfile(f, tmp / f.name)
    if (src / "logs" / "progress.csv").is_file():
        (tmp / "logs").mkdir()
        shutil.copyfile(src / "logs" / "progress.csv", tmp / "logs" / "progress.csv")
    ckpt = src / "checkpoints"
    if not finished and ckpt.is_dir():
        (tmp / "checkpoints").mkdir()
        latest = latest_checkpoint(ckpt)
        keep = [latest] if latest is not None else []
        keep += [f for f in ckpt.iterdir() if f.is_file() and not f.match(STEP_CHECKPOINT) and not _is_temporary(f)]
        for f in keep:
            shutil.copyfile(f, tmp / "checkpoints" / f.name)
    _swap_in(tmp, dst)
    return True


def pack(name: str, budget: str, *, root: Path = DEFAULT_ROOT, archive: Path = ARCHIVE) -> list[Path]:
    """Pack every run of experiment `name` at `budget` that has started under `root` into `archive`; return the run
    folders written there. Stale runs (set aside under stale/) stay behind."""
    exp = load_experiment(name)
    written = []
    for run in exp.runs:
        for seed in run.seeds:
            dst = run_dir(archive, exp, budget, run, seed)
            if pack_run(run_dir(root, exp, budget, run, seed), dst, run.method):
                written.append(dst)
    return written


def unpack(
    name: str, budget: str, *, root: Path = DEFAULT_ROOT, archive: Path = ARCHIVE
) -> tuple[list[Path], list[Path]]:
    """Copy every packed run of experiment `name` at `budget` from `archive` to `root` where `root` holds none of it
    yet; return (the run folders restored, those left as they were because `root` already holds that run)."""
    exp = load_experiment(name)
    restored, kept = [], []
    for run in exp.runs:
        for seed in run.seeds:
            src, dst = run_dir(archive, exp, budget, run, seed), run_dir(root, exp, budget, run, seed)
            if not src.is_dir():
                continue
            if (dst / "run.json").is_file() or (dst / "result.json").is_file():
                kept.append(dst)
                continue
            tmp = dst.with_name(dst.name + ".tmp")
            shutil.rmtree(tmp, ignore_errors=True)
            shutil.copytree(src, tmp)
            _swap_in(tmp, dst)
            restored.append(dst)
    return restored, kept
