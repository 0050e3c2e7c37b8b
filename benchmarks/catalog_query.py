"""Catalog query latency at 10,000 and 100,000 synthetic assets: p50/p95 of the SQL alone and end to end.

Run: `python benchmarks/catalog_query.py [--sizes 10000 100000] [--repeats 50] [--no-text] [--encoder numpy|torch]`.
Rows are synthetic but realistic (categories, classes, zones, sizes, sources, licences) with random unit
vectors as text embeddings; the end-to-end figure adds embedding the query text with all-MiniLM-L6-v2
(in numpy, as `curbside catalog query` does, or with `--encoder torch` through sentence-transformers).
Target: p95 <= 100 ms at 100,000 assets on a 2-core machine. Figures are printed, never asserted.

Cold mode: `python benchmarks/catalog_query.py --cold 5 [--catalog PATH]` runs the CLI
`curbside catalog query "fire hydrant" --json --limit 5` in a fresh process N times on the procedural catalog
(built into a temporary folder unless --catalog names one) and prints each run's wall and CPU time,
then the warm figure: the same query in one process (encoder loaded, connection open), p50/p95.
Target: a cold query <= 2 s wall on the shared 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from catalogs.categories import CATEGORIES
from catalogs.query import QueryFilters, search
from catalogs.reader import open_catalog
from catalogs.records import AssetRecord
from catalogs.schema import DEFAULT_EMBEDDING_DIM, ZONES
from catalogs.writer import build_catalog

SOURCES = ("procedural", "objaverse", "local")
LICENSES = ("CC0-1.0", "CC-BY-4.0", "CC-BY-NC-4.0")
FILTERS = QueryFilters(category="bench", zone="furnishing", max_height=1.2)


def synthetic_records(n: int, rng: np.random.Generator) -> list[AssetRecord]:
    """`n` plausible asset rows (the files they name do not exist)."""
    names = list(CATEGORIES)
    cats = rng.integers(len(names), size=n)
    sizes = rng.uniform(0.1, 3.0, size=(n, 3))
    out = []
    for i in range(n):
        c = names[cats[i]]
        zones = [str(z) for z in rng.choice(ZONES, size=int(rng.integers(1, 3)), replace=False)]
        out.append(
            AssetRecord(
                asset_id=f"syn-{i:07d}",
                source=SOURCES[i % 3],
                source_id=str(i),
                category=c,
                object_class=CATEGORIES[c].object_class,
                zones=zones,
                depth=float(sizes[i, 0]),
                width=float(sizes[i, 1]),
                height=float(sizes[i, 2]),
                description=f"a {c.replace('_', ' ')} variant {i}",
                synonyms=[c],
                license=LICENSES[i % 3],
                mass=float(sizes[i].prod() * 100),
                mesh_path=f"syn_assets/{i}/mesh.obj",
                params={"seed": i},
            )
        )
    return out


def fill(path: Path, n: int, seed: int = 0) -> None:
    """Write a catalog of `n` synthetic assets with random unit-vector embeddings."""
    rng = np.random.default_rng(seed)
    records = synthetic_records(n, rng)
    vecs = rng.normal(size=(n, DEFAULT_EMBEDDING_DIM)).astype(np.float32)
    with build_catalog(path) as w:
        w.upsert_assets(records)
        w.upsert_embeddings("asset_text", [r.asset_id for r in records], vecs)


def percentiles(times_s: list[float]) -> tuple[float, float]:
    """p50 and p95 in milliseconds."""
    ms = np.asarray(times_s) * 1000.0
    return float(np.percentile(ms, 50)), float(np.percentile(ms, 95))


def cold_runs(catalog: Path, runs: int, text: str = "fire hydrant") -> list[dict]:
    """Run `curbside catalog query TEXT --json` in `runs` fresh processes; wall and CPU seconds of each."""
    cli = Path(sys.executable).with_name("curbside")
    cmd = [str(cli), "catalog", "query", text, "--catalog", str(catalog), "--json", "--limit", "5"]
    env = dict(os.environ, HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1")
    out = []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        top = json.loads(proc.stdout)["results"][0]["category"]
        out.append({"wall_s": wall, "cpu_s": cpu, "top": top, "load1": os.getloadavg()[0]})
    return out


def warm_runs(catalog: Path, repeats: int, text: str = "fire hydrant") -> list[float]:
    """Seconds per query (embed + SQL) in one process with the encoder loaded and the connection open."""
    from catalogs.text_encoder import NumpyTextEncoder

    encoder = NumpyTextEncoder()
    con = open_catalog(catalog)
    search(con, encoder.encode([text])[0], limit=5)  # first query pages the weights and the columns in
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        search(con, encoder.encode([text])[0], limit=5)
        times.append(time.perf_counter() - t0)
    con.close()
    return times


def cold_main(args: argparse.Namespace) -> None:
    """Cold CLI queries in fresh processes, then the warm in-process figure; prints a table."""
    from rich.console import Console
    from rich.table import Table

    console = Console(stderr=True)
    with tempfile.TemporaryDirectory() as tmp:
        catalog = args.catalog
        if catalog is None:
            os.environ.setdefault("HF_HUB_OFFLINE", "1")
            from retrieval.build import build_procedural_catalog

            catalog = Path(tmp) / "default.duckdb"
            build_procedural_catalog(catalog, variants=3, seed=0, progress=False)
            console.print(f"built the procedural catalog (3 variants) in {catalog}")
        runs = cold_runs(catalog, args.cold)
        warm = warm_runs(catalog, args.repeats)
    table = Table(title='cold `curbside catalog query "fire hydrant" --json --limit 5` (fresh process each)')
    for col in ("run", "wall s", "CPU s", "top category", "load avg (1 min)"):
        table.add_column(col, justify="right")
    for i, r in enumerate(runs, 1):
        table.add_row(str(i), f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}", r["top"], f"{r['load1']:.1f}")
    walls = [r["wall_s"] for r in runs]
    table.add_row("median", f"{np.median(walls):.2f}", f"{np.median([r['cpu_s'] for r in runs]):.2f}", "", "")
    Console().print(table)
    p50, p95 = percentiles(warm)
    Console().print(
        f"warm (one process, numpy encoder loaded): embed + SQL p50 {p50:.1f} ms, p95 {p95:.1f} ms "
        f"over {len(warm)} queries"
    )
    console.print(f"machine: {os.cpu_count()} CPU cores visible")


def main() -> None:
    """Fill the catalogs, time the queries, print a rich table."""
    from rich.console import Console
    from rich.table import Table

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--no-text", action="store_true", help="skip the end-to-end runs that embed the query text")
    ap.add_argument(
        "--encoder",
        choices=("numpy", "torch"),
        default="numpy",
        help="query-text encoder of the end-to-end runs (the CLI uses numpy)",
    )
    ap.add_argument(
        "--cold",
        type=int,
        default=0,
        metavar="N",
        help="instead: N cold CLI queries in fresh processes, then the warm in-process figure",
    )
    ap.add_argument("--catalog", type=Path, default=None, help="catalog for --cold (default: build one)")
    args = ap.parse_args()
    if args.cold:
        cold_main(args)
        return
    console = Console(stderr=True)
    encoder = None
    if not args.no_text and args.encoder == "numpy":
        from catalogs.text_encoder import NumpyTextEncoder

        encoder = NumpyTextEncoder()
    elif not args.no_text:
        os.environ.setdefault("HF_HUB_OFFLINE", "1")
        from retrieval.encoders.text import TextEncoder

        encoder = TextEncoder()
        import torch

        # One sentence needs no intra-op parallelism, and torch's spinning OpenMP workers would steal the
        # cores DuckDB scans with (the CLI's query command does the same).
        torch.set_num_threads(1)
    texts = ["fire hydrant", "somewhere to sit", "garbage can", "street light", "red mailbox"]
    table = Table(title=f"catalog query latency (ms, {args.repeats} queries each, limit 10)")
    for col in ("assets", "query", "p50", "p95"):
        table.add_column(col, justify="right" if col in ("p50", "p95") else "left")
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            path = Path(tmp) / f"bench_{n}.duckdb"
            t0 = time.perf_counter()
            fill(path, n)
            console.print(f"filled {n:,} assets in {time.perf_counter() - t0:.1f} s")
            con = open_catalog(path)
            qs = rng.normal(size=(args.repeats, DEFAULT_EMBEDDING_DIM)).astype(np.float32)
            t0 = time.perf_counter()
            search(con, qs[0])  # first query reads the columns from disk into DuckDB's buffer pool
            first = time.perf_counter() - t0
            table.add_row(f"{n:,}", "SQL, first query on a fresh connection", f"{first * 1000:.1f}", "")
            for label, filters in (("SQL, no filter", None), ("SQL, category+zone+height", FILTERS)):
                times = []
                for q in qs:
                    t0 = time.perf_counter()
                    search(con, q, filters, limit=10)
                    times.append(time.perf_counter() - t0)
                p50, p95 = percentiles(times)
                table.add_row(f"{n:,}", label, f"{p50:.1f}", f"{p95:.1f}")
            if encoder is not None:
                for label, filters in (("end to end (embed + SQL)", None), ("end to end, filtered", FILTERS)):
                    times = []
                    for i in range(args.repeats):
                        t0 = time.perf_counter()
                        search(con, encoder.encode([texts[i % len(texts)]])[0], filters, limit=10)
                        times.append(time.perf_counter() - t0)
                    p50, p95 = percentiles(times)
                    table.add_row(f"{n:,}", label, f"{p50:.1f}", f"{p95:.1f}")
            con.close()
    Console().print(table)
    console.print(f"machine: {os.cpu_count()} CPU cores visible")


if __name__ == "__main__":
    main()
