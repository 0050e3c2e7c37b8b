"""Benchmark: embed (packaged MiniLM) + DBSCAN-cluster N synthetic street-object descriptions; prints seconds."""

from __future__ import annotations

import argparse
import time

import numpy as np

from catalogs.categories import CATEGORIES
from pipelines.cluster import dbscan_labels
from pipelines.embed import embed_texts

COLOURS = [
    "red",
    "green",
    "blue",
    "gray",
    "black",
    "white",
    "yellow",
    "orange",
    "brown",
    "silver",
    "dark green",
    "teal",
]
MATERIALS = ["metal", "wooden", "plastic", "concrete", "steel", "stone", "aluminium", "cast iron"]
SIZES = ["small", "medium", "large", "tall", "short", "wide", "narrow"]
EXTRAS = [
    "",
    " with a backrest",
    " on a pole",
    " next to the curb",
    " with a sticker",
    " covered in graffiti",
    " with a logo",
    " near a crosswalk",
    " in front of a shop",
    " with a rounded top",
]


def synthetic_descriptions(n: int, seed: int = 0) -> list[str]:
    """n varied descriptions '<a> <size> <colour> <material> <category><extra>' drawn with a seeded generator."""
    rng = np.random.default_rng(seed)
    pick = lambda xs: [xs[i] for i in rng.integers(0, len(xs), n)]  # noqa: E731
    parts = zip(pick(SIZES), pick(COLOURS), pick(MATERIALS), pick(list(CATEGORIES)), pick(EXTRAS), strict=True)
    return [f"a {s} {c} {m} {CATEGORIES[cat].words}{e}" for s, c, m, cat, e in parts]


def main() -> None:
    """Time embedding and clustering; print the figures."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=25_000)
    ap.add_argument("--eps", type=float, default=0.15)
    ap.add_argument("--min-samples", type=int, default=2)
    a = ap.parse_args()
    texts = synthetic_descriptions(a.n)
    t0 = time.perf_counter()
    vecs, model = embed_texts(texts, None, 64)  # 64 measured fastest on a 2-core CPU (32-256 tried)
    t1 = time.perf_counter()
    labels = dbscan_labels(vecs, a.eps, a.min_samples)
    t2 = time.perf_counter()
    print(f"descriptions: {a.n} ({len(set(texts))} unique), model {model}, dim {vecs.shape[1]}")
    print(f"embed: {t1 - t0:.1f} s ({a.n / (t1 - t0):.0f} texts/s)")
    print(f"cluster (DBSCAN cosine eps={a.eps}): {t2 - t1:.1f} s, {len(np.unique(labels))} pool entries")
    print(f"total: {t2 - t0:.1f} s (target <= 60 s)")


if __name__ == "__main__":
    main()
