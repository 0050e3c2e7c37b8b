"""embed + cluster (real MiniLM, DBSCAN) -> pool, catalog upsert, distribution, the `pool show` CLI, dvc.yaml."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from pipelines.cluster import build_pool, write_pool_to_catalog
from pipelines.distribution import compute_distribution, load_distribution
from pipelines.embed import embed_texts, load_embeddings, save_embeddings
from tests.helpers import cli, one_error_line

ROWS = [
    ("a green trash bin", "trash_bin", "images", "JP", 3),
    ("a green rubbish bin", "trash_bin", "osm", "JP", 2),
    ("a green trash can", "trash_bin", "osm", "FI", 1),
    ("a street lamp", "street_lamp", "osm", "FI", 5),
    ("a street light", "street_lamp", "closed_set", None, 1),
    ("a red fire hydrant", "fire_hydrant", "osm", "FI", 2),
]


@pytest.fixture(scope="module")
def descriptions():
    return pd.DataFrame(ROWS, columns=["text", "category", "source", "country", "count"]).astype({"country": "string"})


@pytest.fixture(scope="module")
def embedded(descriptions, tmp_path_factory):
    texts = sorted(set(descriptions["text"]))
    vecs, name = embed_texts(texts)
    path = save_embeddings(tmp_path_factory.mktemp("emb") / "e.parquet", texts, vecs, name)
    return load_embeddings(path)


def test_pool_clusters_paraphrases(descriptions, embedded):
    texts, vecs, model = embedded
    assert model == "all-MiniLM-L6-v2" and vecs.shape == (6, 384)
    pool = build_pool(descriptions, texts, vecs, eps=0.3, min_samples=2)
    by_text = {m: r for r in pool.itertuples() for m in r.members}
    assert by_text["a green trash bin"].cluster_id == by_text["a green rubbish bin"].cluster_id
    assert by_text["a street lamp"].cluster_id == by_text["a street light"].cluster_id
    assert by_text["a street lamp"].cluster_id != by_text["a red fire hydrant"].cluster_id
    bins = by_text["a green trash bin"]
    assert bins.category == "trash_bin" and json.loads(bins.country_counts)["JP"] == 5
    assert pool["count"].sum() == descriptions["count"].sum() and pool["cluster_id"].tolist() == list(range(len(pool)))
    lamps = by_text["a street lamp"]
    assert set(lamps.sources) == {"osm", "closed_set"} and lamps.text == "a street lamp"


def test_pool_to_catalog(descriptions, embedded, tmp_path):
    import duckdb

    texts, vecs, _ = embedded
    pool = build_pool(descriptions, texts, vecs, eps=0.3, min_samples=2)
    assert write_pool_to_catalog(pool, tmp_path / "c.duckdb") == len(pool)
    con = duckdb.connect(str(tmp_path / "c.duckdb"))
    assert con.execute("SELECT count(*) FROM descriptions").fetchone()[0] == len(pool)


def test_distribution_sums_to_one(descriptions, tmp_path):
    df = compute_distribution(descriptions, ["osm", "images"])
    assert list(df.columns) == ["country", "category", "count", "frequency"]
    sums = df.groupby("country")["frequency"].sum()
    assert sums.to_dict() == pytest.approx({"FI": 1.0, "GLOBAL": 1.0, "JP": 1.0})
    df.to_parquet(tmp_path / "d.parquet", index=False)
    assert load_distribution("jp", tmp_path / "d.parquet") == {"trash_bin": 1.0}
    assert load_distribution("GLOBAL", tmp_path / "d.parquet")["street_lamp"] == pytest.approx(5 / 13)
    with pytest.raises(KeyError, match="available: FI, GLOBAL, JP"):
        load_distribution("BR", tmp_path / "d.parquet")


def test_pool_show_cli(descriptions, embedded, tmp_path):
    from typer.testing import CliRunner

    from curbside.cli.main import app

    texts, vecs, _ = embedded
    build_pool(descriptions, texts, vecs, eps=0.3, min_samples=2).to_parquet(tmp_path / "p.parquet")
    res = CliRunner().invoke(app, ["pool", "show", "--pool", str(tmp_path / "p.parquet"), "--country", "JP", "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.output)
    assert len(rows) == 1 and rows[0]["category"] == "trash_bin" and rows[0]["count"] == 5
    bad = CliRunner().invoke(app, ["pool", "show", "--pool", str(tmp_path / "p.parquet"), "--country", "XX"])
    assert bad.exit_code != 0


def test_pool_show_country_absent_from_the_pool(descriptions, embedded, tmp_path, capsys):
    """A valid country the pool lacks is an error naming the countries present, not an empty table."""
    texts, vecs, _ = embedded
    build_pool(descriptions, texts, vecs, eps=0.3, min_samples=2).to_parquet(tmp_path / "p.parquet")
    argv = ["pool", "show", "--pool", str(tmp_path / "p.parquet")]
    for bad, words in (
        (["--country", "US"], "countries present: FI, JP"),
        (["--country", "XX"], "ISO 3166-1"),
        (["--pool", str(tmp_path / "none.parquet")], "dvc repro"),
    ):
        assert words in one_error_line(*cli([*argv, *bad], capsys))


STAGES = ["closed_set", "osm", "detect", "describe", "embed", "cluster", "distribution"]


def _keys_read(module: str) -> set[str]:
    """The params keys a stage's `run` reads: every `p["key"]` on the dict `load_params` returned."""
    import ast
    import importlib
    import inspect

    tree = ast.parse(inspect.getsource(importlib.import_module(f"pipelines.{module}")))
    run = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "run")
    return {
        n.slice.value
        for n in ast.walk(run)
        if isinstance(n, ast.Subscript)
        and isinstance(n.value, ast.Name)
        and n.value.id == "p"
        and isinstance(n.slice, ast.Constant)
    }


def test_dvc_yaml_stages_match_modules_and_params():
    """Each stage is a dvc.yaml stage reading its params.yaml section, and every key it reads is declared there
    (and every declared key is read: a declared parameter nothing reads would be silently ignored)."""
    import yaml

    from pipelines.common import REPO_ROOT

    stages = yaml.safe_load((REPO_ROOT / "dvc.yaml").read_text())["stages"]
    params = yaml.safe_load((REPO_ROOT / "params.yaml").read_text())
    assert list(stages) == STAGES and list(params) == STAGES
    for name, st in stages.items():
        assert st["cmd"] == f"${{portable}} python -m pipelines.{name} --params params.yaml"
        assert st["params"] == [name] and st["metrics"], name
        read = _keys_read(name)
        assert read, f"pipelines.{name}.run reads no p[...] key: the check has lost track of the stage"
        assert read == set(params[name]), (name, sorted(read ^ set(params[name])))


def test_params_files_merge_strictly_over_params_yaml(tmp_path):
    """A given params file's section merges over the repo's params.yaml: an empty or missing section gives the
    declared defaults, a key overrides one, an unknown key is one error line naming the valid keys."""
    import subprocess
    import sys

    import yaml

    from pipelines.common import DEFAULT_PARAMS, REPO_ROOT, PipelineError, load_params, stage_defaults

    declared = yaml.safe_load(DEFAULT_PARAMS.read_text())
    given = tmp_path / "params.yaml"
    for text in ("cluster: {}\n", "cluster:\n", "embed: {batch_size: 8}\n", ""):
        given.write_text(text)
        assert load_params(given, "cluster") == stage_defaults("cluster") == declared["cluster"], text
    assert load_params(None, "cluster") == declared["cluster"]
    given.write_text("cluster: {eps: 0.3}\n")
    assert load_params(given, "cluster") == {**declared["cluster"], "eps": 0.3}

    given.write_text("cluster: {epss: 0.3}\n")
    with pytest.raises(PipelineError) as exc:
        load_params(given, "cluster")
    valid = ", ".join(sorted(declared["cluster"]))
    assert str(exc.value) == f"unknown key 'epss' in params.yaml:cluster; valid keys: {valid}"
    res = subprocess.run(
        [sys.executable, "-m", "pipelines.cluster", "--params", str(given)],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 2 and not res.stdout, (res.stdout, res.stderr)
    assert res.stderr.strip().splitlines() == [f"cluster: {exc.value}"]


def test_pool_show_renders_open_vocabulary_entries(descriptions, embedded, tmp_path):
    """An entry without a category (open vocabulary) shows as "(open)" in the table and null in JSON."""
    from typer.testing import CliRunner

    from curbside.cli.main import app

    texts, vecs, _ = embedded
    open_rows = descriptions.assign(category=descriptions["category"].where(descriptions["category"] != "street_lamp"))
    build_pool(open_rows, texts, vecs, eps=0.3, min_samples=2).to_parquet(tmp_path / "p.parquet")
    argv = ["pool", "show", "--pool", str(tmp_path / "p.parquet")]
    table = CliRunner().invoke(app, argv)
    assert table.exit_code == 0 and "(open)" in table.output, table.output
    rows = json.loads(CliRunner().invoke(app, [*argv, "--json"]).output)
    assert any(r["category"] is None for r in rows) and all(r["category"] != "street_lamp" for r in rows)
