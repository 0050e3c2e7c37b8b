"""Read API: sampling by category/zone/size, determinism, path resolution, and its import footprint."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from catalogs.reader import CatalogReader
from catalogs.writer import build_catalog

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture()
def reader(tmp_path: Path, make_asset) -> CatalogReader:
    path = tmp_path / "c.duckdb"
    records = [
        make_asset(
            f"bench-{i}",
            height=0.5 + 0.1 * i,
            zones=["furnishing"] if i % 2 else ["frontage"],
            mesh_path=f"c_assets/bench/{i}/model.obj",
        )
        for i in range(10)
    ]
    records.append(
        make_asset(
            "hydrant-0", category="fire_hydrant", object_class="standard", height=0.8, mesh_path="/abs/hydrant.obj"
        )
    )
    with build_catalog(path) as w:
        w.upsert_assets(records)
    return CatalogReader(path)


def test_categories_and_get(reader: CatalogReader) -> None:
    assert reader.categories() == {"bench": 10, "fire_hydrant": 1}
    assert len(reader) == 11
    assert reader.get("bench-3").height == pytest.approx(0.8)
    with pytest.raises(KeyError, match="nope"):
        reader.get("nope")


def test_sample_respects_category_zone_and_size(reader: CatalogReader) -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        rec = reader.sample(rng, "bench", zone="furnishing", max_height=1.0)
        assert rec is not None
        assert rec.category == "bench" and "furnishing" in rec.zones and rec.height <= 1.0
    ids = {reader.table.asset_id[i] for i in reader.candidates("bench", zone="furnishing", max_height=1.0)}
    assert ids == {"bench-1", "bench-3", "bench-5"}  # heights 0.6, 0.8, 1.0: the limit is inclusive
    assert len(reader.candidates("bench", max_width=1.0)) == 0  # every bench is 1.8 m wide
    assert reader.sample(rng, "bench", max_height=0.1) is None
    assert reader.sample(rng, "no_such_category") is None


def test_sample_is_deterministic_per_seed(reader: CatalogReader) -> None:
    def draw(seed: int) -> list[str]:
        rng = np.random.default_rng(seed)
        return [reader.sample(rng, "bench").asset_id for _ in range(20)]

    assert draw(1) == draw(1)
    assert draw(1) != draw(2)
    assert len(set(draw(1))) > 3  # it really samples, not always the first


def test_resolve_paths(reader: CatalogReader) -> None:
    assert reader.resolve(reader.get("bench-2").mesh_path) == reader.path.parent / "c_assets/bench/2/model.obj"
    assert reader.resolve(reader.get("hydrant-0").mesh_path) == Path("/abs/hydrant.obj")
    assert reader.resolve(None) is None


def test_reader_imports_only_duckdb_and_numpy() -> None:
    code = (
        "import sys, catalogs.reader; "
        "heavy = [m for m in ('torch', 'pyarrow', 'transformers', 'sentence_transformers', 'trimesh', 'pybullet',"
        " 'pandas', 'open_clip', 'rich', 'typer') if m in sys.modules]; print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_candidates_match_a_plain_filter_for_small_and_large_categories(tmp_path: Path, make_asset) -> None:
    # 10 benches take the small-category (Python) filter, 100 bins the numpy one: both must equal a plain filter.
    rng = np.random.default_rng(3)
    zones = (["furnishing"], ["frontage"], ["furnishing", "frontage"])
    records = [
        make_asset(
            f"{cat}-{i:03d}",
            category=cat,
            zones=list(zones[i % 3]),
            depth=float(rng.uniform(0.2, 1.2)),
            width=float(rng.uniform(0.2, 2.0)),
            height=float(rng.uniform(0.3, 2.5)),
        )
        for cat, n in (("bench", 10), ("trash_bin", 100))
        for i in range(n)
    ]
    with build_catalog(tmp_path / "c.duckdb") as w:
        w.upsert_assets(records)
    reader = CatalogReader(tmp_path / "c.duckdb")
    for cat in ("bench", "trash_bin"):
        for zone in (None, "furnishing", "frontage", "clear"):
            for limits in ((None, None, None), (0.7, None, None), (0.9, 1.2, None), (None, None, 1.5), (1.0, 1.0, 1.0)):
                got = reader.candidates(cat, zone=zone, max_depth=limits[0], max_width=limits[1], max_height=limits[2])
                want = [
                    i
                    for i, r in enumerate(reader.table.asset_id)
                    if reader.get(r).category == cat
                    and (zone is None or zone in reader.get(r).zones)
                    and all(lim is None or v <= lim for v, lim in zip(reader.table.size[i], limits))
                ]
                assert got.tolist() == want, (cat, zone, limits)
                again = reader.candidates(
                    cat, zone=zone, max_depth=limits[0], max_width=limits[1], max_height=limits[2]
                )
                assert again is got and not got.flags.writeable  # the cached answer, shared read-only


def test_by_depth_lists_each_categorys_zone_assets_shallowest_first(tmp_path: Path, make_asset) -> None:
    path = tmp_path / "d.duckdb"
    depths = [0.9, 0.4, 0.7, 0.4, 0.5]
    with build_catalog(path) as w:
        w.upsert_assets(
            [
                make_asset(f"bench-{i}", depth=d, zones=["furnishing"] if i != 2 else ["frontage"])
                for i, d in enumerate(depths)
            ]
        )
    reader = CatalogReader(path)
    index, size = reader.by_depth(("bench", "tree"), "furnishing")
    assert [reader.table.asset_id[i] for i in index[0] if i >= 0] == ["bench-1", "bench-3", "bench-4", "bench-0"]
    assert size[0, :, 0].tolist() == [0.4, 0.4, 0.5, 0.9] and index.shape == (2, 4) and size.shape == (2, 4, 3)
    assert (index[1] == -1).all() and np.isinf(size[1]).all()  # no tree in the catalog: a row of padding
    assert reader.by_depth(("bench", "tree"), "furnishing")[0] is index  # answered once
    with pytest.raises(ValueError):
        index[0, 0] = 3  # shared: read-only
    assert len([i for i in reader.by_depth(("bench",))[0][0] if i >= 0]) == 5  # any zone


def test_read_catalog_reads_a_file_once_and_a_rebuilt_one_again(tmp_path: Path, make_asset) -> None:
    from catalogs.reader import read_catalog

    path = tmp_path / "shared.duckdb"
    with build_catalog(path) as w:
        w.upsert_assets([make_asset(f"bench-{i}") for i in range(3)])
    first = read_catalog(path)
    assert read_catalog(str(path)) is first  # every env and scene build of the process shares one read
    assert len(first) == 3
    with build_catalog(path) as w:  # a rebuild changes the file's size (and mtime): the next read sees it
        w.upsert_assets([make_asset(f"hydrant-{i}", category="fire_hydrant") for i in range(40)])
    again = read_catalog(path)
    assert again is not first
    assert again.categories() == CatalogReader(path).categories() != first.categories()
    assert again.categories()["fire_hydrant"] == 40
