"""The aligned scorer: captions and their requirements, colour features, deterministic training of the heads on a
small procedural subset, the numpy heads against torch's, and the shipped weights on held-out variants."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from retrieval.aligned.captions import Attributes, detail_phrases, positives, satisfies


def _attrs(category: str, colour: str, material: str = "plastic", size: str = "medium", details=()) -> Attributes:
    from retrieval.aligned.captions import COLOUR_FAMILY

    return Attributes(
        category,
        frozenset((colour, *COLOUR_FAMILY.get(colour, ()))),
        material,
        size,
        frozenset(details),
        (category.replace("_", " "),),
        f"a {colour} {category}",
    )


def test_captions_require_what_they_say_and_colour_families_count():
    gray, blue = _attrs("trash_bin", "gray"), _attrs("trash_bin", "blue", details=("with a lid",))
    lamp = _attrs("street_lamp", "dark green", material="metal")
    gray_bin = (("category", "trash_bin"), ("colour", "gray"))
    assert satisfies(gray, gray_bin) and not satisfies(blue, gray_bin) and not satisfies(lamp, gray_bin)
    assert satisfies(lamp, (("colour", "green"),)) and satisfies(lamp, (("colour", "dark green"),))
    assert not satisfies(gray, (("colour", "green"),))
    assert satisfies(blue, (("category", "trash_bin"), ("detail", "with a lid")))
    assert not satisfies(gray, (("category", "trash_bin"), ("detail", "with a lid")))
    pos = positives([gray, blue, lamp], [gray_bin, (("category", "trash_bin"),)])
    assert pos.tolist() == [[True, True], [False, True], [False, False]]


def test_detail_phrases_split_lists_and_drop_counts():
    got = detail_phrases("a 0.9 m blue plastic trash bin with a round body and a lid")
    assert got == {"with a round body", "with a lid"}
    assert detail_phrases("a 9.9 m gray steel utility pole with a crossarm and 3 insulators") == {"with a crossarm"}


def test_colour_features_tell_gray_from_blue_and_ignore_the_background():
    from retrieval.aligned.features import COLOUR_DIM, colour_features

    img = np.full((32, 32, 3), 255, dtype=np.uint8)
    gray, blue = img.copy(), img.copy()
    gray[8:24, 8:24] = (128, 128, 128)
    blue[8:24, 8:24] = (40, 70, 170)
    fg, fb = colour_features(gray), colour_features(blue)
    assert fg.shape == fb.shape == (COLOUR_DIM,)
    assert fg[:18].sum() == 0 and fb[:18].sum() == pytest.approx(1.0)  # blue's pixels are all chromatic
    big = img.copy()
    big[4:28, 4:28] = (128, 128, 128)
    np.testing.assert_allclose(colour_features(big), fg, atol=1e-6)  # fractions of the object, not of the image
    assert not colour_features(img).any()  # nothing rendered: zeros


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """Two trainings of the heads on 3 categories x 3 seeds x 4 views, same config: (metadata, paths)."""
    from retrieval.aligned.train import TrainConfig, train

    cfg = TrainConfig(
        train_seeds=3,
        heldout_seeds=1,
        calibration_seeds=2,
        n_views=4,
        image_size=96,
        hidden=64,
        captions_per_asset=8,
        batch=24,
        steps=40,
        categories=("trash_bin", "bench", "traffic_cone"),
    )
    out = tmp_path_factory.mktemp("aligned")
    metas = [train(cfg, out / f"run{k}" / "aligned.npz", progress=False) for k in range(2)]
    return metas, [out / f"run{k}" / "aligned.npz" for k in range(2)]


def test_training_is_byte_reproducible_and_reports_heldout_accuracy(tiny_run):
    metas, paths = tiny_run
    digests = {hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}
    assert len(digests) == 1  # same config and seeds: the same weights, byte for byte
    assert paths[0].with_suffix(".json").read_bytes() == paths[1].with_suffix(".json").read_bytes()
    held = metas[0]["heldout"]
    assert held["heldout_assets"] == 3 and 0.0 <= held["category_accuracy"] <= 1.0
    assert metas[0]["train_assets"] == 9 and metas[0]["train_views"] == 36


def test_numpy_heads_equal_the_torch_modules(tiny_run):
    import torch

    from catalogs.aligned import load_heads
    from retrieval.aligned.train import TrainConfig, _heads

    heads = load_heads(str(tiny_run[1][0]))
    with np.load(tiny_run[1][0]) as z:
        arrays = {k: z[k] for k in z.files}
    image, text = _heads(heads.feature_dim, TrainConfig(hidden=64), 384)
    image.load_state_dict({k[6:]: torch.from_numpy(v) for k, v in arrays.items() if k.startswith("image.")})
    text.load_state_dict({k[5:]: torch.from_numpy(v) for k, v in arrays.items() if k.startswith("text.")})
    rng = np.random.default_rng(0)
    f = rng.normal(size=(5, heads.feature_dim)).astype(np.float32) * heads.std + heads.mean
    t = rng.normal(size=(4, 384)).astype(np.float32)
    with torch.no_grad():
        ref_i = torch.nn.functional.normalize(image(torch.from_numpy((f - heads.mean) / heads.std)), dim=-1).numpy()
        ref_t = torch.nn.functional.normalize(text(torch.from_numpy(t)), dim=-1).numpy()
    np.testing.assert_allclose(heads.image(f), ref_i, atol=1e-5)
    np.testing.assert_allclose(heads.text(t), ref_t, atol=1e-5)


def test_unknown_training_keys_and_categories_are_refused():
    from kernel.config import ConfigError
    from retrieval.aligned.train import TrainConfig, train, train_config

    with pytest.raises(ConfigError, match="valid: train_seeds"):
        train_config({"epochs": 3})
    with pytest.raises(ConfigError, match="unknown procedural categories"):
        train(TrainConfig(categories=("flying_car",)), progress=False)


def test_f1_threshold_separates_positives_and_prefers_recall_on_ties():
    from retrieval.encoders.aligned import f1_threshold

    assert f1_threshold(np.array([0.2, 0.9, 0.3, 0.8]), np.array([False, True, False, True])) == pytest.approx(0.55)
    # One positive below a negative: cutting below it (F1 0.857) beats cutting above it (F1 0.8).
    t = f1_threshold(np.array([0.9, 0.8, 0.7, 0.6, 0.1]), np.array([True, True, False, True, False]))
    assert t == pytest.approx(0.35)


def test_calibrated_thresholds_exist_for_the_categories_of_the_labelled_set(tiny_run):
    from retrieval.encoders.aligned import AlignedEncoder
    from retrieval.encoders.text import TextEncoder

    enc = AlignedEncoder(TextEncoder(None), weights=str(tiny_run[1][0]))
    texts = ["a photo of a trash bin", "a photo of a bench", "a bronze statue"]
    thr = enc.thresholds(enc.encode_texts(texts), ["trash_bin", "bench", None])
    assert np.isfinite(thr[:2]).all() and np.isnan(thr[2]) and np.all(np.abs(thr[:2]) <= 1.0)
