"""`curbside catalog`: Build, search, inspect and validate the DuckDB asset catalog."""

from __future__ import annotations

import typer

app = typer.Typer(help="Build, search, inspect and validate the DuckDB asset catalog.", no_args_is_help=True)
