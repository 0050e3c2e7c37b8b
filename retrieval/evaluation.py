"""Retrieval quality on a labelled set: category accuracy (top-1 match) and precision@k per description.

Built-in set: procedural assets under noisy, Objaverse-like names ("SM_Bench_low_v2.fbx", "untitled scan 07")
with the category label hidden from the scorer; with an Objaverse cache the LVIS labels are used instead.
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from catalogs.reader import asset_categories, open_catalog, ranked_matches
from retrieval.ingest import IngestConfig, ingest
from retrieval.pipeline import asset_id
from retrieval.sources import Source, SourceItem

_NOISE = (
    "SM_{c}_low_v2",
    "{c} final FINAL",
    "untitled scan {k:02d}",
    "model_{k:04d}",
    "{c}",
    "Object{k}",
    "{c} 3d model free",
)


@dataclass
class EvalReport:
    """Metrics of one evaluation."""

    n_assets: int
    category_accuracy: float
    precision_at_k: dict[int, float]

    def table(self) -> str:
        """Plain-text summary."""
        p = ", ".join(f"P@{k}={v:.3f}" for k, v in self.precision_at_k.items())
        return f"assets={self.n_assets} category_accuracy={self.category_accuracy:.3f} {p}"


class _Unlabelled:
    """Wraps a source: hides the category label and swaps the name for a noisy one, keeping the truth aside."""

    name = "eval"

    def __init__(self, source: Source, seed: int = 0) -> None:
        self.source, self.rng = source, np.random.default_rng(seed)
        self.labels: dict[str, str] = {}  # asset id -> the category the source gave

    def items(self, limit: int | None = None) -> Iterator[SourceItem]:
        """The source's items without their labels, under noisy names."""
        k = 0
        for it in self.source.items(limit):
            if it.category is None:
                continue  # an unlabelled item has no truth to score against: left out of the evaluation
            self.labels[asset_id(it.source, it.source_id)] = it.category
            tmpl = _NOISE[int(self.rng.integers(len(_NOISE)))]
            category = it.category.replace("_", " ")
            noisy = tmpl.format(c=category.title().replace(" ", "_"), k=k)
            yield dataclasses.replace(it, category=None, name=noisy, description=None, tags=[])
            k += 1


def evaluate(
    source: Source,
    config: IngestConfig | None = None,
    ks: tuple[int, ...] = (1, 5),
    limit: int | None = None,
    workdir: str | Path | None = None,
) -> EvalReport:
    """Ingest `source` without its labels into a scratch catalog and score the matches against the labels."""
    wrapped = _Unlabelled(source)
    with tempfile.TemporaryDirectory() as tmp:
        cat = Path(workdir or tmp) / "eval.duckdb"
        ingest(wrapped, cat, config or IngestConfig(), limit=limit, progress=False)
        con = open_catalog(cat)
        try:
            assets, matches = asset_categories(con), ranked_matches(con)
        finally:
            con.close()
    labels = wrapped.labels
    acc = float(np.mean([assets.get(a) == c for a, c in labels.items()])) if labels else 0.0
    by_cat: dict[str | None, list[str]] = {}  # descriptions without a category share the None key
    for aid, category, _ in matches:
        by_cat.setdefault(category, []).append(aid)
    prec = {}
    for k in ks:
        vals = [np.mean([labels.get(a) == c for a in aids[:k]]) for c, aids in by_cat.items() if aids]
        prec[k] = float(np.mean(vals)) if vals else 0.0
    return EvalReport(len(labels), acc, prec)
