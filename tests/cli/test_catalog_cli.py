"""`curbside catalog ...` on a real small catalog (one procedural variant per category, MiniLM embeddings)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import duckdb
import pytest
from typer.testing import CliRunner

from catalogs.reader import CatalogReader
from curbside.cli.main import app
from tests.helpers import cli, one_error_line

runner = CliRunner()
REPO = Path(__file__).resolve().parents[2]


def run(*args: str):
    """Invoke `curbside catalog ARGS` in-process (the MiniLM model stays loaded between calls)."""
    return runner.invoke(app, ["catalog", *args])


def query_json(catalog: Path, text: str, *extra: str) -> dict:
    res = run("query", text, "--catalog", str(catalog), "--json", *extra)
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_fire_hydrant_first(small_catalog: Path) -> None:
    doc = query_json(small_catalog, "fire hydrant", "--limit", "5")
    assert doc["count"] == 5 and len(doc["results"]) == 5
    assert doc["results"][0]["category"] == "fire_hydrant"
    scores = [r["score"] for r in doc["results"]]
    assert scores == sorted(scores, reverse=True)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("somewhere to sit", "bench"),
        ("garbage can", "trash_bin"),
        ("street light", "street_lamp"),
        ("lamp post", "street_lamp"),
        ("traffic cone", "traffic_cone"),
        ("postbox", "mailbox"),
    ],
)
def test_paraphrases_find_the_right_category(small_catalog: Path, text: str, expected: str) -> None:
    assert query_json(small_catalog, text)["results"][0]["category"] == expected


def test_filters(small_catalog: Path) -> None:
    doc = query_json(small_catalog, "something on the sidewalk", "--object-class", "clutter", "--limit", "50")
    assert doc["results"] and all(r["object_class"] == "clutter" for r in doc["results"])
    doc = query_json(small_catalog, "street light", "--max-height", "1.5", "--limit", "50")
    assert doc["results"] and all(r["height"] <= 1.5 for r in doc["results"])
    assert "street_lamp" not in {r["category"] for r in doc["results"]}
    doc = query_json(small_catalog, "seat", "--category", "bench", "--source", "procedural", "--license", "CC0-1.0")
    assert [r["category"] for r in doc["results"]] == ["bench"]
    reader = CatalogReader(small_catalog)
    doc = query_json(small_catalog, "bin", "--zone", "frontage", "--limit", "50")
    assert doc["results"] and all("frontage" in reader.get(r["asset_id"]).zones for r in doc["results"])
    assert doc["filters"] == {"zone": "frontage"}


def test_sql_in_query_text_is_plain_text(small_catalog: Path) -> None:
    evil = "'; DROP TABLE assets; --"
    assert query_json(small_catalog, evil)["count"] > 0
    doc = query_json(small_catalog, evil, "--category", evil)
    assert doc["count"] == 0 and "no category" in doc["message"]
    con = duckdb.connect(str(small_catalog), read_only=True)
    assert con.execute("SELECT count(*) FROM assets").fetchone()[0] == len(CatalogReader(small_catalog))
    con.close()


def test_empty_result_says_so(small_catalog: Path) -> None:
    res = run("query", "bench", "--catalog", str(small_catalog), "--max-height", "0.001")
    assert res.exit_code == 0
    assert "no asset matches" in res.stdout and "max_height" in res.stdout
    doc = query_json(small_catalog, "bench", "--max-height", "0.001")
    assert doc["results"] == [] and "no asset matches" in doc["message"]


def test_bad_filter_values_are_explained(small_catalog: Path) -> None:
    res = run("query", "bench", "--catalog", str(small_catalog), "--zone", "sidewalk")
    assert res.exit_code != 0 and "furnishing" in res.stderr
    res = run("query", "bench", "--catalog", str(small_catalog), "--object-class", "furniture")
    assert res.exit_code != 0 and "non_standard" in res.stderr


@pytest.mark.parametrize("cmd", [["query", "bench"], ["stats"], ["show", "x"], ["export"], ["validate"]])
def test_missing_catalog_names_the_build_command(capsys, tmp_path: Path, cmd: list[str]) -> None:
    missing = tmp_path / "none.duckdb"
    code, out, err = cli(["catalog", *cmd, "--catalog", str(missing)], capsys)
    line = one_error_line(code, out, err)  # exit 2: a missing file the user named is bad input
    assert f"curbside catalog build --catalog {missing}" in line and out == ""


def test_stats(small_catalog: Path) -> None:
    res = run("stats", "--catalog", str(small_catalog), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    n = len(CatalogReader(small_catalog))
    assert n >= 30
    assert doc["tables"]["assets"] == n and doc["tables"]["embeddings"] == n
    assert all(v == 1 for v in doc["category"].values()) and len(doc["category"]) == n
    assert set(doc["object_class"]) == {"standard", "non_standard", "clutter"}
    assert doc["source"] == {"procedural": n} and doc["license"] == {"CC0-1.0": n}
    res = run("stats", "--catalog", str(small_catalog))
    assert res.exit_code == 0 and "fire_hydrant" in res.stdout


def test_show(capsys, small_catalog: Path) -> None:
    asset_id = query_json(small_catalog, "fire hydrant")["results"][0]["asset_id"]
    res = run("show", asset_id, "--catalog", str(small_catalog), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["asset_id"] == asset_id and doc["category"] == "fire_hydrant"
    assert Path(doc["mesh_path_resolved"]).is_file()
    line = one_error_line(*cli(["catalog", "show", "no/such/asset", "--catalog", str(small_catalog)], capsys))
    assert "no/such/asset" in line and "catalog query" in line


@pytest.mark.parametrize("fmt", ["parquet", "csv", "jsonl"])
def test_export(small_catalog: Path, tmp_path: Path, fmt: str) -> None:
    out = tmp_path / f"assets.{fmt}"
    res = run("export", "--catalog", str(small_catalog), "--format", fmt, "--out", str(out))
    assert res.exit_code == 0, res.output
    reader = {"parquet": "read_parquet", "csv": "read_csv", "jsonl": "read_json"}[fmt]
    rows = duckdb.sql(f"SELECT asset_id, category FROM {reader}('{out}') ORDER BY asset_id").fetchall()
    assert [r[0] for r in rows] == sorted(CatalogReader(small_catalog).table.asset_id)
    res = run("export", "--catalog", str(small_catalog), "--format", "xlsx", "--out", str(out))
    assert res.exit_code != 0 and "parquet" in res.stderr


def test_validate_passes_on_built_catalog(small_catalog: Path) -> None:
    res = run("validate", "--catalog", str(small_catalog), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["ok"] and doc["assets_checked"] == len(CatalogReader(small_catalog))


def test_validate_reports_corrupt_and_missing_meshes(small_catalog: Path, copy_catalog) -> None:
    cat = copy_catalog(small_catalog)
    reader = CatalogReader(cat)
    broken, gone = sorted(reader.table.asset_id)[:2]
    reader.resolve(reader.get(broken).mesh_path).write_text("v 0 0 0\nnot an obj\n")
    reader.resolve(reader.get(gone).mesh_path).unlink()
    res = run("validate", "--catalog", str(cat), "--json")
    assert res.exit_code == 1
    problems = json.loads(res.stdout)["problems"]
    assert {p["asset_id"] for p in problems} == {broken, gone}
    assert any(p["asset_id"] == gone and "mesh file missing" in p["reason"] for p in problems)
    assert any(p["asset_id"] == broken and "does not load" in p["reason"] for p in problems)
    res = run("validate", "--catalog", str(cat))
    assert res.exit_code == 1 and broken in res.stdout and gone in res.stdout


def test_json_stdout_is_one_document_in_a_real_process(small_catalog: Path) -> None:
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "COLUMNS": "80"}
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "curbside.cli.main",
            "catalog",
            "query",
            "fire hydrant",
            "--json",
            "--limit",
            "5",
            "--catalog",
            str(small_catalog),
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)  # raises if anything else reached stdout
    assert doc["results"][0]["category"] == "fire_hydrant"
