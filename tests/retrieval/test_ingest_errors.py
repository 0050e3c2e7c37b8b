"""Bad input on the ingest side: configuration errors are never per-asset rejections, rejections remember the
configuration that produced them, a bad sidecar rejects only its asset, and objaverse downloads are atomic."""

from __future__ import annotations

import gzip
import http.server
import json
import threading
from pathlib import Path

import duckdb
import pytest

from catalogs.records import RejectionRecord
from catalogs.writer import CatalogWriter
from kernel.config import ConfigError
from retrieval.ingest import IngestConfig, config_hash, ingest
from retrieval.normalize import QualityLimits
from retrieval.scoring import ScoringConfig
from retrieval.sources import SourceCacheCorrupt, SourceUnavailable
from retrieval.sources.local import LocalSource
from retrieval.sources.objaverse import DownloadError, ObjaverseSource, download

from .conftest import bench_mesh

FAST = dict(n_views=2, n_informative=1, image_size=64, scoring=ScoringConfig(image_encoder="none"))


def _rows(path: Path, sql: str) -> list[tuple]:
    con = duckdb.connect(str(path), read_only=True)
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


@pytest.fixture()
def two_meshes(tmp_path: Path) -> Path:
    """A bench with a good sidecar and a trash bin whose sidecar says {"tags": 5}."""
    root = tmp_path / "meshes"
    root.mkdir()
    bench_mesh().export(root / "a_bench.ply")
    (root / "a_bench.json").write_text('{"name": "park bench", "category": "bench", "tags": ["seat"]}')
    bench_mesh().export(root / "trash_bin.ply")
    (root / "trash_bin.json").write_text('{"tags": 5}')
    return root


@pytest.mark.parametrize("bad", [{"n_views": 0}, {"n_views": 21}, {"n_informative": 0}, {"image_size": 0}])
def test_bad_config_is_refused_up_front(bad: dict) -> None:
    with pytest.raises(ConfigError):
        IngestConfig(**bad)


def test_bad_sidecar_rejects_that_asset_only(two_meshes: Path, tmp_path: Path) -> None:
    cat = tmp_path / "c.duckdb"
    report = ingest(LocalSource(two_meshes), cat, IngestConfig(**FAST), progress=False)
    assert (report.written, report.rejected) == (1, 1)
    assert _rows(cat, "SELECT asset_id FROM assets") == [("local:a_bench.ply",)]
    [(sid, stage, reason, detail)] = _rows(cat, "SELECT source_id, stage, reason, detail FROM rejections")
    assert (sid, stage, reason) == ("trash_bin.ply", "fetch", "bad_metadata")
    assert "trash_bin.json" in detail and "tags must be a list of strings" in detail
    # Fixing the sidecar changes the content hash: the next run retries the asset and writes it.
    (two_meshes / "trash_bin.json").write_text('{"tags": ["bin"], "category": "trash_bin"}')
    report = ingest(LocalSource(two_meshes), cat, IngestConfig(**FAST), progress=False)
    assert (report.written, report.skipped) == (1, 1)
    assert _rows(cat, "SELECT count(*) FROM rejections") == [(0,)]


def test_rejections_are_retried_when_the_configuration_changes(two_meshes: Path, tmp_path: Path) -> None:
    (two_meshes / "trash_bin.json").unlink()
    src = LocalSource(two_meshes)
    cat = tmp_path / "c.duckdb"
    strict = IngestConfig(**FAST, limits=QualityLimits(max_faces=10))  # refuses both benches
    report = ingest(src, cat, strict, progress=False)
    assert (report.written, report.rejected, report.reasons) == (0, 2, {"too_many_faces": 2})
    assert {r[0] for r in _rows(cat, "SELECT config_hash FROM rejections")} == {config_hash(strict)}
    # Same bytes, same configuration: the verdict stands.
    assert ingest(src, cat, strict, progress=False).skipped == 2
    # Another configuration: both are retried (the old code skipped them forever by content hash).
    report = ingest(src, cat, IngestConfig(**FAST), progress=False)
    assert (report.written, report.skipped) == (2, 0)
    assert _rows(cat, "SELECT count(*) FROM rejections") == [(0,)]


def test_rejections_recorded_before_config_hash_are_retried(two_meshes: Path, tmp_path: Path) -> None:
    """A catalog poisoned by the old `--views 0` bug (rejections keyed by content hash only) heals on the next run."""
    (two_meshes / "trash_bin.json").unlink()
    src = LocalSource(two_meshes)
    cat = tmp_path / "c.duckdb"
    with CatalogWriter(cat) as w:
        w.record_rejections(
            RejectionRecord(
                "local",
                i.source_id,
                "render",
                "error",
                f"ValueError: n_views must be in 1..20, got 0 [sha256:{i.content_hash()[:16]}]",
            )
            for i in src.items()
        )
    report = ingest(src, cat, IngestConfig(**FAST), progress=False)
    assert (report.written, report.skipped) == (2, 0)


def test_bad_executor_stops_before_any_asset_and_leaves_no_catalog(two_meshes: Path, tmp_path: Path) -> None:
    cat = tmp_path / "c.duckdb"
    with pytest.raises(ConfigError, match="local, process, ray"):
        ingest(LocalSource(two_meshes), cat, IngestConfig(**FAST), executor="bogus", progress=False)
    assert not cat.exists() and not Path(f"{cat}.wal").exists()


# --- objaverse: downloads through a real local HTTP server ---------------------------------------------------


class _Handler(http.server.BaseHTTPRequestHandler):
    files: dict[str, bytes] = {}
    short: set[str] = set()  # paths answered with a Content-Length larger than the body, then a closed socket
    hits: dict[str, int] = {}

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path = self.path.lstrip("/")
        self.hits[path] = self.hits.get(path, 0) + 1
        body = self.files.get(path)
        if body is None:
            self.send_error(404)
            return
        self.send_response(200)
        self.send_header("Content-Length", str(len(body) * (2 if path in self.short else 1)))
        self.end_headers()
        self.wfile.write(body)
        self.wfile.flush()
        if path in self.short:
            self.close_connection = True

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture()
def server():
    """A local HTTP server standing in for the objaverse mirror; yields (base url, handler class)."""
    handler = type("H", (_Handler,), {"files": {}, "short": set(), "hits": {}})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    t = threading.Thread(target=httpd.serve_forever, daemon=True)
    t.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}", handler
    finally:
        httpd.shutdown()
        httpd.server_close()


def _gz(obj: object) -> bytes:
    return gzip.compress(json.dumps(obj).encode())


def test_download_is_atomic_and_retried(server, tmp_path: Path) -> None:
    url, h = server
    h.files["ok.bin"] = b"x" * 5000
    h.files["short.bin"] = b"y" * 5000
    h.short.add("short.bin")
    dest = tmp_path / "d" / "ok.bin"
    assert download(f"{url}/ok.bin", dest, timeout=5, retries=2).read_bytes() == b"x" * 5000
    with pytest.raises(DownloadError, match="short.bin"):
        download(f"{url}/short.bin", tmp_path / "d" / "short.bin", timeout=5, retries=2)
    assert h.hits["short.bin"] == 2  # retried
    with pytest.raises(DownloadError, match="404"):
        download(f"{url}/missing.bin", tmp_path / "d" / "missing.bin", timeout=5, retries=1)
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["ok.bin"]  # no partial or .part file


def test_objaverse_interrupted_annotation_download_leaves_nothing(server, tmp_path: Path) -> None:
    url, h = server
    h.files["lvis-annotations.json.gz"] = _gz({"bench": ["u1"]})
    h.short.add("lvis-annotations.json.gz")
    src = ObjaverseSource(cache_dir=tmp_path / "cache", base_url=url, timeout=5, retries=2)
    with pytest.raises(SourceUnavailable, match="objaverse needs network access .*--source local:DIR"):
        list(src.items())
    assert not any(p.is_file() for p in (tmp_path / "cache").rglob("*"))  # the old code kept a truncated file
    h.short.clear()
    h.files["object-paths.json.gz"] = _gz({"u1": "glbs/000-000/u1.glb"})
    h.files["metadata/000-000.json.gz"] = _gz({"u1": {"name": "bench", "license": "by"}})
    h.files["glbs/000-000/u1.glb"] = b"not really a glb"
    [item] = list(src.items())
    assert item.path.endswith("u1.glb") and Path(item.path).read_bytes() == b"not really a glb"
    assert "rejected" not in item.metadata


def test_objaverse_glb_download_failure_rejects_that_asset(server, tmp_path: Path) -> None:
    url, h = server
    h.files["lvis-annotations.json.gz"] = _gz({"bench": ["u1", "u2"]})
    h.files["object-paths.json.gz"] = _gz({"u1": "glbs/000-000/u1.glb", "u2": "glbs/000-000/u2.glb"})
    h.files["metadata/000-000.json.gz"] = _gz({u: {"name": "bench", "license": "by"} for u in ("u1", "u2")})
    h.files["glbs/000-000/u1.glb"] = b"glb bytes"
    items = list(ObjaverseSource(cache_dir=tmp_path / "cache", base_url=url, timeout=5, retries=1).items())
    assert [i.metadata.get("rejected", [None])[0] for i in items] == [None, "download_failed"]


def test_truncated_annotation_file_names_the_file(tmp_path: Path) -> None:
    base = tmp_path / "cache" / "hf-objaverse-v1"
    base.mkdir(parents=True)
    full = _gz({"bench": [f"u{i}" for i in range(500)]})
    (base / "lvis-annotations.json.gz").write_bytes(full[: len(full) // 2])
    with pytest.raises(SourceCacheCorrupt) as err:
        list(ObjaverseSource(cache_dir=tmp_path / "cache", base_url="http://127.0.0.1:9").items())
    assert str(base / "lvis-annotations.json.gz") in str(err.value) and "delete it" in str(err.value)


@pytest.mark.parametrize("target", ["fifo", "/dev/zero", ".", "huge"])
def test_a_bad_material_reference_rejects_that_asset_only(target: str, two_meshes: Path, tmp_path: Path) -> None:
    import os

    root = two_meshes
    (root / "trash_bin.json").unlink()
    if target == "fifo":
        os.mkfifo(root / "lamp.mtl")  # a reader of it would block forever
        ref = "lamp.mtl"
    elif target == "huge":
        with open(root / "lamp.mtl", "wb") as f:
            f.truncate(65 * 2**20)  # sparse: past the 64 MB a material file may hold
        ref = "lamp.mtl"
    else:
        ref = target
    bench_mesh().export(root / "lamp.obj")
    text = (root / "lamp.obj").read_text()
    (root / "lamp.obj").write_text(
        f"mtllib {ref}\n" + "\n".join(ln for ln in text.splitlines() if not ln.startswith("mtllib"))
    )
    cat = tmp_path / "c.duckdb"
    report = ingest(LocalSource(root), cat, IngestConfig(**FAST), progress=False)
    assert report.written == 2 and report.rejected == 1  # the bench and the trash bin (no sidecar now) go in
    reasons = _rows(cat, "SELECT reason FROM rejections")
    assert reasons == [("bad_reference",)]
