"""`aligned` image-text encoder (the default scorer): frozen per-view features (retrieval.aligned.features) and
frozen MiniLM text embeddings, each through its trained head (catalogs.aligned) into one joint space, where a
view and a description that matches it ("a gray trash bin with a lid") have a high cosine.

Weights: retrieval/models/aligned.npz, built by the `train_scorer` DVC stage (retrieval/aligned/train.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from catalogs.aligned import AlignedHeads, load_heads


class AlignedEncoder:
    """Image and text embeddings (unit vectors) in the aligned scorer's joint space."""

    name = "aligned"

    def __init__(
        self,
        text_encoder: Any,
        weights: str | None = None,
        heads: AlignedHeads | None = None,
        threads: int | None = None,
    ) -> None:
        from retrieval.aligned.features import FEATURE_DIM, FEATURE_VERSION

        if threads:  # a fixed thread count: the same float sums in every worker, so every executor scores alike
            import torch
            from threadpoolctl import threadpool_limits

            torch.set_num_threads(threads)
            # The heads' matrices are small: BLAS worker threads only spin (a 3-view projection took 10-30 ms
            # with OpenBLAS's threads on the shared cores, 0.8 ms on one).
            threadpool_limits(limits=threads, user_api="blas")
        self.heads = heads or load_heads(weights)
        if self.heads.feature_version != FEATURE_VERSION or self.heads.feature_dim != FEATURE_DIM:
            raise ValueError(
                f"aligned weights were trained on features {self.heads.feature_version!r}, this code makes "
                f"{FEATURE_VERSION!r}; retrain them (dvc repro retrieval/dvc.yaml:train_scorer)"
            )
        self.text_encoder = text_encoder
        self.dim = self.heads.dim

    @classmethod
    def from_arrays(cls, arrays: dict[str, Any], text_encoder: Any) -> AlignedEncoder:
        """An encoder on in-memory weights (the trainer's report, before they are written)."""
        from retrieval.aligned.features import FEATURE_VERSION

        return cls(text_encoder, heads=AlignedHeads({"feature_version": FEATURE_VERSION, **arrays}))

    def project_features(self, features: np.ndarray) -> np.ndarray:
        """Joint-space vectors of precomputed view features."""
        return self.heads.image(features)

    def encode_images(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, dim) unit embeddings of HxWx3 uint8 renders on white."""
        from retrieval.aligned.features import view_features

        return self.heads.image(view_features(images))

    def encode_texts(self, texts: list[str]) -> np.ndarray:
        """(n, dim) unit embeddings of descriptions."""
        return self.heads.text(self.text_encoder.encode(list(texts)))

    def thresholds(self, text_embeddings: np.ndarray, categories: list[str | None]) -> np.ndarray:
        """Per description, the image cosine that best separates the calibration assets of its category from the
        others (max F1 over the asset's best view); NaN where it has no category in the labelled set."""
        out = np.full(len(categories), np.nan)
        if self.heads.calibration is None:
            return out
        emb, owner, cats = self.heads.calibration
        sims = np.asarray(text_embeddings, dtype=np.float32) @ emb.T  # (descriptions, calibration views)
        best = np.full((len(categories), len(cats)), -np.inf)
        for k in range(len(cats)):
            best[:, k] = sims[:, owner == k].max(axis=1)
        known = set(cats)
        for d, cat in enumerate(categories):
            if cat is not None and cat in known:
                out[d] = f1_threshold(best[d], cats == cat)
        return out


def f1_threshold(scores: np.ndarray, positive: np.ndarray) -> float:
    """The threshold (midway between neighbouring scores) that maximises F1 of `scores >= t` against `positive`;
    ties go to the lower threshold (more recall)."""
    s = np.asarray(scores, dtype=np.float64)
    order = np.argsort(-s, kind="stable")
    s, pos = s[order], np.asarray(positive, dtype=bool)[order]
    tp = np.cumsum(pos)
    k = np.arange(1, len(s) + 1)  # predicted positives when the cut is after the k-th score
    f1 = 2 * tp / (k + pos.sum())
    i = int(np.flatnonzero(f1 == f1.max())[-1])
    return float((s[i] + s[i + 1]) / 2) if i + 1 < len(s) else float(s[i] - 1e-6)
