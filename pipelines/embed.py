"""Stage `embed`: sentence embeddings of every unique description (packaged MiniLM by default, any model from a path)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pipelines.common import load_params, stage_cli, write_metrics

DEFAULTS: dict[str, Any] = {
    "model": "all-MiniLM-L6-v2",
    "batch_size": 64,
    "descriptions": "data/describe/descriptions.parquet",
    "out_dir": "data/embed",
}


def embed_texts(texts: list[str], model: str | None = None, batch_size: int = 64) -> tuple[np.ndarray, str]:
    """Pure function of the stage: (n, d) unit float32 vectors for `texts` and the model's name."""
    from retrieval.encoders.text import TextEncoder

    enc = TextEncoder(model, batch_size=batch_size)
    # Street descriptions repeat ("a green metal bench"): embed each distinct text once, then scatter back.
    unique, inverse = np.unique(np.asarray(list(texts), dtype=object), return_inverse=True)
    vecs = enc.encode(unique.tolist(), show_progress=len(unique) > 2000)
    return vecs[inverse.reshape(-1)], enc.name


def save_embeddings(path: str | Path, texts: list[str], vectors: np.ndarray, model: str) -> Path:
    """Write (text, vector) rows as parquet with the model name in the schema metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    d = vectors.shape[1] if vectors.ndim == 2 else 0
    vec = pa.FixedSizeListArray.from_arrays(pa.array(vectors.reshape(-1).astype(np.float32)), d)
    table = pa.table({"text": pa.array(texts, pa.string()), "vector": vec}).replace_schema_metadata({"model": model})
    pq.write_table(table, p)
    return p


def load_embeddings(path: str | Path) -> tuple[list[str], np.ndarray, str]:
    """Read (texts, (n, d) float32 vectors, model name) written by save_embeddings."""
    import pyarrow.parquet as pq

    t = pq.read_table(path)
    texts = t.column("text").to_pylist()
    col = t.column("vector").combine_chunks()
    d = col.type.list_size
    vecs = col.flatten().to_numpy(zero_copy_only=False).astype(np.float32).reshape(len(texts), d)
    return texts, vecs, (t.schema.metadata or {}).get(b"model", b"").decode()


def run(params_path: str | None = None) -> dict[str, Any]:
    """Stage entry: write data/embed/embeddings.parquet and metrics.json."""
    import pandas as pd

    p = load_params(params_path, "embed", DEFAULTS)
    texts = sorted(set(pd.read_parquet(p["descriptions"])["text"]))
    vecs, name = embed_texts(texts, p["model"] or None, int(p["batch_size"]))
    out = Path(p["out_dir"])
    save_embeddings(out / "embeddings.parquet", texts, vecs, name)
    metrics = {"texts_embedded": len(texts), "dim": int(vecs.shape[1])}
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("embed", run)
