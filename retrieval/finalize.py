"""After an ingest: rank matches per description (keep the top k) and remove near-duplicate assets.

Both steps read the whole catalog and are deterministic (ties broken by asset id), so every executor, and every
order of arrival, leads to the same catalog.
"""

from __future__ import annotations

import numpy as np

from catalogs.records import RejectionRecord
from catalogs.schema import ASSET_IMAGE_KIND as IMAGE_KIND
from catalogs.schema import ASSET_TEXT_KIND
from retrieval.curation import near_duplicates



def rank_matches(writer, top_k: int) -> int:  # noqa: ANN001 - CatalogWriter
    """Set `rank` to the asset's rank within its description and delete matches beyond `top_k`; returns deleted."""
    con = writer.con
    with writer.transaction():
        con.execute("""
            UPDATE matches SET rank = r.rk FROM (
                SELECT asset_id, description_id,
                       ROW_NUMBER() OVER (PARTITION BY description_id ORDER BY score DESC, asset_id) AS rk
                FROM matches) r
            WHERE matches.asset_id = r.asset_id AND matches.description_id = r.description_id""")
        n = con.execute("SELECT count(*) FROM matches WHERE rank > ?", [top_k]).fetchone()[0]
        con.execute("DELETE FROM matches WHERE rank > ?", [top_k])
    return int(n)


def remove_near_duplicates(writer, threshold: float) -> int:  # noqa: ANN001 - CatalogWriter
    """Drop assets whose image embedding and size duplicate an earlier asset (by id); the reason is recorded."""
    con = writer.con
    rows = con.execute(f"""
        SELECT a.asset_id, a.source, a.source_id, a.depth, a.width, a.height, e.vector
        FROM assets a JOIN embeddings e ON e.owner_id = a.asset_id AND e.owner_kind = '{IMAGE_KIND}'
        ORDER BY a.asset_id""").fetchall()
    if len(rows) < 2:
        return 0
    ids = [r[0] for r in rows]
    vecs = np.asarray([r[6] for r in rows], dtype=np.float64)
    dims = np.asarray([r[3:6] for r in rows], dtype=np.float64)
    dup = near_duplicates(ids, vecs, dims, threshold=threshold)
    by_id = {r[0]: r for r in rows}
    recs = [RejectionRecord(by_id[d][1], by_id[d][2], "curate", "near_duplicate", f"duplicates {k}") for d, k in dup.items()]
    if recs:
        # Carry the content hash over, so a re-run skips the duplicate instead of re-processing it.
        hashes = dict(con.execute("SELECT asset_id, content_hash FROM assets").fetchall())
        for r, d in zip(recs, dup):
            r.detail += f" [sha256:{(hashes.get(d) or '')[:16]}]"
        writer.record_rejections(recs)
        with writer.transaction():
            for d in dup:
                for table in ("matches", "views", "assets"):
                    con.execute(f"DELETE FROM {table} WHERE asset_id = ?", [d])
                con.execute("DELETE FROM embeddings WHERE owner_id = ? AND owner_kind IN (?, ?)", [d, ASSET_TEXT_KIND, IMAGE_KIND])
    return len(dup)


def finalize(writer, config) -> tuple[int, int]:  # noqa: ANN001
    """Run both steps; returns (pruned matches, removed duplicates)."""
    dups = remove_near_duplicates(writer, config.dedupe_threshold)
    pruned = rank_matches(writer, config.scoring.top_k_per_description)
    return pruned, dups
