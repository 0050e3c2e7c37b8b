"""`curbside catalog ingest` and `curbside catalog eval`: the retrieval pipeline's commands (registered on the catalog group)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from enum import Enum
from pathlib import Path

import typer

from catalogs import DEFAULT_CATALOG  # light: only the schema constants
from curbside.cli.errors import RunError, UsageError, catalog_cli_errors
from curbside.cli.executor_options import Executor  # kernel.executors.EXECUTORS, one choice across the CLI
from retrieval import defaults  # the pipeline's defaults and view limit (no imports)
from retrieval.defaults import MAX_VIEWS

# Option choices as Enums and ranges, so click refuses a bad value before the catalog is touched: a bad value
# reaching the per-asset steps would be recorded as every asset's rejection.
Scorer = Enum(
    "Scorer",
    {"aligned": "aligned", "imagenet": "imagenet", "clip": "clip", "blip": "blip", "blip2": "blip2", "none": "none"},
    type=str,
)  # retrieval.scoring.IMAGE_ENCODERS
MeshSet = Enum("MeshSet", {"procedural": "procedural", "primitives": "primitives"}, type=str)
Calibration = Enum(
    "Calibration", {"softmax": "softmax", "zscore": "zscore", "none": "none"}, type=str
)  # scoring.CALIBRATIONS
Thresholds = Enum("Thresholds", {"global": "global", "calibrated": "calibrated"}, type=str)  # scoring.THRESHOLDS


@contextlib.contextmanager
def _source_errors() -> Iterator[None]:
    """Map a source that cannot list its assets, or a stopped run, to the CLI's one-line errors."""
    from retrieval.ingest import TooManyRejections
    from retrieval.sources import SourceError

    try:
        yield
    except (SourceError, TooManyRejections) as e:
        raise RunError(str(e)) from e


def register(app: typer.Typer) -> None:
    """Add the retrieval commands to the `catalog` group."""

    @app.command("ingest")
    def ingest_cmd(
        source: str = typer.Option("procedural", help="objaverse | objaverse-xl[:SOURCES] | local:DIR | procedural"),
        limit: int = typer.Option(None, min=1, help="at most this many assets from the source"),
        executor: Executor = typer.Option(Executor.local.value, help="where the per-asset steps run"),
        address: str = typer.Option(None, help="Ray cluster address (with --executor ray)"),
        workers: int = typer.Option(None, min=1, help="worker processes (process/ray executors)"),
        catalog: Path = typer.Option(Path(DEFAULT_CATALOG), help="catalog file (created if missing)"),
        scorer: Scorer = typer.Option(defaults.DEFAULT_IMAGE_ENCODER, help="image encoder"),
        clip_model: str = typer.Option(None, help="CLIP/BLIP/BLIP-2 weights folder (with --scorer clip|blip|blip2)"),
        views: int = typer.Option(defaults.DEFAULT_N_VIEWS, min=1, max=MAX_VIEWS, help="rendered views per asset"),
        calibration: Calibration = typer.Option(
            defaults.DEFAULT_CALIBRATION, help="per-signal calibration over the pool"
        ),
        thresholds: Thresholds = typer.Option(
            defaults.DEFAULT_THRESHOLDS,
            help="global: one threshold; calibrated: per description, from the aligned scorer's labelled set",
        ),
        per_category: int = typer.Option(defaults.DEFAULT_PER_CATEGORY, min=1, help="procedural variants per category"),
        objaverse_cache: Path = typer.Option(None, help="objaverse / objaverse-xl cache folder (default ~/.objaverse)"),
    ) -> None:
        """Retrieve assets from a source, render, score and curate them into the catalog (resumable)."""
        from rich import print as rprint

        from retrieval.ingest import IngestConfig, ingest
        from retrieval.scoring import ScoringConfig
        from retrieval.sources import open_source

        opts: dict = {}
        if source == "procedural":
            opts = {"per_category": per_category, "work_dir": catalog.parent / ".procedural_source"}
        elif source.split(":")[0] in ("objaverse", "objaverse-xl") and objaverse_cache:
            opts = {"cache_dir": objaverse_cache}
        try:
            src = open_source(source, **opts)
            config = IngestConfig(
                n_views=views,
                scoring=ScoringConfig(
                    image_encoder=Scorer(scorer).value,
                    clip_model=clip_model,
                    calibration=Calibration(calibration).value,
                    thresholds=Thresholds(thresholds).value,
                ),
            )
        except (ValueError, FileNotFoundError) as exc:
            raise UsageError(str(exc)) from None
        with catalog_cli_errors(catalog), _source_errors():
            report = ingest(
                src, catalog, config, executor=Executor(executor).value, workers=workers, address=address, limit=limit
            )
        rprint(
            f"[bold]ingest[/bold] {source} -> {catalog}: written {report.written}, rejected {report.rejected} "
            f"{report.reasons}, skipped {report.skipped}, duplicates {report.duplicates}"
        )

    @app.command("eval")
    def eval_cmd(
        per_category: int = typer.Option(1, min=1, help="procedural assets per category in the built-in labelled set"),
        scorer: Scorer = typer.Option(defaults.DEFAULT_IMAGE_ENCODER, help="image encoder"),
        clip_model: str = typer.Option(None, help="CLIP/BLIP/BLIP-2 weights folder (with --scorer clip|blip|blip2)"),
        objaverse_cache: Path = typer.Option(None, help="evaluate on this objaverse cache's LVIS labels instead"),
        mesh_set: MeshSet = typer.Option(
            MeshSet.procedural.value,
            help="procedural: held-out library variants; primitives: hand-built meshes the scorer never trained on",
        ),
        limit: int = typer.Option(None, min=1, help="at most this many assets"),
        calibration: Calibration = typer.Option(
            defaults.DEFAULT_CALIBRATION, help="per-signal calibration over the pool"
        ),
        thresholds: Thresholds = typer.Option(
            defaults.DEFAULT_THRESHOLDS,
            help="global: one threshold; calibrated: per description, from the aligned scorer's labelled set",
        ),
    ) -> None:
        """Retrieval quality (category accuracy, precision@k) on a labelled set."""
        import tempfile

        from retrieval.evaluation import evaluate
        from retrieval.ingest import IngestConfig
        from retrieval.scoring import ScoringConfig
        from retrieval.sources import open_source

        try:
            config = IngestConfig(
                scoring=ScoringConfig(
                    image_encoder=Scorer(scorer).value,
                    clip_model=clip_model,
                    calibration=Calibration(calibration).value,
                    thresholds=Thresholds(thresholds).value,
                )
            )
        except (ValueError, FileNotFoundError) as exc:
            raise UsageError(str(exc)) from None
        with tempfile.TemporaryDirectory() as tmp, _source_errors():
            if objaverse_cache:
                src = open_source("objaverse", cache_dir=objaverse_cache)
            elif MeshSet(mesh_set) == MeshSet.primitives:
                from retrieval.primitive_set import build_set

                build_set(Path(tmp) / "primitives")
                src = open_source(f"local:{Path(tmp) / 'primitives'}")
            else:
                src = open_source("procedural", per_category=per_category, work_dir=Path(tmp) / "proc")
            report = evaluate(src, config, limit=limit)
        typer.echo(report.table())
