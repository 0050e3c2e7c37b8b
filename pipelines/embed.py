"""Stage `embed`: sentence embeddings of every unique description (packaged MiniLM by default, any model from a path)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kernel.reproducible import write_parquet
from pipelines.common import load_params, progress, stage_cli, write_metrics

# Stored vectors are rounded to this many decimals: float noise in the last bits (BLAS kernels, batch padding
# shapes) mostly falls below the grid, so the same texts give the same bytes more often across machines. The
# rounding moves a cosine by < 1e-4, far below DBSCAN's eps.
DECIMALS = 5
CHUNK = 2048  # texts per encode call: a rich progress bar advances per chunk (fixed, so batches are too)


def embed_texts(texts: list[str], model: str | None = None, batch_size: int = 64) -> tuple[np.ndarray, str]:
    """Pure function of the stage: (n, d) unit float32 vectors for `texts` and the model's name."""
    import torch

    from retrieval.encoders.text import TextEncoder

    enc = TextEncoder(model, batch_size=batch_size)
    # Street descriptions repeat ("a green metal bench"): embed each distinct text once, then scatter back.
    # np.unique sorts, so the batches (and their padding) depend only on the set of texts, not on their order.
    unique, inverse = np.unique(np.asarray(list(texts), dtype=object), return_inverse=True)
    todo = unique.tolist()
    chunks = [todo[i : i + CHUNK] for i in range(0, len(todo), CHUNK)]
    was = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)  # no nondeterministic kernels; restored after, it is process-global
    try:
        if len(chunks) <= 1:
            vecs = enc.encode(todo)
        else:
            parts = []
            with progress() as bar:
                task = bar.add_task("embed", total=len(todo))
                for chunk in chunks:
                    parts.append(enc.encode(chunk))
                    bar.advance(task, len(chunk))
            vecs = np.concatenate(parts)
    finally:
        torch.use_deterministic_algorithms(was)
    return vecs[inverse.reshape(-1)], enc.name


def save_embeddings(path: str | Path, texts: list[str], vectors: np.ndarray, model: str) -> Path:
    """Write (text, vector) rows as parquet (vectors rounded to DECIMALS), the model name in the schema metadata."""
    import pyarrow as pa

    d = vectors.shape[1] if vectors.ndim == 2 else 0
    flat = np.round(np.asarray(vectors, dtype=np.float32).reshape(-1), DECIMALS).astype(np.float32)
    vec = pa.FixedSizeListArray.from_arrays(pa.array(flat), d)
    table = pa.table({"text": pa.array(texts, pa.string()), "vector": vec}).replace_schema_metadata({"model": model})
    return write_parquet(table, path)


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

    p = load_params(params_path, "embed")
    texts = sorted(set(pd.read_parquet(p["descriptions"])["text"]))
    vecs, name = embed_texts(texts, p["model"] or None, int(p["batch_size"]))
    out = Path(p["out_dir"])
    save_embeddings(out / "embeddings.parquet", texts, vecs, name)
    metrics = {"texts_embedded": len(texts), "dim": int(vecs.shape[1])}
    write_metrics(out / "metrics.json", metrics)
    return metrics


if __name__ == "__main__":
    stage_cli("embed", run)
