"""Catalog summaries and exports (stats per category/class/source/licence; parquet, csv, jsonl) in DuckDB."""

from __future__ import annotations

from pathlib import Path

import duckdb

EXPORT_FORMATS = {"parquet": "(FORMAT parquet)", "csv": "(FORMAT csv, HEADER true)", "jsonl": "(FORMAT json)"}


def catalog_stats(con: duckdb.DuckDBPyConnection) -> dict:
    """Counts of assets per category, object class, source and licence, plus table sizes and metadata."""
    meta = dict(con.execute("SELECT key, value FROM meta").fetchall())

    def counts(column: str) -> dict[str, int]:
        rows = con.execute(f"SELECT {column}, count(*) FROM assets GROUP BY 1 ORDER BY 2 DESC, 1").fetchall()
        return {str(k): int(v) for k, v in rows}

    tables = {
        t: int(con.execute(f"SELECT count(*) FROM {t}").fetchone()[0])
        for t in ("assets", "views", "descriptions", "matches", "embeddings", "rejections")
    }
    return {
        "schema_version": int(meta.get("schema_version", -1)),
        "embedding_model": meta.get("embedding_model"),
        "embedding_dim": int(meta.get("embedding_dim", 0)),
        "tables": tables,
        "category": counts("category"),
        "object_class": counts("object_class"),
        "source": counts("source"),
        "license": counts("license"),
    }


def export_assets(con: duckdb.DuckDBPyConnection, fmt: str, out: str | Path) -> int:
    """Write the assets table to `out` as parquet, csv or jsonl; returns the number of rows."""
    if fmt not in EXPORT_FORMATS:
        raise ValueError(f"unknown export format {fmt!r}; choose one of {', '.join(EXPORT_FORMATS)}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    # COPY takes no bound parameter for its target, so the path is quoted as a SQL string literal.
    target = "'" + str(out).replace("'", "''") + "'"
    con.execute(f"COPY (SELECT * FROM assets ORDER BY asset_id) TO {target} {EXPORT_FORMATS[fmt]}")
    return int(con.execute("SELECT count(*) FROM assets").fetchone()[0])
