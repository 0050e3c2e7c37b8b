"""Stage `cluster`: DBSCAN (cosine) over description embeddings -> the description pool."""

from __future__ import annotations

import hashlib
import json
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from pipelines.common import PipelineError, load_params, stage_cli, write_metrics, write_table

POOL_COLUMNS = [
    "description_id",
    "cluster_id",
    "text",
    "category",
    "members",
    "n_members",
    "sources",
    "country_counts",
    "count",
]


def dbscan_labels(vectors: np.ndarray, eps: float, min_samples: int) -> np.ndarray:
    """DBSCAN labels with cosine distance; noise points get their own new labels (singleton pool entries)."""
    from sklearn.cluster import DBSCAN

    if len(vectors) == 0:
        return np.zeros(0, dtype=np.int64)
    # Unit vectors: euclidean eps' = sqrt(2 eps) is the same neighbourhood as cosine eps and uses the fast tree.
    labels = DBSCAN(eps=float(np.sqrt(2 * eps)), min_samples=min_samples, metric="euclidean").fit(vectors).labels_
    labels = labels.astype(np.int64)
    noise = np.flatnonzero(labels < 0)
    labels[noise] = labels.max(initial=-1) + 1 + np.arange(len(noise))
    return labels


def medoid(vectors: np.ndarray, weights: np.ndarray) -> int:
    """Index of the member with the highest count-weighted mean cosine similarity to the others."""
    sims = vectors @ vectors.T
    return int(np.argmax(sims @ weights))


def build_pool(descriptions: Any, texts: list[str], vectors: np.ndarray, *, eps: float, min_samples: int) -> Any:
    """Pure function of the stage: one row per cluster with its medoid text, members, sources and country counts."""
    import pandas as pd

    index = {t: i for i, t in enumerate(texts)}
    missing = sorted(set(descriptions["text"]) - set(index))
    if missing:
        raise PipelineError(
            f"{len(missing)} descriptions have no embedding (e.g. {missing[0]!r}); re-run the embed stage"
        )
    labels = dbscan_labels(vectors, eps, min_samples)
    weight = np.zeros(len(texts))
    cats: dict[int, Counter] = defaultdict(Counter)
    srcs: dict[int, set] = defaultdict(set)
    countries: dict[int, Counter] = defaultdict(Counter)
    for r in descriptions.itertuples():
        i = index[r.text]
        weight[i] += r.count
        lab = int(labels[i])
        cats[lab][r.category if isinstance(r.category, str) and r.category else None] += r.count
        srcs[lab].add(r.source)
        if isinstance(r.country, str) and r.country:
            countries[lab][r.country] += int(r.count)
    rows = []
    for lab in np.unique(labels):
        members = np.flatnonzero(labels == lab)
        w = weight[members]
        rep = members[medoid(vectors[members], w)]
        order = sorted(members, key=lambda m: (-weight[m], texts[m]))
        # The members' majority category; None (open vocabulary) only when no member has a category: a cluster
        # that joins "a statue" to a categorised description is that category's.
        named = {c: n for c, n in cats[int(lab)].items() if c is not None}
        cat = min(named.items(), key=lambda kv: (-kv[1], kv[0]))[0] if named else None
        rows.append(
            {
                "description_id": "pool-" + hashlib.sha1(texts[rep].encode()).hexdigest()[:12],
                "text": texts[rep],
                "category": cat,
                "members": [texts[m] for m in order],
                "n_members": len(members),
                "sources": sorted(srcs[int(lab)]),
                "country_counts": json.dumps(dict(sorted(countries[int(lab)].items()))),
                "count": int(w.sum()),
            }
        )
    # Cluster ids follow size so that id 0 is the largest cluster whatever DBSCAN's visiting order.
    rows.sort(key=lambda r: (-r["count"], -r["n_members"], r["text"]))
    for cid, r in enumerate(rows):
        r["cluster_id"] = cid
    return pd.DataFrame(rows, columns=POOL_COLUMNS)


def write_pool_to_catalog(pool: Any, catalog: str | Path) -> int:
    """Upsert the pool into the catalog's descriptions table (catalogs.writer.CatalogWriter)."""
    from catalogs.records import DescriptionRecord
    from catalogs.writer import CatalogWriter

    recs = [
        DescriptionRecord(
            description_id=r.description_id,
            text=r.text,
            category=r.category,
            cluster_id=int(r.cluster_id),
            members=list(r.members),
            sources=list(r.sources),
            country_counts={k: int(v) for k, v in json.loads(r.country_counts).items()},
        )
        for r in pool.itertuples()
    ]
    with CatalogWriter(catalog) as w:
        return w.upsert_descriptions(recs)


def run(params_path: str | None = None) -> dict[str, Any]:
    """Stage entry: write data/pool/pool.parquet and metrics.json (and the catalog's descriptions when configured)."""
    import pandas as pd

    from pipelines.embed import load_embeddings

    p = load_params(params_path, "cluster")
    if not 0 < float(p["eps"]) < 2 or int(p["min_samples"]) < 1:
        raise PipelineError(f"cluster.eps must be in (0, 2) and min_samples >= 1, got {p['eps']}, {p['min_samples']}")
    texts, vecs, _ = load_embeddings(p["embeddings"])
    pool = build_pool(
        pd.read_parquet(p["descriptions"]), texts, vecs, eps=float(p["eps"]), min_samples=int(p["min_samples"])
    )
    out = Path(p["out_dir"])
    write_table(pool, out / "pool.parquet")
    metrics = {
        "clusters": len(pool),
        "clusters_multi_member": int((pool["n_members"] > 1).sum()),
        "largest_cluster_members": int(pool["n_members"].max()) if len(pool) else 0,
        "clusters_open_vocabulary": int(pool["category"].isna().sum()),
        "descriptions": int(pool["n_members"].sum()),
    }
    if p["catalog"]:
        metrics["catalog_descriptions_written"] = write_pool_to_catalog(pool, p["catalog"])
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("cluster", run)
