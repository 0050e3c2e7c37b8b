"""Objaverse end to end offline: a cache in the `objaverse` package's layout, read by the package itself and
ingested, scored and curated by `curbside catalog ingest --source objaverse --objaverse-cache DIR`."""

from __future__ import annotations

import json
from pathlib import Path

import duckdb
import pytest

from catalogs.categories import CATEGORIES
from retrieval.sources.objaverse import ObjaverseSource
from retrieval.sources.objaverse_fixture import OBJECTS, build_objaverse_cache, fixture_uid
from tests.helpers import cli

UID = {o.key: fixture_uid(o.key) for o in OBJECTS}


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fixture cache (Objaverse 1.0 and the XL sources), built once for the module."""
    return build_objaverse_cache(tmp_path_factory.mktemp("objaverse"), xl=True)


def test_the_objaverse_package_reads_the_fixture_cache(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import objaverse
    from objaverse.xl.sketchfab import SketchfabDownloader

    # The package keeps its cache folder in module globals (BASE_PATH/_VERSIONED_PATH): point them at the fixture.
    monkeypatch.setattr(objaverse, "BASE_PATH", str(cache))
    monkeypatch.setattr(objaverse, "_VERSIONED_PATH", str(cache / "hf-objaverse-v1"))
    items = {i.source_id: i for i in ObjaverseSource(cache_dir=cache).items()}
    ok = [u for u, i in items.items() if "rejected" not in i.metadata]
    assert objaverse.load_lvis_annotations() == SketchfabDownloader.get_lvis_annotations(download_dir=str(cache))
    assert sorted(u for us in objaverse.load_lvis_annotations().values() for u in us) == sorted(items)
    ann = objaverse.load_annotations(sorted(items))
    assert {u: a["license"] for u, a in ann.items()} == {o: items[o].metadata["license_code"] for o in items}
    assert {u: a["user"]["displayName"] for u, a in ann.items()} == {o: items[o].metadata["author"] for o in items}
    # load_objects finds every GLB in place (a missing one would be downloaded: offline, that raises).
    assert objaverse.load_objects(ok) == {u: items[u].path for u in ok}


def test_the_fixture_cache_is_reproducible(cache: Path, tmp_path: Path) -> None:
    again = build_objaverse_cache(tmp_path / "again", xl=True)
    files = sorted(p.relative_to(cache) for p in cache.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(again) for p in again.rglob("*") if p.is_file())
    assert all((cache / f).read_bytes() == (again / f).read_bytes() for f in files)


def test_cli_ingests_scores_and_curates_the_fixture_with_licences(
    cache: Path, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CURBSIDE_OBJAVERSE_URL", "http://127.0.0.1:9")  # any download attempt would fail
    cat = tmp_path / "c.duckdb"
    code, out, err = cli(
        [
            "catalog",
            "ingest",
            "--source",
            "objaverse",
            "--objaverse-cache",
            str(cache),
            "--catalog",
            str(cat),
            "--views",
            "4",
            "--scorer",
            "imagenet",
        ],
        capsys,
    )
    assert code == 0, err
    assert "rejected" in out and "Traceback" not in out + err
    con = duckdb.connect(str(cat), read_only=True)
    try:
        assets = {
            r[0].split(":", 1)[1]: r[1:]
            for r in con.execute(
                "SELECT asset_id, category, license, attribution, glb_path, params FROM assets"
            ).fetchall()
        }
        rejections = dict(con.execute("SELECT source_id, reason FROM rejections").fetchall())
        matched = {r[0].split(":", 1)[1] for r in con.execute("SELECT DISTINCT asset_id FROM matches").fetchall()}
    finally:
        con.close()
    # The corrupt upload is refused when it is loaded, the non-commercial model before any download.
    assert {rejections.get(UID["broken"]), rejections.get(UID["nc"])} == {"corrupt_file", "license"}
    assert {assets[UID[k]][0] for k in ("bench", "bin", "lamp")} == {"bench", "trash_bin", "street_lamp"}
    # LVIS 'pole' and 'statue' name no single category: the scorer files each under one of the table's categories
    # or, with no open-vocabulary description in this pool (the category prompts), refuses it as no_match.
    for key in ("bollard", "statue"):
        assert (UID[key] in assets and assets[UID[key]][0] in CATEGORIES) or rejections[UID[key]] == "no_match"
    assert set(assets) | set(rejections) == set(UID.values()) and matched == set(assets)
    expected = {
        "bench": "CC-BY-4.0",
        "bin": "CC0-1.0",
        "lamp": "CC-BY-SA-4.0",
        "bollard": "CC-BY-4.0",
        "statue": "CC-BY-4.0",
    }
    licences = {k: assets[UID[k]][1] for k in expected if UID[k] in assets}
    assert licences == {k: v for k, v in expected.items() if k in licences} and len(licences) >= 3
    for key, (_, _, attribution, glb, params) in ((k, assets[UID[k]]) for k in licences):
        name = next(o.name for o in OBJECTS if o.key == key)
        assert attribution == f"{name} by Curbside Fixture Maker (https://sketchfab.com/3d-models/{UID[key]})"
        p = json.loads(params)
        assert p["author"] == "Curbside Fixture Maker" and p["source_url"].endswith(UID[key])
        assert (cat.parent / glb).is_file() or Path(glb).is_file()


def test_open_vocabulary_description_keeps_an_asset_outside_the_categories(cache: Path, tmp_path: Path) -> None:
    from catalogs.records import DescriptionRecord
    from catalogs.writer import CatalogWriter
    from retrieval.ingest import IngestConfig, ingest
    from retrieval.scoring import ScoringConfig

    cat = tmp_path / "c.duckdb"
    with CatalogWriter(cat) as w:  # a pool as the cluster stage writes it: categorised and open entries
        w.upsert_descriptions(
            [
                DescriptionRecord("d-bench", "a wooden bench", "bench"),
                DescriptionRecord("d-bin", "a green trash bin", "trash_bin"),
                DescriptionRecord("d-lamp", "a street lamp", "street_lamp"),
                DescriptionRecord("d-statue", "a bronze statue", None),
            ]
        )
    src = ObjaverseSource(cache_dir=cache, lvis_categories=["bench", "statue_(sculpture)"])
    # Text signal only (MiniLM on the Sketchfab name, tags and LVIS label): this test is about what curation does
    # with an open-vocabulary best match, not about how well an image encoder sees a primitive statue.
    config = IngestConfig(n_views=4, n_informative=2, scoring=ScoringConfig(image_encoder="none"))
    report = ingest(src, cat, config, progress=False)
    assert report.written == 2
    con = duckdb.connect(str(cat), read_only=True)
    try:
        rows = {
            r[0].split(":", 1)[1]: r[1:]
            for r in con.execute(
                "SELECT a.asset_id, a.category, a.zones, a.params, m.description_id FROM assets a "
                "JOIN matches m ON m.asset_id = a.asset_id AND m.rank = 1"
            ).fetchall()
        }
    finally:
        con.close()
    category, zones, params, best = rows[UID["statue"]]
    assert (category, zones, best) == ("bronze_statue", [], "d-statue")
    assert json.loads(params)["open_vocabulary"] is True
    assert rows[UID["bench"]][0] == "bench"  # an LVIS category that names one of ours is trusted, not re-scored


def test_objaverse_xl_sources_through_the_same_interface(cache: Path, tmp_path: Path) -> None:
    from retrieval.ingest import IngestConfig, ingest
    from retrieval.scoring import ScoringConfig
    from retrieval.sources import open_source

    src = open_source("objaverse-xl:smithsonian,thingiverse", cache_dir=cache, timeout=2, retries=1)
    cat = tmp_path / "c.duckdb"
    config = IngestConfig(n_views=4, n_informative=2, scoring=ScoringConfig(image_encoder="imagenet"))
    report = ingest(src, cat, config, progress=False)
    assert report.written == 2
    con = duckdb.connect(str(cat), read_only=True)
    try:
        assets = {
            r[0]: r[1:]
            for r in con.execute(
                "SELECT json_extract_string(params, '$.xl_source'), category, license, attribution FROM assets"
            ).fetchall()
        }
        rejections = sorted(r[0] for r in con.execute("SELECT reason FROM rejections").fetchall())
    finally:
        con.close()
    # The stored Smithsonian bollard (CC0) and Thingiverse bin (CC-BY) are curated with their licence and source;
    # the Smithsonian object never downloaded cannot be fetched offline, the all-rights-reserved one is refused.
    assert assets["smithsonian"][0] in CATEGORIES and assets["thingiverse"][0] in CATEGORIES
    assert (assets["smithsonian"][1], assets["thingiverse"][1]) == ("CC0-1.0", "CC-BY")
    assert "Smithsonian" in assets["smithsonian"][2] and "thingiverse.com/thing:1001" in assets["thingiverse"][2]
    assert rejections == ["download_failed", "license"]


def test_objaverse_xl_refuses_a_changed_object_and_github(cache: Path, tmp_path: Path) -> None:
    import shutil

    from retrieval.sources.objaverse_xl import ObjaverseXLSource

    copy = tmp_path / "cache"
    shutil.copytree(cache / "thingiverse", copy / "thingiverse")
    stl = copy / "thingiverse" / "thing-1001-file-2001.stl"
    stl.write_bytes(stl.read_bytes() + b"\n")  # the bytes no longer match the annotation's sha256
    item = next(iter(ObjaverseXLSource(cache_dir=copy, sources=("thingiverse",)).items()))
    assert (
        item.metadata["rejected"][0] == "download_failed"
        and "differs from the Objaverse-XL" in item.metadata["rejected"][1]
    )
    with pytest.raises(ValueError, match="github is not supported.*--source local:DIR"):
        ObjaverseXLSource(cache_dir=copy, sources=("github",))
