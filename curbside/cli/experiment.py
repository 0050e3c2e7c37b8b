"""`curbside experiment`: run the paper's experiments from their declarative files and report them beside the paper."""

from __future__ import annotations

from pathlib import Path

import typer

from curbside.cli.errors import fail
from curbside.cli.extras import require
from kernel.config import ConfigError

app = typer.Typer(rich_markup_mode=None, help="Run the MetaUrban paper's experiments (Table 1, 2, 5, ablations, seeds) and report them.",
                  no_args_is_help=True)


@app.command("list")
def list_cmd() -> None:
    """The experiments curbside ships, with their runs."""
    from curbside.experiments.spec import load_experiment, names

    for name in names():
        exp = load_experiment(name)
        seeds = sum(len(r.seeds) for r in exp.runs)
        typer.echo(f"{name:26} {exp.title} ({len(exp.runs)} runs, {seeds} trainings, protocol {exp.protocol})")


@app.command("run")
def run_cmd(
    name: str = typer.Argument(..., help="An experiment name (`curbside experiment list`) or a path to a .yaml file."),
    budget: str = typer.Option("small", help="smoke (minutes: the plumbing), small (one working session), paper."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where runs train and keep their results."),
    only: str | None = typer.Option(None, help="Comma-separated run ids to run (default: all)."),
) -> None:
    """Train and evaluate every run of the experiment that has no result yet; a killed run resumes from its checkpoint."""
    require("train", "experiment run")
    from curbside.experiments.runner import run_experiment
    from curbside.experiments.spec import budget_of, load_experiment

    try:
        budget_of(load_experiment(name), budget)
        ids = [s for s in only.split(",") if s] if only else None
        results = run_experiment(name, budget, root=root, only=ids, log=typer.echo)
    except (ConfigError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    typer.echo(f"{len(results)} runs finished; report them with `curbside experiment report {name} --budget {budget}`")


@app.command("report")
def report_cmd(
    name: str = typer.Argument(..., help="An experiment name or a path to a .yaml file."),
    budget: str = typer.Option("small", help="The budget whose runs to report."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where the runs are."),
    out: Path = typer.Option(Path("benchmarks/results"), help="Reports go to OUT/<experiment>/."),
) -> None:
    """Write results.csv (ours beside the paper's numbers) and results.png for the experiment's finished runs."""
    from curbside.experiments.report import write_report
    from curbside.experiments.spec import budget_of, load_experiment

    try:
        budget_of(load_experiment(name), budget)
        path = write_report(name, budget, root=root, out_root=out)
    except (ConfigError, FileNotFoundError) as e:
        raise fail(str(e)) from None
    typer.echo(f"wrote {path} and {path.with_suffix('.png')}")
