"""The ingest stage: source items -> normalise -> render -> score -> curate -> catalog rows, resumable.

`process_item` is a pure per-asset function (files under the asset folder, records returned) that any executor
runs; `ingest` writes its results from one process. Per asset the rows are written views, embeddings, matches,
then the asset row last: the asset row (with its content hash) marks the asset finished, so a run killed midway
redoes at most the unfinished asset, and primary-key upserts make the redo replace rather than duplicate.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from catalogs.records import AssetRecord, MatchRecord, RejectionRecord, ViewRecord
from catalogs.schema import ASSET_IMAGE_KIND, ASSET_TEXT_KIND
from curbside.config import ConfigError
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

    def __post_init__(self) -> None:
        # Checked here, once, so a bad value stops the run before any asset: inside process_item it would
        # become a per-asset rejection of every asset, remembered by content hash (issue 12: --views 0).
        from retrieval.render import MAX_VIEWS

        if not (isinstance(self.n_views, int) and 1 <= self.n_views <= MAX_VIEWS):
            raise ConfigError(f"n_views must be an integer in 1..{MAX_VIEWS}, got {self.n_views!r}; e.g. --views 8")
        if not (isinstance(self.n_informative, int) and self.n_informative >= 1):
            raise ConfigError(f"n_informative must be an integer >= 1, got {self.n_informative!r}")
        if not (isinstance(self.image_size, int) and self.image_size >= 16):
            raise ConfigError(f"image_size must be an integer >= 16 pixels, got {self.image_size!r}")
        if len(self.elevations) != 2:
            raise ConfigError(f"elevations must be two angles in degrees, got {self.elevations!r}")
        if self.max_rejections is not None and self.max_rejections < 0:
            raise ConfigError(f"max_rejections must be >= 0 or None, got {self.max_rejections!r}")


def config_hash(config: IngestConfig) -> str:
    """Short hash of everything in the configuration that can change an asset's verdict (not max_rejections)."""
    d = dataclasses.asdict(config)
    d.pop("max_rejections", None)  # a run-level stop rule: it never decides one asset's fate
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


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


def _reject(item: SourceItem, h: str, stage: str, reason: str, detail: str, config: IngestConfig) -> ItemResult:
    # The content hash in the detail lets a re-run skip the same bytes yet retry a fixed file; the config hash
    # makes a run under another configuration retry it too.
    rec = RejectionRecord(item.source, item.source_id, stage, reason, f"{detail} [sha256:{h[:16]}]",
                          config_hash(config))
    return ItemResult(item.source, item.source_id, h, rejection=rec)


def process_item(item: SourceItem, config: IngestConfig, pool: DescriptionPool, asset_root: str,
                 catalog_dir: str) -> ItemResult:
    """Normalise, render, score and curate one item; never raises for a bad asset (returns a rejection)."""
    h = item.content_hash()
    if "rejected" in item.metadata:  # refused by the source's prefilter (licence, annotated size, download)
        reason, detail = item.metadata["rejected"]
        return _reject(item, h, "fetch", reason, detail, config)
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
        return _reject(item, h, stage, rej.reason, rej.detail, config)
    except ConfigError:
        raise  # a bad configuration is wrong for every asset: stop the run, never blame (and skip) the asset
    except Exception as exc:  # noqa: BLE001 - one broken asset must never stop the stage; the reason is kept
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return _reject(item, h, stage, "error", tb[:400], config)


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
    from catalogs.writer import CatalogWriter

    config = config or IngestConfig()
    catalog_path = Path(catalog_path)
    report = IngestReport()
    created = not catalog_path.exists()
    try:
        with CatalogWriter(catalog_path) as writer:
            _ingest_into(writer, source, catalog_path, config, report, executor=executor, workers=workers,
                         address=address, limit=limit, progress=progress)
    except BaseException:
        if created and report.written == 0 and report.rejected == 0:
            # Nothing was recorded (e.g. the source was unreachable): leave no empty catalog that looks built.
            _remove_empty_catalog(catalog_path)
        raise
    return report


def _remove_empty_catalog(catalog_path: Path) -> None:
    """Delete a catalog this run created and wrote nothing to (its file, WAL and empty asset folders)."""
    from catalogs.writer import asset_root

    for f in (catalog_path, Path(str(catalog_path) + ".wal")):
        f.unlink(missing_ok=True)
    root = asset_root(catalog_path)
    if root.is_dir() and not any(p.is_file() for p in root.rglob("*")):
        import shutil

        shutil.rmtree(root, ignore_errors=True)


def _ingest_into(writer, source, catalog_path: Path, config: IngestConfig, report: IngestReport, *,  # noqa: ANN001
                 executor: str, workers: int | None, address: str | None, limit: int | None, progress: bool) -> None:
    """The body of `ingest` on an open writer; fills `report`."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from catalogs.writer import asset_root
    from retrieval.curation import load_size_priors
    from retrieval.executors import check_executor, run_map
    from retrieval.scoring import cached_scorer, load_pool

    check_executor(executor)  # before any asset: a typo here must not cost a run
    con = writer.con
    done = {(s, i): h for s, i, h in con.execute("SELECT source, source_id, content_hash FROM assets").fetchall()}
    # A rejection is final only for the same bytes under the same configuration; download failures are
    # transient and always retried. Rows from before config_hash existed (NULL) are retried once.
    cfg = config_hash(config)
    refused = {(s, i): d for s, i, d in con.execute(
        "SELECT source, source_id, detail FROM rejections WHERE config_hash = ? AND reason <> 'download_failed'",
        [cfg]).fetchall()}
    pending = []
    for item in source.items(limit):
        key = (item.source, item.source_id)
        if key in done or key in refused:
            h = item.content_hash()
            if done.get(key) == h or (refused.get(key) or "").endswith(f"[sha256:{h[:16]}]"):
                report.skipped += 1
                continue
        pending.append(item)
    # Models load after the source listed its items: an unreachable source fails in seconds, not after them.
    pool = load_pool(con, sorted(load_size_priors()))
    # Build the scorer now: a missing model folder is a configuration error of the run, not of each asset.
    cached_scorer(config.scoring, pool)
    record_pool(writer, pool, config)
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
