"""`curbside sim`: Run, evaluate, render and benchmark the PyBullet simulator."""

from __future__ import annotations

import typer

app = typer.Typer(help="Run, evaluate, render and benchmark the PyBullet simulator.", no_args_is_help=True)
