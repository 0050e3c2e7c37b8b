"""Text search over the catalog: cosine similarity computed in DuckDB, filters bound as SQL parameters.

Callers embed the query text (retrieval.encoders.text) and pass the vector here; this module stays
free of torch so it can be timed and reused on its own. Catalogs scored by the aligned scorer also hold one
embedding per scored view in the scorer's joint space (catalogs.aligned): a query then ranks by
(1 - view_weight) x text cosine + view_weight x best view cosine, so what the views show (colour, shape, "with a
lid") counts beside what the metadata says.
"""

from __future__ import annotations

from dataclasses import dataclass

import duckdb
import numpy as np

from catalogs.reader import read_meta
from catalogs.schema import ASSET_TEXT_KIND, ASSET_VIEW_KIND


@dataclass
class QueryFilters:
    """Optional filters of a catalog query; each one is bound as a SQL parameter, never formatted in."""

    category: str | None = None
    object_class: str | None = None
    zone: str | None = None
    max_height: float | None = None
    source: str | None = None
    license: str | None = None


RESULT_COLUMNS = (
    "asset_id",
    "category",
    "object_class",
    "source",
    "license",
    "depth",
    "width",
    "height",
    "description",
    "score",
)


def _asset_filters(filters: QueryFilters) -> tuple[list[str], dict[str, object]]:
    """SQL conditions on `assets a` and their bound parameters; values never enter the SQL text."""
    where: list[str] = []
    params: dict[str, object] = {}
    for column in ("category", "object_class", "source", "license"):
        value = getattr(filters, column)
        if value is not None:
            where.append(f"a.{column} = ${column}")
            params[column] = str(value)
    if filters.zone is not None:
        where.append("list_contains(a.zones, $zone)")
        params["zone"] = str(filters.zone)
    if filters.max_height is not None:
        where.append("a.height <= $max_height")
        params["max_height"] = float(filters.max_height)
    return where, params


def has_view_embeddings(con: duckdb.DuckDBPyConnection, view_model: str = "aligned") -> bool:
    """Whether the catalog holds per-view embeddings of `view_model` (an aligned-scorer ingest)."""
    # An existence probe, not a count: every query of a 100k-asset catalog runs it.
    return (
        con.execute(
            "SELECT 1 FROM embeddings WHERE owner_kind = ? AND model LIKE ? LIMIT 1",
            [ASSET_VIEW_KIND, f"{view_model}%#view%"],
        ).fetchone()
        is not None
    )


def search(
    con: duckdb.DuckDBPyConnection,
    query_vector: np.ndarray,
    filters: QueryFilters | None = None,
    *,
    limit: int = 10,
    model: str | None = None,
    view_vector: np.ndarray | None = None,
    view_model: str = "aligned",
    view_weight: float = 0.5,
) -> list[dict]:
    """Return up to `limit` assets ranked by cosine similarity of their text embedding to `query_vector`, fused
    with the best of their `view_model` view embeddings' cosines to `view_vector` when one is given."""
    filters = filters or QueryFilters()
    if int(limit) < 1:
        raise ValueError(f"limit must be at least 1, got {limit}")
    meta = read_meta(con)
    dim = int(meta["embedding_dim"])
    model = model or meta["embedding_model"]
    vec = np.asarray(query_vector, dtype=np.float32).reshape(-1)
    if vec.shape[0] != dim:
        raise ValueError(f"query vector has {vec.shape[0]} dimensions, the catalog's embeddings have {dim}")
    norm = float(np.linalg.norm(vec))
    if not np.isfinite(norm) or norm == 0.0:
        raise ValueError("query vector is zero or not finite; embed a non-empty text")
    # Stored vectors are unit length (CatalogWriter.upsert_embeddings), so the inner product with the unit
    # query vector is the cosine similarity, without recomputing 100k norms per query.
    vec = vec / norm
    where, params = _asset_filters(filters)
    params.update({"kind": ASSET_TEXT_KIND, "model": model, "q": vec.tolist(), "limit": int(limit)})
    score = f"array_inner_product(e.vector, $q::FLOAT[{dim}])"
    columns = ", ".join(f"a.{c}" for c in RESULT_COLUMNS if c != "score")
    if view_vector is not None:
        v = np.asarray(view_vector, dtype=np.float32).reshape(-1)
        if v.shape[0] != dim or not np.isfinite(v).all() or not np.any(v):
            raise ValueError(f"view vector must be a finite non-zero vector of {dim} dimensions, got shape {v.shape}")
        params.update(
            {
                "vkind": ASSET_VIEW_KIND,
                "vmodel": f"{view_model}%#view%",
                "v": (v / np.linalg.norm(v)).tolist(),
                "w": float(view_weight),
            }
        )
        sql = f"""
            WITH txt AS (SELECT e.owner_id, {score} AS s FROM embeddings e
                         WHERE e.owner_kind = $kind AND e.model = $model),
                 img AS (SELECT owner_id, max(array_inner_product(vector, $v::FLOAT[{dim}])) AS s FROM embeddings
                         WHERE owner_kind = $vkind AND model LIKE $vmodel GROUP BY owner_id)
            SELECT {columns}, (1 - $w) * txt.s + $w * coalesce(img.s, txt.s) AS score
            FROM txt JOIN assets a ON a.asset_id = txt.owner_id LEFT JOIN img ON img.owner_id = txt.owner_id
            {"WHERE " + " AND ".join(where) if where else ""}
            ORDER BY score DESC, a.asset_id
            LIMIT $limit
        """
    elif where:
        # Selective filters first: the join computes similarities only for the assets that pass.
        sql = f"""
            SELECT {columns}, {score} AS score
            FROM embeddings e JOIN assets a ON a.asset_id = e.owner_id
            WHERE e.owner_kind = $kind AND e.model = $model AND {" AND ".join(where)}
            ORDER BY score DESC, a.asset_id
            LIMIT $limit
        """
    else:
        # No filter: rank the embeddings alone (a top-k scan), then fetch the few winning asset rows.
        sql = f"""
            WITH top AS (
                SELECT e.owner_id, {score} AS score FROM embeddings e
                WHERE e.owner_kind = $kind AND e.model = $model
                ORDER BY score DESC, e.owner_id
                LIMIT $limit
            )
            SELECT {columns}, top.score AS score
            FROM top JOIN assets a ON a.asset_id = top.owner_id
            ORDER BY score DESC, a.asset_id
        """
    rows = con.execute(sql, params).fetchall()
    return [dict(zip(RESULT_COLUMNS, r)) for r in rows]
