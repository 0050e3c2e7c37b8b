"""Ranked search in DuckDB: order by cosine similarity, filters bound as parameters, SQL text stays text."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from catalogs.query import QueryFilters, search
from catalogs.reader import open_catalog
from catalogs.writer import build_catalog

SPECS = [  # asset_id, category, object_class, zones, height, source, licence
    ("bench-a", "bench", "non_standard", ["furnishing"], 0.9, "procedural", "CC0-1.0"),
    ("bench-b", "bench", "non_standard", ["frontage"], 1.1, "objaverse", "CC-BY-4.0"),
    ("hydrant-a", "fire_hydrant", "standard", ["furnishing"], 0.8, "procedural", "CC0-1.0"),
    ("lamp-a", "street_lamp", "standard", ["furnishing", "near_road_buffer"], 6.0, "procedural", "CC0-1.0"),
    ("can-a", "drink_can", "clutter", ["clear"], 0.12, "local", "CC-BY-4.0"),
]


@pytest.fixture()
def con(tmp_path: Path, make_asset, random_unit_vectors):
    path = tmp_path / "c.duckdb"
    vecs = random_unit_vectors(len(SPECS), seed=3)
    with build_catalog(path) as w:
        w.upsert_assets(
            [
                make_asset(a, category=c, object_class=k, zones=z, height=h, source=s, license=lic)
                for a, c, k, z, h, s, lic in SPECS
            ]
        )
        w.upsert_embeddings("asset_text", [s[0] for s in SPECS], vecs)
    c = open_catalog(path)
    yield c, vecs
    c.close()


def test_ranks_by_cosine_similarity(con) -> None:
    con, vecs = con
    for i, spec in enumerate(SPECS):
        res = search(con, vecs[i] * 3.0, limit=5)  # the query need not be unit length
        assert res[0]["asset_id"] == spec[0]
        assert res[0]["score"] == pytest.approx(1.0, abs=1e-5)
        expected = [SPECS[j][0] for j in np.argsort(-(vecs @ vecs[i]), kind="stable")]
        assert [r["asset_id"] for r in res] == expected
        assert [r["score"] for r in res] == sorted((r["score"] for r in res), reverse=True)
    assert len(search(con, vecs[0], limit=2)) == 2


@pytest.mark.parametrize(
    ("filters", "expected"),
    [
        (QueryFilters(category="bench"), {"bench-a", "bench-b"}),
        (QueryFilters(object_class="standard"), {"hydrant-a", "lamp-a"}),
        (QueryFilters(zone="furnishing"), {"bench-a", "hydrant-a", "lamp-a"}),
        (QueryFilters(zone="near_road_buffer"), {"lamp-a"}),
        (QueryFilters(max_height=1.0), {"bench-a", "hydrant-a", "can-a"}),
        (QueryFilters(source="procedural", license="CC0-1.0"), {"bench-a", "hydrant-a", "lamp-a"}),
        (QueryFilters(license="CC-BY-4.0", max_height=0.5), {"can-a"}),
        (QueryFilters(category="bench", zone="clear"), set()),
    ],
)
def test_filters(con, filters: QueryFilters, expected: set[str]) -> None:
    con, vecs = con
    res = search(con, vecs[4], filters, limit=10)
    assert {r["asset_id"] for r in res} == expected


def test_sql_in_filter_values_is_plain_text(con) -> None:
    con, vecs = con
    evil = "'; DROP TABLE assets; --"
    for f in (QueryFilters(category=evil), QueryFilters(zone=evil), QueryFilters(source=evil + " OR 1=1")):
        assert search(con, vecs[0], f) == []
    assert con.execute("SELECT count(*) FROM assets").fetchone()[0] == len(SPECS)


def test_bad_query_vectors_and_limits(con) -> None:
    con, vecs = con
    with pytest.raises(ValueError, match="384"):
        search(con, np.ones(10))
    with pytest.raises(ValueError, match="zero"):
        search(con, np.zeros(384))
    with pytest.raises(ValueError, match="limit"):
        search(con, vecs[0], limit=0)


def test_other_embedding_models_are_not_mixed_in(tmp_path: Path, make_asset, random_unit_vectors) -> None:
    path = tmp_path / "m.duckdb"
    v = random_unit_vectors(2)
    with build_catalog(path) as w:
        w.upsert_assets([make_asset("a"), make_asset("b")])
        w.upsert_embeddings("asset_text", ["a"], v[:1])
        w.upsert_embeddings("asset_text", ["b"], v[:1], model="other-model")
        w.upsert_embeddings("view_image", ["b"], v[:1])
    c = open_catalog(path)
    assert [r["asset_id"] for r in search(c, v[0])] == ["a"]
    assert [r["asset_id"] for r in search(c, v[0], model="other-model")] == ["b"]
    c.close()
