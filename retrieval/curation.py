"""Curation: real-world size normalisation (with a unit guess) and near-duplicates."""

from __future__ import annotations

import math

import numpy as np

from catalogs.categories import CATEGORIES, Category

# Unit factors tried when a mesh's height is implausible for its category: file units -> metres.
UNIT_FACTORS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048, "dm": 0.1}


def normalize_size(extents: np.ndarray, category: str, priors: dict[str, Category] | None = None) -> tuple[float, str]:
    """Uniform scale that brings the height into the category's prior range, and the unit it implies.

    The raw height is first read in each plausible unit (m, cm, mm, in, ft, dm); the first unit that lands inside
    the range wins (scale = that unit's factor). If none does, the mesh is scaled to the range's geometric
    middle and the unit is reported as "rescaled".
    """
    priors = priors or CATEGORIES
    prior = priors.get(category)
    height = float(extents[2])
    if prior is None or height <= 0:
        return 1.0, "m"
    lo, hi = prior.height
    for unit, factor in UNIT_FACTORS.items():
        if lo <= height * factor <= hi:
            return factor, unit
    return math.sqrt(lo * hi) / height, "rescaled"


# An open-vocabulary asset (a statue, a clock: none of the categories) has no size prior of its own; street
# objects span this range of heights, so a unit that lands inside it is trusted, as for a category's prior.
OPEN_HEIGHT_RANGE = (0.05, 12.0)
# Open-vocabulary assets are placed by no generator rule (zones are empty): "non_standard" as furniture-like.
OPEN_OBJECT_CLASS = "non_standard"


def normalize_open_size(extents: np.ndarray) -> tuple[float, str]:
    """normalize_size for an asset outside the category table: the generic street-object height range."""
    prior = Category(
        "open_vocabulary", OPEN_OBJECT_CLASS, (), (1.0, 1.0, 1.0), (0.01, 50.0), (0.01, 50.0), OPEN_HEIGHT_RANGE, ""
    )
    return normalize_size(extents, prior.name, {prior.name: prior})


def near_duplicates(
    ids: list[str], vectors: np.ndarray, dims: np.ndarray, threshold: float = 0.995, dim_tolerance: float = 0.02
) -> dict[str, str]:
    """Greedy near-duplicate detection in `ids` order: {duplicate_id: kept_id}.

    Two assets are near-duplicates when their image embeddings have cosine >= `threshold` AND their extents
    agree within `dim_tolerance` (relative): the embedding alone would merge distinct variants of one category.
    """
    if len(ids) == 0:
        return {}
    v = np.asarray(vectors, dtype=np.float64)
    v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    sims = v @ v.T
    dims = np.asarray(dims, dtype=np.float64)
    dup: dict[str, str] = {}
    kept: list[int] = []
    for i in range(len(ids)):
        for j in kept:
            rel = np.abs(dims[i] - dims[j]) / np.maximum(np.maximum(dims[i], dims[j]), 1e-9)
            if sims[i, j] >= threshold and (rel <= dim_tolerance).all():
                dup[ids[i]] = ids[j]
                break
        else:
            kept.append(i)
    return dup
