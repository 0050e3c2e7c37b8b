"""After an ingest: rank matches per description (keep the top k) and remove near-duplicate assets.

Both steps read the whole catalog and are deterministic (ties broken by asset id), so every executor, and every
order of arrival, leads to the same catalog.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from catalogs.records import RejectionRecord
from catalogs.schema import ASSET_IMAGE_KIND
from retrieval.curation import near_duplicates

if TYPE_CHECKING:
    from catalogs.writer import CatalogWriter
    from retrieval.pipeline import IngestConfig


def remove_near_duplicates(writer: CatalogWriter, threshold: float) -> int:
    """Drop assets whose image embedding and size duplicate an earlier asset (by id); the reason is recorded."""
    rows = writer.embedded_assets(ASSET_IMAGE_KIND)
    if len(rows) < 2:
        return 0
    vecs = np.asarray([r.vector for r in rows], dtype=np.float64)
    dims = np.asarray([r.size for r in rows], dtype=np.float64)
    dup = near_duplicates([r.asset_id for r in rows], vecs, dims, threshold=threshold)
    by_id = {r.asset_id: r for r in rows}
    # The content hash in the detail lets a re-run skip the duplicate instead of re-processing it.
    writer.reject_assets(
        (
            d,
            RejectionRecord(
                by_id[d].source,
                by_id[d].source_id,
                "curate",
                "near_duplicate",
                f"duplicates {k} [sha256:{(by_id[d].content_hash or '')[:16]}]",
            ),
        )
        for d, k in dup.items()
    )
    return len(dup)


def finalize(writer: CatalogWriter, config: IngestConfig) -> tuple[int, int]:
    """Remove near-duplicates, then rank matches (top k per description); returns (pruned matches, duplicates)."""
    dups = remove_near_duplicates(writer, config.dedupe_threshold)
    pruned = writer.rank_matches(config.scoring.top_k_per_description)
    return pruned, dups
