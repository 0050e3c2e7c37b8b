"""The numpy MiniLM query encoder against the real sentence-transformers model and the catalogs it embedded."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from catalogs.text_encoder import (
    NumpyTextEncoder,
    default_model_path,
    model_folder,
    read_safetensors,
    supports,
)

TEXTS = [
    "fire hydrant",
    "somewhere to sit",
    "garbage can",
    "A gray trash bin. Metal, with a lid, near the road. bin, waste basket, litter bin.",
    "",
    "Ünïcödé café ☕ 東京 straße",
    "x" * 500,  # one word longer than WordPiece's 100-character limit: [UNK]
    "street light " * 200,  # 400+ tokens: truncated at sentence-transformers' max_seq_length (256)
]


@pytest.fixture(scope="module")
def encoder() -> NumpyTextEncoder:
    """The numpy encoder of the packaged all-MiniLM-L6-v2."""
    return NumpyTextEncoder()


def test_matches_sentence_transformers(encoder: NumpyTextEncoder, text_encoder) -> None:
    ours = encoder.encode(TEXTS)
    ref = text_encoder.encode(TEXTS)
    assert ours.shape == ref.shape == (len(TEXTS), 384) and ours.dtype == np.float32
    cosine = np.sum(ours.astype(np.float64) * ref, axis=1)
    assert np.all(cosine > 1 - 1e-5), cosine
    assert np.abs(ours - ref).max() < 1e-5
    np.testing.assert_allclose(np.linalg.norm(ours, axis=1), 1.0, atol=1e-6)


def test_truncates_like_sentence_transformers(encoder: NumpyTextEncoder) -> None:
    # Past 256 tokens the text is cut, so adding words at the end changes nothing; below it, it does.
    long_a, long_b = "street light " * 200, "street light " * 200 + "red fire hydrant"
    a, b = encoder.encode([long_a, long_b])
    assert encoder.max_seq_length == 256
    assert np.abs(a - b).max() < 1e-6
    short_a, short_b = encoder.encode(["street light", "street light red fire hydrant"])
    assert np.abs(short_a - short_b).max() > 1e-2


def test_batching_and_padding_do_not_change_vectors(encoder: NumpyTextEncoder) -> None:
    together = encoder.encode(TEXTS)
    alone = np.stack([encoder.encode([t])[0] for t in TEXTS])
    np.testing.assert_allclose(together, alone, atol=2e-6)
    small_batches = NumpyTextEncoder(batch_size=3).encode(TEXTS)
    np.testing.assert_allclose(together, small_batches, atol=2e-6)
    assert encoder.encode([]).shape == (0, 384)


def test_reproduces_the_catalog_embeddings(encoder: NumpyTextEncoder, small_catalog: Path) -> None:
    # The catalog's asset vectors were written by sentence-transformers: queries embedded in numpy must
    # land in the same space, so re-embedding each asset's text gives back its stored vector.
    from catalogs.reader import open_catalog
    from retrieval.build import asset_text

    con = open_catalog(small_catalog)
    try:
        rows = con.execute(
            "SELECT a.category, a.description, a.synonyms, e.vector FROM assets a JOIN embeddings e "
            "ON e.owner_id = a.asset_id AND e.owner_kind = 'asset_text' ORDER BY a.asset_id"
        ).fetchall()
    finally:
        con.close()
    assert len(rows) >= 30
    texts = [asset_text(cat, desc, list(syn)) for cat, desc, syn, _ in rows]
    stored = np.asarray([vec for *_, vec in rows], dtype=np.float32)
    cosine = np.sum(encoder.encode(texts) * stored, axis=1)
    assert np.all(cosine > 1 - 1e-5), cosine.min()


def test_read_safetensors_equals_the_safetensors_library() -> None:
    from safetensors.numpy import load_file

    path = default_model_path() / "model.safetensors"
    ours, ref = read_safetensors(path), load_file(str(path))
    assert ours.keys() == ref.keys()
    for name in ref:
        assert ours[name].dtype == ref[name].dtype and ours[name].shape == ref[name].shape
        np.testing.assert_array_equal(ours[name], ref[name])


def test_supports_only_mean_pooled_bert(tmp_path: Path) -> None:
    src = default_model_path()
    assert supports(src) and model_folder("all-MiniLM-L6-v2") == src and model_folder(None) == src
    assert model_folder("/some/folder") == Path("/some/folder")
    assert not supports(tmp_path / "missing")

    def variant(name: str, edit: str, change: dict) -> Path:
        dst = tmp_path / name
        shutil.copytree(src, dst, ignore=shutil.ignore_patterns("model.safetensors"))
        (dst / "model.safetensors").symlink_to(src / "model.safetensors")
        cfg = json.loads((dst / edit).read_text())
        cfg.update(change)
        (dst / edit).write_text(json.dumps(cfg))
        return dst

    assert supports(variant("same", "config.json", {}))
    cls = variant("cls", "1_Pooling/config.json", {"pooling_mode_cls_token": True, "pooling_mode_mean_tokens": False})
    assert not supports(cls)
    roberta = variant("roberta", "config.json", {"model_type": "roberta"})
    assert not supports(roberta)
    with pytest.raises(ValueError, match="mean-pooling"):
        NumpyTextEncoder(cls)


def test_cli_query_does_not_load_torch(small_catalog: Path) -> None:
    # The cold-start fix is that `curbside catalog query` never imports torch or sentence-transformers.
    code = (
        "import sys\n"
        "from curbside.cli.main import cli\n"
        f"sys.argv = ['curbside', 'catalog', 'query', 'fire hydrant', '--catalog', {str(small_catalog)!r},"
        " '--json', '--limit', '3']\n"
        "try:\n    cli()\nexcept SystemExit as e:\n    rc = e.code\n"
        "heavy = sorted(m for m in ('torch', 'sentence_transformers', 'transformers') if m in sys.modules)\n"
        "print('HEAVY=' + ','.join(heavy), file=sys.stderr)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=Path(__file__).resolve().parents[2],
    )
    assert "HEAVY=\n" in proc.stderr, proc.stderr[-2000:]
    doc = json.loads(proc.stdout)
    assert doc["results"][0]["category"] == "fire_hydrant"
