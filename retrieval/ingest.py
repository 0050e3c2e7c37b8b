"""`ingest`: the fused driver of `retrieval.pipeline`, every item through all four steps, resumable.

`pipeline.process_item` is a pure per-asset function (files under the asset folder, records returned) that any
executor runs; `ingest` writes its results from one process, each asset in one transaction with its asset row
last (the row and its content hash mark the asset finished), so a run killed midway redoes at most the unfinished
asset, and primary-key upserts make the redo replace rather than duplicate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from catalogs.layout import asset_root
from catalogs.writer import CatalogWriter
from retrieval.pipeline import IngestConfig, config_hash, process_item, record_pool, write_result
from retrieval.sources import Source

__all__ = ["IngestConfig", "IngestReport", "TooManyRejections", "config_hash", "ingest"]


class TooManyRejections(RuntimeError):
    """More assets were rejected than `max_rejections` allows: the source is probably broken."""


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


def ingest(
    source: Source,
    catalog_path: str | Path,
    config: IngestConfig | None = None,
    *,
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    limit: int | None = None,
    progress: bool = True,
) -> IngestReport:
    """Run the pipeline on every item of `source` into the catalog at `catalog_path` (created if missing); resumable."""
    config = config or IngestConfig()
    catalog_path = Path(catalog_path)
    report = IngestReport()
    created = not catalog_path.exists()
    try:
        with CatalogWriter(catalog_path) as writer:
            _ingest_into(
                writer,
                source,
                catalog_path,
                config,
                report,
                executor=executor,
                workers=workers,
                address=address,
                limit=limit,
                progress=progress,
            )
    except BaseException:
        if created and report.written == 0 and report.rejected == 0:
            # Nothing was recorded (e.g. the source was unreachable): leave no empty catalog that looks built.
            _remove_empty_catalog(catalog_path)
        raise
    return report


def _remove_empty_catalog(catalog_path: Path) -> None:
    """Delete a catalog this run created and wrote nothing to (its file, WAL and empty asset folders)."""
    for f in (catalog_path, Path(str(catalog_path) + ".wal")):
        f.unlink(missing_ok=True)
    root = asset_root(catalog_path)
    if root.is_dir() and not any(p.is_file() for p in root.rglob("*")):
        import shutil

        shutil.rmtree(root, ignore_errors=True)


def _ingest_into(
    writer: CatalogWriter,
    source: Source,
    catalog_path: Path,
    config: IngestConfig,
    report: IngestReport,
    *,
    executor: str,
    workers: int | None,
    address: str | None,
    limit: int | None,
    progress: bool,
) -> None:
    """The body of `ingest` on an open writer; fills `report`."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from catalogs.categories import NAMES
    from kernel.executors import check_executor, run_map
    from retrieval.scoring import cached_scorer, load_pool

    check_executor(executor)  # before any asset: a typo here must not cost a run
    done = writer.finished_hashes()
    # A rejection is final only for the same bytes under the same configuration; download failures are
    # transient and always retried. Rows from before config_hash existed (NULL) are retried once.
    refused = writer.rejection_details(config_hash(config), retried=("download_failed",))
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
    pool = load_pool(writer.descriptions(), sorted(NAMES))
    # Build the scorer now: a missing model folder is a configuration error of the run, not of each asset.
    cached_scorer(config.scoring, pool)
    record_pool(writer, pool, config)
    root = asset_root(catalog_path)
    args = (config, pool, str(root), str(catalog_path.parent))
    columns = (TextColumn("[bold]ingest {task.fields[src]}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, disable=not progress) as bar:
        task = bar.add_task("ingest", total=len(pending), src=getattr(source, "name", "?"))
        for res in run_map(process_item, pending, executor=executor, workers=workers, address=address, args=args):
            write_result(writer, res, config, catalog_path)  # one asset lands whole or not at all, even under SIGKILL
            for k, v in res.seconds.items():
                report.seconds[k] = report.seconds.get(k, 0.0) + v
            if res.rejection is not None:
                report.rejected += 1
                report.reasons[res.rejection.reason] = report.reasons.get(res.rejection.reason, 0) + 1
                if config.max_rejections is not None and report.rejected > config.max_rejections:
                    raise TooManyRejections(
                        f"{report.rejected} assets rejected (> max_rejections {config.max_rejections}); last: "
                        f"{res.source_id}: {res.rejection.reason}. Check the source, or raise max_rejections; "
                        f"finished assets are kept and a re-run resumes"
                    )
            else:
                report.written += 1
            bar.advance(task)
    from retrieval.finalize import finalize

    report.pruned_matches, report.duplicates = finalize(writer, config)
