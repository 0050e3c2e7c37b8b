"""The ingest stage: source items -> normalise -> render -> score -> curate -> catalog rows, resumable.

`process_item` is a pure per-asset function (files under the asset folder, records returned) that any executor
runs; `ingest` writes its results from one process. Per asset the rows are written views, embeddings, matches,
then the asset row last: the asset row (with its content hash) marks the asset finished, so a run killed midway
redoes at most the unfinished asset, and primary-key upserts make the redo replace rather than duplicate.
"""

from __future__ import annotations

import dataclasses
import re
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.records import AssetRecord, MatchRecord, RejectionRecord, ViewRecord
from retrieval.normalize import AssetRejected, QualityLimits
from retrieval.scoring import DescriptionPool, ScoringConfig
from retrieval.sources import SourceItem

IMAGE_EMBEDDING_KIND = "asset_image"
TEXT_EMBEDDING_KIND = "asset"


class TooManyRejections(RuntimeError):
    """More assets were rejected than `max_rejections` allows: the source is probably broken."""


@dataclass(frozen=True)
class IngestConfig:
    """Parameters of the ingest stage (defaults mirror retrieval/params.yaml)."""

    n_views: int = 8
    n_informative: int = 3
    image_size: int = 224
    elevations: tuple[float, float] = (15.0, 40.0)
    scoring: ScoringConfig = ScoringConfig()
    limits: QualityLimits = QualityLimits()
    collision: str = "convex"
    dedupe_threshold: float = 0.995
    max_rejections: int | None = None
    write_glb: bool = True


@dataclass
class ItemResult:
    """What `process_item` returns: the rows of one finished asset, or its rejection."""

    source: str
    source_id: str
    content_hash: str
    asset: AssetRecord | None = None
    views: list[ViewRecord] = field(default_factory=list)
    matches: list[MatchRecord] = field(default_factory=list)
    image_embedding: np.ndarray | None = None
    text_embedding: np.ndarray | None = None
    rejection: RejectionRecord | None = None
    seconds: dict[str, float] = field(default_factory=dict)


def asset_id_for(item: SourceItem) -> str:
    """Stable catalog id of an item: source and source id."""
    return f"{item.source}:{item.source_id}"


def asset_dir_for(item: SourceItem, root: Path) -> Path:
    """Folder of an asset's files under the catalog's asset root."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", item.source_id).strip("_")[:80] or "asset"
    return root / "retrieval" / item.source / slug


def _reject(item: SourceItem, h: str, stage: str, reason: str, detail: str) -> ItemResult:
    # The content hash in the detail lets a re-run skip the same bytes yet retry a fixed file.
    rec = RejectionRecord(item.source, item.source_id, stage, reason, f"{detail} [sha256:{h[:16]}]")
    return ItemResult(item.source, item.source_id, h, rejection=rec)


def process_item(item: SourceItem, config: IngestConfig, pool: DescriptionPool, asset_root: str,
                 catalog_dir: str) -> ItemResult:
    """Normalise, render, score and curate one item; never raises for a bad asset (returns a rejection)."""
    from retrieval.curation import load_size_priors, normalize_size
    from retrieval.normalize import export_collision, export_glb, export_obj, load_canonical, scale_mesh
    from retrieval.render import contact_sheet, render_obj, select_informative, view_specs
    from retrieval.scoring import cached_scorer

    h = item.content_hash()
    stage = "normalize"
    times: dict[str, float] = {}
    try:
        t0 = time.perf_counter()
        canon = load_canonical(item.path, up_axis=item.up_axis, limits=config.limits)
        out = asset_dir_for(item, Path(asset_root))
        obj, _, _ = export_obj(canon, out, "mesh")
        times["normalize"] = time.perf_counter() - t0

        stage = "render"
        t0 = time.perf_counter()
        specs = view_specs(config.n_views, config.elevations)
        images = render_obj(obj, specs, size=config.image_size, bounds=canon.mesh.bounds)
        selected, info = select_informative(images, config.n_informative)
        if max(info) <= 0.0:
            raise AssetRejected("degenerate", "every rendered view is empty")
        from PIL import Image

        (out / "views").mkdir(exist_ok=True)
        views = []
        for i, (spec, im) in enumerate(zip(specs, images)):
            path = out / "views" / f"view_{i:02d}.png"
            Image.fromarray(im).save(path)
            views.append(ViewRecord(asset_id_for(item), i, spec.azimuth, spec.elevation,
                                    path.relative_to(catalog_dir).as_posix(), i in selected, round(info[i], 6)))
        contact_sheet(images, selected, title=f"{item.source}:{item.source_id}").save(out / "contact_sheet.png")
        times["render"] = time.perf_counter() - t0

        stage = "score"
        t0 = time.perf_counter()
        scorer = cached_scorer(config.scoring, pool)
        scores = scorer.score([images[i] for i in selected], item.metadata_text)
        top = scorer.top_matches(scores)
        times["score"] = time.perf_counter() - t0

        stage = "curate"
        t0 = time.perf_counter()
        priors = load_size_priors()
        category = item.category or next((pool.categories[i] for i, _ in top if pool.categories[i]), None)
        if category is None:
            best = int(np.argmax(scores.fused))
            raise AssetRejected("no_match", f"best {pool.ids[best]} at {scores.fused[best]:.3f} < threshold "
                                            f"{config.scoring.threshold}")
        scale, unit = normalize_size(canon.extents, category, priors)
        final = scale_mesh(canon, scale)
        obj, _, _ = export_obj(final, out, "mesh")
        coll = export_collision(final, out) if config.collision == "convex" else None
        glb = export_glb(final, out) if config.write_glb else None
        depth, width, height = (float(x) for x in final.extents)
        prior = priors.get(category)
        aid = asset_id_for(item)
        rel = lambda p: p.relative_to(catalog_dir).as_posix() if p else None  # noqa: E731
        asset = AssetRecord(
            asset_id=aid, source=item.source, source_id=item.source_id, category=category,
            object_class=prior.object_class if prior else "clutter",
            zones=list(prior.zones) if prior else ["clear"], depth=round(depth, 6), width=round(width, 6),
            height=round(height, 6), description=item.description or pool.texts[top[0][0]] if top else (item.description or item.name),
            synonyms=list(item.tags), license=item.license, attribution=item.attribution,
            mesh_path=rel(obj), glb_path=rel(glb), collision=config.collision, collision_path=rel(coll),
            face_count=int(final.mesh.faces.shape[0]), watertight=bool(final.mesh.is_watertight), content_hash=h,
            params={**canon.params, "scale": round(scale, 9), "unit_guess": unit, "name": item.name,
                    "scorer": config.scoring.scorer_name, "informative_views": selected,
                    **{k: v for k, v in item.metadata.items() if k != "companion_files"}},
        )
        matches = [MatchRecord(aid, pool.ids[i], round(s, 6), config.scoring.scorer_name,
                               None if scores.image is None else round(float(scores.image[i]), 6),
                               None if scores.text is None else round(float(scores.text[i]), 6), rank)
                   for rank, (i, s) in enumerate(top, start=1)]
        times["curate"] = time.perf_counter() - t0
        return ItemResult(item.source, item.source_id, h, asset, views, matches, scores.image_embedding,
                          scores.text_embedding, seconds=times)
    except AssetRejected as rej:
        return _reject(item, h, stage, rej.reason, rej.detail)
    except Exception as exc:  # noqa: BLE001 - one broken asset must never stop the stage; the reason is kept
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return _reject(item, h, stage, "error", tb[:400])


def _config_from_dict(d: dict[str, Any]) -> IngestConfig:
    """Build an IngestConfig from a plain (e.g. params.yaml) dict, strict about keys."""
    from curbside.config import merge_strict

    base = dataclasses.asdict(IngestConfig())
    merged = merge_strict(base, d, name="ingest config")
    merged["scoring"] = ScoringConfig(**merged["scoring"])
    merged["limits"] = QualityLimits(**merged["limits"])
    merged["elevations"] = tuple(merged["elevations"])
    return IngestConfig(**merged)


config_from_dict = _config_from_dict
