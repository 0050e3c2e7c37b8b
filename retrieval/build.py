"""Build a catalog from curbside's procedural street-object library: generate, export, write, embed (atomically)."""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

from catalogs.layout import asset_root, procedural_asset_dir
from catalogs.schema import ASSET_TEXT_KIND
from catalogs.writer import build_catalog

MAX_VARIANTS = 1000  # variants per category in one build; keeps the seeds of different build seeds disjoint


@dataclass
class BuildReport:
    """What a build wrote: where, how many assets per category, with which seeds and embedding model."""

    path: Path
    n_assets: int
    per_category: dict[str, int]
    variants: int
    seed: int
    variant_seeds: list[int]
    embedding_model: str
    seconds: float
    asset_ids: list[str] = field(default_factory=list)


def variant_seeds(seed: int, variants: int) -> list[int]:
    """The per-variant generator seeds derived from the build seed (the same for every category)."""
    if not 1 <= variants <= MAX_VARIANTS:
        raise ValueError(f"variants must be between 1 and {MAX_VARIANTS}, got {variants}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    # Readable and disjoint: build seed 0 gives variants 0, 1, 2...; build seed 1 gives 1000, 1001...
    return [int(seed) * MAX_VARIANTS + i for i in range(int(variants))]


def asset_text(category: str, description: str, synonyms: list[str]) -> str:
    """The text embedded for search: category words, description and synonyms."""
    words = category.replace("_", " ")
    syn = ", ".join(synonyms)
    return f"{words}. {description}. {syn}." if syn else f"{words}. {description}."


def build_procedural_catalog(
    path: str | Path,
    variants: int = 3,
    seed: int = 0,
    categories: list[str] | None = None,
    progress: bool = True,
    text_model: str | None = None,
) -> BuildReport:
    """Generate `variants` variants per category, export their files, write and embed them into a new catalog."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from retrieval.encoders.text import TextEncoder
    from retrieval.procedural import category_names, export_asset, generate, to_record

    t0 = time.perf_counter()
    path = Path(path)
    names = category_names()
    if categories is not None:
        unknown = [c for c in categories if c not in names]
        if unknown:
            raise ValueError(f"unknown procedural categories {unknown}; valid categories: {', '.join(names)}")
        names = list(categories)
    seeds = variant_seeds(seed, variants)
    root = asset_root(path)
    # Folders this build adds: a failed build (a full disk, an interrupt) removes them, so no asset file is left
    # that no catalog lists. Folders of the previous build stay: its catalog still lists them.
    created = [d for d in (root, *(root / c for c in names)) if not d.exists()]
    root.mkdir(parents=True, exist_ok=True)
    console = Console(stderr=True)
    jobs = [(c, s) for c in names for s in seeds]
    records = []
    try:
        with Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=console,
            disable=not progress,
            transient=False,
        ) as bar:
            task = bar.add_task("generating assets", total=len(jobs))
            for category, s in jobs:
                bar.update(task, description=f"generating {category}")
                asset = generate(category, s)
                # One folder per asset, named like its id (procedural/<category>/<seed>).
                folder = procedural_asset_dir(root, category, s)
                if not folder.exists():
                    created.append(folder)
                exported = export_asset(asset, folder)
                records.append(to_record(asset, exported, path.parent))
                bar.advance(task)
            bar.update(task, description="embedding asset texts")
            encoder = TextEncoder(text_model)
            vectors = encoder.encode([asset_text(r.category, r.description, r.synonyms) for r in records])
            bar.update(task, description="writing catalog")
            with (
                build_catalog(path, embedding_dim=encoder.dim, embedding_model=encoder.name) as writer,
                writer.transaction(),
            ):
                writer.upsert_assets(records)
                writer.upsert_embeddings(ASSET_TEXT_KIND, [r.asset_id for r in records], vectors)
                writer.set_meta(
                    {
                        "built_by": "retrieval.build.build_procedural_catalog",
                        "build_variants": str(variants),
                        "build_seed": str(seed),
                        "build_categories": ",".join(names),
                    }
                )
            bar.update(task, description="catalog written")
    except BaseException:
        for d in reversed(created):
            shutil.rmtree(d, ignore_errors=True)
        raise
    per_category: dict[str, int] = {}
    for r in records:
        per_category[r.category] = per_category.get(r.category, 0) + 1
    return BuildReport(
        path=path,
        n_assets=len(records),
        per_category=per_category,
        variants=variants,
        seed=seed,
        variant_seeds=seeds,
        embedding_model=encoder.name,
        seconds=time.perf_counter() - t0,
        asset_ids=[r.asset_id for r in records],
    )
