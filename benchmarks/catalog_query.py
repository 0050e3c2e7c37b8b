"""Catalog query latency at 10,000 and 100,000 synthetic assets: p50/p95 of the SQL alone and end to end.

Run: `python benchmarks/catalog_query.py [--sizes 10000 100000] [--repeats 50] [--no-text]`.
Rows are synthetic but realistic (categories, classes, zones, sizes, sources, licences) with random unit
vectors as text embeddings; the end-to-end figure adds embedding the query text with all-MiniLM-L6-v2.
Target (issue 2): p95 <= 100 ms at 100,000 assets on a 2-core machine. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from catalogs.query import QueryFilters, search
from catalogs.reader import open_catalog
from catalogs.records import AssetRecord
from catalogs.schema import DEFAULT_EMBEDDING_DIM, ZONES
from catalogs.writer import build_catalog

CATEGORIES = {
    "street_lamp": "standard", "utility_pole": "standard", "traffic_sign": "standard", "traffic_light": "standard",
    "fire_hydrant": "standard", "bollard": "standard", "tree": "standard", "bench": "non_standard",
    "trash_bin": "non_standard", "recycling_bin": "non_standard", "planter": "non_standard",
    "mailbox": "non_standard", "bike_rack": "non_standard", "newspaper_box": "non_standard",
    "vending_machine": "non_standard", "phone_booth": "non_standard", "bus_shelter": "non_standard",
    "kiosk": "non_standard", "cafe_table": "non_standard", "chair": "non_standard", "traffic_cone": "clutter",
    "barrier": "clutter", "bicycle": "clutter", "e_scooter": "clutter", "shopping_bag": "clutter",
    "cardboard_box": "clutter", "drink_can": "clutter",
}
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
        out.append(AssetRecord(
            asset_id=f"syn-{i:07d}", source=SOURCES[i % 3], source_id=str(i), category=c,
            object_class=CATEGORIES[c], zones=zones, depth=float(sizes[i, 0]), width=float(sizes[i, 1]),
            height=float(sizes[i, 2]), description=f"a {c.replace('_', ' ')} variant {i}", synonyms=[c],
            license=LICENSES[i % 3], mass=float(sizes[i].prod() * 100), mesh_path=f"syn_assets/{i}/mesh.obj",
            params={"seed": i},
        ))
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


def main() -> None:
    """Fill the catalogs, time the queries, print a rich table."""
    from rich.console import Console
    from rich.table import Table

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--no-text", action="store_true", help="skip the end-to-end runs that embed the query text")
    args = ap.parse_args()
    console = Console(stderr=True)
    encoder = None
    if not args.no_text:
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
