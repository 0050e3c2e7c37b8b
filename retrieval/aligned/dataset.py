"""Training and held-out data of the aligned scorer: seeded procedural variants rendered as the ingest renders them.

Each asset goes through the ingest's own normalise and render code (retrieval.normalize, retrieval.render), so
the heads see views framed, lit and sized exactly as at scoring time. Training seeds start at TRAIN_SEED0, far
from the seeds `curbside catalog eval` uses (0, 1, ...): the evaluation's variants are never trained on.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from retrieval.aligned.captions import Attributes, attributes_of

TRAIN_SEED0 = 100_000
HELDOUT_SEED0 = 0  # the seeds `curbside catalog eval` ingests: reported, never trained on
CALIBRATION_SEED0 = 50_000  # the labelled set per-description thresholds are calibrated on (neither of the above)


@dataclass
class Split:
    """Per-view features of rendered assets: features[i] shows asset view_asset[i], whose attributes are attrs[k]."""

    features: np.ndarray  # (views, FEATURE_DIM) float32
    view_asset: np.ndarray  # (views,) int index into attrs
    attrs: list[Attributes]


def render_asset(
    category: str, seed: int, n_views: int, size: int, elevations: tuple[float, float], work: Path
) -> tuple[list[np.ndarray], Attributes]:
    """The views of procedural (category, seed) as the ingest renders them, and its attributes."""
    from retrieval.normalize import export_obj, load_canonical
    from retrieval.procedural import export_asset, generate
    from retrieval.render import render_obj, view_specs

    asset = generate(category, seed)
    exported = export_asset(asset, work / "src")
    canon = load_canonical(str(exported.obj_path), up_axis="+z")
    obj, _, _ = export_obj(canon, work / "norm", "mesh")
    images = render_obj(obj, view_specs(n_views, elevations), size=size, bounds=canon.mesh.bounds)
    return images, attributes_of(asset)


def build_split(
    categories: list[str],
    seeds: list[int],
    n_views: int,
    size: int,
    elevations: tuple[float, float] = (15.0, 40.0),
    progress: bool = True,
) -> Split:
    """Render every (category, seed) and compute its views' features (rich progress)."""
    from rich.progress import Progress

    from retrieval.aligned.features import view_features

    feats, owner, attrs = [], [], []
    jobs = [(c, s) for s in seeds for c in categories]
    with tempfile.TemporaryDirectory() as tmp, Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("render + features", total=len(jobs))
        for k, (cat, seed) in enumerate(jobs):
            images, a = render_asset(cat, seed, n_views, size, elevations, Path(tmp) / f"{k}")
            feats.append(view_features(images))
            owner += [k] * len(images)
            attrs.append(a)
            bar.advance(task)
    return Split(np.concatenate(feats), np.asarray(owner, dtype=np.int64), attrs)
