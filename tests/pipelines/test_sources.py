"""closed_set and osm stages on the shipped lists and the real Helsinki extract."""

from __future__ import annotations

import pytest

from catalogs.categories import CATEGORIES
from pipelines import closed_set, osm
from pipelines.common import CLOSED_SET_DIR, PipelineError


def test_closed_set_covers_vocabulary_with_provenance():
    df = closed_set.load_closed_set(CLOSED_SET_DIR / "segmentation_classes.csv", CLOSED_SET_DIR / "handbook_objects.csv")
    assert set(df["category"]) == set(CATEGORIES)
    assert 45 <= (df["source"] == "handbook").sum() <= 60
    assert {"cityscapes", "mapillary_vistas"} <= set(df["source"])
    assert (df["provenance"].str.len() > 5).all()


def test_closed_set_rejects_unknown_category(tmp_path):
    bad = tmp_path / "hb.csv"
    bad.write_text("name,category,prompt,provenance\nhover board,hoverboard,a hoverboard,made up\n")
    with pytest.raises(ValueError, match="hoverboard.*not in the curbside vocabulary"):
        closed_set.load_closed_set(CLOSED_SET_DIR / "segmentation_classes.csv", bad)


@pytest.fixture(scope="module")
def helsinki():
    rules = osm.load_tag_rules(CLOSED_SET_DIR / "osm_tags.csv")
    return osm.extract_osm([{"path": "", "country": "auto", "region": "Helsinki"}], rules,
                           street_highways=osm.DEFAULTS["street_highways"], snap_m=25.0, max_gap_m=300.0, tile_deg=0.25)


def test_helsinki_counts_and_country(helsinki):
    objects, counts, _ = helsinki
    assert set(objects["country"]) == {"FI"}
    c = dict(zip(counts["category"], counts["count"], strict=True))
    assert c["street_lamp"] == 586 and c["tree"] == 649 and c["fire_hydrant"] == 37
    assert set(c) <= set(CATEGORIES)


def test_helsinki_spacing_is_plausible(helsinki):
    _, _, spacing = helsinki
    lamps = spacing[(spacing["category"] == "street_lamp") & (spacing["method"] == "along_street")].iloc[0]
    # Street lights are typically 15-40 m apart along urban streets.
    assert lamps["n"] > 200 and 8 < lamps["median_m"] < 50
    nn = spacing[spacing["method"] == "nearest_neighbour"]
    assert (nn["p10_m"] <= nn["median_m"]).all() and (nn["median_m"] <= nn["p90_m"]).all()


def test_corrupt_pbf_and_bad_country(tmp_path):
    bad = tmp_path / "broken.osm.pbf"
    bad.write_bytes(b"\x00\x00\x00\x0dnot a pbf at all" * 10)
    rules = osm.load_tag_rules(CLOSED_SET_DIR / "osm_tags.csv")
    with pytest.raises(PipelineError, match="corrupt or not a .osm.pbf"):
        osm.read_extract(bad, rules, ["residential"])
    with pytest.raises(ValueError, match="not an ISO 3166-1 alpha-2"):
        osm.resolve_country("XZ", {}, bad)


def test_along_street_gaps_on_a_known_street():
    import numpy as np
    import pandas as pd

    # A straight east-west street at 60 N and lamps every ~20 m along it.
    lon = 24.9 + np.arange(5) * 20 / (111_195 * np.cos(np.radians(60)))
    objs = pd.DataFrame({"lon": lon, "lat": 60.0 + 1e-5, "category": "street_lamp"})
    street = np.array([[24.89, 60.0], [24.92, 60.0]])
    gaps = osm.along_street_gaps(objs, [street], snap_m=25, max_gap_m=300, tile_deg=0.25)
    assert np.allclose(gaps["street_lamp"], 20.0, atol=0.3)
