"""Shared plumbing of the pipeline stages: strict params, parquet and metrics output, progress, stage CLIs."""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from kernel.config import ConfigError, load_yaml, merge_strict
from kernel.reproducible import quiet_third_party, write_frame

REPO_ROOT = Path(__file__).resolve().parent.parent
CLOSED_SET_DIR = REPO_ROOT / "catalogs" / "closed_set"
DEFAULT_PARAMS = REPO_ROOT / "params.yaml"


class PipelineError(ValueError):
    """Bad pipeline input (a file, a column, a code); the message names the problem and the fix."""


def _read_params(p: Path) -> dict[str, Any]:
    """The mapping a params file holds (empty for an empty file); PipelineError when it is missing or not YAML."""
    if not p.exists():
        raise PipelineError(f"params file {p} not found; pass --params with the path of params.yaml")
    try:
        data = load_yaml(p.read_text(), str(p)) or {}
    except ConfigError as exc:
        raise PipelineError(str(exc)) from None
    if not isinstance(data, Mapping):
        raise PipelineError(f"params file {p} must be a mapping of stage sections, got {type(data).__name__}")
    return dict(data)


def stage_defaults(section: str) -> dict[str, Any]:
    """The defaults of a stage: its section of the repo's params.yaml (DEFAULT_PARAMS), the one declaration."""
    declared = _read_params(DEFAULT_PARAMS).get(section)
    if not isinstance(declared, Mapping) or not declared:
        raise PipelineError(f"{DEFAULT_PARAMS.name} declares no section {section!r}; add its keys there")
    return dict(declared)


def load_params(path: str | Path | None, section: str) -> dict[str, Any]:
    """Read `section` of a params file and merge it strictly over the stage's defaults (`stage_defaults`)."""
    p = Path(path) if path else DEFAULT_PARAMS
    data = _read_params(p)
    try:
        return merge_strict(stage_defaults(section), data.get(section) or {}, name=f"{p.name}:{section}")
    except ConfigError as exc:
        raise PipelineError(str(exc)) from None


def write_table(df: Any, path: str | Path) -> Path:
    """Write a DataFrame as parquet, no index or pandas metadata: equal frames give equal bytes."""
    return write_frame(df, path)


def write_metrics(path: str | Path, metrics: Mapping[str, Any]) -> Path:
    """Write a flat metrics JSON (sorted keys so re-runs are byte-identical) for `dvc metrics show`."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(dict(metrics), indent=2, sort_keys=True) + "\n")
    return p


def progress():  # noqa: ANN201 - rich.progress.Progress, imported lazily
    """A rich progress bar with a counter and elapsed time (transient; off when stderr is not a terminal)."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )


def die_with_parent() -> None:
    """End this process when its parent (dvc, or the shell that ran it) dies, even by SIGKILL (Linux prctl)."""
    from kernel.executors import die_with_parent as _die_with_parent

    _die_with_parent(os.getppid())


def stage_cli(name: str, run: Callable[[str], Mapping[str, Any]]) -> None:
    """Run a stage from the command line: `python -m pipelines.<name> --params params.yaml`."""
    import typer
    from rich.console import Console

    def main(params: str = typer.Option(str(DEFAULT_PARAMS), "--params", help="Path of params.yaml.")) -> None:
        die_with_parent()
        quiet_third_party()
        try:
            metrics = run(params)
        except PipelineError as exc:
            typer.secho(f"{name}: {exc}", fg="red", err=True)
            raise typer.Exit(2) from None
        summary = ", ".join(f"{k}={v}" for k, v in sorted(metrics.items()))
        Console(highlight=False, soft_wrap=True).print(f"[bold]{name}[/bold]: {summary}")

    typer.run(main)
