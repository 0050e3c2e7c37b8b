"""`curbside catalog build`: variants and seeds, determinism, atomic replacement, bad input."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from catalogs.reader import CatalogReader
from curbside.cli.main import app
from retrieval.build import asset_text, variant_seeds
from tests.helpers import cli, one_error_line

runner = CliRunner()


def build(catalog: Path, *extra: str):
    return runner.invoke(app, ["catalog", "build", "--catalog", str(catalog), "--category", "bench",
                               "--category", "bollard", *extra])


def test_build_variants_seeds_and_determinism(tmp_path: Path) -> None:
    a, b = tmp_path / "a" / "c.duckdb", tmp_path / "b" / "c.duckdb"
    assert build(a, "--variants", "2", "--seed", "1").exit_code == 0
    res = build(b, "--variants", "2", "--seed", "1")
    assert res.exit_code == 0, res.output
    assert "4 assets" in res.stdout
    ra, rb = CatalogReader(a), CatalogReader(b)
    assert ra.categories() == {"bench": 2, "bollard": 2}
    assert sorted(ra.table.asset_id) == ["procedural/bench/1000", "procedural/bench/1001",
                                         "procedural/bollard/1000", "procedural/bollard/1001"]
    for asset_id in ra.table.asset_id:  # same seed, same bytes
        assert ra.get(asset_id).content_hash == rb.get(asset_id).content_hash
        assert ra.resolve(ra.get(asset_id).mesh_path).is_file()
    assert ra.meta["build_seed"] == "1" and ra.meta["build_variants"] == "2"
    # Rebuilding in place replaces the catalog (no leftovers from the earlier build's rows).
    assert build(a, "--variants", "1", "--seed", "0").exit_code == 0
    assert sorted(CatalogReader(a).table.asset_id) == ["procedural/bench/0000", "procedural/bollard/0000"]
    assert sorted(p.name for p in a.parent.iterdir()) == ["c.duckdb", "c_assets"]


def test_build_refuses_unknown_category_and_keeps_nothing(tmp_path: Path, capfd) -> None:
    cat = tmp_path / "c.duckdb"
    line = one_error_line(*cli(["catalog", "build", "--catalog", str(cat), "--category", "spaceship"], capfd))
    assert "spaceship" in line and "fire_hydrant" in line
    assert not cat.exists()


def test_seed_derivation_and_asset_text() -> None:
    assert variant_seeds(0, 3) == [0, 1, 2] and variant_seeds(2, 2) == [2000, 2001]
    text = asset_text("fire_hydrant", "a red hydrant", ["fireplug", "hydrant"])
    assert text == "fire hydrant. a red hydrant. fireplug, hydrant."
