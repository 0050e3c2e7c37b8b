"""Tests of the procedural street-object library: table, generators, export, PyBullet loading, records, renders."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from catalogs.schema import OBJECT_CLASSES, ZONES
from retrieval.procedural import (
    RECIPES,
    category_names,
    contact_sheet,
    export_asset,
    generate,
    pybullet_extents,
    render_views,
    to_record,
)
from retrieval.procedural.spec import TABLE_PATH, load_recipes

EXPECTED = {
    "standard": {
        "street_lamp",
        "utility_pole",
        "traffic_sign",
        "traffic_light",
        "fire_hydrant",
        "bollard",
        "tree",
        "parking_meter",
    },
    "non_standard": {
        "bench",
        "trash_bin",
        "recycling_bin",
        "planter",
        "mailbox",
        "bike_rack",
        "newspaper_box",
        "vending_machine",
        "phone_booth",
        "bus_shelter",
        "advertising_board",
        "kiosk",
        "cafe_table",
        "chair",
        "food_cart",
        "street_cabinet",
        "drinking_fountain",
        "building_facade",
    },
    "clutter": {"traffic_cone", "barrier", "bicycle", "e_scooter", "shopping_bag", "cardboard_box", "drink_can"},
}
ALL = category_names()


def test_table_has_exactly_the_agreed_categories_and_classes():
    assert len(ALL) == 33
    for cls, names in EXPECTED.items():
        assert {n for n, s in RECIPES.items() if s.object_class == cls} == names
    for spec in RECIPES.values():
        assert spec.object_class in OBJECT_CLASSES
        assert spec.zones and set(spec.zones) <= set(ZONES)
        assert spec.source and spec.synonyms and spec.variants
        assert "{" in spec.description  # a template, formatted per variant
    assert RECIPES["building_facade"].zones == ("building",)
    assert "garbage can" in RECIPES["trash_bin"].synonyms
    assert "somewhere to sit" in RECIPES["bench"].synonyms
    assert "street light" in RECIPES["street_lamp"].synonyms


def test_recipes_stay_inside_their_category_priors(tmp_path: Path):
    text = TABLE_PATH.read_text()
    bad = tmp_path / "bad.csv"
    bad.write_text(text.replace("street_lamp,0.8,2.5", "street_lamp,0.8,25.0", 1))
    with pytest.raises(ValueError, match="leaves the category's prior"):
        load_recipes(bad)
    bad.write_text(text.replace("\nbench,", "\nbenches,", 1))
    with pytest.raises(ValueError, match="'benches' is not in the curbside vocabulary"):
        load_recipes(bad)


@pytest.mark.parametrize("category", ALL)
def test_generate_respects_ranges_and_mesh_convention(category: str):
    spec = RECIPES[category]
    for seed in (0, 1):
        a = generate(category, seed)
        lo, hi = a.mesh.bounds
        # Recorded dims are the mesh bounding box: depth = x, width = y, height = z.
        np.testing.assert_allclose(a.dims, hi - lo, rtol=1e-5)
        for axis, v in zip(("depth", "width", "height"), a.dims):
            rlo, rhi = spec.range(axis)
            assert rlo - 1e-5 <= v <= rhi + 1e-5, (category, seed, axis, v, (rlo, rhi))
        assert abs(lo[2]) < 1e-9
        assert abs(lo[0] + hi[0]) < 1e-6 and abs(lo[1] + hi[1]) < 1e-6
        # Parts are laid out to fill the sampled box; a large correcting scale would mean a distorted generator.
        assert all(0.8 <= s <= 1.25 for s in a.params["fit_scale"]), a.params["fit_scale"]
        assert a.face_colors.shape == (len(a.mesh.faces), 4) and a.face_colors.dtype == np.uint8
        assert a.watertight == a.mesh.is_watertight
        assert spec.mass[0] <= a.mass <= spec.mass[1]
        variant = next(v for v in spec.variants if (v.color, v.material) == (a.color, a.material))
        assert variant.rgba in {tuple(int(x) for x in c) for c in a.palette}  # the body wears the variant colour
        assert "{" not in a.description and a.color in a.description
        assert a.object_class == spec.object_class and a.zones == list(spec.zones)


def test_many_seeds_generate_within_ranges():
    for category in ALL:
        spec = RECIPES[category]
        for seed in range(10, 18):
            a = generate(category, seed)
            assert all(0.8 <= s <= 1.25 for s in a.params["fit_scale"]), (category, seed, a.params["fit_scale"])
            for axis, v in zip(("depth", "width", "height"), a.dims):
                assert spec.range(axis)[0] - 1e-5 <= v <= spec.range(axis)[1] + 1e-5, (category, seed, axis)


def test_generate_is_deterministic_per_seed_and_varies_across_seeds():
    for category in ("bench", "bicycle", "tree", "building_facade"):
        a, b, c = generate(category, 7), generate(category, 7), generate(category, 8)
        np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
        np.testing.assert_array_equal(a.face_colors, b.face_colors)
        assert a.params == b.params and a.description == b.description
        assert a.dims != c.dims


def test_unknown_category_lists_valid_names():
    with pytest.raises(ValueError, match="unknown procedural category 'hovercraft'.*street_lamp.*drink_can"):
        generate("hovercraft", 0)


def test_export_all_categories_load_in_pybullet_with_matching_extents(tmp_path: Path):
    for category in ALL:
        a = generate(category, 3)
        e = export_asset(a, tmp_path / category)
        ext = pybullet_extents(e.obj_path)
        np.testing.assert_allclose(ext, a.dims, rtol=0.02, err_msg=category)
        tex = np.asarray(Image.open(e.texture_path).convert("RGB")).reshape(-1, 3)
        tex_colors = {tuple(c) for c in np.unique(tex, axis=0)}
        assert {tuple(c[:3]) for c in a.palette} <= tex_colors
        assert "map_Kd texture.png" in e.mtl_path.read_text()
        glb = trimesh.load(e.glb_path, force="scene")
        np.testing.assert_allclose(glb.extents, a.dims, rtol=1e-4)


def test_export_bytes_are_deterministic(tmp_path: Path):
    for category in ("street_lamp", "food_cart", "drink_can"):
        e1 = export_asset(generate(category, 5), tmp_path / "a" / category)
        e2 = export_asset(generate(category, 5), tmp_path / "b" / category)
        for f in ("obj_path", "mtl_path", "texture_path", "glb_path"):
            assert getattr(e1, f).read_bytes() == getattr(e2, f).read_bytes(), (category, f)
        e3 = export_asset(generate(category, 6), tmp_path / "c" / category)
        assert e3.obj_path.read_bytes() != e1.obj_path.read_bytes()


def test_to_record_paths_relative_and_hash(tmp_path: Path):
    a = generate("fire_hydrant", 12)
    e = export_asset(a, tmp_path / "assets" / "procedural" / "fire_hydrant" / "0012")
    r = to_record(a, e, tmp_path)
    assert r.asset_id == "procedural/fire_hydrant/0012" and r.source_id == "fire_hydrant/0012"
    assert r.source == "procedural" and r.license == "CC0-1.0" and r.attribution == "generated by curbside"
    assert r.mesh_path == "assets/procedural/fire_hydrant/0012/model.obj"
    assert r.glb_path == "assets/procedural/fire_hydrant/0012/model.glb"
    assert (tmp_path / r.mesh_path).is_file()
    assert r.content_hash == hashlib.sha256(e.obj_path.read_bytes()).hexdigest()
    assert r.face_count == len(a.mesh.faces) and r.watertight == a.watertight and r.collision == "box"
    assert r.size == a.dims and r.params["fit_scale"] == a.params["fit_scale"]
    with pytest.raises(ValueError, match="not inside the catalog directory"):
        to_record(a, e, tmp_path / "elsewhere")


def test_render_views_white_background_and_textured_object(tmp_path: Path):
    a = generate("trash_bin", 0)
    e = export_asset(a, tmp_path / "bin")
    views = render_views(e.obj_path, a.dims, [0.0, 90.0], elevation=15.0, size=64)
    assert len(views) == 2
    for img in views:
        assert img.shape == (64, 64, 3) and img.dtype == np.uint8
        assert (img[0, 0] == 255).all() and (img[-1, -1] == 255).all()
        obj = img[(img != 255).any(axis=2)]
        assert len(obj) > 200  # the object fills a good part of the frame
        body = np.asarray(a.face_colors[0][:3], dtype=float)
        # Lit pixels keep the hue of the baked body colour (not the default grey of an untextured mesh).
        assert np.min(np.linalg.norm(obj.astype(float) / obj.max() - body / body.max(), axis=1)) < 0.15
    assert not np.array_equal(views[0], views[1])


def test_contact_sheet_writes_grid(tmp_path: Path):
    assets = [generate(c, 0) for c in ("bench", "bollard", "drink_can")]
    out = contact_sheet(assets, tmp_path / "sheet.png", size=64)
    img = Image.open(out)
    assert img.size == (3 * 64, 1 * (64 + 18))
    px = np.asarray(img.convert("RGB"))
    for i in range(3):
        cell = px[:64, i * 64 : (i + 1) * 64]
        assert (cell != 255).any(axis=2).sum() > 50
    pairs = [(assets[0], export_asset(assets[0], tmp_path / "b"))]
    assert Image.open(contact_sheet(pairs, tmp_path / "one.png", size=48)).size == (2 * 48, 48 + 18)
