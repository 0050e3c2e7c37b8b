"""`curbside pool`: Inspect the description pool from the distribution pipeline."""

from __future__ import annotations

import typer

app = typer.Typer(help="Inspect the description pool from the distribution pipeline.", no_args_is_help=True)
