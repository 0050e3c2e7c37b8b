"""`curbside pool`: Inspect the description pool from the distribution pipeline."""

from __future__ import annotations

import typer

from curbside.cli.errors import UsageError
from curbside.cli.extras import require

app = typer.Typer(
    rich_markup_mode=None, help="Inspect the description pool from the distribution pipeline.", no_args_is_help=True
)

DEFAULT_POOL = "data/pool/pool.parquet"
POOL_COLUMNS = ("cluster_id", "text", "category", "count", "n_members", "members", "sources", "country_counts")


@app.command("show")
def show(
    country: str = typer.Option(
        None, "--country", help="ISO 3166-1 alpha-2 code: rank clusters by this country's count."
    ),
    top: int = typer.Option(20, "--top", min=1, help="Number of clusters to list."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
    pool: str = typer.Option(DEFAULT_POOL, "--pool", help="Path of pool.parquet (written by `dvc repro`)."),
) -> None:
    """List the largest description-pool clusters (overall or for one country)."""
    require("pipelines", "pool show", ("pandas",))
    import json
    from pathlib import Path

    import pandas as pd

    from pipelines.countries import check_country

    if not Path(pool).exists():
        raise UsageError(f"{pool} not found; run `DVC_NO_ANALYTICS=1 dvc repro` first, or pass --pool PATH")
    df = pd.read_parquet(pool)
    missing = [c for c in POOL_COLUMNS if c not in df.columns]
    if missing:
        raise UsageError(
            f"{pool} is not a description pool (no column {', '.join(missing)}); pass the pool.parquet "
            "that `DVC_NO_ANALYTICS=1 dvc repro` writes"
        )
    counts = [json.loads(c) for c in df["country_counts"]]
    if country:
        try:
            code = check_country(country, where="--country")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        present = sorted({k for c in counts for k, n in c.items() if n > 0})
        if code not in present:
            # An empty table with exit 0 reads as "this country has no street objects"; it means no data.
            raise UsageError(
                f"--country {code}: the pool {pool} has no descriptions from {code}; countries present: "
                f"{', '.join(present) or 'none'} (add {code}'s sources to the pipelines and "
                f"`dvc repro` to include it)"
            )
        df = df.assign(rank_count=[c.get(code, 0) for c in counts])
        df = df[df["rank_count"] > 0]
    else:
        df = df.assign(rank_count=df["count"])
    df = df.sort_values(["rank_count", "cluster_id"], ascending=[False, True]).head(top)
    # Open-vocabulary entries have no category (pandas reads the NULL as NaN): None in JSON, "(open)" in the table.
    rows = [
        {
            "cluster_id": int(r.cluster_id),
            "text": r.text,
            "category": r.category if isinstance(r.category, str) else None,
            "count": int(r.rank_count),
            "n_members": int(r.n_members),
            "members": list(r.members)[:5],
            "sources": list(r.sources),
            "country_counts": json.loads(r.country_counts),
        }
        for r in df.itertuples()
    ]
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"description pool{' - ' + code if country else ''}: top {len(rows)}")
    for col in ("id", "representative", "category", "count", "members", "sources", "example members"):
        table.add_column(col)
    for r in rows:
        table.add_row(
            str(r["cluster_id"]),
            r["text"],
            r["category"] or "(open)",
            str(r["count"]),
            str(r["n_members"]),
            ",".join(r["sources"]),
            "; ".join(r["members"][1:4]),
        )
    Console().print(table)
