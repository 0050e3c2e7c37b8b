"""Executors give identical catalogs; the objaverse source drives the real `objaverse` functions on a local cache."""

from __future__ import annotations

import gzip
import json

import duckdb
import trimesh

from retrieval.ingest import IngestConfig, ingest
from retrieval.sources.local import LocalSource
from retrieval.sources.objaverse import ObjaverseSource

from .conftest import bench_mesh, cone_mesh

TABLES = {
    "assets": "SELECT asset_id, category, depth, width, height, content_hash, mesh_path FROM assets ORDER BY 1",
    "views": "SELECT asset_id, view_index, informative, informativeness FROM views ORDER BY 1, 2",
    "matches": "SELECT asset_id, description_id, score, image_score, text_score, scorer, rank FROM matches ORDER BY 1, 2",
    "rejections": "SELECT source_id, stage, reason FROM rejections ORDER BY 1",
}


def _dump(path):
    con = duckdb.connect(str(path), read_only=True)
    try:
        return {k: con.execute(q).fetchall() for k, q in TABLES.items()}
    finally:
        con.close()


def test_ray_executor_gives_the_local_catalog(mesh_folder, tmp_path):
    import ray

    config = IngestConfig(n_views=4, n_informative=2)
    local = tmp_path / "local" / "c.duckdb"
    remote = tmp_path / "ray" / "c.duckdb"
    ingest(LocalSource(mesh_folder["root"]), local, config, progress=False, limit=3)
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        ingest(LocalSource(mesh_folder["root"]), remote, config, executor="ray", progress=False, limit=3)
    finally:
        ray.shutdown()
    a, b = _dump(local), _dump(remote)
    assert len(a["assets"]) == 2 and len(a["rejections"]) == 1
    assert a == b


def test_process_executor_gives_the_local_catalog(mesh_folder, tmp_path):
    config = IngestConfig(n_views=4, n_informative=2)
    local = tmp_path / "local" / "c.duckdb"
    procs = tmp_path / "process" / "c.duckdb"
    ingest(LocalSource(mesh_folder["root"]), local, config, progress=False, limit=3)
    # Two spawned workers: results arrive from both, and must still be written in input order.
    ingest(LocalSource(mesh_folder["root"]), procs, config, executor="process", workers=2, progress=False, limit=3)
    a, b = _dump(local), _dump(procs)
    assert len(a["assets"]) == 2 and len(a["rejections"]) == 1 and a["matches"]
    assert a == b


def _fake_objaverse_cache(root):
    """Objaverse's cache layout: object-paths, one metadata shard, LVIS annotations and glbs/."""
    base = root / "hf-objaverse-v1"
    (base / "glbs" / "000-000").mkdir(parents=True)
    (base / "metadata").mkdir()
    objects = {
        "u_bench": ("bench", bench_mesh(), "by", 72),
        "u_cone": ("cone", cone_mesh(), "by-nc", 48),
        "u_bench2": ("bench", bench_mesh(), "cc0", 5_000_000),
    }
    paths, meta, lvis = {}, {}, {}
    for uid, (cat, mesh, lic, faces) in objects.items():
        paths[uid] = f"glbs/000-000/{uid}.glb"
        trimesh.Scene([mesh]).export(base / paths[uid])
        meta[uid] = {
            "name": f"{cat} model",
            "license": lic,
            "faceCount": faces,
            "tags": [{"name": cat}],
            "user": {"displayName": "Tester"},
            "viewerUrl": f"https://sketchfab.com/3d-models/{uid}",
            "archives": {"glb": {"size": 1000, "faceCount": faces}},
        }
        lvis.setdefault(cat, []).append(uid)
    for name, obj in (
        ("object-paths.json.gz", paths),
        ("metadata/000-000.json.gz", meta),
        ("lvis-annotations.json.gz", lvis),
    ):
        with gzip.open(base / name, "wt") as fh:
            json.dump(obj, fh)
    return root


def test_objaverse_source_on_local_cache(tmp_path):
    cache = _fake_objaverse_cache(tmp_path / "objaverse")
    src = ObjaverseSource(cache_dir=cache, lvis_categories=["bench", "cone"], timeout=2, retries=1)
    items = list(src.items())
    assert [i.source_id for i in items] == ["u_bench", "u_bench2", "u_cone"]
    assert items[0].path.endswith("u_bench.glb") and items[0].license == "CC-BY-4.0"
    assert "Tester" in items[0].attribution
    cat = tmp_path / "c.duckdb"
    report = ingest(src, cat, IngestConfig(n_views=4, n_informative=2), progress=False)
    assert report.written == 1
    d = _dump(cat)
    assert [a[:2] for a in d["assets"]] == [("objaverse:u_bench", "bench")]
    assert dict((r[0], r[2]) for r in d["rejections"]) == {"u_bench2": "too_many_faces", "u_cone": "license"}
