"""`curbside scenes`: Generate, render and collect urban scenes (scene specs as JSON)."""

from __future__ import annotations

import typer

app = typer.Typer(help="Generate, render and collect urban scenes (scene specs as JSON).", no_args_is_help=True)
