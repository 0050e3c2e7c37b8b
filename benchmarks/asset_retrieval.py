"""Retrieval throughput per core: normalise, render (8 views), score (imagenet / text), and an extrapolation table.

Run: HF_HUB_OFFLINE=1 python benchmarks/asset_retrieval.py [N_ASSETS]
"""

from __future__ import annotations

import sys
import tempfile
import time



def main(n: int = 12) -> None:
    """Ingest `n` procedural assets on one core and print assets/s per stage and the Objaverse table."""
    import torch

    from retrieval.ingest import IngestConfig, ingest
    from retrieval.sources import open_source

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        src = open_source("procedural", per_category=1, work_dir=f"{tmp}/proc")
        ingest(src, f"{tmp}/warm.duckdb", IngestConfig(), limit=2, progress=False)  # model loading excluded
        t0 = time.perf_counter()
        rep = ingest(src, f"{tmp}/c.duckdb", IngestConfig(), limit=n, progress=False)
        wall = time.perf_counter() - t0
    done = rep.written + rep.rejected
    print(f"{done} assets, wall {wall:.1f}s = {done / wall:.2f} assets/s on 1 core (incl. catalog writes)")
    for stage, sec in rep.seconds.items():
        print(f"  {stage:10s} {done / sec:8.2f} assets/s/core  ({1000 * sec / done:.0f} ms/asset)")
    per_core = done / sum(rep.seconds.values())
    print(f"render+score+curate: {per_core:.2f} assets/s/core")
    print("| dataset | objects | workers (1 core each) | hours |")
    for name, count in (("Objaverse", 800_000), ("Objaverse-XL", 10_000_000)):
        for workers in (16, 64, 256):
            print(f"| {name} | {count:,} | {workers} | {count / (per_core * workers) / 3600:.1f} |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 12)
