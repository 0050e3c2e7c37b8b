"""Train the aligned scorer's heads: `python -m retrieval.aligned.train --params retrieval/params.yaml` (DVC stage
`train_scorer`). Renders seeded procedural variants, computes their frozen features, trains the two heads with a
multi-positive contrastive loss and writes `retrieval/models/aligned.npz` plus a report (held-out accuracy).

Loss: for each view, -log of the softmax mass on the batch's captions it satisfies (captions.satisfies), and the
same per caption over the batch's views (CLIP's symmetric loss, with every satisfying pair a positive). One CPU
thread, fixed seeds: the same parameters give the same weights, byte for byte.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from kernel.config import ConfigError
from kernel.reproducible import write_npz

DEFAULT_WEIGHTS = Path(__file__).resolve().parents[1] / "models" / "aligned.npz"


@dataclass(frozen=True)
class TrainConfig:
    """Data and optimisation of the heads (retrieval/params.yaml, section `aligned`)."""

    train_seeds: int = 24  # variants per category trained on
    heldout_seeds: int = 2  # variants per category reported on (the seeds `catalog eval` uses)
    calibration_seeds: int = 2  # variants per category kept as the labelled set thresholds are calibrated on
    n_views: int = 12
    image_size: int = 160
    joint_dim: int = 384  # = MiniLM's width: aligned image embeddings fit the catalog's embeddings table
    hidden: int = 768
    captions_per_asset: int = 40
    batch: int = 256
    steps: int = 2500
    lr: float = 2e-3
    weight_decay: float = 1e-4
    seed: int = 0
    categories: tuple[str, ...] | None = None  # None: every procedural category (a subset keeps tests small)


def train_config(values: dict[str, Any] | None) -> TrainConfig:
    """TrainConfig from a params section; unknown keys are refused with the valid ones."""
    valid = [f.name for f in fields(TrainConfig)]
    bad = sorted(set(values or {}) - set(valid))
    if bad:
        raise ConfigError(f"unknown keys {bad} in params section 'aligned'; valid: {', '.join(valid)}")
    values = dict(values or {})
    if values.get("categories") is not None:
        values["categories"] = tuple(values["categories"])
    return TrainConfig(**values)


def caption_bank(attrs: list, per_asset: int, seed: int) -> tuple[list[str], list[tuple], np.ndarray]:
    """Distinct captions drawn for every asset, their requirements and the (asset, caption) positives matrix."""
    from retrieval.aligned.captions import caption, positives

    rng = np.random.default_rng(seed)
    texts: dict[str, tuple] = {}
    for a in attrs:
        texts.update(caption(a, rng) for _ in range(per_asset))
        texts.setdefault(f"a photo of a {a.names[0]}", (("category", a.category),))  # the category prompts
    names = sorted(texts)
    reqs = [texts[t] for t in names]
    return names, reqs, positives(attrs, reqs)


def _heads(dim_in: int, cfg: TrainConfig, text_dim: int):  # noqa: ANN202 - (image head, text head) torch modules
    import torch
    from torch import nn

    image = nn.Sequential(nn.Linear(dim_in, cfg.hidden), nn.GELU(), nn.Linear(cfg.hidden, cfg.joint_dim))
    text = nn.Linear(text_dim, cfg.joint_dim)
    with torch.no_grad():  # start the text side at MiniLM itself: the heads only have to bend it
        text.weight.copy_(torch.eye(cfg.joint_dim, text_dim))
        text.bias.zero_()
    return image, text


def fit(train, text_emb: np.ndarray, pos: np.ndarray, cfg: TrainConfig, progress: bool = True) -> dict[str, Any]:  # noqa: ANN001
    """Train both heads on `train` (a dataset.Split); returns the weights as numpy arrays."""
    import torch
    from rich.progress import Progress

    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    mean, std = train.features.mean(0), train.features.std(0) + 1e-6
    x_all = torch.from_numpy((train.features - mean) / std)
    t_all = torch.from_numpy(text_emb)
    image, text = _heads(x_all.shape[1], cfg, t_all.shape[1])
    log_scale = torch.nn.Parameter(torch.tensor(float(np.log(1 / 0.07))))
    params = [*image.parameters(), *text.parameters(), log_scale]
    opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=cfg.steps, pct_start=0.1)
    pos_t = torch.from_numpy(pos)
    asset_caps = [np.flatnonzero(pos[k]) for k in range(pos.shape[0])]
    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("train heads", total=cfg.steps)
        for _ in range(cfg.steps):
            views = rng.choice(len(x_all), size=cfg.batch, replace=False)
            owners = train.view_asset[views]
            caps = np.array([asset_caps[k][rng.integers(len(asset_caps[k]))] for k in owners])
            zi = torch.nn.functional.normalize(image(x_all[views]), dim=-1)
            zt = torch.nn.functional.normalize(text(t_all[caps]), dim=-1)
            logits = log_scale.exp().clamp(max=100.0) * zi @ zt.T
            mask = pos_t[torch.from_numpy(owners)][:, torch.from_numpy(caps)]
            neg_inf = torch.finfo(logits.dtype).min
            i2t = torch.logsumexp(logits.masked_fill(~mask, neg_inf), 1) - torch.logsumexp(logits, 1)
            t2i = torch.logsumexp(logits.masked_fill(~mask, neg_inf), 0) - torch.logsumexp(logits, 0)
            loss = -(i2t.mean() + t2i.mean()) / 2
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            bar.update(task, advance=1, description=f"train heads (loss {loss.item():.3f})")
    sd = {f"image.{k}": v.detach().numpy() for k, v in image.state_dict().items()}
    sd.update({f"text.{k}": v.detach().numpy() for k, v in text.state_dict().items()})
    return {
        **sd,
        "feature_mean": mean.astype(np.float32),
        "feature_std": std.astype(np.float32),
        "logit_scale": np.float32(log_scale.exp().item()),
        "final_loss": np.float32(loss.item()),
    }


def heldout_report(weights: dict[str, Any], split, text_encoder) -> dict[str, float]:  # noqa: ANN001
    """Category accuracy (33 prompts, views' max) and colour accuracy (the asset's category in each of its
    category's colours) of held-out variants."""
    from retrieval.encoders.aligned import AlignedEncoder
    from retrieval.procedural.library import RECIPES

    enc = AlignedEncoder.from_arrays(weights, text_encoder)
    img = enc.project_features(split.features)
    cats = list(dict.fromkeys(a.category for a in split.attrs))  # the categories evaluated (and trained on)
    prompts = enc.encode_texts([f"a photo of a {c.replace('_', ' ')}" for c in cats])
    right_cat, right_col, n_col = 0, 0, 0
    for k, a in enumerate(split.attrs):
        views = img[split.view_asset == k]
        right_cat += cats[int(np.argmax((views @ prompts.T).max(0)))] == a.category
        colours = sorted({v.color for v in RECIPES[a.category].variants})
        if len(colours) > 1:
            name = a.category.replace("_", " ")
            texts = enc.encode_texts([f"a {c} {name}" for c in colours])
            n_col += 1
            right_col += colours[int(np.argmax((views @ texts.T).max(0)))] in a.colours
    n = len(split.attrs)
    return {
        "heldout_assets": n,
        "category_accuracy": round(right_cat / n, 4),
        "colour_accuracy": round(right_col / max(n_col, 1), 4),
    }


def train(cfg: TrainConfig, out: Path = DEFAULT_WEIGHTS, progress: bool = True) -> dict[str, Any]:
    """Build the data, fit the heads, write `out` (npz) and `out`.json (config, data sizes, held-out report)."""
    import torch

    from retrieval.aligned.dataset import CALIBRATION_SEED0, HELDOUT_SEED0, TRAIN_SEED0, build_split
    from retrieval.aligned.features import FEATURE_VERSION
    from retrieval.encoders.text import TextEncoder
    from retrieval.procedural import category_names

    torch.set_num_threads(1)  # one thread: the same floating-point sums every run, so the same weights
    t0 = time.perf_counter()
    cats = list(cfg.categories) if cfg.categories else category_names()
    unknown = sorted(set(cats) - set(category_names()))
    if unknown:
        raise ConfigError(
            f"unknown procedural categories {unknown} in params section 'aligned'; valid: {', '.join(category_names())}"
        )
    train_split = build_split(
        cats, list(range(TRAIN_SEED0, TRAIN_SEED0 + cfg.train_seeds)), cfg.n_views, cfg.image_size, progress=progress
    )
    held = build_split(
        cats,
        list(range(HELDOUT_SEED0, HELDOUT_SEED0 + cfg.heldout_seeds)),
        cfg.n_views,
        cfg.image_size,
        progress=progress,
    )
    calib = build_split(
        cats,
        list(range(CALIBRATION_SEED0, CALIBRATION_SEED0 + cfg.calibration_seeds)),
        cfg.n_views,
        cfg.image_size,
        progress=progress,
    )
    t_data = time.perf_counter() - t0
    te = TextEncoder(None)
    texts, _, pos = caption_bank(train_split.attrs, cfg.captions_per_asset, cfg.seed)
    weights = fit(train_split, te.encode(texts), pos, cfg, progress)
    report = heldout_report(weights, held, te)
    from retrieval.encoders.aligned import AlignedEncoder

    # The labelled calibration set, as joint-space view embeddings: Scorers derive per-description thresholds
    # from it for whatever pool they match against (AlignedEncoder.thresholds).
    weights["calibration_embeddings"] = (
        AlignedEncoder.from_arrays(weights, te).project_features(calib.features).astype(np.float16)
    )
    weights["calibration_view_asset"] = calib.view_asset.astype(np.int32)
    weights["calibration_category"] = np.array([a.category for a in calib.attrs])
    meta = {
        "config": asdict(cfg),
        "feature_version": FEATURE_VERSION,
        "text_model": te.name,
        "train_assets": len(train_split.attrs),
        "train_views": len(train_split.features),
        "captions": len(texts),
        "final_loss": round(float(weights["final_loss"]), 4),
        "seconds": {"data": round(t_data, 1), "total": round(time.perf_counter() - t0, 1)},
        "heldout": report,
    }
    write_npz(
        {
            "feature_version": np.str_(FEATURE_VERSION),
            "text_model": np.str_(te.name),
            **{k: v for k, v in weights.items() if k != "final_loss"},
        },
        out,
    )
    out.with_suffix(".json").write_text(
        json.dumps({k: v for k, v in meta.items() if k != "seconds"}, indent=2, sort_keys=True) + "\n"
    )
    return meta


def main(argv: list[str] | None = None) -> None:
    """`python -m retrieval.aligned.train [--params retrieval/params.yaml] [--out retrieval/models/aligned.npz]`."""
    import yaml

    ap = argparse.ArgumentParser(prog="python -m retrieval.aligned.train", description=__doc__.splitlines()[0])
    ap.add_argument("--params", type=Path, default=Path("retrieval/params.yaml"))
    ap.add_argument("--out", type=Path, default=DEFAULT_WEIGHTS)
    a = ap.parse_args(argv)
    params = yaml.safe_load(a.params.read_text()) or {}
    meta = train(train_config(params.get("aligned")), a.out)
    print(json.dumps(meta, indent=2))


if __name__ == "__main__":
    main()
