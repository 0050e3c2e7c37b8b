"""Bad input on the catalog side: a corrupt, locked or misplaced catalog gives one accurate error line, no traceback.

Every command runs through `curbside.cli.errors.run` (what the console script does), on real DuckDB files.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import duckdb
import numpy as np
import pytest

from tests.helpers import cli, one_error_line

BLOCK = 256 * 1024  # DuckDB's block size; data blocks follow a 12 KiB header and start with their checksum
HEADER = 3 * 4096


@pytest.fixture(scope="module")
def synthetic_catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real catalog of 200 assets with text embeddings (enough rows to span several DuckDB blocks)."""
    from catalogs.records import AssetRecord
    from catalogs.writer import CatalogWriter

    path = tmp_path_factory.mktemp("syn") / "syn.duckdb"
    recs = [
        AssetRecord(
            asset_id=f"a{i:03d}",
            source="procedural",
            source_id=f"a{i:03d}",
            category="bench",
            object_class="non_standard",
            zones=["furnishing"],
            depth=0.6,
            width=1.8,
            height=0.85,
            description=f"bench {i}",
            synonyms=["seat"],
            license="CC0-1.0",
        )
        for i in range(200)
    ]
    with CatalogWriter(path) as w:
        w.upsert_assets(recs)
        w.upsert_embeddings(
            "asset_text", [r.asset_id for r in recs], np.random.default_rng(0).normal(size=(len(recs), 384))
        )
    return path


def _corrupt_block(src: Path, dst: Path, block: int) -> None:
    shutil.copy(src, dst)
    with open(dst, "r+b") as fh:
        fh.seek(HEADER + block * BLOCK + 100)  # past the block's checksum: its content no longer matches it
        fh.write(b"\xff" * 16)


def _opens(path: Path) -> bool:
    try:
        con = duckdb.connect(str(path), read_only=True)
        con.execute("SELECT * FROM meta").fetchall()
        con.close()
        return True
    except duckdb.Error:
        return False


def _fails(path: Path, sql: str) -> bool:
    con = duckdb.connect(str(path), read_only=True)
    try:
        con.execute(sql).fetchall()
        return False
    except duckdb.Error:
        return True
    finally:
        con.close()


def _kind(path: Path) -> str | None:
    """Where a damaged block shows: on open, when the assets are read, or only when the vectors are read."""
    if not _opens(path):
        return "open"
    if _fails(path, "SELECT * FROM assets"):
        return "assets"
    if _fails(path, "SELECT sum(list_sum(vector::FLOAT[])) FROM embeddings"):
        return "embeddings"
    return None


@pytest.fixture(scope="module")
def corrupt(synthetic_catalog: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Checksum-corrupt copies: one that fails on open, one on reading assets, one on reading the vectors."""
    out: dict[str, Path] = {}
    d = tmp_path_factory.mktemp("corrupt")
    n_blocks = (synthetic_catalog.stat().st_size - HEADER) // BLOCK
    for b in range(n_blocks):
        cand = d / f"block{b}.duckdb"
        _corrupt_block(synthetic_catalog, cand, b)
        kind = _kind(cand)
        if kind and kind not in out:
            out[kind] = cand
    assert set(out) == {"open", "assets", "embeddings"}, f"found only {set(out)}"
    return out


@pytest.mark.parametrize("where", ["open", "assets"])
@pytest.mark.parametrize("cmd", [["stats"], ["stats", "--json"], ["export", "--format", "csv"], ["show", "a001"]])
def test_corrupt_catalog_is_one_line_naming_the_rebuild(capsys, corrupt, where: str, cmd: list[str]) -> None:
    path = corrupt[where]
    code, out, err = cli(["catalog", *cmd, "--catalog", str(path)], capsys)
    line = one_error_line(code, out, err)
    assert out == ""
    assert "corrupt" in line and str(path) in line and f"curbside catalog build --catalog {path}" in line
    assert "locked" not in line


@pytest.mark.parametrize("where", ["open", "embeddings"])
def test_corrupt_catalog_query(capsys, corrupt, where: str) -> None:
    code, out, err = cli(["catalog", "query", "bench", "--catalog", str(corrupt[where]), "--json"], capsys)
    line = one_error_line(code, out, err)
    assert out == "" and "corrupt" in line and "checksum" in line


@pytest.mark.parametrize("where", ["open", "assets", "embeddings"])
def test_validate_reports_corruption(capsys, corrupt, where: str) -> None:
    code, out, err = cli(["catalog", "validate", "--catalog", str(corrupt[where]), "--json"], capsys)
    assert code == 1 and "Traceback" not in err
    doc = json.loads(out)
    assert doc["ok"] is False
    catalog_problems = [p["reason"] for p in doc["problems"] if p["asset_id"] is None]
    assert len(catalog_problems) == 1 and "corrupt" in catalog_problems[0], doc["problems"]


def test_not_a_duckdb_file_and_not_a_catalog(capsys, tmp_path: Path) -> None:
    junk = tmp_path / "junk.duckdb"
    junk.write_text("hello")
    assert "not a DuckDB database file" in one_error_line(*cli(["catalog", "stats", "--catalog", str(junk)], capsys))
    other = tmp_path / "other.duckdb"
    con = duckdb.connect(str(other))
    con.execute("CREATE TABLE t (x INTEGER)")
    con.close()
    assert "not a curbside catalog" in one_error_line(*cli(["catalog", "stats", "--catalog", str(other)], capsys))


HOLD = """
import sys, time, duckdb
con = duckdb.connect(sys.argv[1])  # the write lock, as a running ingest holds it
print("ready", flush=True)
time.sleep(120)
"""


@pytest.fixture()
def locked(synthetic_catalog: Path, tmp_path: Path):
    """A copy of the catalog with another process holding its DuckDB write lock; yields (path, holder pid)."""
    path = tmp_path / "busy.duckdb"
    shutil.copy(synthetic_catalog, path)
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "ready"
        yield path, holder.pid
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.parametrize(
    "cmd",
    [["stats"], ["query", "bench"], ["validate"], ["export"], ["show", "a001"], ["ingest", "--source", "local:{dir}"]],
)
def test_locked_catalog_says_locked_not_rebuild(capsys, locked, tmp_path: Path, cmd: list[str]) -> None:
    path, pid = locked
    (tmp_path / "meshes").mkdir()
    cmd = [c.format(dir=tmp_path / "meshes") for c in cmd]
    code, out, err = cli(["catalog", *cmd, "--catalog", str(path)], capsys)
    line = one_error_line(code, out, err, exit_code=1)
    assert out == ""
    assert "locked" in line and f"process {pid}" in line and "retry" in line
    assert "rebuild" not in line and "corrupt" not in line and "catalog build" not in line
    # The holder's file is untouched: once it lets go, the catalog reads normally.


def test_export_to_an_existing_directory(capsys, synthetic_catalog: Path, tmp_path: Path) -> None:
    export = ["catalog", "export", "--catalog", str(synthetic_catalog)]
    line = one_error_line(*cli([*export, "--out", str(tmp_path)], capsys))
    assert "is a directory" in line and str(tmp_path / "assets.parquet") in line
    code, _, err = cli([*export, "--format", "xlsx"], capsys)
    assert code == 2 and "parquet" in err and "Traceback" not in err


# --- catalog ingest -------------------------------------------------------------------------------------------


@pytest.fixture()
def mesh_dir(tmp_path: Path) -> Path:
    """One good mesh (the ingest never gets far enough to need more)."""
    from tests.retrieval.conftest import bench_mesh

    d = tmp_path / "meshes"
    d.mkdir()
    bench_mesh().export(d / "a_bench.ply")
    return d


@pytest.mark.parametrize(
    ("option", "value", "words"),
    [
        ("--views", "0", "--views"),
        ("--views", "21", "--views"),
        ("--executor", "bogus", "'local', 'process', 'ray'"),
        ("--scorer", "resnet", "'aligned', 'imagenet', 'clip', 'blip', 'blip2', 'none'"),
        ("--calibration", "max", "'softmax', 'zscore', 'none'"),
        ("--limit", "0", "--limit"),
        ("--workers", "0", "--workers"),
    ],
)
def test_ingest_bad_option_is_refused_before_the_catalog(
    capsys, mesh_dir: Path, tmp_path: Path, option: str, value: str, words: str
) -> None:
    cat = tmp_path / "c.duckdb"
    code, _, err = cli(
        ["catalog", "ingest", "--source", f"local:{mesh_dir}", "--catalog", str(cat), option, value], capsys
    )
    assert code == 2 and words in err and "Traceback" not in err
    assert not cat.exists()  # the old code created it and recorded every asset as rejected (--views 0)


def test_cli_view_limit_is_the_renderer_limit() -> None:
    from curbside.cli.catalog_ingest import MAX_VIEWS
    from retrieval.render import MAX_VIEWS as RENDER_MAX

    assert MAX_VIEWS == RENDER_MAX


def test_ingest_objaverse_offline_is_one_line_and_leaves_no_catalog(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("CURBSIDE_OBJAVERSE_URL", "http://127.0.0.1:9")  # refuses connections, like no network
    cat = tmp_path / "c.duckdb"
    code, out, err = cli(
        [
            "catalog",
            "ingest",
            "--source",
            "objaverse",
            "--objaverse-cache",
            str(tmp_path / "cache"),
            "--catalog",
            str(cat),
            "--scorer",
            "none",
        ],
        capsys,
    )
    line = one_error_line(code, out, err, exit_code=1)
    assert "objaverse needs network access" in line and "--source local:DIR" in line
    assert not cat.exists() and not list(tmp_path.glob("c.duckdb*")) and not (tmp_path / "c_assets").exists()


def test_ingest_truncated_objaverse_annotations_names_the_file(capsys, tmp_path: Path, monkeypatch) -> None:
    import gzip

    monkeypatch.setenv("CURBSIDE_OBJAVERSE_URL", "http://127.0.0.1:9")
    lvis = tmp_path / "cache" / "hf-objaverse-v1" / "lvis-annotations.json.gz"
    lvis.parent.mkdir(parents=True)
    full = gzip.compress(json.dumps({"bench": [f"uid{i:05d}" for i in range(2000)]}).encode())
    lvis.write_bytes(full[: len(full) // 2])
    cat = tmp_path / "c.duckdb"
    code, out, err = cli(
        [
            "catalog",
            "ingest",
            "--source",
            "objaverse",
            "--objaverse-cache",
            str(tmp_path / "cache"),
            "--catalog",
            str(cat),
            "--scorer",
            "none",
        ],
        capsys,
    )
    line = one_error_line(code, out, err, exit_code=1)
    assert str(lvis) in line and "delete it" in line and "aborted" not in line.lower()
    assert not cat.exists()
