"""Generator API: determinism, strict config, block codes, catalog use and fallback, refusals, distributions."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from kernel.config import ConfigError
from sim.scene import DEFAULT_CONFIG, dumps, generate_scene, load, save
from sim.scene.spec import canonical


def _quiet(cfg: dict, seed: int, catalog=None) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return generate_scene(cfg, seed, catalog)


def test_same_inputs_give_byte_identical_json_and_seeds_differ() -> None:
    a, b = dumps(_quiet({"blocks": "SXC"}, 7)), dumps(_quiet({"blocks": "SXC"}, 7))
    assert a == b
    assert a != dumps(_quiet({"blocks": "SXC"}, 8))
    spec = json.loads(a)
    assert spec["version"] == "curbside.scene/1" and spec["config"]["blocks"] == "SXC"
    assert dumps(spec) == a  # already canonical: re-serialising changes nothing


def test_block_codes_are_followed_and_counts_grow_blocks() -> None:
    spec = _quiet({"blocks": "SCXTO"}, 1)
    assert [r["block"] for r in spec["roads"]] == list("SCXTO")
    assert len(_quiet({"blocks": 4}, 2)["roads"]) == 4
    island = [r for r in spec["roads"] if r["block"] == "O"][0]["island"]
    assert island is not None and len(island) > 8


@pytest.mark.parametrize(
    ("cfg", "needle"),
    [
        ({"blokcs": 3}, "valid keys"),
        ({"blocks": "SXZ"}, r"valid: S \(straight\)"),
        ({"templates": "abh"}, r"valid: a \(narrow\)"),
        ({"lane_width": [4.0, 3.0]}, "min <= max"),
        ({"exclude_categories": ["unicorn"]}, "unknown categories"),
        ({"crosswalks": ["nope:start"]}, "candidates of this scene"),
    ],
)
def test_bad_config_raises_naming_the_valid_choices(cfg: dict, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        _quiet(cfg, 0)


def test_templates_are_respected() -> None:
    spec = _quiet({"blocks": 2, "templates": "g"}, 3)
    assert {s["template"] for s in spec["sidewalks"]} == {"g"}
    kinds = {z["kind"] for s in spec["sidewalks"] for z in s["zones"]}
    assert {"furnishing", "clear", "frontage_buffer", "frontage"} <= kinds


def test_explicit_crosswalk_list_and_density() -> None:
    assert _quiet({"blocks": "S", "crosswalk_density": 0.0, "connect_crosswalks": False}, 0)["crosswalks"] == []
    assert len(_quiet({"blocks": "S", "crosswalk_density": 1.0}, 0)["crosswalks"]) == 2
    spec = _quiet({"blocks": "S", "crosswalks": ["r0.0:end"]}, 0)
    assert len(spec["crosswalks"]) == 1 and spec["crosswalks"][0]["road_id"] == "r0"


def test_no_catalog_falls_back_to_boxes_with_a_warning() -> None:
    with pytest.warns(UserWarning, match="default-size boxes for category"):
        spec = generate_scene({"blocks": "S"}, 0)
    assert spec["catalog"] is None and spec["stats"]["fallback_categories"]
    assert all(o["asset_id"] is None for o in spec["objects"])


def test_catalog_assets_are_used_and_missing_categories_fall_back(tiny_catalog: Path) -> None:
    with pytest.warns(UserWarning, match="has no 'trash_bin' asset|has no '"):
        spec = generate_scene({"blocks": "SX", "object_density": 2.0}, 4, tiny_catalog)
    from_catalog = [o for o in spec["objects"] if o["asset_id"]]
    assert {o["category"] for o in from_catalog} >= {"street_lamp", "building_facade"}
    assert all(o["asset_id"].startswith(f"test/{o['category']}/") for o in from_catalog)
    lamp = next(o for o in from_catalog if o["category"] == "street_lamp")
    assert lamp["size"] == [0.25, 0.25, 5.5]
    assert "bench" not in spec["stats"]["fallback_categories"] and "mailbox" in spec["stats"]["fallback_categories"]
    assert spec["catalog"] == str(tiny_catalog)
    assert dumps(_quiet({"blocks": "SX", "object_density": 2.0}, 4, tiny_catalog)) == dumps(spec)


def test_impossible_density_places_what_fits_and_reports_refusals() -> None:
    low = _quiet({"blocks": "S", "object_density": 1.0}, 5)
    high = _quiet({"blocks": "S", "object_density": 40.0}, 5)
    assert high["stats"]["objects"] > low["stats"]["objects"]
    assert (
        high["stats"]["refused_total"] > 50 and sum(high["stats"]["refused"].values()) == high["stats"]["refused_total"]
    )


def test_excluded_categories_never_appear() -> None:
    held = ["bench", "kiosk", "tree", "bicycle"]
    spec = _quiet({"blocks": 3, "exclude_categories": held, "object_density": 3.0}, 6)
    assert not {o["category"] for o in spec["objects"]} & set(held)


def test_country_distribution(tmp_path: Path) -> None:
    import duckdb

    table = tmp_path / "distribution.parquet"
    with pytest.raises(ConfigError, match="dvc repro"):
        _quiet({"country": "FI", "distribution_path": str(table)}, 0)
    con = duckdb.connect()
    con.execute(
        "COPY (SELECT * FROM (VALUES ('FI', 'bench', 90, 0.9), ('FI', 'street_lamp', 10, 0.1), ('GLOBAL', 'tree', 1, 1.0))"
        f" t(country, category, count, frequency)) TO '{table}' (FORMAT PARQUET)"
    )
    con.close()
    with pytest.raises(ConfigError, match="available: FI, GLOBAL"):
        _quiet({"country": "JP", "distribution_path": str(table)}, 0)
    spec = _quiet({"blocks": 2, "country": "fi", "distribution_path": str(table)}, 0)
    cats = {
        o["category"] for o in spec["objects"] if o["object_class"] != "clutter" and o["category"] != "building_facade"
    }
    assert cats <= {"bench", "street_lamp"} and spec["stats"]["distribution"] == "FI"


def test_load_refuses_other_versions(tmp_path: Path) -> None:
    spec = _quiet({"blocks": "S"}, 0)
    path = save(spec, tmp_path / "s.json")
    assert load(path) == spec
    bad = dict(spec, version="curbside.scene/0")
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(ValueError, match="curbside.scene/1"):
        load(tmp_path / "bad.json")


def test_default_config_is_not_mutated() -> None:
    before = json.dumps(DEFAULT_CONFIG, sort_keys=True)
    _quiet({"blocks": "SC", "templates": "g"}, 0)
    assert json.dumps(DEFAULT_CONFIG, sort_keys=True) == before


def test_fast_writer_matches_the_standard_json_encoder_and_refuses_non_finite(tmp_path: Path) -> None:
    spec = _quiet({"blocks": "SX", "preset": "metaurban12k"}, 3)
    text = dumps(spec)
    # orjson (sim.scene.spec.encode) must write exactly what the standard library writes for the same spec.
    assert text == json.dumps(canonical(spec), sort_keys=True, separators=(",", ":"), allow_nan=False)
    # Non-ASCII text and integers past 64 bits go through json too: the same bytes as json.dumps.
    odd = {**spec, "catalog": "catálogos/ñ.duckdb", "seed": 2**70}
    assert dumps(odd) == json.dumps(canonical(odd), sort_keys=True, separators=(",", ":"), allow_nan=False)
    # The generator returns a canonical spec: saving it without re-rounding gives the same bytes.
    save(spec, tmp_path / "a.json")
    save(spec, tmp_path / "b.json", is_canonical=True)
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes() == text.encode()
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="finite"):
            dumps({**spec, "bounds": [0.0, 0.0, bad, 1.0]})
        with pytest.raises(ValueError, match="finite"):
            dumps({**spec, "curb_height": bad})
        with pytest.raises(ValueError, match="finite"):
            dumps({**spec, "roads": [{"polygon": [[0.0, 1.0]] * 40 + [[bad, 2.0]]}]})
