"""`curbside experiment`: run the paper's experiments from their declarative files and report them beside the paper."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import typer

from curbside.cli.errors import fail
from curbside.cli.extras import require
from kernel.config import ConfigError

T = TypeVar("T")

app = typer.Typer(
    rich_markup_mode=None,
    help="Run the MetaUrban paper's experiments (Table 1, 2, 5, ablations, seeds) and report them.",
    no_args_is_help=True,
)


def _checked(name: str, budget: str, call: Callable[[], T]) -> T:
    """`call()` once the experiment file `name` and its `budget` are known to be valid; bad input of either, or a
    ConfigError from the call, is one line and exit 2."""
    from curbside.experiments.spec import budget_of, load_experiment

    try:
        budget_of(load_experiment(name), budget)
        return call()
    except (ConfigError, FileNotFoundError) as e:
        raise fail(str(e)) from None


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
    seeds: str | None = typer.Option(None, help="Comma-separated seeds to run (default: each run's)."),
    reevaluate: bool = typer.Option(
        False, help="Evaluate the finished runs again with the simulator as it is now (their training untouched)."
    ),
) -> None:
    """Train and evaluate every run of the experiment that has no result yet; a killed run resumes from its checkpoint."""
    require("train", "experiment run")
    from curbside.experiments.runner import run_experiment

    ids = [s for s in only.split(",") if s] if only else None

    def run() -> list[dict]:
        try:
            seed_list = [int(s) for s in seeds.split(",") if s.strip()] if seeds else None
        except ValueError:
            raise ConfigError(f"--seeds must be comma-separated integers such as 0,1,2, got {seeds!r}") from None
        return run_experiment(name, budget, root=root, only=ids, seeds=seed_list, reevaluate=reevaluate, log=typer.echo)

    results = _checked(name, budget, run)
    done = "evaluated again" if reevaluate else "finished"
    typer.echo(f"{len(results)} runs {done}; report them with `curbside experiment report {name} --budget {budget}`")


@app.command("report")
def report_cmd(
    name: str = typer.Argument(..., help="An experiment name or a path to a .yaml file."),
    budget: str = typer.Option("small", help="The budget whose runs to report."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where the runs are."),
    out: Path = typer.Option(
        Path("benchmarks/results"), help="Reports go to OUT/<experiment>/ (budget small) or OUT/<experiment>/<budget>/."
    ),
) -> None:
    """Write results.csv (ours beside the paper's numbers), summary.csv (mean and std over seeds) and results.png for
    the experiment's finished runs."""
    from curbside.experiments.report import write_report

    path = _checked(name, budget, lambda: write_report(name, budget, root=root, out_root=out))
    typer.echo(f"wrote {path}, {path.with_name('summary.csv')} and {path.with_suffix('.png')}")


@app.command("release")
def release_cmd(
    name: str = typer.Argument(..., help="An experiment name or a path to a .yaml file."),
    budget: str = typer.Option("small", help="The budget whose runs to release."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where the runs are."),
    zoo: Path = typer.Option(
        Path("policies"),
        help="Policies go to ZOO/<task>/<method>[-<setting>]/ (`paper`), ZOO/<protocol>/<task>/... (others).",
    ),
    seed: int = typer.Option(0, min=0, help="The seed whose policy to release."),
    only: str | None = typer.Option(None, help="Comma-separated run ids to release (default: every finished one)."),
) -> None:
    """Copy the experiment's finished policies into the policy zoo, each with a card.json; `curbside train eval
    ZOO/<task>/<method>` evaluates one."""
    require("train", "experiment release")
    from curbside.experiments.release import release

    ids = [s for s in only.split(",") if s] if only else None
    written = _checked(
        name, budget, lambda: release(name, budget, root=root, zoo=zoo, seed=seed, only=ids, log=typer.echo)
    )
    for path in written:
        typer.echo(f"released {path}")
    if not written:
        typer.echo(
            f"no policy of {name} at budget {budget} released: run `curbside experiment run {name} --budget "
            f"{budget}` first"
        )


@app.command("pack")
def pack_cmd(
    name: str = typer.Argument(..., help="An experiment name or a path to a .yaml file."),
    budget: str = typer.Option("small", help="The budget whose runs to pack."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where the runs are."),
    archive: Path = typer.Option(Path("benchmarks/runs"), help="Runs go to ARCHIVE/<experiment>/<budget>/."),
) -> None:
    """Copy what each started run needs to go on (a finished run's result and policy, an unfinished run's newest
    checkpoint) into ARCHIVE, so that another machine continues the experiment after `curbside experiment unpack`."""
    require("train", "experiment pack")
    from curbside.experiments.archive import pack

    written = _checked(name, budget, lambda: pack(name, budget, root=root, archive=archive))
    for path in written:
        state = "finished" if (path / "result.json").is_file() else "to resume"
        typer.echo(f"packed {path} ({state})")
    if not written:
        typer.echo(f"no run of {name} at budget {budget} has started under {root}; nothing packed")


@app.command("unpack")
def unpack_cmd(
    name: str = typer.Argument(..., help="An experiment name or a path to a .yaml file."),
    budget: str = typer.Option("small", help="The budget whose runs to unpack."),
    root: Path = typer.Option(Path("outputs/experiments"), help="Where the runs train and keep their results."),
    archive: Path = typer.Option(Path("benchmarks/runs"), help="Where `curbside experiment pack` put the runs."),
) -> None:
    """Put the packed runs of the experiment back under ROOT where ROOT holds none of them yet; `curbside experiment
    run` then skips the finished ones and resumes the others."""
    from curbside.experiments.archive import unpack

    restored, kept = _checked(name, budget, lambda: unpack(name, budget, root=root, archive=archive))
    for path in restored:
        typer.echo(f"restored {path}")
    for path in kept:
        typer.echo(f"kept {path} (it holds that run already)")
    if not restored and not kept:
        typer.echo(f"{archive} holds no packed run of {name} at budget {budget}")


@app.command("findings")
def findings_cmd(
    results: Path = typer.Option(Path("benchmarks/results"), help="Folder of the experiments' reports."),
) -> None:
    """Check the paper's ten findings on the reports under RESULTS and write RESULTS/findings.json."""
    from curbside.experiments.findings import write_findings

    if not results.is_dir():
        raise fail(f"{results} is not a folder; pass the folder that `curbside experiment report` writes to")
    path = write_findings(results)
    data = json.loads(path.read_text())
    for f in data["findings"]:
        state = {True: "reproduced", False: "not reproduced", None: "not run"}[f["reproduced"]]
        typer.echo(f"{f['finding']:2d}. {state:15} {f['claim']}")
    typer.echo(f"{data['reproduced']} of 10 reproduced, {data['not_run']} not run yet; wrote {path}")
