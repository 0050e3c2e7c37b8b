"""The shipped aligned scorer end to end: ingest, per-view embeddings in the catalog, attribute-aware queries."""

from __future__ import annotations

import duckdb
import numpy as np
import pytest

from retrieval.ingest import IngestConfig, ingest
from retrieval.sources.procedural import ProceduralSource


@pytest.fixture(scope="module")
def bins(tmp_path_factory):
    """Trash bins of seeds 0-5 (five blue, seed 5 gray) and two benches, ingested with the default scorer."""
    tmp = tmp_path_factory.mktemp("bins")
    cat = tmp / "c.duckdb"
    ingest(
        ProceduralSource(per_category=6, categories=["trash_bin"], work_dir=tmp / "proc"),
        cat,
        IngestConfig(n_views=8),
        progress=False,
    )
    ingest(
        ProceduralSource(per_category=2, categories=["bench"], work_dir=tmp / "proc2"),
        cat,
        IngestConfig(n_views=8),
        progress=False,
    )
    return cat


def test_views_are_stored_per_scored_view_in_the_joint_space(bins):
    con = duckdb.connect(str(bins), read_only=True)
    try:
        rows = con.execute("SELECT owner_id, model, vector FROM embeddings WHERE owner_kind = 'asset_view'").fetchall()
        informative = dict(con.execute("SELECT asset_id, params->>'informative_views' FROM assets").fetchall())
    finally:
        con.close()
    assert len(rows) == 8 * 3  # 8 assets, 3 informative views each
    for owner, model, vec in rows:
        assert model.startswith("aligned") and int(model.split("#view")[1]) in eval(informative[owner])
        assert np.linalg.norm(vec) == pytest.approx(1.0, abs=1e-5)


def test_gray_trash_bin_ranks_a_gray_bin_first(bins):
    from catalogs.aligned import load_heads
    from catalogs.query import has_view_embeddings, search
    from catalogs.text_encoder import NumpyTextEncoder

    colours = {f"procedural:trash_bin-{s:04d}": c for s, c in enumerate(["blue"] * 5 + ["gray"])}
    con = duckdb.connect(str(bins), read_only=True)
    try:
        assert has_view_embeddings(con)
        vec = NumpyTextEncoder().encode(["gray trash bin"])[0]
        view = load_heads().text(vec[None])[0]
        fused = search(con, vec, limit=3, view_vector=view)
        views_only = search(con, vec, limit=3, view_vector=view, view_weight=1.0)
        blue = search(
            con, vec, limit=3, view_vector=load_heads().text(NumpyTextEncoder().encode(["blue trash bin"]))[0]
        )
    finally:
        con.close()
    assert colours[fused[0]["asset_id"]] == "gray"
    assert colours[views_only[0]["asset_id"]] == "gray"  # the pixels alone say gray
    assert colours[blue[0]["asset_id"]] == "blue"
