"""The aligned scorer's trained heads in numpy (no torch): project frozen image features and MiniLM text
embeddings into their joint space. Used by retrieval's `aligned` encoder and by catalog queries that rank
assets by their stored view embeddings (catalogs.query). Weights: retrieval/models/aligned.npz (retrieval/aligned).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.text_encoder import _gelu

DEFAULT_WEIGHTS = Path(__file__).resolve().parents[1] / "retrieval" / "models" / "aligned.npz"
ALIGNED_MODEL = "aligned"  # the `model` of aligned embeddings in the catalog's embeddings table


def _unit(x: np.ndarray) -> np.ndarray:
    return (x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-12)).astype(np.float32)


class AlignedHeads:
    """Image head (MLP) and text head (linear) of the aligned scorer, with the feature standardisation."""

    def __init__(self, arrays: dict[str, Any]) -> None:
        a = {k: np.asarray(v) for k, v in arrays.items()}
        self.feature_version = str(a.get("feature_version", ""))
        self.text_model = str(a.get("text_model", ""))
        self.mean, self.std = a["feature_mean"].astype(np.float32), a["feature_std"].astype(np.float32)
        self.w1, self.b1 = a["image.0.weight"].T.astype(np.float32), a["image.0.bias"].astype(np.float32)
        self.w2, self.b2 = a["image.2.weight"].T.astype(np.float32), a["image.2.bias"].astype(np.float32)
        self.wt, self.bt = a["text.weight"].T.astype(np.float32), a["text.bias"].astype(np.float32)
        self.dim = int(self.b2.shape[0])
        self.feature_dim = int(self.mean.shape[0])
        # The labelled calibration set (joint-space view embeddings, owner asset, asset category), when stored.
        self.calibration = None
        if "calibration_embeddings" in a:
            self.calibration = (
                a["calibration_embeddings"].astype(np.float32),
                a["calibration_view_asset"],
                a["calibration_category"].astype(str),
            )

    def image(self, features: np.ndarray) -> np.ndarray:
        """(n, dim) unit joint-space vectors of (n, feature_dim) frozen view features."""
        f = np.asarray(features, dtype=np.float32)
        if f.ndim != 2 or f.shape[1] != self.feature_dim:
            raise ValueError(
                f"aligned heads take (n, {self.feature_dim}) features, got {f.shape}; were the heads "
                f"trained on another feature version than {self.feature_version!r}?"
            )
        h = _gelu(((f - self.mean) / self.std) @ self.w1 + self.b1)
        return _unit(h @ self.w2 + self.b2)

    def text(self, embeddings: np.ndarray) -> np.ndarray:
        """(n, dim) unit joint-space vectors of (n, 384) MiniLM sentence embeddings."""
        return _unit(np.asarray(embeddings, dtype=np.float32) @ self.wt + self.bt)


@lru_cache(maxsize=4)
def load_heads(path: str | None = None) -> AlignedHeads:
    """The heads stored at `path` (default: the versioned retrieval/models/aligned.npz)."""
    p = Path(path) if path else DEFAULT_WEIGHTS
    if not p.is_file():
        raise FileNotFoundError(
            f"no aligned scorer weights at {p}; train them with `dvc repro retrieval/dvc.yaml:"
            f"train_scorer` (or `python -m retrieval.aligned.train`), or pick another --scorer"
        )
    with np.load(p, allow_pickle=False) as z:
        return AlignedHeads({k: z[k] for k in z.files})
