"""Shared plumbing of the pipeline stages: strict params, parquet and metrics output, progress, stage CLIs."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from curbside.config import ConfigError, merge_strict

REPO_ROOT = Path(__file__).resolve().parent.parent
CLOSED_SET_DIR = REPO_ROOT / "catalogs" / "closed_set"
DEFAULT_PARAMS = REPO_ROOT / "params.yaml"


class PipelineError(ValueError):
    """Bad pipeline input (a file, a column, a code); the message names the problem and the fix."""


def load_params(path: str | Path | None, section: str, defaults: Mapping[str, Any]) -> dict[str, Any]:
    """Read `section` of a params.yaml and merge it strictly over the stage's `defaults`."""
    import yaml

    p = Path(path) if path else DEFAULT_PARAMS
    if not p.exists():
        raise PipelineError(f"params file {p} not found; pass --params with the path of params.yaml")
    data = yaml.safe_load(p.read_text()) or {}
    try:
        return merge_strict(defaults, data.get(section) or {}, name=f"{p.name}:{section}")
    except ConfigError as exc:
        raise PipelineError(str(exc)) from None


def write_table(df: Any, path: str | Path) -> Path:
    """Write a pandas DataFrame as parquet (creating the folder), without the pandas index."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    df.to_parquet(p, index=False)
    return p


def write_metrics(path: str | Path, metrics: Mapping[str, Any]) -> Path:
    """Write a flat metrics JSON (sorted keys so re-runs are byte-identical) for `dvc metrics show`."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(dict(metrics), indent=2, sort_keys=True) + "\n")
    return p


def progress():  # noqa: ANN201 - rich.progress.Progress, imported lazily
    """A rich progress bar with a counter and elapsed time (transient so logs stay readable)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        transient=True,
    )


def stage_cli(name: str, run: Callable[[str], Mapping[str, Any]]) -> None:
    """Run a stage from the command line: `python -m pipelines.<name> --params params.yaml`."""
    import typer

    def main(params: str = typer.Option(str(DEFAULT_PARAMS), "--params", help="Path of params.yaml.")) -> None:
        try:
            metrics = run(params)
        except PipelineError as exc:
            typer.secho(f"{name}: {exc}", fg="red", err=True)
            raise typer.Exit(2) from None
        typer.echo(f"{name}: " + ", ".join(f"{k}={v}" for k, v in sorted(metrics.items())))

    typer.run(main)
