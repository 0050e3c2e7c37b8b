"""The `clip` backend on a tiny CLIP built from a small CLIPConfig, loaded through ClipEncoder's real code path."""

from __future__ import annotations

import duckdb
import numpy as np
import pytest

from retrieval.scoring import ScoringConfig

from .conftest import ingest_two_procedural


@pytest.fixture(scope="module")
def tiny_clip(tmp_path_factory) -> str:
    """A randomly initialised 2-layer CLIP (16-d projection) with a byte-level tokenizer, saved like a hub folder."""
    import torch
    from tokenizers import pre_tokenizers
    from transformers import CLIPConfig, CLIPImageProcessor, CLIPModel, CLIPProcessor, CLIPTokenizer

    out = tmp_path_factory.mktemp("tiny_clip")
    # Byte-level alphabet, with and without CLIP's end-of-word marker, and no merges: every text tokenises offline.
    chars = sorted(pre_tokenizers.ByteLevel.alphabet())
    vocab = {t: i for i, t in enumerate(["<|startoftext|>", "<|endoftext|>", *chars, *(c + "</w>" for c in chars)])}
    tokenizer = CLIPTokenizer(vocab=vocab, merges=[])
    images = CLIPImageProcessor(size={"shortest_edge": 32}, crop_size={"height": 32, "width": 32})
    torch.manual_seed(0)
    layers = dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2)
    config = CLIPConfig(
        text_config=dict(
            vocab_size=len(vocab), max_position_embeddings=64, bos_token_id=0, eos_token_id=1, pad_token_id=1, **layers
        ),
        vision_config=dict(image_size=32, patch_size=8, **layers),
        projection_dim=16,
    )
    CLIPModel(config).save_pretrained(out)
    CLIPProcessor(image_processor=images, tokenizer=tokenizer).save_pretrained(out)
    return str(out)


def _images(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (224, 224, 3), dtype=np.uint8) for _ in range(n)]


def test_clip_encoder_embeddings_are_unit_and_batch_independent(tiny_clip):
    from retrieval.encoders.clip import ClipEncoder

    enc = ClipEncoder(tiny_clip, device="cpu", batch_size=2)
    assert enc.dim == 16
    ims = _images(5)
    img = enc.encode_images(ims)
    txt = enc.encode_texts(["a park bench", "a tall street lamp with a curved arm", "cone"])
    assert img.shape == (5, 16) and txt.shape == (3, 16) and img.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(img, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(txt, axis=1), 1.0, atol=1e-5)
    # Batches of 2 (3 calls, last one partial) and one batch of 5 give the same vectors; repeats are identical.
    whole = ClipEncoder(tiny_clip, device="cpu", batch_size=5).encode_images(ims)
    np.testing.assert_allclose(img, whole, atol=1e-5)
    np.testing.assert_array_equal(img, enc.encode_images(ims))
    assert not np.allclose(img[0], img[1])  # different images, different embeddings
    assert enc.encode_images([]).shape == (0, 16)


def test_clip_encoder_missing_folder_is_a_clear_error(tmp_path):
    from retrieval.encoders.clip import ClipEncoder

    with pytest.raises(FileNotFoundError, match="clip-model"):
        ClipEncoder(str(tmp_path / "no_such_model"), device="cpu")


def test_ingest_with_clip_scorer(tiny_clip, tmp_path):
    # Random weights carry no meaning: thresholds off, so the test sees the matches the clip scorer writes.
    scoring = ScoringConfig(image_encoder="clip", clip_model=tiny_clip, threshold=-1.0, min_lift=0.0)
    report, cat = ingest_two_procedural(scoring, tmp_path)
    assert (report.written, report.rejected) == (2, 0)
    con = duckdb.connect(str(cat), read_only=True)
    try:
        assets = con.execute("SELECT asset_id, mesh_path, params->>'scorer' FROM assets ORDER BY 1").fetchall()
        matches = con.execute("SELECT asset_id, scorer, image_score, text_score FROM matches").fetchall()
    finally:
        con.close()
    assert len(assets) == 2 and all(a[2].startswith("clip[") for a in assets)
    assert {m[0] for m in matches} == {a[0] for a in assets}
    assert all(m[1].startswith("clip[") and m[2] is not None and -1.0 <= m[2] <= 1.0 for m in matches)
    for _, mesh, _ in assets:
        # CLIP's 16-d space differs from the catalog's embedding width: the vector is kept next to the asset.
        emb = np.load((cat.parent / mesh).parent / "image_embedding.npy")
        assert emb.shape == (16,) and abs(float(np.linalg.norm(emb)) - 1.0) < 1e-5
