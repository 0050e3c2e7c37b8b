"""closed_set and osm stages on the shipped lists and the real Helsinki extract."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from catalogs.categories import CATEGORIES
from pipelines import closed_set, describe, osm, signs
from pipelines.common import CLOSED_SET_DIR, PipelineError, stage_defaults


def test_closed_set_covers_vocabulary_with_provenance():
    df = closed_set.load_closed_set(
        CLOSED_SET_DIR / "segmentation_classes.csv", CLOSED_SET_DIR / "handbook_objects.csv"
    )
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
    p = stage_defaults("osm")
    return osm.extract_osm(
        [{"path": "", "country": "auto", "region": "Helsinki"}],
        rules,
        street_highways=p["street_highways"],
        snap_m=p["snap_distance_m"],
        max_gap_m=p["max_gap_m"],
        tile_deg=p["tile_deg"],
    )


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


RAW_CODE = re.compile(r"\b[A-Z]{2}:\d|\[|\]")


def test_helsinki_open_vocabulary_objects_stay_out_of_the_counts(helsinki):
    objects, counts, spacing = helsinki
    open_vocab = objects[objects["category"].isna()]
    # Surveillance cameras, flagpoles, artworks... are street objects of none of the categories: kept with a label.
    assert {"surveillance camera", "flagpole"} <= set(open_vocab["label"])
    assert open_vocab["label"].notna().all()
    assert counts["category"].notna().all() and spacing["category"].notna().all()
    assert counts["count"].sum() == objects["category"].notna().sum()


def test_helsinki_descriptions_name_signs_and_keep_open_vocabulary(helsinki):
    objects, _, _ = helsinki
    closed = pd.DataFrame({"prompt": ["a bench"], "category": ["bench"]})
    desc = describe.build_descriptions(closed, objects, pd.DataFrame(), {})
    osm_texts = desc.loc[desc["source"] == "osm", "text"]
    assert not osm_texts.str.contains(RAW_CODE).any(), osm_texts[osm_texts.str.contains(RAW_CODE)].tolist()[:5]
    signs = desc[(desc["source"] == "osm") & (desc["category"] == "traffic_sign")]
    by_text = dict(zip(signs["text"], signs["count"], strict=True))
    # FI:372 (237 nodes in the extract) is the no-stopping sign, FI:511 (199) the pedestrian crossing sign.
    assert by_text["a no stopping sign"] >= 237 and by_text["a pedestrian crossing sign"] >= 199
    assert by_text["a 30 km/h speed limit zone sign"] >= 25
    open_vocab = desc[desc["category"].isna()]
    assert {"a surveillance camera", "a flagpole"} <= set(open_vocab["text"])
    assert set(open_vocab["source"]) == {"osm"}


def test_sign_table_never_shows_a_raw_code():
    t = signs.sign_table()
    assert t.describe("FI:372") == "a no stopping sign"
    assert (
        t.describe("FI:361[40]") == "a 40 km/h speed limit sign"
        and t.describe("DE:274-30") == "a 30 km/h speed limit sign"
    )
    assert t.describe("FI:373;FI:374") == "a no parking zone sign"  # the first sign of a post
    assert t.describe("FI:417") == "a mandatory sign"  # family of an unlisted code
    assert t.describe("DE:1020-30") == "an additional sign panel"  # four digits: the 10xx family, not 1xx
    for value in ("FI:922", "XX:123", "FI:reunapaalu", "yes", "FI:632[FI:674 MAKASIINITERMINAALI]"):
        assert not RAW_CODE.search(t.describe(value)), value


def test_sign_table_refuses_a_bad_row(tmp_path):
    bad = tmp_path / "signs.csv"
    bad.write_text("sign,description,with_value,provenance\nFI:372,no stopping,,made up\n")
    with pytest.raises(PipelineError, match="must start with 'a ' or 'an '"):
        signs.load_sign_table(bad)


def test_osm_tag_table_needs_a_category_or_a_label(tmp_path):
    bad = tmp_path / "tags.csv"
    bad.write_text("key,value,extra_key,extra_value,category,label,provenance\namenity,clock,,,,,made up\n")
    with pytest.raises(PipelineError, match="give a category or.*a label"):
        osm.load_tag_rules(bad)
