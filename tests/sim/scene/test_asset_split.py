"""The catalog's asset split: unseen and finetune scenes draw only assets that train and test scenes never use."""

from __future__ import annotations

import warnings

import pytest

from catalogs.reader import CatalogReader
from catalogs.writer import build_catalog
from sim.scene import generate_scene
from sim.scene.dataset import split_config
from tests.sim.scene.conftest import _rec

CATEGORIES = [
    ("bench", "non_standard", ["furnishing", "frontage"], (0.6, 1.6, 0.8)),
    ("street_lamp", "standard", ["furnishing"], (0.25, 0.25, 5.5)),
    ("tree", "standard", ["furnishing"], (1.0, 1.0, 7.0)),
    ("trash_bin", "non_standard", ["furnishing", "frontage"], (0.5, 0.5, 1.0)),
    ("building_facade", "non_standard", ["building"], (7.5, 14.0, 15.0)),
]


@pytest.fixture(scope="module")
def variant_catalog(tmp_path_factory) -> CatalogReader:
    path = tmp_path_factory.mktemp("catalog") / "variants.duckdb"
    recs = [
        _rec(c, cls, zones, tuple(v * (1 + 0.01 * k) for v in size), k)
        for c, cls, zones, size in CATEGORIES
        for k in range(12)
    ]
    with build_catalog(path) as w:
        w.upsert_assets(recs)
    return CatalogReader(path)


def test_the_split_holds_out_a_fifth_of_each_category_deterministically(variant_catalog) -> None:
    seen, held = variant_catalog.asset_split("seen"), variant_catalog.asset_split("held_out")
    assert len(seen) + len(held) == len(variant_catalog) == 60
    assert set(seen.table.asset_id).isdisjoint(held.table.asset_id)
    assert all(n == 3 for n in held.categories().values()) and all(n == 9 for n in seen.categories().values())
    again = CatalogReader(variant_catalog.path).asset_split("held_out")
    assert sorted(again.table.asset_id) == sorted(held.table.asset_id)
    whole = variant_catalog.asset_split("held_out", ("bench",))
    assert (
        whole.categories()["bench"] == 12
        and variant_catalog.asset_split("seen", ("bench",)).categories().get("bench", 0) == 0
    )  # a held-out category is held out whole
    assert variant_catalog.asset_split("held_out") is held  # views are kept
    with pytest.raises(ValueError, match="valid: seen, held_out"):
        variant_catalog.asset_split("train")


def test_unseen_split_scenes_use_no_asset_of_train_split_scenes(variant_catalog) -> None:
    def assets(split: str, seeds: range) -> set[str]:
        cfg, offset = split_config(split, {"blocks": 1})
        out: set[str] = set()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for s in seeds:
                out |= {
                    o["asset_id"] for o in generate_scene(cfg, offset + s, variant_catalog)["objects"] if o["asset_id"]
                }
        return out

    train, test, unseen = assets("train", range(4)), assets("test", range(2)), assets("unseen", range(4))
    assert len(train) >= 10 and len(unseen) >= 5  # both sides really draw from the catalog
    assert train.isdisjoint(unseen) and test.isdisjoint(unseen)
    held = set(variant_catalog.asset_split("held_out").table.asset_id)
    assert unseen <= held and not (train & held)
