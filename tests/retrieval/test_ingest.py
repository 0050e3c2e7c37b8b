"""The ingest stage end to end on a local folder: good assets land, bad ones are rejected with reasons, resumable."""

from __future__ import annotations

import dataclasses

import duckdb
import pytest

from retrieval.ingest import IngestConfig, TooManyRejections, ingest
from retrieval.normalize import QualityLimits
from retrieval.sources.local import LocalSource

CONFIG = IngestConfig(limits=QualityLimits(max_faces=5000))


def _rows(path, sql):
    con = duckdb.connect(str(path), read_only=True)
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


def test_local_folder_fills_catalog_and_rejects_bad_input(mesh_folder, tmp_path):
    cat = tmp_path / "c.duckdb"
    report = ingest(LocalSource(mesh_folder["root"]), cat, CONFIG, progress=False)
    assert report.written == 2 and report.rejected == 6
    rej = dict(_rows(cat, "SELECT source_id, reason FROM rejections"))
    assert rej == mesh_folder["reasons"]
    assets = {
        r[0]: r
        for r in _rows(
            cat,
            "SELECT source_id, category, height, license, params->>'unit_guess', mesh_path, collision_path FROM assets",
        )
    }
    assert set(assets) == set(mesh_folder["good"])
    assert assets["a_bench.ply"][1] == "bench" and assets["a_bench.ply"][3] == "CC0-1.0"
    # The cone was modelled in centimetres: 70 units tall reads as 0.70 m in cm.
    assert assets["b_cone.glb"][1] == "traffic_cone"
    assert assets["b_cone.glb"][2] == pytest.approx(0.70, abs=1e-3) and assets["b_cone.glb"][4] == "cm"
    for _, _, _, _, _, mesh, coll in assets.values():
        assert (cat.parent / mesh).exists() and (cat.parent / coll).exists()
    views = _rows(cat, "SELECT asset_id, count(*), sum(informative::INT) FROM views GROUP BY 1")
    assert sorted(v[1:] for v in views) == [(20, 3), (20, 3)]
    matches = _rows(cat, "SELECT asset_id, description_id, score, image_score, text_score, scorer FROM matches")
    top = {m[0]: m for m in sorted(matches, key=lambda m: m[2])}
    assert top["local:a_bench.ply"][1] == "category:bench"  # no label: the category comes from the best match
    assert ("local:b_cone.glb", "category:traffic_cone") in {m[:2] for m in matches}
    assert all(m[5].startswith("aligned+all-MiniLM-L6-v2") and m[3] is not None for m in matches)
    assert {m[0] for m in matches} == {"local:a_bench.ply", "local:b_cone.glb"}
    assert _rows(cat, "SELECT count(*) FROM embeddings WHERE owner_kind = 'asset_image'")[0][0] == 2
    assert (cat.parent / "c_assets" / "retrieval" / "local" / "a_bench.ply" / "contact_sheet.png").exists()
    # Ingested assets are searchable like built ones: `catalog query` ranks their text embeddings.
    from catalogs.query import search
    from retrieval.encoders.text import TextEncoder

    con = duckdb.connect(str(cat), read_only=True)
    try:
        hits = search(con, TextEncoder().encode(["traffic cone"])[0], limit=2)
    finally:
        con.close()
    assert [h["asset_id"] for h in hits][0] == "local:b_cone.glb"

    again = ingest(LocalSource(mesh_folder["root"]), cat, CONFIG, progress=False)
    assert (again.written, again.rejected, again.skipped) == (0, 0, 8)


def test_interrupted_run_resumes_without_loss_or_duplicates(mesh_folder, tmp_path):
    cat = tmp_path / "c.duckdb"
    # The stage stops at the first rejection (c_corrupt.glb): a real abort path, after two finished assets.
    with pytest.raises(TooManyRejections, match="max_rejections 0"):
        ingest(LocalSource(mesh_folder["root"]), cat, dataclasses.replace(CONFIG, max_rejections=0), progress=False)
    assert _rows(cat, "SELECT count(*) FROM assets")[0][0] == 2
    report = ingest(LocalSource(mesh_folder["root"]), cat, CONFIG, progress=False)
    assert report.skipped == 3 and report.written == 0 and report.rejected == 5
    assert _rows(cat, "SELECT count(*) FROM assets")[0][0] == 2
    assert _rows(cat, "SELECT count(*), count(DISTINCT (asset_id, view_index)) FROM views")[0] == (40, 40)
    assert _rows(cat, "SELECT count(*) FROM rejections")[0][0] == 6
