"""`curbside catalog`: Build, search, inspect and validate the DuckDB asset catalog."""

from __future__ import annotations

import typer

app = typer.Typer(help="Build, search, inspect and validate the DuckDB asset catalog.", no_args_is_help=True)

# The retrieval pipeline's commands live in their own module; registered last so they list after the core ones.
from curbside.cli import catalog_ingest  # noqa: E402

catalog_ingest.register(app)
