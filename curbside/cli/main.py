"""Entry point of the `curbside` command; each subsystem adds its own group module (heavy imports stay inside commands)."""

from __future__ import annotations

import typer

from curbside import __version__
from curbside.cli import catalog, experiment, pool, scenes, sim, train
from curbside.cli.errors import run

app = typer.Typer(
    rich_markup_mode=None,  # plain click help: wraps at any width, and [extras] in help stay literal
    name="curbside",
    help="curbside: urban micromobility research platform: data pipelines, asset catalog, scenes, simulator.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
)
app.add_typer(catalog.app, name="catalog")
app.add_typer(scenes.app, name="scenes")
app.add_typer(sim.app, name="sim")
app.add_typer(pool.app, name="pool")
app.add_typer(train.app, name="train")
app.add_typer(train.demos_app, name="demos")
app.add_typer(experiment.app, name="experiment")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"curbside {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
    debug: bool = typer.Option(False, "--debug", help="Show the full traceback of an error (also CURBSIDE_DEBUG=1)."),
) -> None:
    """curbside: urban micromobility research platform."""


def cli() -> None:
    """The `curbside` console script: the app with one error line per failure (curbside.cli.errors)."""
    raise SystemExit(run(typer.main.get_command(app)))


if __name__ == "__main__":
    cli()
