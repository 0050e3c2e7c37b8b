"""Fixtures for scene generator tests: a tiny real DuckDB catalog with box-sized assets."""

from __future__ import annotations

from pathlib import Path

import pytest

from catalogs.records import AssetRecord
from catalogs.writer import build_catalog


def _rec(category: str, object_class: str, zones: list[str], size: tuple[float, float, float], k: int) -> AssetRecord:
    return AssetRecord(
        asset_id=f"test/{category}/{k:04d}",
        source="test",
        source_id=f"{category}-{k}",
        category=category,
        object_class=object_class,
        zones=zones,
        depth=size[0],
        width=size[1],
        height=size[2],
        description=f"test {category}",
        synonyms=[],
        license="CC0-1.0",
    )


@pytest.fixture(scope="session")
def tiny_catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A catalog holding benches, lamps, trees and facades only (every other category falls back)."""
    path = tmp_path_factory.mktemp("catalog") / "tiny.duckdb"
    recs = [
        _rec("bench", "non_standard", ["furnishing", "frontage"], (0.55, 1.6, 0.8), 0),
        _rec("bench", "non_standard", ["furnishing", "frontage"], (0.7, 2.0, 0.9), 1),
        _rec("street_lamp", "standard", ["furnishing"], (0.25, 0.25, 5.5), 0),
        _rec("tree", "standard", ["furnishing"], (1.0, 1.0, 7.0), 0),
        _rec("building_facade", "non_standard", ["building"], (7.5, 14.0, 15.0), 0),
    ]
    with build_catalog(path) as w:
        w.upsert_assets(recs)
    return path
