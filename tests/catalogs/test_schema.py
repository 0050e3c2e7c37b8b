"""The versioned schema: tables, FLOAT[n] embeddings, version recorded, other versions refused."""

from __future__ import annotations

from pathlib import Path

import duckdb
import pytest

from catalogs.reader import CatalogReader, open_catalog
from catalogs.schema import SCHEMA_VERSION, CatalogCorrupt, CatalogError, CatalogSchemaError, ddl
from catalogs.writer import CatalogWriter, build_catalog

TABLES = {"meta", "assets", "views", "descriptions", "matches", "embeddings", "rejections"}


def _set_version(path: Path, version: str) -> None:
    con = duckdb.connect(str(path))
    con.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", [version])
    con.close()


def test_new_catalog_has_every_table_and_records_version(tmp_path: Path) -> None:
    path = tmp_path / "c.duckdb"
    with build_catalog(path):
        pass
    con = open_catalog(path)
    tables = {r[0] for r in con.execute("SELECT table_name FROM information_schema.tables").fetchall()}
    meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
    vec_type = con.execute(
        "SELECT data_type FROM information_schema.columns WHERE table_name = 'embeddings' AND column_name = 'vector'"
    ).fetchone()[0]
    con.close()
    assert TABLES <= tables
    assert meta["schema_version"] == str(SCHEMA_VERSION)
    assert meta["embedding_dim"] == "384"
    assert vec_type == "FLOAT[384]"


def test_ddl_uses_requested_embedding_dim() -> None:
    assert any("FLOAT[512]" in s for s in ddl(512))


@pytest.mark.parametrize("version", [str(SCHEMA_VERSION + 1), "0", "not-a-number"])
def test_reader_and_writer_refuse_other_schema_version(tmp_path: Path, version: str) -> None:
    path = tmp_path / "c.duckdb"
    with build_catalog(path):
        pass
    _set_version(path, version)
    with pytest.raises(CatalogError, match="schema version") as err:
        CatalogReader(path)
    assert "curbside catalog build" in str(err.value)
    with pytest.raises(CatalogError, match="schema version"):
        CatalogWriter(path)


def test_missing_catalog_names_build_command(tmp_path: Path) -> None:
    with pytest.raises(CatalogError, match=r"curbside catalog build --catalog .*nope\.duckdb"):
        open_catalog(tmp_path / "nope.duckdb")


def test_non_catalog_files_are_refused(tmp_path: Path) -> None:
    junk = tmp_path / "junk.duckdb"
    junk.write_bytes(b"this is not a database")
    with pytest.raises(CatalogCorrupt, match="not a DuckDB database file"):
        open_catalog(junk)
    other = tmp_path / "other.duckdb"
    con = duckdb.connect(str(other))
    con.execute("CREATE TABLE t (x INTEGER)")
    con.close()
    with pytest.raises(CatalogSchemaError, match="not a curbside catalog"):
        open_catalog(other)
    with pytest.raises(CatalogError, match="directory"):
        open_catalog(tmp_path)
