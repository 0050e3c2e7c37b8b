"""Text search over the catalog: cosine similarity computed in DuckDB, filters bound as SQL parameters.

Callers embed the query text (retrieval.encoders.text) and pass the vector here; this module stays
free of torch so it can be timed and reused on its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import duckdb
import numpy as np


@dataclass
class QueryFilters:
    """Optional filters of a catalog query; each one is bound as a SQL parameter, never formatted in."""

    category: str | None = None
    object_class: str | None = None
    zone: str | None = None
    max_height: float | None = None
    source: str | None = None
    license: str | None = None


RESULT_COLUMNS = ("asset_id", "category", "object_class", "source", "license", "depth", "width", "height", "description", "score")


def search(
    con: duckdb.DuckDBPyConnection,
    query_vector: np.ndarray,
    filters: QueryFilters | None = None,
    *,
    limit: int = 10,
    model: str | None = None,
) -> list[dict]:
    """Return up to `limit` assets ranked by cosine similarity of their text embedding to `query_vector`."""
    filters = filters or QueryFilters()
    meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
    dim = int(meta["embedding_dim"])
    model = model or meta["embedding_model"]
    vec = np.asarray(query_vector, dtype=np.float32).reshape(-1)
    if vec.shape[0] != dim:
        raise ValueError(f"query vector has {vec.shape[0]} dimensions, the catalog's embeddings have {dim}")
    where = ["e.owner_kind = 'asset_text'", "e.model = $model"]
    params: dict[str, object] = {"model": model, "q": vec.tolist(), "limit": int(limit)}
    if filters.category is not None:
        where.append("a.category = $category")
        params["category"] = filters.category
    if filters.object_class is not None:
        where.append("a.object_class = $object_class")
        params["object_class"] = filters.object_class
    if filters.zone is not None:
        where.append("list_contains(a.zones, $zone)")
        params["zone"] = filters.zone
    if filters.max_height is not None:
        where.append("a.height <= $max_height")
        params["max_height"] = float(filters.max_height)
    if filters.source is not None:
        where.append("a.source = $source")
        params["source"] = filters.source
    if filters.license is not None:
        where.append("a.license = $license")
        params["license"] = filters.license
    sql = f"""
        SELECT a.asset_id, a.category, a.object_class, a.source, a.license, a.depth, a.width, a.height,
               a.description, array_cosine_similarity(e.vector, $q::FLOAT[{dim}]) AS score
        FROM embeddings e JOIN assets a ON a.asset_id = e.owner_id
        WHERE {' AND '.join(where)}
        ORDER BY score DESC, a.asset_id
        LIMIT $limit
    """
    rows = con.execute(sql, params).fetchall()
    return [dict(zip(RESULT_COLUMNS, r)) for r in rows]
