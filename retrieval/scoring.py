"""Scoring: per-view text-image similarity against the description pool, aggregated over the informative views,
fused with metadata-text similarity; thresholds and top-k.

Each signal is first calibrated against the description pool, per asset: raw cosines sit on signal-specific
baselines (the imagenet image signal gives every description ~0.3-0.5), so fusing raw cosines lets the flatter,
higher signal dominate. `softmax` (default) turns each signal into a distribution over the pool,
softmax(cos / temperature); an uninformative signal (e.g. a name like "Object12") comes out near-uniform and so
weighs little, a confident one peaks. `zscore` standardises over the pool; `none` fuses raw cosines.

fused = (w_image * cal(aggregate_v cos(image_v, d)) + w_text * cal(cos(metadata_text, d))) / (w_image + w_text),
with the weights renormalised over the signals present (no metadata text -> image only). A match needs the raw
fused cosine >= threshold (absolute evidence) and the calibrated score >= min_lift x uniform (softmax: 1/|pool|;
zscore: the pool mean plus min_lift standard deviations).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from catalogs.schema import DEFAULT_TEXT_MODEL
from kernel.config import check_choice
from retrieval.defaults import DEFAULT_CALIBRATION, DEFAULT_IMAGE_ENCODER, DEFAULT_THRESHOLDS

if TYPE_CHECKING:  # the encoders load lazily, only the configured one
    from retrieval.encoders.aligned import AlignedEncoder
    from retrieval.encoders.blip import BlipEncoder
    from retrieval.encoders.clip import ClipEncoder
    from retrieval.encoders.imagenet import ImageNetEncoder

IMAGE_ENCODERS = ("aligned", "imagenet", "clip", "blip", "blip2", "none")
AGGREGATES = ("max", "mean")
CALIBRATIONS = ("softmax", "zscore", "none")
THRESHOLDS = ("calibrated", "global")


@dataclass(frozen=True)
class DescriptionPool:
    """The descriptions assets are matched against: ids, texts and the category of each."""

    ids: tuple[str, ...]
    texts: tuple[str, ...]
    categories: tuple[str | None, ...]
    origin: str = "descriptions"


def category_pool(categories: list[str]) -> DescriptionPool:
    """One prompt per category ("a photo of a street lamp"), used when the catalog's description pool is empty."""
    cats = sorted(categories)
    return DescriptionPool(
        tuple(f"category:{c}" for c in cats),
        tuple(f"a photo of a {c.replace('_', ' ')}" for c in cats),
        tuple(cats),
        "category_prompts",
    )


def load_pool(rows: Sequence[tuple[str, str, str | None]], categories: list[str]) -> DescriptionPool:
    """The catalog's description pool (CatalogWriter.descriptions rows) when it has entries, else the category prompts."""
    if not rows:
        return category_pool(categories)
    return DescriptionPool(tuple(r[0] for r in rows), tuple(r[1] for r in rows), tuple(r[2] for r in rows))


@dataclass(frozen=True)
class ScoringConfig:
    """How images and metadata text are scored against the pool."""

    image_encoder: str = DEFAULT_IMAGE_ENCODER
    clip_model: str | None = None  # the clip / blip / blip2 weights folder (or a cached hub name)
    aligned_weights: str | None = None  # the aligned scorer's heads; None: retrieval/models/aligned.npz
    text_model: str | None = None
    aggregate: str = "max"
    image_weight: float = 0.6
    text_weight: float = 0.4
    threshold: float = 0.35
    calibration: str = DEFAULT_CALIBRATION
    temperature: float = 0.1
    min_lift: float = 1.0
    top_k_per_asset: int = 3
    top_k_per_description: int = 100
    threads: int = 1
    # calibrated: a description with a category gets its own image-cosine threshold from the aligned scorer's
    # labelled calibration set (AlignedEncoder.thresholds): more precise, less recall on shapes unlike the
    # procedural library's (docs/retrieval.md); global: `threshold` for every description and scorer.
    thresholds: str = DEFAULT_THRESHOLDS

    def __post_init__(self) -> None:
        check_choice(self.image_encoder, IMAGE_ENCODERS, what="image encoder")
        check_choice(self.aggregate, AGGREGATES, what="view aggregate")
        check_choice(self.calibration, CALIBRATIONS, what="score calibration")
        check_choice(self.thresholds, THRESHOLDS, what="thresholds")
        if self.temperature <= 0:
            raise ValueError(f"temperature must be > 0 (softmax calibration), got {self.temperature}")
        if self.image_encoder in ("clip", "blip", "blip2") and not self.clip_model:
            raise ValueError(
                f"the {self.image_encoder} image encoder needs a local weights folder (--clip-model); "
                f"or use the offline `aligned` scorer"
            )
        if self.image_weight < 0 or self.text_weight < 0 or self.image_weight + self.text_weight <= 0:
            raise ValueError("image_weight and text_weight must be >= 0 and not both 0")

    @property
    def scorer_name(self) -> str:
        """Identifies the scorer in every MatchRecord (encoders, aggregate, weights)."""
        img = self.image_encoder
        if img in ("clip", "blip", "blip2"):
            img = f"{img}[{str(self.clip_model).rstrip('/').split('/')[-1]}]"
        text = (self.text_model or DEFAULT_TEXT_MODEL).rstrip("/").split("/")[-1]
        cal = {"softmax": f"sm{self.temperature:g}", "zscore": "z", "none": "raw"}[self.calibration]
        per_description = ":tcal" if self.thresholds == "calibrated" and self.image_encoder == "aligned" else ""
        return f"{img}+{text}:{self.aggregate}:w{self.image_weight:g}/{self.text_weight:g}:{cal}{per_description}"


def calibrate(scores: np.ndarray, method: str, temperature: float = 0.1) -> np.ndarray:
    """Calibrate one signal's cosines against the pool: softmax(cos / T), z-score, or unchanged (`none`)."""
    s = np.asarray(scores, dtype=np.float64)
    if method == "none" or s.size == 0:
        return s
    if method == "softmax":
        e = np.exp((s - s.max()) / temperature)  # shift by the max: no overflow, same distribution
        return e / e.sum()
    sd = float(s.std())
    # A pool of one entry (or identical scores) has no spread to standardise by: nothing stands out.
    return (s - s.mean()) / sd if sd > 1e-12 else np.zeros_like(s)


@dataclass
class AssetScores:
    """Scores of one asset against every pool entry, plus its embeddings."""

    fused: np.ndarray  # calibrated and fused: what matches are ranked by and store as `score`
    image: np.ndarray | None  # raw aggregated image cosines
    text: np.ndarray | None
    image_embedding: np.ndarray | None  # mean of the selected views' embeddings (image encoder's space)
    text_embedding: np.ndarray | None  # metadata text embedding (text encoder's space)
    raw_fused: np.ndarray | None = None  # fused raw cosines: the absolute threshold applies to these
    view_embeddings: np.ndarray | None = None  # (views, dim) unit embeddings of the scored views
    extra: dict = field(default_factory=dict)


class Scorer:
    """Loads the encoders once and scores assets against a fixed pool."""

    def __init__(self, config: ScoringConfig, pool: DescriptionPool) -> None:
        from retrieval.encoders.text import TextEncoder

        self.config = config
        self.pool = pool
        self.text_encoder = TextEncoder(config.text_model)
        self.image_encoder: ImageNetEncoder | AlignedEncoder | ClipEncoder | BlipEncoder | None = None
        if config.image_encoder == "imagenet":
            from retrieval.encoders.imagenet import ImageNetEncoder

            self.image_encoder = ImageNetEncoder(self.text_encoder, threads=config.threads)
        elif config.image_encoder == "aligned":
            from retrieval.encoders.aligned import AlignedEncoder

            self.image_encoder = AlignedEncoder(self.text_encoder, config.aligned_weights, threads=config.threads)
        elif config.image_encoder == "clip":
            from retrieval.encoders.clip import ClipEncoder

            assert config.clip_model is not None  # ScoringConfig refuses clip without a model
            self.image_encoder = ClipEncoder(config.clip_model)
        elif config.image_encoder in ("blip", "blip2"):
            from retrieval.encoders.blip import BlipEncoder

            assert config.clip_model is not None  # ScoringConfig refuses blip without a model
            self.image_encoder = BlipEncoder(config.clip_model, kind=config.image_encoder)
        self.pool_text = self.text_encoder.encode(list(pool.texts))
        self.pool_image = self.image_encoder.encode_texts(list(pool.texts)) if self.image_encoder else None
        self.description_thresholds = np.full(len(pool.ids), np.nan)
        if config.thresholds == "calibrated" and hasattr(self.image_encoder, "thresholds"):
            # hasattr(None, ...) is False, and an image encoder has encoded the pool just above
            assert self.image_encoder is not None and self.pool_image is not None
            self.description_thresholds = self.image_encoder.thresholds(self.pool_image, list(pool.categories))

    def score(self, images: list[np.ndarray], metadata_text: str) -> AssetScores:
        """Score the (selected) views and the metadata text against every pool entry."""
        c = self.config
        img_scores = img_emb = views = None
        if self.image_encoder is not None and images:
            assert self.pool_image is not None  # __init__ encodes the pool whenever there is an image encoder
            if hasattr(self.image_encoder, "view_scores"):  # BLIP-2: a view's best query token per text
                per_view, views = self.image_encoder.view_scores(images, self.pool_image)
            else:
                views = self.image_encoder.encode_images(images)
                per_view = views @ self.pool_image.T
            img_scores = per_view.max(axis=0) if c.aggregate == "max" else per_view.mean(axis=0)
            img_emb = views.mean(axis=0)
            img_emb = img_emb / max(float(np.linalg.norm(img_emb)), 1e-12)
        txt_scores = txt_emb = None
        if metadata_text.strip():
            txt_emb = self.text_encoder.encode([metadata_text])[0]
            txt_scores = self.pool_text @ txt_emb
        wi = c.image_weight if img_scores is not None else 0.0
        wt = c.text_weight if txt_scores is not None else 0.0
        n = len(self.pool.ids)
        if wi + wt == 0:
            fused = raw = np.zeros(n, dtype=np.float64)
        else:

            def mix(f):  # noqa: ANN001, ANN202 - weighted mean of f(signal) over the signals present
                parts = [w * f(x) for w, x in ((wi, img_scores), (wt, txt_scores)) if x is not None and w > 0]
                return sum(parts) / (wi + wt)

            raw = mix(lambda x: np.asarray(x, dtype=np.float64))
            fused = mix(lambda x: calibrate(x, c.calibration, c.temperature))
        return AssetScores(
            np.asarray(fused, dtype=np.float64),
            img_scores,
            txt_scores,
            img_emb,
            txt_emb,
            raw_fused=np.asarray(raw, dtype=np.float64),
            view_embeddings=None if img_scores is None else np.asarray(views, dtype=np.float32),
        )

    def passes(self, scores: AssetScores, i: int) -> bool:
        """Whether pool entry i clears the absolute threshold (raw fused cosine) and the calibrated lift."""
        c = self.config
        own = self.description_thresholds[i]
        if not np.isnan(own) and scores.image is not None:
            if scores.image[i] < own:  # this description's own evidence bar, calibrated on labelled assets
                return False
        else:
            raw = scores.raw_fused if scores.raw_fused is not None else scores.fused
            if raw[i] < c.threshold:
                return False
        if c.calibration == "softmax":
            return scores.fused[i] * len(scores.fused) >= c.min_lift
        if c.calibration == "zscore":
            return scores.fused[i] >= c.min_lift
        return True

    def top_matches(self, scores: AssetScores) -> list[tuple[int, float]]:
        """(pool index, fused score) of the best entries above the threshold, best first, at most top_k_per_asset."""
        order = sorted(range(len(scores.fused)), key=lambda i: (-round(float(scores.fused[i]), 9), i))
        return [(i, float(scores.fused[i])) for i in order[: self.config.top_k_per_asset] if self.passes(scores, i)]


@lru_cache(maxsize=2)
def cached_scorer(config: ScoringConfig, pool: DescriptionPool) -> Scorer:
    """One Scorer per (config, pool) per process: workers reuse the loaded models across assets."""
    return Scorer(config, pool)
