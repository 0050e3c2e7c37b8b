"""The ingest stage: source items -> normalise -> render -> score -> curate -> catalog rows, resumable.

`process_item` is a pure per-asset function (files under the asset folder, records returned) that any executor
runs; `ingest` writes its results from one process. Per asset the rows are written views, embeddings, matches,
then the asset row last: the asset row (with its content hash) marks the asset finished, so a run killed midway
redoes at most the unfinished asset, and primary-key upserts make the redo replace rather than duplicate.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.records import AssetRecord, MatchRecord, RejectionRecord, ViewRecord
from catalogs.schema import ASSET_IMAGE_KIND, ASSET_TEXT_KIND
from retrieval.normalize import AssetRejected, QualityLimits
from retrieval.scoring import DescriptionPool, ScoringConfig
from retrieval.sources import SourceItem
from retrieval.steps import (
    asset_dir_for,
    asset_id_for,
    curate_step,
    normalise_step,
    render_step,
    score_step,
    view_records,
)

IMAGE_EMBEDDING_KIND = ASSET_IMAGE_KIND
TEXT_EMBEDDING_KIND = ASSET_TEXT_KIND


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


def _reject(item: SourceItem, h: str, stage: str, reason: str, detail: str) -> ItemResult:
    # The content hash in the detail lets a re-run skip the same bytes yet retry a fixed file.
    rec = RejectionRecord(item.source, item.source_id, stage, reason, f"{detail} [sha256:{h[:16]}]")
    return ItemResult(item.source, item.source_id, h, rejection=rec)


def process_item(item: SourceItem, config: IngestConfig, pool: DescriptionPool, asset_root: str,
                 catalog_dir: str) -> ItemResult:
    """Normalise, render, score and curate one item; never raises for a bad asset (returns a rejection)."""
    h = item.content_hash()
    if "rejected" in item.metadata:  # refused by the source's prefilter (licence, annotated size, download)
        reason, detail = item.metadata["rejected"]
        return _reject(item, h, "fetch", reason, detail)
    stage = "normalize"
    times: dict[str, float] = {}
    try:
        out = asset_dir_for(item, Path(asset_root))
        t0 = time.perf_counter()
        norm = normalise_step(item, config, out)
        times["normalize"] = time.perf_counter() - t0

        stage = "render"
        t0 = time.perf_counter()
        rendered = render_step(item, norm.obj, norm.canon.mesh.bounds, config, out)
        views = view_records(asset_id_for(item), rendered,
                             [f.relative_to(catalog_dir).as_posix() for f in rendered.files])
        times["render"] = time.perf_counter() - t0

        stage = "score"
        t0 = time.perf_counter()
        scores, top = score_step(item, [rendered.images[i] for i in rendered.selected], config, pool)
        times["score"] = time.perf_counter() - t0

        stage = "curate"
        t0 = time.perf_counter()
        asset, matches = curate_step(item, h, norm.canon, scores, top, rendered.selected, config, pool, out,
                                     catalog_dir)
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


@dataclass
class IngestReport:
    """Counts and per-stage timings of one ingest run."""

    written: int = 0
    rejected: int = 0
    skipped: int = 0
    duplicates: int = 0
    pruned_matches: int = 0
    seconds: dict[str, float] = field(default_factory=dict)
    reasons: dict[str, int] = field(default_factory=dict)


def ingest(source, catalog_path: str | Path, config: IngestConfig | None = None, *, executor: str = "local",  # noqa: ANN001
           workers: int | None = None, address: str | None = None, limit: int | None = None,
           progress: bool = True) -> IngestReport:
    """Run the stage for a source into the catalog at `catalog_path` (created if missing); resumable."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from catalogs.writer import CatalogWriter, asset_root
    from retrieval.curation import load_size_priors
    from retrieval.executors import run_map
    from retrieval.scoring import load_pool

    config = config or IngestConfig()
    catalog_path = Path(catalog_path)
    report = IngestReport()
    with CatalogWriter(catalog_path) as writer:
        con = writer.con
        pool = load_pool(con, sorted(load_size_priors()))
        record_pool(writer, pool, config)
        done = {(s, i): h for s, i, h in con.execute("SELECT source, source_id, content_hash FROM assets").fetchall()}
        refused = {(s, i): d for s, i, d in con.execute("SELECT source, source_id, detail FROM rejections").fetchall()}
        pending = []
        for item in source.items(limit):
            key = (item.source, item.source_id)
            if key in done or key in refused:
                h = item.content_hash()
                if done.get(key) == h or (refused.get(key) or "").endswith(f"[sha256:{h[:16]}]"):
                    report.skipped += 1
                    continue
            pending.append(item)
        root = asset_root(catalog_path)
        args = (config, pool, str(root), str(catalog_path.parent))
        columns = (TextColumn("[bold]ingest {task.fields[src]}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with Progress(*columns, disable=not progress) as bar:
            task = bar.add_task("ingest", total=len(pending), src=getattr(source, "name", "?"))
            for res in run_map(process_item, pending, executor=executor, workers=workers, address=address, args=args):
                with writer.transaction():  # one asset lands whole or not at all, even under SIGKILL
                    _write_result(writer, res, config, catalog_path)
                for k, v in res.seconds.items():
                    report.seconds[k] = report.seconds.get(k, 0.0) + v
                if res.rejection is not None:
                    report.rejected += 1
                    report.reasons[res.rejection.reason] = report.reasons.get(res.rejection.reason, 0) + 1
                    if config.max_rejections is not None and report.rejected > config.max_rejections:
                        raise TooManyRejections(
                            f"{report.rejected} assets rejected (> max_rejections {config.max_rejections}); last: "
                            f"{res.source_id}: {res.rejection.reason}. Check the source, or raise max_rejections; "
                            f"finished assets are kept and a re-run resumes")
                else:
                    report.written += 1
                bar.advance(task)
        from retrieval.finalize import finalize

        report.pruned_matches, report.duplicates = finalize(writer, config)
    return report


def record_pool(writer, pool: DescriptionPool, config: IngestConfig) -> None:  # noqa: ANN001 - CatalogWriter
    """Store the category prompts (and their embeddings) when they are the pool, so matches reference real rows."""
    from retrieval.scoring import cached_scorer

    if pool.origin != "category_prompts":
        return
    from catalogs.records import DescriptionRecord

    scorer = cached_scorer(config.scoring, pool)
    writer.upsert_descriptions(DescriptionRecord(i, t, c, sources=["category_prompt"])
                               for i, t, c in zip(pool.ids, pool.texts, pool.categories))
    if scorer.pool_text.shape[1] == writer.embedding_dim:
        writer.upsert_embeddings("description", list(pool.ids), scorer.pool_text)


def _write_result(writer, res: ItemResult, config: IngestConfig, catalog_path: Path) -> None:  # noqa: ANN001
    """Write one result; the asset row goes last because it marks the asset finished."""
    con = writer.con
    aid = f"{res.source}:{res.source_id}"
    if res.rejection is not None:
        # A file that changed and now fails must not leave its old rows behind.
        for table in ("matches", "views"):
            con.execute(f"DELETE FROM {table} WHERE asset_id = ?", [aid])
        con.execute("DELETE FROM embeddings WHERE owner_id = ? AND owner_kind IN (?, ?)",
                    [aid, IMAGE_EMBEDDING_KIND, TEXT_EMBEDDING_KIND])
        con.execute("DELETE FROM assets WHERE asset_id = ?", [aid])
        writer.record_rejections([res.rejection])
        return
    con.execute("DELETE FROM rejections WHERE source = ? AND source_id = ?", [res.source, res.source_id])
    con.execute("DELETE FROM views WHERE asset_id = ?", [aid])
    con.execute("DELETE FROM matches WHERE asset_id = ?", [aid])
    writer.upsert_views(res.views)
    if res.text_embedding is not None:
        writer.upsert_embeddings(TEXT_EMBEDDING_KIND, [aid], res.text_embedding[None, :])
    if res.image_embedding is not None:
        if res.image_embedding.shape[0] == writer.embedding_dim:
            writer.upsert_embeddings(IMAGE_EMBEDDING_KIND, [aid], res.image_embedding[None, :],
                                     model=config.scoring.scorer_name.split(":")[0])
        else:
            # CLIP's space has another width than the catalog's FLOAT[n] column: kept next to the asset instead.
            from catalogs.writer import asset_root

            np.save(asset_root(catalog_path) / "retrieval" / res.source / Path(res.asset.mesh_path).parent.name /
                    "image_embedding.npy", res.image_embedding)
    writer.upsert_matches(res.matches)
    writer.upsert_assets([res.asset])
