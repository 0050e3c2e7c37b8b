"""The `blip` and `blip2` backends on tiny models built from configs, loaded through BlipEncoder's real code path
(from_pretrained on a saved folder), and one ingest scored by each."""

from __future__ import annotations

import string

import duckdb
import numpy as np
import pytest

from retrieval.scoring import ScoringConfig

from .conftest import ingest_two_procedural

LAYERS = dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2, initializer_range=0.5)


def _tokenizer(folder):  # noqa: ANN001, ANN202 - a BertTokenizer over single characters: every text tokenises
    from transformers import BertTokenizer

    chars = list(string.ascii_lowercase + string.digits + ".,-'")
    vocab = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", *chars, *(f"##{c}" for c in chars)]
    path = folder / "vocab.txt"
    path.write_text("\n".join(vocab) + "\n")
    return BertTokenizer(str(path)), len(vocab)


@pytest.fixture(scope="module")
def tiny_blip(tmp_path_factory) -> str:
    """A randomly initialised 2-layer BLIP (16-d ITC space) saved like a hub folder."""
    import torch
    from transformers import BlipConfig, BlipForImageTextRetrieval, BlipImageProcessor, BlipProcessor

    out = tmp_path_factory.mktemp("tiny_blip")
    tok, n = _tokenizer(out)
    torch.manual_seed(0)
    config = BlipConfig(
        text_config=dict(vocab_size=n, max_position_embeddings=64, pad_token_id=0, **LAYERS),
        vision_config=dict(image_size=32, patch_size=8, **LAYERS),
        image_text_hidden_size=16,
    )
    BlipForImageTextRetrieval(config).save_pretrained(out)
    BlipProcessor(image_processor=BlipImageProcessor(size={"height": 32, "width": 32}), tokenizer=tok).save_pretrained(
        out
    )
    return str(out)


@pytest.fixture(scope="module")
def tiny_blip2(tmp_path_factory) -> str:
    """A randomly initialised BLIP-2 retrieval model (Q-Former with 4 queries, 16-d ITC space)."""
    import torch
    from transformers import Blip2Config, Blip2ForImageTextRetrieval, Blip2Processor, BlipImageProcessor

    out = tmp_path_factory.mktemp("tiny_blip2")
    tok, n = _tokenizer(out)
    torch.manual_seed(0)
    config = Blip2Config(
        vision_config=dict(image_size=32, patch_size=8, **LAYERS),
        qformer_config=dict(
            vocab_size=n,
            max_position_embeddings=64,
            pad_token_id=0,
            encoder_hidden_size=32,
            use_qformer_text_input=True,
            **LAYERS,
        ),
        text_config=dict(
            model_type="opt",
            vocab_size=n,
            hidden_size=32,
            ffn_dim=64,
            num_hidden_layers=1,
            num_attention_heads=2,
            word_embed_proj_dim=32,
        ),
        num_query_tokens=4,
        image_text_hidden_size=16,
    )
    Blip2ForImageTextRetrieval(config).save_pretrained(out)
    Blip2Processor(
        image_processor=BlipImageProcessor(size={"height": 32, "width": 32}), tokenizer=tok, num_query_tokens=None
    ).save_pretrained(out)
    return str(out)


def _images(n: int) -> list[np.ndarray]:
    """Flat images of different colours: noise images all normalise to the same statistics."""
    return [np.full((64, 64, 3), (70 * k) % 256, dtype=np.uint8) + np.uint8(k) for k in range(n)]


@pytest.mark.parametrize("kind", ["blip", "blip2"])
def test_blip_embeddings_are_unit_batch_independent_and_scores_match_the_model(kind, tiny_blip, tiny_blip2):
    import torch

    from retrieval.encoders.blip import BlipEncoder

    folder = tiny_blip if kind == "blip" else tiny_blip2
    enc = BlipEncoder(folder, kind=kind, device="cpu", batch_size=2)
    ims, texts = _images(3), ["a park bench", "a tall street lamp", "cone"]
    img, txt = enc.encode_images(ims), enc.encode_texts(texts)
    assert img.shape == (3, 16) and txt.shape == (3, 16) and img.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(txt, axis=1), 1.0, atol=1e-5)
    whole = BlipEncoder(folder, kind=kind, device="cpu", batch_size=8)
    np.testing.assert_allclose(img, whole.encode_images(ims), atol=1e-5)
    assert not np.allclose(img[0], img[1])
    # The ITC similarity equals what the model's own forward computes for the same inputs.
    sims, _ = enc.view_scores(ims, txt)
    inputs = enc.processor(images=ims, text=texts, return_tensors="pt", padding=True)
    with torch.inference_mode():
        if kind == "blip":
            ref = enc.model(**inputs, use_itm_head=False).itm_score.numpy()
        else:
            ref = enc.model(**inputs, use_image_text_matching_head=False).logits_per_image.numpy()
    np.testing.assert_allclose(sims, ref, atol=1e-4)
    prob = enc.match_probability(ims[:2], texts)
    assert prob.shape == (2, 3) and np.all((prob > 0) & (prob < 1))


def test_blip_missing_folder_is_a_clear_error(tmp_path):
    from retrieval.encoders.blip import BlipEncoder

    with pytest.raises(FileNotFoundError, match="clip-model"):
        BlipEncoder(str(tmp_path / "nothing"), kind="blip2", device="cpu")


@pytest.mark.parametrize("kind", ["blip", "blip2"])
def test_ingest_with_blip_scorers(kind, tiny_blip, tiny_blip2, tmp_path):
    # Random weights carry no meaning: thresholds off, so the test sees the matches the scorer writes.
    folder = tiny_blip if kind == "blip" else tiny_blip2
    scoring = ScoringConfig(image_encoder=kind, clip_model=folder, threshold=-1.0, min_lift=0.0)
    report, cat = ingest_two_procedural(scoring, tmp_path)
    assert (report.written, report.rejected) == (2, 0)
    con = duckdb.connect(str(cat), read_only=True)
    try:
        scorers = {r[0] for r in con.execute("SELECT scorer FROM matches").fetchall()}
    finally:
        con.close()
    assert scorers and all(s.startswith(f"{kind}[") for s in scorers)
