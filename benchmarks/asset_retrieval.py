"""Retrieval throughput per core at the ingest defaults (20 views at 160 px, 3 scored by the aligned scorer + text):
normalise, render, score, curate per stage, and an extrapolation table. The headline is assets per CPU-second of this
process (one torch thread), so other processes' load does not count against it; stage and wall times are beside.

Run: HF_HUB_OFFLINE=1 python benchmarks/asset_retrieval.py [N_ASSETS] [--scorer aligned|imagenet]
"""

from __future__ import annotations

import tempfile
import time


def main(n: int = 12, scorer: str = "aligned") -> None:
    """Ingest `n` procedural assets on one core and print assets/s per stage and the Objaverse table."""
    import json
    from pathlib import Path

    import torch

    from retrieval.ingest import IngestConfig, ingest
    from retrieval.scoring import ScoringConfig
    from retrieval.sources import open_source

    torch.set_num_threads(1)
    config = IngestConfig(scoring=ScoringConfig(image_encoder=scorer))
    with tempfile.TemporaryDirectory() as tmp:
        src = open_source("procedural", per_category=1, work_dir=f"{tmp}/proc")
        ingest(src, f"{tmp}/warm.duckdb", config, limit=2, progress=False)  # model loading excluded
        # The meshes exist before the clock starts, as downloaded Objaverse files do: generating procedural
        # meshes is the source's work, not retrieval's.
        items = list(src.items(n))
        ready = type("Ready", (), {"name": src.name, "items": lambda self, limit=None: iter(items[:limit])})()
        t0, c0 = time.perf_counter(), time.process_time()
        rep = ingest(ready, f"{tmp}/c.duckdb", config, limit=n, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    done = rep.written + rep.rejected
    print(
        f"{done} assets ({config.n_views} views at {config.image_size} px, {config.n_informative} scored, scorer "
        f"{scorer}): {cpu:.1f} CPU-s = {done / cpu:.2f} assets per CPU-second; wall {wall:.1f} s = "
        f"{done / wall:.2f} assets/s (incl. catalog writes)"
    )
    for stage, sec in rep.seconds.items():
        print(f"  {stage:10s} {done / sec:8.2f} assets/s  ({1000 * sec / done:.0f} ms/asset, wall)")
    per_core = done / cpu
    print("| dataset | objects | workers (1 core each) | hours |")
    for name, count in (("Objaverse", 800_000), ("Objaverse-XL", 10_000_000)):
        for workers in (16, 64, 256):
            print(f"| {name} | {count:,} | {workers} | {count / (per_core * workers) / 3600:.1f} |")
    out = Path(__file__).parent / "results" / "retrieval"
    out.mkdir(parents=True, exist_ok=True)
    (out / f"asset_retrieval_{scorer}.json").write_text(
        json.dumps(
            {
                "command": f"HF_HUB_OFFLINE=1 python benchmarks/asset_retrieval.py {n} --scorer {scorer}",
                "assets": done,
                "views": config.n_views,
                "image_size": config.image_size,
                "scored_views": config.n_informative,
                "assets_per_cpu_s": round(per_core, 3),
                "wall_assets_per_s": round(done / wall, 3),
                "stage_ms_wall": {k: round(1000 * v / done, 1) for k, v in rep.seconds.items()},
            },
            indent=2,
        )
        + "\n"
    )


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n", nargs="?", type=int, default=12, help="assets to ingest")
    ap.add_argument("--scorer", default="aligned", choices=("aligned", "imagenet", "none"))
    a = ap.parse_args()
    main(a.n, a.scorer)
