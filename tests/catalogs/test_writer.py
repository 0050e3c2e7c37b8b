"""Write API: idempotent upserts, transactions that roll back, atomic builds, record checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from catalogs.layout import asset_root
from catalogs.reader import CatalogReader, open_catalog
from catalogs.records import DescriptionRecord, MatchRecord, RejectionRecord, ViewRecord
from catalogs.schema import CatalogError
from catalogs.writer import CatalogWriter, build_catalog


def _count(path: Path, table: str) -> int:
    con = open_catalog(path)
    try:
        return int(con.execute(f"SELECT count(*) FROM {table}").fetchone()[0])
    finally:
        con.close()


def test_asset_root_sits_next_to_catalog(tmp_path: Path) -> None:
    assert asset_root(tmp_path / "default.duckdb") == tmp_path / "default_assets"


def test_upserts_are_idempotent_and_replace_by_key(tmp_path: Path, make_asset, random_unit_vectors) -> None:
    path = tmp_path / "c.duckdb"
    ids = [f"a{i}" for i in range(4)]
    with CatalogWriter(path) as w:
        for _ in range(2):
            assert w.upsert_assets([make_asset(i) for i in ids]) == 4
            w.upsert_embeddings("asset_text", ids, random_unit_vectors(4))
            w.upsert_views([ViewRecord("a0", 0, 0.0, 20.0, "v/a0_0.png")])
            w.upsert_descriptions([DescriptionRecord("d0", "gray trash bin", members=["x"], country_counts={"JP": 2})])
            w.upsert_matches([MatchRecord("a0", "d0", 0.5, "clip")])
            w.record_rejections([RejectionRecord("objaverse", "u1", "quality", "too few faces")])
        w.upsert_assets([make_asset("a1", height=2.5, zones=["frontage", "building"], params={"k": [1, 2]})])
    for table, n in [
        ("assets", 4),
        ("embeddings", 4),
        ("views", 1),
        ("descriptions", 1),
        ("matches", 1),
        ("rejections", 1),
    ]:
        assert _count(path, table) == n, table
    rec = CatalogReader(path).get("a1")
    assert rec.height == 2.5 and rec.zones == ["frontage", "building"] and rec.params == {"k": [1, 2]}


def test_duplicate_keys_in_one_batch_are_refused(tmp_path: Path, make_asset) -> None:
    with CatalogWriter(tmp_path / "c.duckdb") as w:
        with pytest.raises(CatalogError, match="twice"):
            w.upsert_assets([make_asset("a0"), make_asset("a0")])
        with pytest.raises(CatalogError, match="duplicate owner ids"):
            w.upsert_embeddings("asset_text", ["a0", "a0"], np.ones((2, 384)))


def test_transaction_rolls_back_everything_on_error(tmp_path: Path, make_asset) -> None:
    path = tmp_path / "c.duckdb"
    with CatalogWriter(path) as w:
        w.upsert_assets([make_asset("keep")])
        with pytest.raises(RuntimeError, match="boom"), w.transaction():
            w.upsert_assets([make_asset("lost1")])
            w.upsert_assets([make_asset("keep", height=9.0)])  # nested upsert joins the outer transaction
            raise RuntimeError("boom")
        # A failing statement inside an upsert rolls back its own batch too.
        with pytest.raises(CatalogError):
            w.upsert_embeddings("asset_text", ["keep"], np.full((1, 384), np.nan))
        # The writer still works after a rollback.
        w.upsert_assets([make_asset("after")])
    reader = CatalogReader(path)
    assert sorted(reader.categories()) == ["bench"]
    assert sorted(reader.table.asset_id) == ["after", "keep"]
    assert reader.get("keep").height == 0.85


def test_embeddings_are_normalised_and_shape_checked(tmp_path: Path) -> None:
    path = tmp_path / "c.duckdb"
    with CatalogWriter(path) as w:
        w.upsert_embeddings("asset_text", ["a", "b"], np.arange(768, dtype=np.float32).reshape(2, 384) + 1)
        with pytest.raises(CatalogError, match=r"shape \(n, 384\)"):
            w.upsert_embeddings("asset_text", ["c"], np.ones((1, 10)))
        with pytest.raises(CatalogError, match="owner ids"):
            w.upsert_embeddings("asset_text", ["c", "d"], np.ones((1, 384)))
    con = open_catalog(path)
    norms = [r[0] for r in con.execute("SELECT sqrt(array_inner_product(vector, vector)) FROM embeddings").fetchall()]
    con.close()
    assert np.allclose(norms, 1.0, atol=1e-5)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"object_class": "furniture"}, "object_class"),
        ({"zones": ["sidewalk"]}, "unknown zone"),
        ({"height": -1.0}, "height must be a positive"),
        ({"depth": float("nan")}, "depth must be a positive"),
        ({"mass": 0.0}, "mass must be"),
    ],
)
def test_invalid_records_are_refused_with_the_field_named(tmp_path: Path, make_asset, overrides, message) -> None:
    with CatalogWriter(tmp_path / "c.duckdb") as w:
        with pytest.raises(CatalogError, match=message):
            w.upsert_assets([make_asset("x", **overrides)])
        with pytest.raises(CatalogError, match="empty asset_id"):
            w.upsert_assets([make_asset("")])
        assert w.con.execute("SELECT count(*) FROM assets").fetchone()[0] == 0


def test_build_is_atomic_and_leaves_no_half_catalog(tmp_path: Path, make_asset) -> None:
    path = tmp_path / "c.duckdb"
    with pytest.raises(RuntimeError, match="crash"), build_catalog(path) as w:
        w.upsert_assets([make_asset("a0")])
        raise RuntimeError("crash")
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []  # the temporary file is gone too

    with build_catalog(path) as w:
        w.upsert_assets([make_asset("old")])
        assert not path.exists()  # nothing at the final path until the build completes
    with pytest.raises(RuntimeError, match="crash"), build_catalog(path) as w:
        w.upsert_assets([make_asset("new")])
        raise RuntimeError("crash")
    assert list(CatalogReader(path).table.asset_id) == ["old"]  # the previous catalog is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.duckdb"]

    with build_catalog(path) as w:
        w.upsert_assets([make_asset("new")])
    assert list(CatalogReader(path).table.asset_id) == ["new"]  # a build replaces, it does not merge


def test_an_asset_is_replaced_rejected_and_deleted_across_every_table(tmp_path: Path, make_asset) -> None:
    path = tmp_path / "c.duckdb"
    vec = np.eye(384, dtype=np.float32)
    with CatalogWriter(path) as w:
        w.upsert_descriptions([DescriptionRecord("d0", "a bench")])
        w.upsert_embeddings("description", ["d0"], vec[:1])  # not the asset's: survives its deletion
        for aid, score in (("a", 0.9), ("b", 0.5)):
            w.record_rejections([RejectionRecord("procedural", aid, "render", "error", "old", "h1")])
            w.replace_asset(
                make_asset(aid, content_hash=f"hash-{aid}"),
                [ViewRecord(aid, 0, 0.0, 15.0, f"{aid}.png")],
                [MatchRecord(aid, "d0", score, "s")],
                text_embedding=vec[1],
                image_embedding=vec[2],
                image_model="imagenet",
            )
        assert w.finished_hashes() == {("procedural", "a"): "hash-a", ("procedural", "b"): "hash-b"}
        assert w.rejection_details("h1") == {}  # a finished asset clears its item's rejection
        assert [(e.asset_id, e.content_hash) for e in w.embedded_assets()] == [("a", "hash-a"), ("b", "hash-b")]
        assert w.rank_matches(1) == 1  # b ranks second for d0
        w.reject_assets([("a", RejectionRecord("procedural", "a", "curate", "near_duplicate", "of b", "h2"))])
        assert w.rejection_details("h2", retried=("near_duplicate",)) == {}
        assert w.rejection_details("h2") == {("procedural", "a"): "of b"}
        w.delete_assets(["b"])
    for table in ("assets", "views", "matches"):
        assert _count(path, table) == 0, table
    assert _count(path, "embeddings") == 1 and _count(path, "rejections") == 1
