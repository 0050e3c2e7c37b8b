"""A real ingest subprocess SIGKILLed midway resumes to exactly the catalog of an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import duckdb

from retrieval.ingest import IngestConfig, ingest
from retrieval.sources.procedural import ProceduralSource

REPO = Path(__file__).resolve().parents[2]
N = 12


def _cmd(cat: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "curbside.cli.main",
        "catalog",
        "ingest",
        "--source",
        "procedural",
        "--per-category",
        "1",
        "--limit",
        str(N),
        "--views",
        "4",
        "--catalog",
        str(cat),
    ]


def _summary(cat: Path) -> dict:
    con = duckdb.connect(str(cat), read_only=True)
    try:
        q = {
            "assets": "SELECT asset_id, content_hash, category, depth, width, height FROM assets ORDER BY 1",
            "views": "SELECT asset_id, count(*), count(DISTINCT view_index), sum(informative::INT) FROM views "
            "GROUP BY 1 ORDER BY 1",
            "matches": "SELECT asset_id, description_id, rank FROM matches ORDER BY 1, 2",
            "embeddings": "SELECT owner_kind, owner_id FROM embeddings WHERE owner_kind LIKE 'asset%' ORDER BY 1, 2",
            "rejections": "SELECT source_id, reason FROM rejections ORDER BY 1",
        }
        return {k: con.execute(v).fetchall() for k, v in q.items()}
    finally:
        con.close()


def test_sigkill_midway_then_rerun_equals_uninterrupted(tmp_path):
    cat = tmp_path / "killed" / "c.duckdb"
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    log = tmp_path / "first.log"
    with open(log, "wb") as fh:
        proc = subprocess.Popen(_cmd(cat), cwd=REPO, env=env, stdout=fh, stderr=subprocess.STDOUT)
    # The catalog file is locked by the writer, so progress is read from the asset files: the local executor
    # writes asset k's rows before it starts asset k+1, so 4 exported GLBs mean at least 3 assets are committed.
    glbs = cat.parent / "c_assets" / "retrieval" / "procedural"
    deadline = time.monotonic() + 180
    while len(list(glbs.glob("*/mesh.glb"))) < 4:
        assert proc.poll() is None, f"ingest ended before it could be killed:\n{log.read_text()[-2000:]}"
        assert time.monotonic() < deadline, "ingest made no progress in 180 s"
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(30) == -signal.SIGKILL
    partial = _summary(cat)  # reopening replays DuckDB's write-ahead log left by the killed process
    assert 3 <= len(partial["assets"]) < N
    assert {a for a, *_ in partial["views"]} == {a for a, *_ in partial["assets"]}  # no half-written asset

    done = subprocess.run(_cmd(cat), cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert f"skipped {len(partial['assets'])}" in " ".join(done.stdout.split())
    resumed = _summary(cat)

    ref = tmp_path / "ref" / "c.duckdb"
    ingest(
        ProceduralSource(per_category=1, work_dir=ref.parent / ".procedural_source"),
        ref,
        IngestConfig(n_views=4),
        limit=N,
        progress=False,
    )
    expected = _summary(ref)
    assert len(expected["assets"]) == N and not expected["rejections"]
    assert [a[:2] for a in resumed["assets"]] == [a[:2] for a in expected["assets"]]  # ids and content hashes
    assert resumed == expected
    assert all(n == d == 4 and i == 3 for _, n, d, i in resumed["views"])  # no duplicated or missing views
