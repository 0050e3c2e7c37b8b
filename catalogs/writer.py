"""Write API of the catalog: idempotent upserts in transactions, and atomic builds (temporary file, then rename)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

import duckdb
import numpy as np
import pyarrow as pa

from catalogs.reader import catalog_error, catalog_errors, descriptions, first_value, read_meta
from catalogs.records import AssetRecord, DescriptionRecord, MatchRecord, RejectionRecord, ViewRecord
from catalogs.schema import (
    ASSET_COLUMNS,
    ASSET_IMAGE_KIND,
    ASSET_KINDS,
    ASSET_TEXT_KIND,
    ASSET_VIEW_KIND,
    DEFAULT_EMBEDDING_DIM,
    DEFAULT_TEXT_MODEL,
    OBJECT_CLASSES,
    SCHEMA_VERSION,
    ZONES,
    CatalogError,
    CatalogSchemaError,
    ddl,
    stored_version,
)


@dataclass(frozen=True)
class EmbeddedAsset:
    """An asset with one of its embeddings: what near-duplicate detection compares."""

    asset_id: str
    source: str
    source_id: str
    size: tuple[float, float, float]  # depth, width, height in metres
    vector: np.ndarray
    content_hash: str | None


def check_asset(record: AssetRecord) -> None:
    """Raise CatalogError naming the field when an asset record breaks the schema's conventions."""
    where = f"asset {record.asset_id!r}"
    if not record.asset_id:
        raise CatalogError("an asset record has an empty asset_id; give every asset a unique id")
    if record.object_class not in OBJECT_CLASSES:
        raise CatalogError(f"{where}: object_class {record.object_class!r} is not one of {', '.join(OBJECT_CLASSES)}")
    bad_zones = [z for z in record.zones if z not in ZONES]
    if bad_zones:
        raise CatalogError(f"{where}: unknown zone(s) {bad_zones}; valid zones are {', '.join(ZONES)}")
    for name, value in zip(("depth", "width", "height"), record.size):
        if not (np.isfinite(value) and value > 0):
            raise CatalogError(f"{where}: {name} must be a positive number of metres, got {value!r}")
    if record.mass is not None and not (np.isfinite(record.mass) and record.mass > 0):
        raise CatalogError(f"{where}: mass must be a positive number of kilograms or None, got {record.mass!r}")


class CatalogWriter:
    """Read-write handle on a catalog; every upsert runs in one transaction and replaces rows by primary key."""

    def __init__(
        self,
        path: str | Path,
        *,
        embedding_dim: int = DEFAULT_EMBEDDING_DIM,
        embedding_model: str = DEFAULT_TEXT_MODEL,
    ) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._depth = 0  # nesting level of transaction(); only the outermost one begins and commits
        try:
            self.con = duckdb.connect(str(self.path))
        except duckdb.Error as e:
            raise catalog_error(e, self.path) from e  # locked by another writer, corrupt, or not DuckDB
        try:
            with catalog_errors(self.path):
                self._init_schema(embedding_dim, embedding_model)
        except BaseException:
            self.con.close()
            raise

    def _init_schema(self, embedding_dim: int, embedding_model: str) -> None:
        existing = {r[0] for r in self.con.execute("SELECT table_name FROM information_schema.tables").fetchall()}
        if "meta" in existing:
            meta = read_meta(self.con)
            if stored_version(meta) != SCHEMA_VERSION:
                raise CatalogSchemaError(
                    f"catalog {self.path} has schema version {meta.get('schema_version')}, this curbside writes "
                    f"version {SCHEMA_VERSION}; rebuild it with `curbside catalog build --catalog {self.path}`"
                )
            self.embedding_dim = int(meta["embedding_dim"])
            self.embedding_model = meta["embedding_model"]
            # Additive, nullable column (still schema 1): catalogs written before it get it on first write.
            self.con.execute("ALTER TABLE rejections ADD COLUMN IF NOT EXISTS config_hash VARCHAR")
            return
        with self.transaction():
            for stmt in ddl(embedding_dim):
                self.con.execute(stmt)
            self._set_meta(
                {
                    "schema_version": str(SCHEMA_VERSION),
                    "embedding_dim": str(embedding_dim),
                    "embedding_model": embedding_model,
                }
            )
        self.embedding_dim = embedding_dim
        self.embedding_model = embedding_model

    def _set_meta(self, items: dict[str, str]) -> None:
        for k, v in items.items():
            self.con.execute("DELETE FROM meta WHERE key = ?", [k])
            self.con.execute("INSERT INTO meta VALUES (?, ?)", [k, v])

    def set_meta(self, items: dict[str, str]) -> None:
        """Set free-form metadata entries (e.g. the build parameters)."""
        with self.transaction():
            self._set_meta(items)

    @contextmanager
    def transaction(self) -> Iterator[duckdb.DuckDBPyConnection]:
        """Run a block in one transaction: all of it lands, or none of it (nested blocks join the outer one)."""
        if self._depth > 0:
            # DuckDB has no savepoints: an inner block joins the outer transaction, and an error in it
            # propagates so the outermost block rolls everything back.
            self._depth += 1
            try:
                yield self.con
            finally:
                self._depth -= 1
            return
        self.con.execute("BEGIN TRANSACTION")
        self._depth = 1
        try:
            yield self.con
        except BaseException:
            self._depth = 0
            self.con.execute("ROLLBACK")
            raise
        self._depth = 0
        self.con.execute("COMMIT")

    def _replace(self, table: str, keys: Sequence[str], rows: list[dict], columns: Sequence[str]) -> int:
        """Delete rows whose key matches, then insert: an upsert that works for LIST and JSON columns."""
        if not rows:
            return 0
        seen: set[tuple] = set()
        for r in rows:
            key = tuple(r[k] for k in keys)
            if key in seen:
                raise CatalogError(
                    f"{table}: the batch holds {dict(zip(keys, key))} twice; give each row a unique key "
                    f"({', '.join(keys)}) or write the two rows in separate calls"
                )
            seen.add(key)
        data = {c: [r[c] for r in rows] for c in columns}
        batch = pa.table(data)
        self.con.register("_batch", batch)
        try:
            with self.transaction():
                cond = " AND ".join(f"{table}.{k} = _batch.{k}" for k in keys)
                self.con.execute(f"DELETE FROM {table} WHERE EXISTS (SELECT 1 FROM _batch WHERE {cond})")
                cols = ", ".join(columns)
                self.con.execute(f"INSERT INTO {table} ({cols}) SELECT {cols} FROM _batch")
        finally:
            self.con.unregister("_batch")
        return len(rows)

    def upsert_assets(self, records: Iterable[AssetRecord]) -> int:
        """Insert or replace assets by asset_id; returns the number written."""
        rows = []
        for r in records:
            check_asset(r)
            row = r.to_row()
            row["params"] = json.dumps(row["params"], sort_keys=True)
            rows.append(row)
        return self._replace("assets", ["asset_id"], rows, ASSET_COLUMNS)

    def upsert_views(self, records: Iterable[ViewRecord]) -> int:
        """Insert or replace rendered views by (asset_id, view_index)."""
        rows = [asdict(r) for r in records]
        cols = list(ViewRecord.__dataclass_fields__)
        return self._replace("views", ["asset_id", "view_index"], rows, cols)

    def upsert_descriptions(self, records: Iterable[DescriptionRecord]) -> int:
        """Insert or replace description-pool entries by description_id."""
        rows = []
        for r in records:
            row = asdict(r)
            row["country_counts"] = json.dumps(row["country_counts"], sort_keys=True)
            rows.append(row)
        cols = list(DescriptionRecord.__dataclass_fields__)
        return self._replace("descriptions", ["description_id"], rows, cols)

    def upsert_matches(self, records: Iterable[MatchRecord]) -> int:
        """Insert or replace asset-description matches by (asset_id, description_id)."""
        rows = [asdict(r) for r in records]
        cols = list(MatchRecord.__dataclass_fields__)
        return self._replace("matches", ["asset_id", "description_id"], rows, cols)

    def record_rejections(self, records: Iterable[RejectionRecord]) -> int:
        """Record (or update) why assets were refused, keyed by (source, source_id, stage)."""
        rows = [asdict(r) for r in records]
        cols = list(RejectionRecord.__dataclass_fields__)
        return self._replace("rejections", ["source", "source_id", "stage"], rows, cols)

    def upsert_embeddings(
        self, owner_kind: str, owner_ids: Sequence[str], vectors: np.ndarray, model: str | Sequence[str] | None = None
    ) -> int:
        """Insert or replace embedding vectors (rows of `vectors`, L2-normalised here) for the given owners; `model`
        is one name for all rows or one per row."""
        vectors = np.asarray(vectors, dtype=np.float32)
        if vectors.ndim != 2 or vectors.shape[1] != self.embedding_dim:
            raise CatalogError(f"embeddings must have shape (n, {self.embedding_dim}), got {vectors.shape}")
        if len(owner_ids) != len(vectors):
            raise CatalogError(f"{len(owner_ids)} owner ids for {len(vectors)} vectors")
        if not np.isfinite(vectors).all():
            raise CatalogError("embedding vectors contain NaN or inf")
        norms = np.linalg.norm(vectors, axis=1, keepdims=True)
        vectors = vectors / np.maximum(norms, 1e-12)
        n = len(owner_ids)
        models = [model or self.embedding_model] * n if model is None or isinstance(model, str) else list(model)
        if len(models) != n:
            raise CatalogError(f"{len(models)} model names for {n} vectors")
        if n == 0:
            return 0
        if len(set(zip(owner_ids, models))) != n:
            raise CatalogError(f"embeddings: duplicate owner ids in one batch ({owner_kind}); pass each owner once")
        vec = pa.FixedSizeListArray.from_arrays(pa.array(vectors.reshape(-1)), self.embedding_dim)
        batch = pa.table(
            {
                "owner_kind": [owner_kind] * n,
                "owner_id": list(owner_ids),
                "model": models,
                "vector": vec,
            }
        )
        self.con.register("_batch", batch)
        try:
            with self.transaction():
                self.con.execute(
                    "DELETE FROM embeddings WHERE EXISTS (SELECT 1 FROM _batch b WHERE embeddings.owner_kind = b.owner_kind"
                    " AND embeddings.owner_id = b.owner_id AND embeddings.model = b.model)"
                )
                self.con.execute(
                    f"INSERT INTO embeddings SELECT owner_kind, owner_id, model, vector::FLOAT[{self.embedding_dim}] FROM _batch"
                )
        finally:
            self.con.unregister("_batch")
        return n

    def finished_hashes(self) -> dict[tuple[str, str], str | None]:
        """Content hash of every asset in the catalog, by (source, source_id): what a resumed run may skip."""
        rows = self.con.execute("SELECT source, source_id, content_hash FROM assets").fetchall()
        return {(s, i): h for s, i, h in rows}

    def rejection_details(self, config_hash: str, *, retried: Sequence[str] = ()) -> dict[tuple[str, str], str | None]:
        """Detail of each rejection made under `config_hash`, by (source, source_id), but those of `retried` reasons."""
        rows = self.con.execute(
            "SELECT source, source_id, detail FROM rejections WHERE config_hash = ? AND NOT list_contains(?, reason)",
            [config_hash, list(retried)],
        ).fetchall()
        return {(s, i): d for s, i, d in rows}

    def descriptions(self) -> list[tuple[str, str, str | None]]:
        """(description_id, text, category) of the description pool, sorted by id."""
        return descriptions(self.con)

    def embedded_assets(self, owner_kind: str = ASSET_IMAGE_KIND) -> list[EmbeddedAsset]:
        """Every asset that has an embedding of `owner_kind` (any model), with it, sorted by asset id."""
        rows = self.con.execute(
            "SELECT a.asset_id, a.source, a.source_id, a.depth, a.width, a.height, e.vector, a.content_hash "
            "FROM assets a JOIN embeddings e ON e.owner_id = a.asset_id AND e.owner_kind = ? ORDER BY a.asset_id",
            [owner_kind],
        ).fetchall()
        return [
            EmbeddedAsset(r[0], r[1], r[2], (r[3], r[4], r[5]), np.asarray(r[6], dtype=np.float64), r[7]) for r in rows
        ]

    def delete_assets(self, asset_ids: Iterable[str]) -> None:
        """Delete assets and everything of theirs (views, matches, asset embeddings) in one transaction."""
        ids = list(asset_ids)
        if not ids:
            return
        with self.transaction():
            for table in ("matches", "views", "assets"):
                self.con.execute(f"DELETE FROM {table} WHERE list_contains(?, asset_id)", [ids])
            self.con.execute(
                "DELETE FROM embeddings WHERE list_contains(?, owner_id) AND list_contains(?, owner_kind)",
                [ids, list(ASSET_KINDS)],
            )

    def reject_assets(self, rejected: Iterable[tuple[str, RejectionRecord]]) -> int:
        """Record why assets (asset_id, rejection) were refused and delete any rows they had, in one transaction."""
        pairs = list(rejected)
        if not pairs:
            return 0
        with self.transaction():
            # A file that changed and now fails must not leave its old rows behind.
            self.delete_assets(aid for aid, _ in pairs)
            return self.record_rejections(rec for _, rec in pairs)

    def replace_asset(
        self,
        asset: AssetRecord,
        views: Sequence[ViewRecord] = (),
        matches: Sequence[MatchRecord] = (),
        *,
        text_embedding: np.ndarray | None = None,
        image_embedding: np.ndarray | None = None,
        image_model: str | None = None,
        view_embeddings: np.ndarray | None = None,
        view_ids: Sequence[int] = (),
    ) -> None:
        """Write one finished asset in one transaction, replacing its earlier rows and any rejection of its item;
        `view_embeddings` (one row per view of `view_ids`) are stored as `<image_model>#view<NN>`."""
        aid = asset.asset_id
        with self.transaction():
            self.con.execute(
                "DELETE FROM rejections WHERE source = ? AND source_id = ?", [asset.source, asset.source_id]
            )
            for table in ("views", "matches"):
                self.con.execute(f"DELETE FROM {table} WHERE asset_id = ?", [aid])
            self.upsert_views(views)
            if text_embedding is not None:
                self.upsert_embeddings(ASSET_TEXT_KIND, [aid], np.asarray(text_embedding)[None, :])
            if image_embedding is not None:
                self.upsert_embeddings(ASSET_IMAGE_KIND, [aid], np.asarray(image_embedding)[None, :], model=image_model)
            if view_embeddings is not None and len(view_ids):
                self.upsert_embeddings(
                    ASSET_VIEW_KIND,
                    [aid] * len(view_ids),
                    np.asarray(view_embeddings),
                    model=[f"{image_model}#view{int(v):02d}" for v in view_ids],
                )
            self.upsert_matches(matches)
            # Last: a resumed run treats an asset row with its content hash as a finished asset.
            self.upsert_assets([asset])

    def rank_matches(self, top_k: int) -> int:
        """Set each match's rank within its description (score, then asset id) and delete those past `top_k`."""
        with self.transaction():
            self.con.execute("""
                UPDATE matches SET rank = r.rk FROM (
                    SELECT asset_id, description_id,
                           ROW_NUMBER() OVER (PARTITION BY description_id ORDER BY score DESC, asset_id) AS rk
                    FROM matches) r
                WHERE matches.asset_id = r.asset_id AND matches.description_id = r.description_id""")
            n = first_value(self.con.execute("SELECT count(*) FROM matches WHERE rank > ?", [int(top_k)]).fetchone())
            self.con.execute("DELETE FROM matches WHERE rank > ?", [int(top_k)])
        return int(n)

    def close(self) -> None:
        """Checkpoint and close the connection."""
        try:
            self.con.execute("CHECKPOINT")
        finally:
            self.con.close()

    def __enter__(self) -> CatalogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextmanager
def build_catalog(
    path: str | Path,
    *,
    embedding_dim: int = DEFAULT_EMBEDDING_DIM,
    embedding_model: str = DEFAULT_TEXT_MODEL,
) -> Iterator[CatalogWriter]:
    """Build a new catalog at `path` atomically: write a temporary file and rename it only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # One temporary name per process, so parallel builds (pytest-xdist workers) never share a file.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp_wal = Path(str(tmp) + ".wal")
    for stale in (tmp, tmp_wal):
        stale.unlink(missing_ok=True)
    writer = CatalogWriter(tmp, embedding_dim=embedding_dim, embedding_model=embedding_model)
    try:
        yield writer
        writer.close()
    except BaseException:
        writer.con.close()
        tmp.unlink(missing_ok=True)
        tmp_wal.unlink(missing_ok=True)
        raise
    # A WAL left by an older catalog at `path` would be replayed onto the new file: drop it first.
    Path(str(path) + ".wal").unlink(missing_ok=True)
    os.replace(tmp, path)
