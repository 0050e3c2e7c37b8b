"""Defaults of the retrieval pipeline that `curbside catalog ingest` / `catalog eval` expose, declared once.

IngestConfig, ScoringConfig, ProceduralSource and retrieval.render take them as their defaults and limits, and
the CLI options show the same values. Plain constants with no imports, so the CLI reads them without loading
numpy, trimesh or duckdb.
"""

from __future__ import annotations

MAX_VIEWS = 20  # the most views retrieval.render places around an asset
DEFAULT_N_VIEWS = 20  # IngestConfig.n_views: rendered views per asset
DEFAULT_IMAGE_ENCODER = "aligned"  # ScoringConfig.image_encoder
DEFAULT_CALIBRATION = "softmax"  # ScoringConfig.calibration
DEFAULT_THRESHOLDS = "global"  # ScoringConfig.thresholds
DEFAULT_PER_CATEGORY = 2  # ProceduralSource: seeded variants per category
