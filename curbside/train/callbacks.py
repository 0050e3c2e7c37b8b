"""SB3 callbacks of a training run: whole checkpoints, and a periodic evaluation on a held-out split (the learning
curve of SR, SPL and cost)."""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import Any


def CheckpointEvery(directory: Path, every: int) -> Any:
    """An SB3 callback that saves the model to `directory`/policy_<env steps>_steps.zip every `every` env steps,
    each through a file beside it swapped in whole: a run killed while saving keeps its previous checkpoints
    readable (SB3's CheckpointCallback writes in place and leaves half a zip)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from curbside.train.policies import save_policy

    class _CheckpointEvery(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next_at = every

        def _on_training_start(self) -> None:
            Path(directory).mkdir(parents=True, exist_ok=True)
            self.next_at = (self.num_timesteps // every + 1) * every  # a resumed run goes on where it was

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_at:
                self.next_at = (self.num_timesteps // every + 1) * every
                save_policy(self.model, Path(directory) / f"policy_{self.num_timesteps}_steps.zip")
            return True

    return _CheckpointEvery()


def RolloutThreads(update_threads: int) -> Any:
    """An SB3 callback that runs the rollouts' policy calls on one torch thread and the update on `update_threads`.

    A batched env in the training process traces its LiDAR on every core (numba's OpenMP threads); torch's own
    OpenMP threads spin for a while after each of its parallel regions and take those cores from the tracer: with
    two torch threads during rollouts a 64-env scan costs ~2.7x what it costs alone (benchmarks/training_throughput.py).
    A policy call on 64 observations gains nothing from a second thread."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    class _RolloutThreads(BaseCallback):
        def _on_rollout_start(self) -> None:
            torch.set_num_threads(1)

        def _on_rollout_end(self) -> None:
            torch.set_num_threads(update_threads)

        def _on_training_end(self) -> None:
            torch.set_num_threads(update_threads)

        def _on_step(self) -> bool:
            return True

    return _RolloutThreads()


def SplitEvalCallback(
    task: str,
    env_config: Mapping[str, Any],
    every: int,
    episodes: int,
    split: str,
    csv_path: Path,
    at_start: bool = False,
    actions: str = "mean",
) -> Any:
    """An SB3 callback that evaluates the current policy on `split` every `every` env steps into `csv_path` (and
    before the first step with `at_start`: a fine-tuned run's first row is its source policy's evaluation), acting
    with its mean action or, with `actions` "sampled", draws seeded by each episode's seed."""
    from stable_baselines3.common.callbacks import BaseCallback

    from curbside.train.evaluate import evaluate_policy

    class _SplitEval(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next_at = every

        def _on_training_start(self) -> None:
            self.next_at = (self.num_timesteps // every + 1) * every  # a resumed run goes on where it was
            drop_rows_after(csv_path, self.num_timesteps)  # rows a killed run wrote past its last checkpoint
            if at_start:
                self.record()

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_at:
                self.next_at += every
                self.record()
            return True

        def _on_training_end(self) -> None:
            self.record()

        def record(self) -> None:
            policy = self.model
            summary = evaluate_policy(
                lambda obs: policy.predict(obs, deterministic=actions == "mean")[0],
                task,
                env_config,
                split=split,
                episodes=episodes,
                progress=False,
                seed_torch=actions == "sampled",
            )
            append_eval_row(csv_path, self.num_timesteps, summary, self.logger, split)

    return _SplitEval()


def training_logger(folder: Path, formats: tuple[str, ...], resumed_at: int | None) -> Any:
    """An SB3 logger writing `formats` ("csv", "tensorboard") to `folder`. A resumed run (`resumed_at`: the env steps of
    its checkpoint) keeps the rows its progress.csv holds up to those steps, and goes on below them; SB3's own CSV
    writer starts the file afresh."""
    from stable_baselines3.common.logger import CSVOutputFormat, Logger, make_output_format

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "progress.csv"
    kept: list[dict[str, str]] = []
    header: list[str] = []
    if resumed_at is not None and path.is_file():
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            header = list(reader.fieldnames or [])
            kept = [r for r in reader if int(float(r.get("time/total_timesteps") or 0)) <= resumed_at]
    outputs = []
    for fmt in formats:
        if fmt != "csv":
            outputs.append(make_output_format(fmt, str(folder)))
            continue
        writer = CSVOutputFormat(str(path))
        if header:
            writer.keys = list(header)
            rows = csv.DictWriter(writer.file, fieldnames=header, lineterminator="\n")
            rows.writeheader()
            rows.writerows(kept)
            writer.file.flush()
        outputs.append(writer)
    return Logger(folder=str(folder), output_formats=outputs)


def drop_rows_after(csv_path: Path, steps: int) -> None:
    """Remove the rows of a learning curve past `steps` (a resumed run evaluates those steps again)."""
    if not csv_path.is_file():
        return
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [r for r in rows if int(float(r["steps"])) <= steps]
    if len(keep) < len(rows):
        tmp = csv_path.with_name(csv_path.name + ".tmp")
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(keep)
        tmp.replace(csv_path)


def append_eval_row(csv_path: Path, steps: int, summary: Mapping[str, Any], logger: Any, split: str) -> None:
    """Append one evaluation (SR, SPL, cost, route completion, SNS) at `steps` to the learning-curve CSV and record
    it in the SB3 `logger` under eval_<split>/ (shared by the SB3 and RLlib trainers)."""
    row = {
        "steps": steps,
        **{k: summary[k] for k in ("sr", "spl", "cost", "route_completion", "sns", "path_length") if k in summary},
    }
    old: list[dict[str, str]] = []
    if csv_path.exists():
        with open(csv_path, newline="") as f:
            reader = csv.DictReader(f)
            if list(reader.fieldnames or []) != list(row):  # a curve of another column set: rewrite it in this one
                old = list(reader)
    if old:
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(row), extrasaction="ignore", restval="")
            w.writeheader()
            w.writerows(old)
    new = not csv_path.exists()
    with open(csv_path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(row))
        if new:
            w.writeheader()
        w.writerow(row)
    for k, v in row.items():
        if k != "steps":
            logger.record(f"eval_{split}/{k}", v)
