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
    return runner.invoke(
        app, ["catalog", "build", "--catalog", str(catalog), "--category", "bench", "--category", "bollard", *extra]
    )


def test_build_variants_seeds_and_determinism(tmp_path: Path) -> None:
    a, b = tmp_path / "a" / "c.duckdb", tmp_path / "b" / "c.duckdb"
    assert build(a, "--variants", "2", "--seed", "1").exit_code == 0
    res = build(b, "--variants", "2", "--seed", "1")
    assert res.exit_code == 0, res.output
    assert "4 assets" in res.stdout
    ra, rb = CatalogReader(a), CatalogReader(b)
    assert ra.categories() == {"bench": 2, "bollard": 2}
    assert sorted(ra.table.asset_id) == [
        "procedural/bench/1000",
        "procedural/bench/1001",
        "procedural/bollard/1000",
        "procedural/bollard/1001",
    ]
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


def test_a_full_disk_fails_the_build_in_one_line_and_leaves_the_previous_catalog(tmp_path: Path) -> None:
    """A file-size limit (RLIMIT_FSIZE, how a full disk looks to a writer) stops the rebuild while the catalog is
    written (200 KB) or while asset files are (5 KB): exit 1, one line saying so, the previous catalog byte for byte,
    and no asset folder of the failed build."""
    import resource
    import signal
    import subprocess
    import sys

    catalog = tmp_path / "c.duckdb"
    assert build(catalog, "--variants", "1").exit_code == 0
    before = catalog.read_bytes()
    folders = sorted(p.relative_to(tmp_path) for p in (tmp_path / "c_assets").rglob("*") if p.is_dir())

    for limit, words in (
        (200_000, f"error: cannot write catalog {catalog}: the disk is full"),
        (5_000, "could not write: the disk is full or a file passes a size limit"),
    ):

        def capped(limit: int = limit) -> None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        res = subprocess.run(
            [
                str(Path(sys.executable).with_name("curbside")),
                "catalog",
                "build",
                "--catalog",
                str(catalog),
                "--category",
                "bench",
                "--category",
                "bollard",
                "--variants",
                "2",
                "--seed",
                "1",
            ],
            preexec_fn=capped,
            capture_output=True,
            text=True,
            timeout=300,
        )
        last = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
        assert res.returncode == 1 and len(last) == 1 and words in last[0], res.stderr[-600:]
        assert "Traceback" not in res.stderr
        assert catalog.read_bytes() == before
        assert sorted(p.relative_to(tmp_path) for p in (tmp_path / "c_assets").rglob("*") if p.is_dir()) == folders
        assert sorted(p.name for p in tmp_path.iterdir()) == ["c.duckdb", "c_assets"]
