"""The DVC stages (normalise -> render -> score -> curate) build the same catalog as the fused `ingest`."""

from __future__ import annotations

from pathlib import Path

import duckdb
import yaml

from retrieval import stages
from retrieval.ingest import ingest
from retrieval.sources.procedural import ProceduralSource

CATEGORIES = ["bench", "traffic_cone", "bollard", "street_lamp"]
PARAMS = {
    "source": {"name": "procedural", "per_category": 1},
    "render": {"n_views": 4},
    "score": {"image_encoder": "imagenet"},
    "curate": {"dedupe_threshold": 0.995},
}
QUERIES = {
    "assets": "SELECT asset_id, content_hash, category, depth, width, height, mesh_path, collision_path, "
    "face_count, params FROM assets ORDER BY 1",
    "matches": "SELECT asset_id, description_id, score, image_score, text_score, scorer, rank FROM matches ORDER BY 1, 2",
    "views": "SELECT * FROM views ORDER BY 1, 2",
    "embeddings": "SELECT owner_kind, owner_id, vector FROM embeddings ORDER BY 1, 2",
    "rejections": "SELECT source_id, stage, reason FROM rejections ORDER BY 1",
    "descriptions": "SELECT description_id, text FROM descriptions ORDER BY 1",
}


def _tables(path: Path) -> dict[str, list]:
    con = duckdb.connect(str(path), read_only=True)
    try:
        return {k: con.execute(q).fetchall() for k, q in QUERIES.items()}
    finally:
        con.close()


def test_staged_catalog_equals_ingest(tmp_path):
    source = ProceduralSource(per_category=1, categories=CATEGORIES, work_dir=tmp_path / "src")
    fused = tmp_path / "fused" / "catalog.duckdb"
    ingest(source, fused, stages.config_for(PARAMS), progress=False)

    root = tmp_path / "staged"
    norm, man, vdir, vt, sc = (
        root / "normalised",
        root / "manifest.parquet",
        root / "views",
        root / "views.parquet",
        root / "scores.parquet",
    )
    assert stages.normalise(source, stages.config_for(PARAMS, "normalise"), norm, man) == 4
    assert stages.render(man, norm, stages.config_for(PARAMS, "render"), vdir, vt) == 4
    assert stages.score(man, vt, vdir, stages.config_for(PARAMS, "score"), sc) == 4
    staged = root / "catalog.duckdb"
    assert stages.curate(man, norm, vt, vdir, sc, stages.config_for(PARAMS, "curate"), staged) == (4, 0)

    want, got = _tables(fused), _tables(staged)
    assert len(want["assets"]) == 4 and want["matches"] and want["embeddings"]
    for name in QUERIES:
        assert got[name] == want[name], name
    for (mesh,) in duckdb.connect(str(staged), read_only=True).execute("SELECT mesh_path FROM assets").fetchall():
        assert (fused.parent / mesh).read_bytes() == (staged.parent / mesh).read_bytes()


def test_dvc_stages_list_the_params_each_stage_reads():
    spec = yaml.safe_load((Path(__file__).parents[2] / "retrieval" / "dvc.yaml").read_text())["stages"]
    for stage, sections in stages.STAGE_PARAMS.items():
        assert spec[stage]["params"] == [{"retrieval/params.yaml": list(sections)}], stage
        assert f"retrieval.stages {stage}" in spec[stage]["cmd"]
