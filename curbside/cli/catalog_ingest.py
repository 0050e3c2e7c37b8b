"""`curbside catalog ingest` and `curbside catalog eval`: the retrieval pipeline's commands (registered on the catalog group)."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    """Add the retrieval commands to the `catalog` group."""
