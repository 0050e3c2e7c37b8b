"""Catalog summaries and exports (stats per category/class/source/licence; parquet, csv, jsonl) in DuckDB."""

from __future__ import annotations

from pathlib import Path

import duckdb

from catalogs.reader import first_value, read_meta

EXPORT_FORMATS = {"parquet": "(FORMAT parquet)", "csv": "(FORMAT csv, HEADER true)", "jsonl": "(FORMAT json)"}


def catalog_stats(con: duckdb.DuckDBPyConnection) -> dict:
    """Counts of assets per category, object class, source and licence, plus table sizes and metadata."""
    meta = read_meta(con)

    def counts(column: str) -> dict[str, int]:
        rows = con.execute(f"SELECT {column}, count(*) FROM assets GROUP BY 1 ORDER BY 2 DESC, 1").fetchall()
        return {str(k): int(v) for k, v in rows}

    tables = {
        t: int(first_value(con.execute(f"SELECT count(*) FROM {t}").fetchone()))
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
    return int(first_value(con.execute("SELECT count(*) FROM assets").fetchone()))


def dump_catalog(catalog_path: str | Path, out_dir: str | Path) -> list[str]:
    """Write every table of a catalog as `out_dir/<table>.parquet`, rows sorted: the catalog's bytes-stable record.

    A DuckDB file is not byte-reproducible (each file gets a random identifier, and block contents vary), so DVC
    tracks this dump instead of the .duckdb: equal catalogs give equal dumps. Returns the table names.
    """
    import shutil

    from kernel.reproducible import write_parquet

    out_dir = Path(out_dir)
    if out_dir.exists():
        shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True)
    con = duckdb.connect(str(catalog_path), read_only=True)
    try:
        names = sorted(r[0] for r in con.execute("SELECT table_name FROM information_schema.tables").fetchall())
        for name in names:
            write_parquet(con.sql(f'SELECT * FROM "{name}" ORDER BY ALL').to_arrow_table(), out_dir / f"{name}.parquet")
    finally:
        con.close()
    return names
