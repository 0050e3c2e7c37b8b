"""`curbside catalog ingest` and `curbside catalog eval`: the retrieval pipeline's commands (registered on the catalog group)."""

from __future__ import annotations

from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    """Add the retrieval commands to the `catalog` group."""

    @app.command("ingest")
    def ingest_cmd(
        source: str = typer.Option("procedural", help="objaverse | local:DIR | procedural"),
        limit: int = typer.Option(None, help="at most this many assets from the source"),
        executor: str = typer.Option("local", help="local | process | ray"),
        address: str = typer.Option(None, help="Ray cluster address (with --executor ray)"),
        workers: int = typer.Option(None, help="worker processes (process/ray executors)"),
        catalog: Path = typer.Option(Path("catalogs/default.duckdb"), help="catalog file (created if missing)"),
        scorer: str = typer.Option("imagenet", help="image encoder: imagenet | clip | none"),
        clip_model: str = typer.Option(None, help="CLIP weights folder (with --scorer clip)"),
        views: int = typer.Option(8, help="rendered views per asset (1-20)"),
        calibration: str = typer.Option("softmax", help="per-signal calibration over the pool: softmax | zscore | none"),
        per_category: int = typer.Option(2, help="procedural variants per category"),
        objaverse_cache: Path = typer.Option(None, help="objaverse cache folder (default ~/.objaverse)"),
    ) -> None:
        """Retrieve assets from a source, render, score and curate them into the catalog (resumable)."""
        from rich import print as rprint

        from retrieval.ingest import IngestConfig, ingest
        from retrieval.scoring import ScoringConfig
        from retrieval.sources import open_source

        opts: dict = {}
        if source == "procedural":
            opts = {"per_category": per_category, "work_dir": catalog.parent / ".procedural_source"}
        elif source == "objaverse" and objaverse_cache:
            opts = {"cache_dir": objaverse_cache}
        try:
            src = open_source(source, **opts)
            config = IngestConfig(n_views=views, scoring=ScoringConfig(image_encoder=scorer, clip_model=clip_model,
                                                                       calibration=calibration))
        except (ValueError, FileNotFoundError) as exc:
            raise typer.BadParameter(str(exc)) from None
        report = ingest(src, catalog, config, executor=executor, workers=workers, address=address, limit=limit)
        rprint(f"[bold]ingest[/bold] {source} -> {catalog}: written {report.written}, rejected {report.rejected} "
               f"{report.reasons}, skipped {report.skipped}, duplicates {report.duplicates}")

    @app.command("eval")
    def eval_cmd(
        per_category: int = typer.Option(1, help="procedural assets per category in the built-in labelled set"),
        scorer: str = typer.Option("imagenet", help="image encoder: imagenet | clip | none"),
        clip_model: str = typer.Option(None, help="CLIP weights folder (with --scorer clip)"),
        objaverse_cache: Path = typer.Option(None, help="evaluate on this objaverse cache's LVIS labels instead"),
        limit: int = typer.Option(None, help="at most this many assets"),
        calibration: str = typer.Option("softmax", help="per-signal calibration over the pool: softmax | zscore | none"),
    ) -> None:
        """Retrieval quality (category accuracy, precision@k) on a labelled set."""
        import tempfile

        from retrieval.evaluation import evaluate
        from retrieval.ingest import IngestConfig
        from retrieval.scoring import ScoringConfig
        from retrieval.sources import open_source

        try:
            config = IngestConfig(scoring=ScoringConfig(image_encoder=scorer, clip_model=clip_model,
                                                        calibration=calibration))
        except (ValueError, FileNotFoundError) as exc:
            raise typer.BadParameter(str(exc)) from None
        with tempfile.TemporaryDirectory() as tmp:
            if objaverse_cache:
                src = open_source("objaverse", cache_dir=objaverse_cache)
            else:
                src = open_source("procedural", per_category=per_category, work_dir=Path(tmp) / "proc")
            report = evaluate(src, config, limit=limit)
        typer.echo(report.table())
